//! The 2-D particle systems of GF Sec. VI (point attraction + circle repulsion, unbent/bent ×
//! Riemannian/Finsler, speed-regulated by eq. 40–46): `particle_acceleration`, `particle_rollout` and
//! `particle_defaults`. Rollouts reuse the core integrators through the core `System` trait, with the
//! attraction target as the command and the clearance ‖q − q_o‖ − r (m) as the collision monitor.

use fabric_core::fabric::{
    particle_acceleration as core_particle_acceleration, ParticleParams, ParticleVariant,
};
use fabric_core::rollout::{rollout_system, RolloutOptions, System};
use fabric_core::FabricError;
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rayon::prelude::*;

use crate::convert::{self, output};
use crate::errors::{detached, error};
use crate::rollout::{rollout_options, PyRollout, RolloutKwargs};

/// Variant from its name: "unbent_riemannian", "unbent_finsler", "bent_riemannian", "bent_finsler".
fn parse_variant(name: &str) -> PyResult<ParticleVariant> {
    match name.to_ascii_lowercase().replace('-', "_").as_str() {
        "unbent_riemannian" => Ok(ParticleVariant::UnbentRiemannian),
        "unbent_finsler" => Ok(ParticleVariant::UnbentFinsler),
        "bent_riemannian" => Ok(ParticleVariant::BentRiemannian),
        "bent_finsler" => Ok(ParticleVariant::BentFinsler),
        other => Err(error(FabricError::Value {
            what: "variant".into(),
            message: format!(
                "'{other}' is not one of 'unbent_riemannian', 'unbent_finsler', 'bent_riemannian', 'bent_finsler'"
            ),
        })),
    }
}

/// A 2-vector keyword argument.
fn vec2(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 2]> {
    let v = convert::vector(obj, what, 2)?;
    Ok([v[0], v[1]])
}

/// Parameters: the core defaults (GF Fig. 1 set-up), the desired speed `speed` (m/s) and the keyword
/// overrides in `params`.
fn parse_params(
    speed: Option<f64>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<ParticleParams> {
    let mut p = ParticleParams::default();
    if let Some(v) = speed {
        p.speed.desired_speed = v;
    }
    if let Some(d) = params {
        for (k, v) in d.iter() {
            let key: String = k.extract()?;
            match key.as_str() {
                "target" => p.target = vec2(&v, "target")?,
                "obstacle_center" => p.obstacle_center = vec2(&v, "obstacle_center")?,
                _ => {
                    let x = convert::scalar(&v, &key)?;
                    let slot = match key.as_str() {
                        "obstacle_radius" => &mut p.obstacle_radius,
                        "mass_max" => &mut p.mass_max,
                        "mass_min" => &mut p.mass_min,
                        "mass_width" => &mut p.mass_width,
                        "attraction_gain" => &mut p.attraction_gain,
                        "attraction_sharpness" => &mut p.attraction_sharpness,
                        "barrier_gain" => &mut p.barrier_gain,
                        "barrier_potential_gain" => &mut p.barrier_potential_gain,
                        "x_min" => &mut p.x_min,
                        "braking_time" => &mut p.braking_time,
                        _ => {
                            return Err(error(FabricError::Value {
                                what: "particle parameter".into(),
                                message: format!("unknown keyword '{key}'"),
                            }))
                        }
                    };
                    *slot = x;
                }
            }
        }
    }
    let positive = [
        ("speed", p.speed.desired_speed),
        ("obstacle_radius", p.obstacle_radius),
        ("mass_min", p.mass_min),
        ("x_min", p.x_min),
    ];
    for (what, v) in positive {
        if !(v.is_finite() && v > 0.0) {
            return Err(error(FabricError::Value {
                what: what.into(),
                message: format!("must be > 0, got {v}"),
            }));
        }
    }
    if !(p.braking_time.is_finite() && p.braking_time >= 0.0) {
        return Err(error(FabricError::Value {
            what: "braking_time".into(),
            message: format!(
                "must be >= 0 s (0 = the paper's barrier), got {}",
                p.braking_time
            ),
        }));
    }
    Ok(p)
}

/// A particle variant as a commanded system (command = attraction target).
struct ParticleSystem {
    variant: ParticleVariant,
    params: ParticleParams,
}

impl System for ParticleSystem {
    /// Clearance ‖q − q_o‖ − r (m) at the last evaluation.
    type Workspace = f64;

    fn dof(&self) -> usize {
        2
    }

    fn workspace(&self) -> f64 {
        f64::INFINITY
    }

    fn acceleration(
        &self,
        ws: &mut f64,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &mut [f64],
    ) -> fabric_core::Result<()> {
        let p = ParticleParams {
            target: [command[0], command[1]],
            ..self.params.clone()
        };
        let a = core_particle_acceleration(self.variant, &p, [q[0], q[1]], [qd[0], qd[1]]);
        let c = p.obstacle_center;
        *ws = ((q[0] - c[0]).powi(2) + (q[1] - c[1]).powi(2)).sqrt() - p.obstacle_radius;
        qdd.copy_from_slice(&a);
        Ok(())
    }

    fn clearance(&self, ws: &f64) -> f64 {
        *ws
    }
}

/// Acceleration q̈ (2,) m/s² of one particle at `q` (2,) with velocity `qd` (2,) for `variant`, desired
/// speed `speed` (default 2 m/s) and parameter overrides (`target`, `obstacle_center`, `obstacle_radius`,
/// `mass_max`, `mass_min`, `mass_width`, `attraction_gain`, `attraction_sharpness`, `barrier_gain`,
/// `barrier_potential_gain`, `x_min`, `braking_time`).
#[pyfunction]
#[pyo3(signature = (variant, q, qd, speed=None, **params))]
pub fn particle_acceleration<'py>(
    py: Python<'py>,
    variant: &str,
    q: &Bound<'py, PyAny>,
    qd: &Bound<'py, PyAny>,
    speed: Option<f64>,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let variant = parse_variant(variant)?;
    let p = parse_params(speed, params)?;
    let q = vec2(q, "q")?;
    let qd = vec2(qd, "qd")?;
    let a = core_particle_acceleration(variant, &p, q, qd);
    output(py, a.to_vec(), &[2])
}

/// Roll out particles from `q0` ((2,) or (N, 2), m) at velocity `qd0` (same shape, default rest) toward
/// the attraction target, with desired speed `speed` m/s (GF Fig. 1: 2 or 4). Returns a `Rollout` (for
/// (2,)) or a list of N (for (N, 2)), recorded; `min_clearance` is min ‖q − q_o‖ − r. Options as in
/// `Fabric.rollout` (defaults dt 0.01 s, t_max 7 s, tol 0.01 m); parameter overrides as in
/// `particle_acceleration`. GIL released; batches in parallel.
#[pyfunction]
#[pyo3(signature = (variant, speed, q0, qd0=None, dt=None, t_max=None, tol=None, integrator="euler", **params))]
#[allow(clippy::too_many_arguments)]
pub fn particle_rollout<'py>(
    py: Python<'py>,
    variant: &str,
    speed: f64,
    q0: &Bound<'py, PyAny>,
    qd0: Option<&Bound<'py, PyAny>>,
    dt: Option<f64>,
    t_max: Option<f64>,
    tol: Option<f64>,
    integrator: &str,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Py<PyAny>> {
    let system = ParticleSystem {
        variant: parse_variant(variant)?,
        params: parse_params(Some(speed), params)?,
    };
    let (q0, batch) = convert::vector_or_rows(q0, "q0", 2)?;
    let qd0 = match qd0 {
        Some(v) if !v.is_none() => {
            let (qd, b) = convert::vector_or_rows(v, "qd0", 2)?;
            if b != batch {
                let expected = match batch {
                    None => "(2,)".to_string(),
                    Some(n) => format!("({n}, 2)"),
                };
                let got = match b {
                    None => vec![2],
                    Some(n) => vec![n, 2],
                };
                return Err(convert::shape_error("qd0", &expected, &got));
            }
            qd
        }
        _ => vec![0.0; q0.len()],
    };
    // no stall detection: the figure shows every particle's whole path
    let kwargs = RolloutKwargs {
        dt,
        t_max,
        tol,
        integrator,
    };
    let opts = RolloutOptions {
        stall_window: 0.0,
        ..rollout_options(&kwargs, true)?
    };
    let target = system.params.target;
    let results = detached(py, move || {
        q0.par_chunks_exact(2)
            .zip(qd0.par_chunks_exact(2))
            .map(|(q, qd)| {
                let mut ws = system.workspace();
                rollout_system(&system, &mut ws, q, qd, &target, &opts)
            })
            .collect::<fabric_core::Result<Vec<_>>>()
    })?;
    let mut rollouts: Vec<PyRollout> = results.into_iter().map(|r| PyRollout::new(2, r)).collect();
    match batch {
        None => match rollouts.pop() {
            Some(r) => Ok(Py::new(py, r)?.into_any()),
            None => Err(error(FabricError::Value {
                what: "q0".into(),
                message: "no particle".into(),
            })),
        },
        Some(_) => Ok(PyList::new(
            py,
            rollouts
                .into_iter()
                .map(|r| Py::new(py, r))
                .collect::<PyResult<Vec<_>>>()?,
        )?
        .into_any()
        .unbind()),
    }
}

/// The default particle parameters (GF Sec. VI set-up) as a dict.
#[pyfunction]
pub fn particle_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let p = ParticleParams::default();
    let d = PyDict::new(py);
    d.set_item("target", p.target.to_vec())?;
    d.set_item("obstacle_center", p.obstacle_center.to_vec())?;
    d.set_item("obstacle_radius", p.obstacle_radius)?;
    d.set_item("mass_max", p.mass_max)?;
    d.set_item("mass_min", p.mass_min)?;
    d.set_item("mass_width", p.mass_width)?;
    d.set_item("attraction_gain", p.attraction_gain)?;
    d.set_item("attraction_sharpness", p.attraction_sharpness)?;
    d.set_item("barrier_gain", p.barrier_gain)?;
    d.set_item("barrier_potential_gain", p.barrier_potential_gain)?;
    d.set_item("x_min", p.x_min)?;
    d.set_item("braking_time", p.braking_time)?;
    d.set_item("speed", p.speed.desired_speed)?;
    Ok(d)
}
