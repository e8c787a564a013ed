//! The robot model and its kinematics.
//!
//! * [`Robot`] (model.rs, urdf.rs): an immutable kinematic tree loaded from URDF (revolute, continuous,
//!   prismatic, fixed and mimic joints), its active coordinates q and limits.
//! * [`KinematicsWorkspace`], [`TaskPoint`] (kinematics.rs): recursive forward kinematics, link
//!   velocities, and x, J, J̇q̇ of points and axes for the pullback of GF eq. 11–12 and 16.
//! * [`CollisionSphere`] (spheres.rs) and the self-collision pairs (srdf.rs).
//! * [`LinkGeometry`] (geometry.rs): URDF collision geometry for mesh-based validation.
//! * [`Robot::panda`] (panda.rs): the shipped Franka Panda. [`batch`]: parallel forward kinematics.
//! * [`inverse_kinematics`] (ik.rs): damped least-squares IK of one link for many targets in parallel;
//!   [`point_ik`]: one descent of a link point and axis (the problem generators' IK).

pub mod batch;
mod geometry;
mod ik;
mod kinematics;
pub(crate) mod model;
mod panda;
mod spheres;
mod srdf;
mod tree;
mod urdf;

pub use geometry::{GeometryKind, LinkGeometry};
pub use ik::{inverse_kinematics, point_ik, IkOptions, IkTarget, PointIkOptions, PointTarget};
pub use kinematics::{KinematicsWorkspace, TaskPoint};
pub use model::{Robot, RobotOptions};
pub use panda::{PANDA_SRDF, PANDA_URDF};
pub use spheres::CollisionSphere;
pub use urdf::LOCKED_BOUNDS_TOLERANCE;
