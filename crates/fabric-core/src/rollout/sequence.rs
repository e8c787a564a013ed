//! Command-sequence rollouts: the cost of one candidate of the GFCOP, GFCS eq. 4–8.
//!
//! n free commands q_g¹ … q_gⁿ, then the goal q_g^{n+1} = q_g (eq. 6). Rollout i starts at the final
//! state (configuration and velocity) of rollout i − 1 (eq. 7). Cost = Σᵢ tᵢ* + p·1 (eq. 4) with
//! 1 = 1 unless the final rollout reaches the goal (eq. 8).

use super::rollout::{
    check_positive, distance, run, validate_start, Blend, Buffers, RolloutOptions, StopReason,
    Trajectory,
};
use super::system::System;
use crate::error::{check_finite, FabricError, Result};

/// Options of a command-sequence rollout (GFCS eq. 4–8).
#[derive(Clone, Debug, PartialEq)]
pub struct SequenceOptions {
    /// Options of every rollout; `rollout.tol` is ε of eq. 3 for the final command (the goal) and
    /// `rollout.t_max` the budget of each command.
    pub rollout: RolloutOptions,
    /// Number n of free commands before the goal (the sequence has n + 1 commands). Candidates of
    /// [`super::evaluate_batch`] are rows of n·dof values. Default 1 (GFCS: sequences of length two).
    pub n_commands: usize,
    /// Tolerance (rad / m) at which an intermediate command counts as reached and the next one takes
    /// over, > 0. Looser than `rollout.tol` so that the robot flows through waypoints instead of slowing
    /// at each. Default 0.3 (docs/tuning.md).
    pub waypoint_tol: f64,
    /// Penalty p of eq. 4 (s) when the goal is not reached, ≥ 0. Default 100 s. Every failure costs more
    /// than every success when p > n·t_max (14 s at the defaults).
    pub penalty: f64,
    /// Extension of eq. 4 (s), ≥ 0: added when the sequence collides (minimum clearance below
    /// −`collision_tol`), so that costs rank collision-free sequences first. Default 0 (the paper's cost,
    /// eq. 4, unchanged): the clearance comes from conservative collision spheres, and goals in contact
    /// with objects (e.g. MotionBenchMaker grasps) sit at slightly negative sphere clearance.
    pub collision_penalty: f64,
    /// Penetration depth (m), ≥ 0, tolerated before a negative clearance counts as a collision.
    /// Default 0.
    pub collision_tol: f64,
    /// Extension of eq. 4 (s/rad, or s/m for prismatic coordinates), ≥ 0: when the goal is not reached,
    /// adds `distance_penalty` × the closest approach ‖q − q_g‖ of the final rollout to the goal. Failed
    /// candidates then rank by how near they came (eq. 4 ranks them only by the waypoint times), which
    /// gives CMA-ES a direction on problems where no candidate of a batch succeeds. Default 0 (the
    /// paper's cost).
    pub distance_penalty: f64,
    /// Extension of eq. 7 (s), ≥ 0: at each handover the fabric's command moves from the previous
    /// command to the next one along a smoothstep over this time instead of jumping (the rollout still
    /// starts from the previous final state and is judged against the next command). A jump of the
    /// command is a jump of the acceleration, which dominates the jerk of GFCS trajectories
    /// (docs/tuning.md). Default 0.5 s; 0 = the paper's switch.
    pub blend_time: f64,
}

impl Default for SequenceOptions {
    fn default() -> Self {
        SequenceOptions {
            rollout: RolloutOptions::default(),
            n_commands: 1,
            waypoint_tol: 0.3,
            penalty: 100.0,
            collision_penalty: 0.0,
            collision_tol: 0.0,
            distance_penalty: 0.0,
            blend_time: 0.5,
        }
    }
}

fn check_non_negative(what: &str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(FabricError::Value {
            what: what.to_string(),
            message: format!("must be finite and >= 0, got {v}"),
        })
    }
}

impl SequenceOptions {
    /// Check the rollout options, waypoint_tol > 0, and the penalties, collision_tol and blend_time
    /// finite and ≥ 0.
    pub fn validate(&self) -> Result<()> {
        self.rollout.validate()?;
        check_positive("SequenceOptions.waypoint_tol", self.waypoint_tol)?;
        check_non_negative("SequenceOptions.penalty", self.penalty)?;
        check_non_negative("SequenceOptions.collision_penalty", self.collision_penalty)?;
        check_non_negative("SequenceOptions.collision_tol", self.collision_tol)?;
        check_non_negative("SequenceOptions.distance_penalty", self.distance_penalty)?;
        check_non_negative("SequenceOptions.blend_time", self.blend_time)
    }
}

/// Outcome of one command sequence (one GFCOP candidate).
#[derive(Clone, Debug, PartialEq)]
pub struct SequenceResult {
    /// Σᵢ tᵢ* + (p + distance_penalty·goal_distance)·𝟙(goal not reached) (eq. 4, 8)
    /// + collision_penalty·𝟙(collided) (s).
    pub cost: f64,
    /// Closest approach ‖q − q_g‖ (rad) of the final rollout to the goal (below `rollout.tol` when
    /// reached); when an earlier command diverged and the goal was never commanded, the distance of the
    /// last finite state to the goal.
    pub goal_distance: f64,
    /// tᵢ* of every command, i = 1 … n + 1 (eq. 5), shape (n + 1,). A diverged rollout ends the sequence:
    /// it and every later command count t_max.
    pub t_stars: Vec<f64>,
    /// Stop reason of every command, shape (n + 1,); commands after a divergence are `NonFinite`.
    pub reasons: Vec<StopReason>,
    /// The final rollout reached the goal within `rollout.tol` (eq. 8: 1 = 0). Equivalent to
    /// t*_{n+1} < t_max except when the goal is reached exactly at the last step of the budget.
    pub reached: bool,
    /// Minimum clearance (m) over every step of every rollout (+∞ without a monitor).
    pub min_clearance: f64,
    /// min_clearance < −collision_tol: the sequence went through a collision.
    pub collided: bool,
    /// Final configuration (dof,).
    pub q: Vec<f64>,
    /// Final velocity (dof,).
    pub qd: Vec<f64>,
    /// The concatenated trajectory when `rollout.record` is set: times strictly increasing, each rollout
    /// starting where the previous one stopped (the junction row appears once, with the acceleration
    /// toward the next command).
    pub trajectory: Option<Trajectory>,
}

impl SequenceResult {
    /// Reached the goal without collision.
    pub fn success(&self) -> bool {
        self.reached && !self.collided
    }
}

/// Check commands (n_commands·dof,) and goal (dof,) for shape and finiteness.
fn validate_commands(dof: usize, n_commands: usize, commands: &[f64], goal: &[f64]) -> Result<()> {
    let expected = n_commands
        .checked_mul(dof)
        .ok_or_else(|| FabricError::Value {
            what: "SequenceOptions.n_commands".to_string(),
            message: format!("{n_commands} commands of {dof} values overflow"),
        })?;
    if commands.len() != expected {
        return Err(FabricError::Shape {
            what: "commands".to_string(),
            expected: format!("({n_commands}·{dof},) = ({expected},)"),
            got: format!("({},)", commands.len()),
        });
    }
    crate::error::check_len("goal", goal.len(), dof)?;
    check_finite("commands", commands)?;
    check_finite("goal", goal)
}

/// The sequence on validated inputs (see [`rollout_sequence_system`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_sequence<S: System>(
    system: &S,
    ws: &mut S::Workspace,
    b: &mut Buffers,
    q0: &[f64],
    qd0: &[f64],
    commands: &[f64],
    goal: &[f64],
    opts: &SequenceOptions,
) -> Result<SequenceResult> {
    let dof = system.dof();
    let n = opts.n_commands;
    let ro = &opts.rollout;
    let mut t_stars = Vec::with_capacity(n + 1);
    let mut reasons = Vec::with_capacity(n + 1);
    let mut min_clearance = f64::INFINITY;
    let mut goal_distance = f64::INFINITY;
    let mut trajectory: Option<Trajectory> = None;
    let mut elapsed = 0.0;
    let mut q = q0.to_vec();
    let mut qd = qd0.to_vec();
    for i in 0..=n {
        let (command, tol) = if i < n {
            (&commands[i * dof..(i + 1) * dof], opts.waypoint_tol)
        } else {
            (goal, ro.tol)
        };
        let blend = (i > 0 && opts.blend_time > 0.0).then(|| Blend {
            from: &commands[(i - 1) * dof..i * dof],
            duration: opts.blend_time,
        });
        let r = run(system, ws, b, &q, &qd, command, blend, ro, tol)?;
        t_stars.push(r.t_star);
        reasons.push(r.reason);
        min_clearance = min_clearance.min(r.min_clearance);
        if i == n {
            goal_distance = r.min_distance;
        }
        if let Some(seg) = r.trajectory {
            match trajectory.as_mut() {
                None => trajectory = Some(seg),
                Some(all) => {
                    // The segment's first row is the previous final state: keep it, with its
                    // acceleration toward the new command, in place of the previous last row.
                    all.pop();
                    all.append_shifted(&seg, elapsed);
                }
            }
        }
        elapsed += r.t_end;
        q = r.q;
        qd = r.qd;
        if r.reason == StopReason::NonFinite {
            for _ in i + 1..=n {
                t_stars.push(ro.t_max);
                reasons.push(StopReason::NonFinite);
            }
            break;
        }
    }
    if !goal_distance.is_finite() {
        goal_distance = distance(&q, goal);
    }
    let reached = reasons.last() == Some(&StopReason::Reached);
    let mut cost: f64 = t_stars.iter().sum();
    if !reached {
        cost += opts.penalty + opts.distance_penalty * goal_distance;
    }
    let collided = min_clearance < -opts.collision_tol;
    if collided {
        cost += opts.collision_penalty;
    }
    Ok(SequenceResult {
        cost,
        goal_distance,
        t_stars,
        reasons,
        reached,
        min_clearance,
        collided,
        q,
        qd,
        trajectory,
    })
}

/// Roll out the command sequence (q_g¹ … q_gⁿ, goal) from (`q0`, `qd0`) for any [`System`]
/// (GFCS eq. 4–8, the inner loop of Alg. 1).
///
/// * `commands`: (n·dof,) row-major, n = `opts.n_commands` (may be 0: a plain rollout to the goal).
/// * `goal`: (dof,), the last command (eq. 6), reached within `opts.rollout.tol`; intermediate commands
///   hand over at `opts.waypoint_tol`. Each command has its own budget `opts.rollout.t_max`; a command
///   that times out hands over its final state like one that is reached (eq. 7).
///
/// Errors: `Shape` / `NonFinite` naming `q0`, `qd0`, `commands` or `goal`; `Value` naming the option.
pub fn rollout_sequence_system<S: System>(
    system: &S,
    ws: &mut S::Workspace,
    q0: &[f64],
    qd0: &[f64],
    commands: &[f64],
    goal: &[f64],
    opts: &SequenceOptions,
) -> Result<SequenceResult> {
    opts.validate()?;
    validate_start(system, q0, qd0, &opts.rollout)?;
    validate_commands(system.dof(), opts.n_commands, commands, goal)?;
    let mut buffers = Buffers::new(system.dof());
    run_sequence(system, ws, &mut buffers, q0, qd0, commands, goal, opts)
}
