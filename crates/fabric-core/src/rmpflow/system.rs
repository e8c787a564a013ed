//! RMPflow in a scene as a rollout [`System`], with the rollout, command-sequence and batch entry points
//! of the fabric's (`rollout::fabric`) for the second controller.

use super::engine::{RmpWorkspace, Rmpflow};
use crate::error::Result;
use crate::fabric::EeTargets;
use crate::rollout::{
    breakdown_as_nan, evaluate_batch_system, rollout_sequence_system, rollout_system,
    RolloutOptions, RolloutResult, SequenceOptions, SequenceResult, System,
};
use crate::scene::Scene;

/// An RMPflow policy in a fixed scene: q̈ = `rmp.acceleration(scene, q, q̇, q_g, targets)`, with the
/// clearance monitor min(obstacle, self) of each evaluation. A breakdown of its dynamics at a state
/// becomes a NaN acceleration ([`breakdown_as_nan`]), as for the fabric's system.
#[derive(Clone, Copy)]
pub struct RmpflowSystem<'a> {
    /// The policy.
    pub rmp: &'a Rmpflow,
    /// The obstacles, fixed during the rollout.
    pub scene: &'a Scene,
    /// Fixed end-effector targets, or None for the end-effector position at each command.
    pub targets: Option<&'a EeTargets>,
}

impl System for RmpflowSystem<'_> {
    type Workspace = RmpWorkspace;

    fn dof(&self) -> usize {
        self.rmp.robot().dof()
    }

    fn workspace(&self) -> RmpWorkspace {
        RmpWorkspace::new(self.rmp)
    }

    fn acceleration(
        &self,
        ws: &mut RmpWorkspace,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &mut [f64],
    ) -> Result<()> {
        let result = self
            .rmp
            .acceleration(self.scene, q, qd, command, self.targets, ws, qdd);
        breakdown_as_nan(result, qdd)
    }

    fn clearance(&self, ws: &RmpWorkspace) -> f64 {
        let d = self.rmp.diagnostics(ws);
        d.min_clearance.min(d.min_self_clearance)
    }
}

/// rollout_t (GFCS eq. 1–3) of RMPflow in `scene` toward `command`; see [`rollout_system`].
#[allow(clippy::too_many_arguments)]
pub fn rmp_rollout(
    rmp: &Rmpflow,
    scene: &Scene,
    targets: Option<&EeTargets>,
    q0: &[f64],
    qd0: &[f64],
    command: &[f64],
    opts: &RolloutOptions,
    ws: &mut RmpWorkspace,
) -> Result<RolloutResult> {
    rollout_system(
        &RmpflowSystem {
            rmp,
            scene,
            targets,
        },
        ws,
        q0,
        qd0,
        command,
        opts,
    )
}

/// The cost of one command sequence (GFCS eq. 4–8) under RMPflow; see [`rollout_sequence_system`].
#[allow(clippy::too_many_arguments)]
pub fn rmp_rollout_sequence(
    rmp: &Rmpflow,
    scene: &Scene,
    q0: &[f64],
    qd0: &[f64],
    commands: &[f64],
    goal: &[f64],
    opts: &SequenceOptions,
    ws: &mut RmpWorkspace,
) -> Result<SequenceResult> {
    let sys = RmpflowSystem {
        rmp,
        scene,
        targets: None,
    };
    rollout_sequence_system(&sys, ws, q0, qd0, commands, goal, opts)
}

/// N candidate sequences under RMPflow in parallel; see [`evaluate_batch_system`].
#[allow(clippy::too_many_arguments)]
pub fn rmp_evaluate_batch(
    rmp: &Rmpflow,
    scene: &Scene,
    q0: &[f64],
    qd0: &[f64],
    goal: &[f64],
    candidates: &[f64],
    opts: &SequenceOptions,
    threads: Option<usize>,
) -> Result<Vec<SequenceResult>> {
    let sys = RmpflowSystem {
        rmp,
        scene,
        targets: None,
    };
    evaluate_batch_system(&sys, q0, qd0, goal, candidates, opts, threads)
}
