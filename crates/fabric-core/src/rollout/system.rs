//! The [`System`] abstraction that rollouts, sequences and batches integrate: a commanded second-order
//! system q̈ = f(q, q̇; q_g) (the policy f of GFCS eq. 1), with a per-thread workspace.

use crate::error::{FabricError, Result};

/// A commanded second-order system q̈ = f(q, q̇; q_g), GFCS eq. 1. The model (`&self`) is shared across
/// threads; every evaluation takes a per-thread [`System::Workspace`].
pub trait System: Sync {
    /// Per-thread scratch for one evaluation; created by [`System::workspace`].
    type Workspace: Send;

    /// Number of coordinates d: q, q̇, q̈ and commands are slices of this length.
    fn dof(&self) -> usize;

    /// A fresh workspace.
    fn workspace(&self) -> Self::Workspace;

    /// Write q̈ = f(q, q̇; q_g) into `qdd` for configuration `q`, velocity `qd` and command `command`
    /// (all of length [`System::dof`]; rad or m, rad/s or m/s, rad/s² or m/s²).
    /// The rollout checks lengths and finiteness of its inputs before calling.
    fn acceleration(
        &self,
        ws: &mut Self::Workspace,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &mut [f64],
    ) -> Result<()>;

    /// Clearance (m) at the state of the last [`System::acceleration`] call in `ws`: negative means
    /// collision. Rollouts record its minimum over the step-start states. Default: +∞ (no monitor).
    fn clearance(&self, ws: &Self::Workspace) -> f64 {
        let _ = ws;
        f64::INFINITY
    }
}

/// A policy's evaluation `result` as a [`System::acceleration`] reports it. The rollout checks lengths and
/// finiteness of its inputs first, so a `NonFinite` or `Value` error of the policy at a state means its
/// dynamics broke down there (non-finite q̈, a root metric not positive definite): q̈ is then NaN and the
/// rollout stops with [`super::StopReason::NonFinite`] instead of failing the whole sequence or batch.
/// Other errors (e.g. `Shape` for a workspace of another model) propagate.
pub fn breakdown_as_nan(result: Result<()>, qdd: &mut [f64]) -> Result<()> {
    match result {
        Err(FabricError::NonFinite { .. } | FabricError::Value { .. }) => {
            qdd.fill(f64::NAN);
            Ok(())
        }
        other => other,
    }
}
