//! Rollouts of a geometric fabric in a scene: the policy f of GFCS eq. 1 is [`Fabric::acceleration`].

use super::batch::evaluate_batch_system;
use super::rollout::{rollout_system, RolloutOptions, RolloutResult};
use super::sequence::{rollout_sequence_system, SequenceOptions, SequenceResult};
use super::system::{breakdown_as_nan, System};
use crate::error::Result;
use crate::fabric::{Fabric, FabricWorkspace};
use crate::scene::Scene;

/// A fabric in a fixed scene seen as a [`System`]: q̈ = `fabric.acceleration(scene, q, q̇, q_g)`, with the
/// clearance monitor min(`Diagnostics::min_clearance`, `Diagnostics::min_self_clearance`) (m, negative in
/// collision with an obstacle or with the robot itself, measured with the collision spheres) of each
/// evaluation. Obstacle clearance is +∞ while no sphere is within the obstacle influence radius.
///
/// A breakdown of the fabric's dynamics at a state (non-finite q̈, root metric M̃ not positive definite)
/// becomes a NaN acceleration ([`breakdown_as_nan`]).
#[derive(Clone, Copy)]
pub struct FabricSystem<'a> {
    /// The fabric (robot model and gains).
    pub fabric: &'a Fabric,
    /// The obstacles, fixed during the rollout.
    pub scene: &'a Scene,
}

impl System for FabricSystem<'_> {
    type Workspace = FabricWorkspace;

    fn dof(&self) -> usize {
        self.fabric.robot().dof()
    }

    /// A workspace that skips the forcing potential ψ (rollouts read only q̈ and the clearance).
    fn workspace(&self) -> FabricWorkspace {
        FabricWorkspace::for_rollouts(self.fabric)
    }

    fn acceleration(
        &self,
        ws: &mut FabricWorkspace,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        let result = self
            .fabric
            .acceleration(self.scene, q, qd, command, ws, qdd);
        breakdown_as_nan(result, qdd)
    }

    fn clearance(&self, ws: &FabricWorkspace) -> f64 {
        let d = self.fabric.diagnostics(ws);
        d.min_clearance.min(d.min_self_clearance)
    }
}

/// rollout_t of GFCS eq. 1–3 for a fabric in `scene`: from (`q0`, `qd0`) toward the joint-space command
/// `command` (all (dof,), rad) until ‖q − command‖ < `opts.tol` or t ≥ `opts.t_max`. See
/// [`rollout_system`]; `ws` is a workspace of this fabric (one per thread).
pub fn rollout(
    fabric: &Fabric,
    scene: &Scene,
    q0: &[f64],
    qd0: &[f64],
    command: &[f64],
    opts: &RolloutOptions,
    ws: &mut FabricWorkspace,
) -> Result<RolloutResult> {
    rollout_system(&FabricSystem { fabric, scene }, ws, q0, qd0, command, opts)
}

/// The cost of one command sequence for a fabric in `scene` (GFCS eq. 4–8): `commands` (n·dof,)
/// row-major with n = `opts.n_commands`, then `goal` (dof,). See [`rollout_sequence_system`].
#[allow(clippy::too_many_arguments)]
pub fn rollout_sequence(
    fabric: &Fabric,
    scene: &Scene,
    q0: &[f64],
    qd0: &[f64],
    commands: &[f64],
    goal: &[f64],
    opts: &SequenceOptions,
    ws: &mut FabricWorkspace,
) -> Result<SequenceResult> {
    rollout_sequence_system(
        &FabricSystem { fabric, scene },
        ws,
        q0,
        qd0,
        commands,
        goal,
        opts,
    )
}

/// N candidate sequences (`candidates` (N, n·dof) row-major, n = `opts.n_commands`) for a fabric in
/// `scene`, in parallel on `threads` threads (None: rayon's pool); results in candidate order and
/// identical whatever the thread count. See [`evaluate_batch_system`].
#[allow(clippy::too_many_arguments)]
pub fn evaluate_batch(
    fabric: &Fabric,
    scene: &Scene,
    q0: &[f64],
    qd0: &[f64],
    goal: &[f64],
    candidates: &[f64],
    opts: &SequenceOptions,
    threads: Option<usize>,
) -> Result<Vec<SequenceResult>> {
    evaluate_batch_system(
        &FabricSystem { fabric, scene },
        q0,
        qd0,
        goal,
        candidates,
        opts,
        threads,
    )
}
