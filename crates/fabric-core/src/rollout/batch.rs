//! Batched evaluation of GFCOP candidates ("Do in Parallel" of GFCS Alg. 1) with rayon.
//!
//! Each candidate is rolled out from the same fresh start with its own sequence, so a result depends
//! only on its candidate row: results are bit-identical whatever the thread count.

use rayon::prelude::*;

use super::rollout::{validate_start, Buffers};
use super::sequence::{run_sequence, SequenceOptions, SequenceResult};
use super::system::System;
use crate::error::{check_finite, check_len, FabricError, Result};

/// Run `f` on a rayon pool of `threads` threads, or on the current pool (rayon's default, one thread per
/// core unless configured) when `None`. `Some(0)` is an error.
pub(crate) fn with_threads<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> T + Send,
) -> Result<T> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(FabricError::Value {
            what: "threads".to_string(),
            message: "must be >= 1".to_string(),
        }),
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| FabricError::Value {
                    what: "threads".to_string(),
                    message: format!("cannot build a pool of {n} threads: {e}"),
                })?;
            Ok(pool.install(f))
        }
    }
}

/// Cost (and details) of N candidate command sequences for any [`System`] (GFCS eq. 4 for each).
///
/// * `q0`, `qd0`, `goal`: (dof,), shared by every candidate.
/// * `candidates`: (N, n·dof) row-major with n = `opts.n_commands` ≥ 1: row j holds q_g¹ … q_gⁿ of
///   candidate j. N = 0 gives an empty result.
/// * `threads`: `Some(k)` runs on a dedicated pool of k threads, `None` on rayon's current pool.
///   Results do not depend on it.
///
/// Returns N results in candidate order; trajectories are kept when `opts.rollout.record` is set.
/// Errors: `Shape` when `candidates.len()` is not a multiple of n·dof, `NonFinite`, `Value` for the
/// options, `n_commands` = 0 or `threads` = 0; the first error of any candidate's evaluation.
pub fn evaluate_batch_system<S: System>(
    system: &S,
    q0: &[f64],
    qd0: &[f64],
    goal: &[f64],
    candidates: &[f64],
    opts: &SequenceOptions,
    threads: Option<usize>,
) -> Result<Vec<SequenceResult>> {
    opts.validate()?;
    let dof = system.dof();
    validate_start(system, q0, qd0, &opts.rollout)?;
    check_len("goal", goal.len(), dof)?;
    check_finite("goal", goal)?;
    if opts.n_commands == 0 {
        return Err(FabricError::Value {
            what: "SequenceOptions.n_commands".to_string(),
            message: "must be >= 1 to split candidates into rows".to_string(),
        });
    }
    let row = opts
        .n_commands
        .checked_mul(dof)
        .filter(|&r| r > 0)
        .ok_or_else(|| FabricError::Value {
            what: "SequenceOptions.n_commands".to_string(),
            message: format!(
                "{} commands of {dof} values give no valid row length",
                opts.n_commands
            ),
        })?;
    if !candidates.chunks_exact(row).remainder().is_empty() {
        return Err(FabricError::Shape {
            what: "candidates".to_string(),
            expected: format!("(N, {row}) row-major, length a multiple of {row}"),
            got: format!("({},)", candidates.len()),
        });
    }
    check_finite("candidates", candidates)?;
    with_threads(threads, || {
        candidates
            .par_chunks(row)
            // one candidate per job: rollouts differ in length by up to 7x (stalls, timeouts), and
            // rayon's default chunks left a thread idle at the end of a batch
            .with_max_len(1)
            .map_init(
                || (system.workspace(), Buffers::new(dof)),
                |(ws, buffers), commands| {
                    run_sequence(system, ws, buffers, q0, qd0, commands, goal, opts)
                },
            )
            .collect::<Result<Vec<_>>>()
    })?
}
