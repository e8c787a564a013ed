//! Batched evaluation of GFCOP candidates ("Do in Parallel" of GFCS Alg. 1) with rayon.
//!
//! Each candidate is rolled out from the same fresh start with its own sequence, so a result depends
//! only on its candidate row: results are bit-identical whatever the thread count.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use rayon::prelude::*;

use super::rollout::{validate_start, Buffers};
use super::sequence::{run_sequence, SequenceOptions, SequenceResult};
use super::system::System;
use crate::error::{check_finite, check_len, FabricError, Result};

/// Most threads a dedicated pool gets: 4 × the cores (`std::thread::available_parallelism`). Batches are
/// CPU-bound, so more threads than cores only add start-up and scheduling cost (a pool of thousands of
/// threads costs seconds to build); callers asking for more get this many (see [`pool_threads`]).
pub fn max_threads() -> usize {
    4 * std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The size of the pool that a request for `threads` threads runs on: `threads` capped at
/// [`max_threads`]. `Err(Value)` for 0.
pub fn pool_threads(threads: usize) -> Result<usize> {
    if threads == 0 {
        return Err(FabricError::Value {
            what: "threads".to_string(),
            message: "must be >= 1".to_string(),
        });
    }
    Ok(threads.min(max_threads()))
}

/// The rayon pool that runs a request for `threads` threads: of [`pool_threads`]`(threads)` threads,
/// built on first use and kept for the life of the process (one per size, at most [`max_threads`]
/// sizes), since building a pool spawns its threads, which costs more than a small batch.
/// `Err(Value)` for 0 threads or when the threads cannot be spawned.
pub fn shared_pool(threads: usize) -> Result<Arc<rayon::ThreadPool>> {
    let n = pool_threads(threads)?;
    static POOLS: OnceLock<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>> = OnceLock::new();
    let pools = POOLS.get_or_init(|| Mutex::new(HashMap::new()));
    // a panic while the lock was held cannot leave the map half-updated: take it anyway
    let mut pools = pools.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(p) = pools.get(&n) {
        return Ok(Arc::clone(p));
    }
    let p = rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .thread_name(move |i| format!("gfcs-{n}-{i}"))
        .build()
        .map_err(|e| FabricError::Value {
            what: "threads".to_string(),
            message: format!("cannot build a pool of {n} threads: {e}"),
        })?;
    let p = Arc::new(p);
    pools.insert(n, Arc::clone(&p));
    Ok(p)
}

/// Run `f` on the shared rayon pool of `threads` threads (capped at [`max_threads`], see
/// [`pool_threads`]), or on the current pool (rayon's default, one thread per core unless configured)
/// when `None`. `Some(0)` is an error.
pub(crate) fn with_threads<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> T + Send,
) -> Result<T> {
    match threads {
        None => Ok(f()),
        Some(n) => Ok(shared_pool(n)?.install(f)),
    }
}

/// Cost (and details) of N candidate command sequences for any [`System`] (GFCS eq. 4 for each).
///
/// * `q0`, `qd0`, `goal`: (dof,), shared by every candidate.
/// * `candidates`: (N, n·dof) row-major with n = `opts.n_commands` ≥ 1: row j holds q_g¹ … q_gⁿ of
///   candidate j. N = 0 gives an empty result.
/// * `threads`: `Some(k)` runs on a shared pool of k threads (at most [`max_threads`]), `None` on
///   rayon's current pool. Results do not depend on it.
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
