//! Geometric fabrics (GF = Ratliff et al., "Geometric Fabrics: Generalizing Classical Mechanics to Capture
//! the Physics of Behavior"): Finsler energies, HD2 geometries, the spec algebra of transform trees,
//! energization, speed control, the Panda components of GF Sec. VII-A and the particle systems of Sec. VI.
//!
//! * [`energy`]: Finsler energies, (M, ξ) by Euler–Lagrange, num-dual AD and closed forms (Sec. III-A).
//! * [`potential`]: attractor and barrier potentials (VII-A), with the penetration continuation.
//! * [`spec`]: sum, pullback, energization (eq. 7-16, Thm IV.5-IV.6).
//! * [`components`]: attractor and barrier components in their task spaces (VII-A, App. G).
//! * [`root`]: joint-space accumulation and resolution (eq. 15-17, 40).
//! * [`speed`]: speed control (Sec. V-A, App. E-B, eq. 40-46).
//! * [`config`]: [`FabricConfig`] and [`Mode`], every gain with units and defaults.
//! * [`engine`]: [`Fabric`], [`FabricWorkspace`], [`Diagnostics`]: the robot fabric.
//! * [`leaves`]: task maps (x, ẋ, J, J̇q̇) of obstacle and self-collision distance leaves.
//! * [`particle`]: the four 2-D particle systems of Sec. VI.
//!
//! Conventions: a spec (M, f) means M ẍ + f = 0; pullback (JᵀMJ, Jᵀ(f + M J̇q̇)); SI units.
#![warn(missing_docs)]

pub mod components;
pub mod config;
pub mod energy;
pub mod engine;
pub mod leaves;
pub mod particle;
pub mod potential;
pub mod root;
pub mod spec;
pub mod speed;

pub use config::{
    BarrierConfig, BarrierPotentialConfig, EeAttractionConfig, FabricConfig, GoalDampingForm,
    GoalSpace, JointAttractionConfig, LogCoshConfig, Mode, SpeedConfig,
};
pub use engine::{Diagnostics, EeTargets, Fabric, FabricWorkspace};
pub use particle::{particle_acceleration, ParticleParams, ParticleVariant};
