//! `gfcs._core`: thin PyO3 bindings of `fabric-core`.
//!
//! numpy in and out (float64, shapes checked and named in `ShapeError`s, NaN/inf rejected with
//! `NonFiniteError`), the GIL released during heavy work (batches, rollouts), every core error mapped to a
//! named Python exception (`errors.rs`), and no Rust panic ever reaching Python.
//!
//! Modules: `robot` (Robot), `scene` (Scene, load_motion_plan_request), `config` (FabricConfig), `fabric`
//! (Fabric), `rmpflow` (Rmpflow), `rollout` (Rollout, SequenceRollout), `particle` (GF Sec. VI particle systems), `convert`
//! (numpy and pose conversion), `errors` (exception hierarchy).

mod config;
mod convert;
mod errors;
mod fabric;
mod particle;
mod rmpflow;
mod robot;
mod rollout;
mod scene;
mod validate;

use pyo3::prelude::*;
use pyo3::types::PyTuple;

/// The shipped Panda URDF text (the model behind `Robot.panda()`, same asset file), e.g. to write it to a
/// file for other URDF tools. Its finger joints are locked at 0.04 m by `Robot.panda()`.
#[pyfunction]
fn panda_urdf() -> &'static str {
    fabric_core::robot::PANDA_URDF
}

/// The shipped Panda SRDF text (the self-collision pairs `Robot.panda()` disables, same asset file), e.g. to
/// give another Panda URDF the shipped collision spheres with their pruned pairs (`Robot.with_srdf`).
#[pyfunction]
fn panda_srdf() -> &'static str {
    fabric_core::robot::PANDA_SRDF
}

/// The compiled module `gfcs._core`.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "PLANNING_FRAMES",
        PyTuple::new(m.py(), fabric_core::scene::PLANNING_FRAMES)?,
    )?;
    errors::register(m)?;
    m.add_function(wrap_pyfunction!(errors::_raise_internal_panic, m)?)?;
    m.add_function(wrap_pyfunction!(errors::_raise_core_error, m)?)?;
    m.add_function(wrap_pyfunction!(panda_urdf, m)?)?;
    m.add_function(wrap_pyfunction!(panda_srdf, m)?)?;
    m.add_function(wrap_pyfunction!(scene::load_motion_plan_request, m)?)?;
    m.add_function(wrap_pyfunction!(particle::particle_acceleration, m)?)?;
    m.add_function(wrap_pyfunction!(particle::particle_rollout, m)?)?;
    m.add_function(wrap_pyfunction!(particle::particle_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(rollout::rollout_option_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(convert::max_threads, m)?)?;
    m.add_class::<robot::PyRobot>()?;
    m.add_class::<scene::PyScene>()?;
    m.add_class::<config::PyFabricConfig>()?;
    m.add_class::<fabric::PyFabric>()?;
    m.add_class::<rmpflow::PyRmpflow>()?;
    m.add_class::<rollout::PyRollout>()?;
    m.add_class::<rollout::PySequenceRollout>()?;
    m.add_class::<validate::PyMeshChecker>()?;
    Ok(())
}
