//! RMPflow (Cheng, Mukadam, Issac, Birchfield, Fox, Boots, Ratliff, "RMPflow: A Computational Graph for
//! Automatic Motion Policy Generation", 2018): the second controller of the GF Sec. VII comparison, on the
//! same robot, scene and task maps as the fabric.
//!
//! * [`config`]: [`RmpConfig`], the leaf gains (defaults: the hand-designed Franka RMPflow of RMP²).
//! * [`leaves`]: the leaf RMPs (a, M): posture, end-effector target, joint limits, collision, damping.
//! * [`root`]: pullback f_q += Jᵀ M (a − J̇q̇), M_q += Jᵀ M J and resolve q̈ = M_q⁺ f_q.
//! * [`engine`]: [`Rmpflow`] (model) and [`RmpWorkspace`] (scratch): the policy of a robot in a scene.
//! * [`system`]: rollouts, command sequences and batches, through the fabric's generic rollout code.
//!
//! Unlike a fabric, RMPflow has no energy, bending or speed control: its leaves are hand-designed
//! acceleration policies with velocity-dependent metrics, combined by the metric-weighted least squares
//! of the root.
#![warn(missing_docs)]

pub mod config;
pub mod engine;
pub mod leaves;
pub mod root;
pub mod system;

pub use config::RmpConfig;
pub use engine::{RmpDiagnostics, RmpWorkspace, Rmpflow};
pub use root::{pullback, RmpRoot};
pub use system::{rmp_evaluate_batch, rmp_rollout, rmp_rollout_sequence, RmpflowSystem};
