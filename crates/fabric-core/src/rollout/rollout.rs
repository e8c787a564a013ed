//! One rollout toward one command: rollout_t of GFCS eq. 1–3.
//!
//! From (q₀, q̇₀), integrate q̈ = f(q, q̇; q_g) (eq. 1) with a fixed step until ‖q − q_g‖ < ε (eq. 3) or
//! the budget t_max is spent, and return t* = min(t, t_max) (eq. 2) with the final state.

use super::integrate::{Integrator, StepScratch};
use super::system::System;
use crate::error::{check_finite, check_len, FabricError, Result};

/// Largest number of steps one rollout may take (t_max / dt): a guard against options that would loop
/// for hours or exhaust memory when recording.
pub const MAX_STEPS: usize = 100_000_000;

/// Rows reserved up front for a recorded trajectory (it grows beyond this if needed).
const RECORD_RESERVE: usize = 1 << 14;

/// Options of one rollout (GFCS eq. 1–3).
#[derive(Clone, Debug, PartialEq)]
pub struct RolloutOptions {
    /// Time step (s), > 0. Default 0.01 s (100 Hz, the rate of both papers).
    pub dt: f64,
    /// Time budget per command t_max (s), > 0. Default 7 s (GFCS Sec. V).
    pub t_max: f64,
    /// Tolerance ε of eq. 3 on the Euclidean joint-space distance ‖q − q_g‖ (rad / m), > 0. Default 0.01.
    pub tol: f64,
    /// Integration scheme. Default semi-implicit Euler (the papers' scheme).
    pub integrator: Integrator,
    /// Keep the trajectory (t, q, q̇, q̈ at every step). Default false.
    pub record: bool,
    /// Stall detection (an extension of eq. 2 that saves computation, not a change of the cost of a
    /// rollout that cannot reach): the rollout keeps the smallest distance ‖q − q_g‖ seen so far; when, at
    /// any step, the last `stall_window` seconds have passed without that distance shrinking by at least
    /// `stall_progress` (rad), the fabric is at rest at a local minimum away from the command (Thm IV.4), or
    /// sliding along a barrier with the speed controller keeping it in motion, and would not reach it before
    /// t_max: the rollout stops with [`StopReason::Stalled`] and t* = t_max. Default 0.5 s and 0.005 rad;
    /// `stall_window = 0` turns it off. A rollout that makes no progress for half a second and then
    /// reaches is counted as failed; that is rare, and the detection saves about half of the
    /// integration steps (docs/tuning.md).
    pub stall_window: f64,
    /// See `stall_window` (rad), ≥ 0.
    pub stall_progress: f64,
    /// Goal capture (rad, ≥ 0; 0 = off, the papers' rule): a rollout that stalls (see `stall_window`)
    /// while ‖q − q_g‖ < `capture_tol` has come to rest where the barriers of nearby obstacles hold it
    /// off its command (a goal 7-10 mm from a shelf's boards: 0.02-0.05 rad off). It stops as
    /// [`StopReason::Reached`] with t* = the time it stalled, and the caller's finishing carries it the
    /// rest of the way (a blend checked for collisions). Only a command tolerance below `capture_tol`
    /// is affected: the looser waypoint tolerance of a sequence is not. Needs stall detection.
    pub capture_tol: f64,
}

impl Default for RolloutOptions {
    fn default() -> Self {
        RolloutOptions {
            dt: 0.01,
            t_max: 7.0,
            tol: 0.01,
            integrator: Integrator::SemiImplicitEuler,
            record: false,
            stall_window: 0.5,
            stall_progress: 0.005,
            capture_tol: 0.0,
        }
    }
}

/// `Err(Value)` naming `what` unless `v` is finite and > 0.
pub(crate) fn check_positive(what: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(FabricError::Value {
            what: what.to_string(),
            message: format!("must be finite and > 0, got {v}"),
        })
    }
}

impl RolloutOptions {
    /// Check dt, t_max, tol finite and > 0, and t_max / dt ≤ [`MAX_STEPS`]. Errors name the field.
    pub fn validate(&self) -> Result<()> {
        check_positive("RolloutOptions.dt", self.dt)?;
        check_positive("RolloutOptions.t_max", self.t_max)?;
        check_positive("RolloutOptions.tol", self.tol)?;
        for (what, v) in [
            ("stall_window", self.stall_window),
            ("stall_progress", self.stall_progress),
            ("capture_tol", self.capture_tol),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(FabricError::Value {
                    what: format!("RolloutOptions.{what}"),
                    message: format!("must be finite and >= 0, got {v}"),
                });
            }
        }
        let ratio = self.t_max / self.dt;
        if ratio > MAX_STEPS as f64 {
            return Err(FabricError::Value {
                what: "RolloutOptions.t_max".to_string(),
                message: format!("t_max / dt = {ratio:e} exceeds the limit of {MAX_STEPS} steps"),
            });
        }
        Ok(())
    }

    /// Steps needed to spend the budget: the smallest k ≥ 1 with k·dt ≥ t_max (up to a relative 1e-9, so
    /// that 7 / 0.01 gives 700 whatever the rounding). Assumes [`RolloutOptions::validate`] passed.
    pub fn max_steps(&self) -> usize {
        let ratio = self.t_max / self.dt;
        let k = (ratio - 1e-9 * ratio.max(1.0)).ceil();
        (k.max(1.0) as usize).min(MAX_STEPS)
    }
}

/// Why a rollout stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum StopReason {
    /// ‖q − q_g‖ < tol (eq. 3) at some step t ≤ t_max, or a stall within [`RolloutOptions::capture_tol`].
    Reached,
    /// The budget t_max was spent without reaching the command.
    Timeout,
    /// The acceleration or the integrated state became NaN or infinite; the rollout stopped at the last
    /// finite state.
    NonFinite,
    /// No progress toward the command over a stall window (see [`RolloutOptions::stall_window`]); counted as
    /// not reached, t* = t_max (within [`RolloutOptions::capture_tol`] of the command: `Reached`).
    Stalled,
}

/// A recorded trajectory: T rows, each (t, q, q̇, q̈) with q̈ = f(q, q̇) the acceleration applied from
/// that row to the next. `t` has shape (T,) in s, strictly increasing; `q`, `qd`, `qdd` have shape
/// (T, dof), row-major.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trajectory {
    /// Coordinates per row.
    pub dof: usize,
    /// Times (s), shape (T,).
    pub t: Vec<f64>,
    /// Configurations, (T, dof) row-major.
    pub q: Vec<f64>,
    /// Velocities, (T, dof) row-major.
    pub qd: Vec<f64>,
    /// Accelerations f(q, q̇), (T, dof) row-major.
    pub qdd: Vec<f64>,
}

impl Trajectory {
    /// An empty trajectory with room for `rows` rows.
    pub fn with_capacity(dof: usize, rows: usize) -> Self {
        Trajectory {
            dof,
            t: Vec::with_capacity(rows),
            q: Vec::with_capacity(rows * dof),
            qd: Vec::with_capacity(rows * dof),
            qdd: Vec::with_capacity(rows * dof),
        }
    }

    /// Number of rows T.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Configuration of row `i` (dof,), or `None` past the end.
    pub fn q_row(&self, i: usize) -> Option<&[f64]> {
        self.q.get(i * self.dof..(i + 1) * self.dof)
    }

    /// Velocity of row `i` (dof,), or `None` past the end.
    pub fn qd_row(&self, i: usize) -> Option<&[f64]> {
        self.qd.get(i * self.dof..(i + 1) * self.dof)
    }

    /// Acceleration of row `i` (dof,), or `None` past the end.
    pub fn qdd_row(&self, i: usize) -> Option<&[f64]> {
        self.qdd.get(i * self.dof..(i + 1) * self.dof)
    }

    /// Append one row (slices of length dof, checked by the callers in this module).
    pub(crate) fn push(&mut self, t: f64, q: &[f64], qd: &[f64], qdd: &[f64]) {
        self.t.push(t);
        self.q.extend_from_slice(q);
        self.qd.extend_from_slice(qd);
        self.qdd.extend_from_slice(qdd);
    }

    /// Remove the last row, if any.
    pub(crate) fn pop(&mut self) {
        if self.t.pop().is_some() {
            let n = self.t.len() * self.dof;
            self.q.truncate(n);
            self.qd.truncate(n);
            self.qdd.truncate(n);
        }
    }

    /// Append every row of `other` (same dof) with its times shifted by `offset` seconds.
    pub(crate) fn append_shifted(&mut self, other: &Trajectory, offset: f64) {
        self.t.extend(other.t.iter().map(|t| t + offset));
        self.q.extend_from_slice(&other.q);
        self.qd.extend_from_slice(&other.qd);
        self.qdd.extend_from_slice(&other.qdd);
    }
}

/// Outcome of one rollout (GFCS eq. 2).
#[derive(Clone, Debug, PartialEq)]
pub struct RolloutResult {
    /// t* = min(t, t_max) (s), eq. 2, with t the first step time at which ‖q − q_g‖ < tol. Equals t_max
    /// on [`StopReason::Timeout`] and [`StopReason::NonFinite`] (the command was never reached).
    pub t_star: f64,
    /// Time of the final state (s): `steps`·dt. Differs from `t_star` only on NonFinite, or on Timeout
    /// when t_max is not a multiple of dt (the last step overshoots t_max).
    pub t_end: f64,
    /// Integration steps taken.
    pub steps: usize,
    /// Closest approach ‖q − q_g‖ (rad or m) to the command over the step-start states, the final state
    /// included (below `tol` when reached).
    pub min_distance: f64,
    /// Final configuration (dof,), the state at `t_end` (the last finite state on NonFinite).
    pub q: Vec<f64>,
    /// Final velocity (dof,).
    pub qd: Vec<f64>,
    /// Why the rollout stopped.
    pub reason: StopReason,
    /// Minimum of [`System::clearance`] (m) over the step-start states (+∞ without a monitor);
    /// negative means a collision happened.
    pub min_clearance: f64,
    /// The trajectory when [`RolloutOptions::record`] is set. On NonFinite it ends at the last row whose
    /// acceleration was finite.
    pub trajectory: Option<Trajectory>,
}

/// State buffers and integrator scratch of one rollout, reused across the rollouts of a sequence or of a
/// batch thread so that the time-step loop does not allocate.
pub(crate) struct Buffers {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    q_next: Vec<f64>,
    qd_next: Vec<f64>,
    scratch: StepScratch,
    /// Stall detection: the best distance of the last `window` steps, indexed by step modulo `window`.
    best_history: Vec<f64>,
    /// The blended command of the current step (see [`Blend`]).
    command: Vec<f64>,
}

/// A command handover smoothed in time: during the first `duration` seconds of a rollout the fabric is
/// given c(t) = c_prev + s(t/duration)(c − c_prev), s(u) = 3u² − 2u³ (continuous rate, zero at both ends),
/// instead of switching from c_prev to c in one step. Stopping tests (tolerance, stall) use c itself.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Blend<'a> {
    /// The previous command c_prev (dof,).
    pub from: &'a [f64],
    /// Blend duration (s), ≥ 0.
    pub duration: f64,
}

impl Buffers {
    pub(crate) fn new(dof: usize) -> Self {
        let z = vec![0.0; dof];
        Buffers {
            q: z.clone(),
            qd: z.clone(),
            qdd: z.clone(),
            q_next: z.clone(),
            qd_next: z,
            scratch: StepScratch::new(dof),
            best_history: Vec::new(),
            command: vec![0.0; dof],
        }
    }
}

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

fn distance_squared(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// Euclidean distance ‖a − b‖.
pub(crate) fn distance(a: &[f64], b: &[f64]) -> f64 {
    distance_squared(a, b).sqrt()
}

/// Check q0, qd0 and `command` against the system's dof and for finiteness, plus the options.
pub(crate) fn validate_start<S: System>(
    system: &S,
    q0: &[f64],
    qd0: &[f64],
    opts: &RolloutOptions,
) -> Result<()> {
    let dof = system.dof();
    check_len("q0", q0.len(), dof)?;
    check_len("qd0", qd0.len(), dof)?;
    check_finite("q0", q0)?;
    check_finite("qd0", qd0)?;
    opts.validate()
}

/// The rollout loop on validated inputs, stopping at `tol` (the options' own `tol` is ignored here so
/// that sequences can use their waypoint tolerance). Per step k (t = k·dt): evaluate q̈ = f(q, q̇; q_g)
/// (q_g blended from the previous command while `blend` lasts), monitor the clearance, record, test
/// eq. 3, test the budget, then integrate one step.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run<S: System>(
    system: &S,
    ws: &mut S::Workspace,
    b: &mut Buffers,
    q0: &[f64],
    qd0: &[f64],
    command: &[f64],
    blend: Option<Blend<'_>>,
    opts: &RolloutOptions,
    tol: f64,
) -> Result<RolloutResult> {
    let dof = system.dof();
    b.q.copy_from_slice(q0);
    b.qd.copy_from_slice(qd0);
    let n_max = opts.max_steps();
    let tol2 = tol * tol;
    // goal capture applies to a command tolerance tighter than it (the goal's, not a waypoint's)
    let capture2 = if opts.capture_tol > tol {
        opts.capture_tol * opts.capture_tol
    } else {
        0.0
    };
    let mut trajectory = opts
        .record
        .then(|| Trajectory::with_capacity(dof, (n_max + 1).min(RECORD_RESERVE)));
    let mut min_clearance = f64::INFINITY;
    // stall detection: best distance so far, compared with its value `window` steps earlier
    let window = (opts.stall_window / opts.dt).round() as usize;
    let mut best = f64::INFINITY;
    b.best_history.clear();
    b.best_history.resize(window, f64::INFINITY);
    let mut k = 0usize;
    let reason = loop {
        let t = k as f64 * opts.dt;
        let fabric_command: &[f64] = match blend {
            Some(bl) if t < bl.duration => {
                let u = t / bl.duration;
                let s = u * u * (3.0 - 2.0 * u);
                for ((c, &from), &to) in b.command.iter_mut().zip(bl.from).zip(command) {
                    *c = from + s * (to - from);
                }
                &b.command
            }
            _ => command,
        };
        system.acceleration(ws, &b.q, &b.qd, fabric_command, &mut b.qdd)?;
        if !all_finite(&b.qdd) {
            break StopReason::NonFinite;
        }
        min_clearance = min_clearance.min(system.clearance(ws));
        if let Some(tr) = trajectory.as_mut() {
            tr.push(t, &b.q, &b.qd, &b.qdd);
        }
        let d2 = distance_squared(&b.q, command);
        best = best.min(d2.sqrt());
        if d2 < tol2 {
            break StopReason::Reached;
        }
        if k >= n_max {
            break StopReason::Timeout;
        }
        if window > 0 {
            // the slot of step k − window (+∞ during the first window)
            let slot = &mut b.best_history[k % window];
            if best > *slot - opts.stall_progress {
                break if d2 < capture2 {
                    StopReason::Reached
                } else {
                    StopReason::Stalled
                };
            }
            *slot = best;
        }
        let mut accel = |q: &[f64], qd: &[f64], out: &mut [f64]| {
            system.acceleration(ws, q, qd, fabric_command, out)
        };
        let ok = opts.integrator.step(
            &mut accel,
            opts.dt,
            &b.q,
            &b.qd,
            &b.qdd,
            &mut b.q_next,
            &mut b.qd_next,
            &mut b.scratch,
        )?;
        if !(ok && all_finite(&b.q_next) && all_finite(&b.qd_next)) {
            break StopReason::NonFinite;
        }
        std::mem::swap(&mut b.q, &mut b.q_next);
        std::mem::swap(&mut b.qd, &mut b.qd_next);
        k += 1;
    };
    let t_end = k as f64 * opts.dt;
    let t_star = match reason {
        StopReason::Reached => t_end.min(opts.t_max),
        StopReason::Timeout | StopReason::NonFinite | StopReason::Stalled => opts.t_max,
    };
    Ok(RolloutResult {
        t_star,
        t_end,
        steps: k,
        min_distance: best,
        q: b.q.clone(),
        qd: b.qd.clone(),
        reason,
        min_clearance,
        trajectory,
    })
}

/// rollout_t of GFCS eq. 1–3 for any [`System`]: integrate from (`q0`, `qd0`) toward `command` (all
/// (dof,)) until ‖q − command‖ < `opts.tol` or t ≥ `opts.t_max`.
///
/// Errors: `Shape` / `NonFinite` naming `q0`, `qd0` or `command`; `Value` naming the invalid option;
/// any error of the system's acceleration. Divergence is not an error: it ends the rollout with
/// [`StopReason::NonFinite`].
pub fn rollout_system<S: System>(
    system: &S,
    ws: &mut S::Workspace,
    q0: &[f64],
    qd0: &[f64],
    command: &[f64],
    opts: &RolloutOptions,
) -> Result<RolloutResult> {
    validate_start(system, q0, qd0, opts)?;
    check_len("command", command.len(), system.dof())?;
    check_finite("command", command)?;
    let mut buffers = Buffers::new(system.dof());
    run(
        system,
        ws,
        &mut buffers,
        q0,
        qd0,
        command,
        None,
        opts,
        opts.tol,
    )
}
