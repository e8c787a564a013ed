//! `fabric-core`: geometric fabrics (Ratliff et al., "Geometric Fabrics: Generalizing Classical Mechanics
//! to Capture the Physics of Behavior") and Geometric Fabric Command Sequences (GFCS) in pure Rust.
//!
//! Conventions: SI units (m, rad, s); signed distance positive outside; a spec (M, f) means M ẍ + f = 0.
//! See `docs/architecture.md` for the module map.

pub mod error;
pub mod fabric;
pub mod limits;
mod linalg;
pub mod mesh_tree;
pub mod rmpflow;
pub mod robot;
pub mod rollout;
pub mod scene;
pub mod validate;

pub use error::{FabricError, Result};
