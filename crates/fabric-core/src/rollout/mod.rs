//! Integration, rollouts, command sequences and batches: GFCS Sec. IV-A, eq. 1–8, Alg. 1.
//!
//! * [`integrate`]: fixed-step schemes for the double integrator of eq. 1 (semi-implicit Euler, RK4).
//! * [`rollout_system`]: rollout_t (eq. 2–3) of any [`System`]; [`rollout_sequence_system`]: the cost of
//!   one command sequence (eq. 4–8); [`evaluate_batch_system`]: many candidates in parallel (Alg. 1),
//!   deterministic whatever the thread count.
//! * [`rollout()`], [`rollout_sequence`], [`evaluate_batch`]: the same for a
//!   [`Fabric`](crate::fabric::Fabric) in a [`Scene`](crate::scene::Scene), through [`FabricSystem`].
//!
//! Times in s, joint values in rad (revolute) or m (prismatic), arrays row-major.

pub(crate) mod batch;
mod fabric;
pub mod integrate;
#[allow(clippy::module_inception)]
mod rollout;
mod sequence;
mod system;

pub use batch::{evaluate_batch_system, max_threads, pool_threads, shared_pool};
pub use fabric::{evaluate_batch, rollout, rollout_sequence, FabricSystem};
pub use integrate::{Integrator, StepScratch};
pub use rollout::{
    rollout_system, RolloutOptions, RolloutResult, StopReason, Trajectory, MAX_STEPS,
};
pub use sequence::{rollout_sequence_system, SequenceOptions, SequenceResult};
pub use system::{breakdown_as_nan, System};
