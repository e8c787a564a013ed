//! Result classes of rollouts (`Rollout`, GFCS eq. 1–3) and command sequences (`SequenceRollout`,
//! GFCS eq. 4–8), and the parsing of rollout options from Python keyword arguments.

use std::sync::Arc;

use fabric_core::rollout::{
    Integrator, RolloutOptions, RolloutResult, SequenceOptions, SequenceResult, StopReason,
    Trajectory,
};
use fabric_core::scene::Scene;
use fabric_core::FabricError;
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::convert::{self, output, typed_output};
use crate::errors::{detached, error};

/// Python name of a stop reason: "reached", "timeout", "non_finite" or "stalled".
pub fn reason_name(r: StopReason) -> &'static str {
    match r {
        StopReason::Reached => "reached",
        StopReason::Timeout => "timeout",
        StopReason::NonFinite => "non_finite",
        StopReason::Stalled => "stalled",
    }
}

/// "euler" (semi-implicit Euler, the papers' scheme) or "rk4".
pub fn parse_integrator(name: &str) -> PyResult<Integrator> {
    match name.to_ascii_lowercase().as_str() {
        "euler" | "semi_implicit_euler" => Ok(Integrator::SemiImplicitEuler),
        "rk4" => Ok(Integrator::Rk4),
        other => Err(error(FabricError::Value {
            what: "integrator".to_string(),
            message: format!("'{other}' is not one of 'euler', 'rk4'"),
        })),
    }
}

/// Keyword options of one rollout (the particle rollouts of GF Sec. VI); `None` keeps the core default
/// of `RolloutOptions`.
pub struct RolloutKwargs<'a> {
    pub dt: Option<f64>,
    pub t_max: Option<f64>,
    pub tol: Option<f64>,
    pub integrator: &'a str,
}

/// Rollout options from keyword arguments. Ranges are checked by the core (`InvalidValueError` naming
/// the field).
pub fn rollout_options(k: &RolloutKwargs<'_>, record: bool) -> PyResult<RolloutOptions> {
    let d = RolloutOptions::default();
    let opts = RolloutOptions {
        dt: k.dt.unwrap_or(d.dt),
        t_max: k.t_max.unwrap_or(d.t_max),
        tol: k.tol.unwrap_or(d.tol),
        integrator: parse_integrator(k.integrator)?,
        record,
        ..d
    };
    opts.validate().map_err(error)?;
    Ok(opts)
}

/// The options of one rollout (`Fabric.rollout`, GFCS eq. 1–3), by their Python keyword names.
pub const ROLLOUT_OPTIONS: [&str; 7] = [
    "dt",
    "t_max",
    "tol",
    "stall_window",
    "stall_progress",
    "capture_tol",
    "integrator",
];

/// The further options of a command sequence (`Fabric.rollout_sequence`, `Fabric.evaluate`, GFCS
/// eq. 4–8); a sequence takes these and [`ROLLOUT_OPTIONS`].
pub const SEQUENCE_OPTIONS: [&str; 6] = [
    "waypoint_tol",
    "penalty",
    "collision_penalty",
    "collision_tol",
    "distance_penalty",
    "blend_time",
];

/// `Value` error naming the keyword option `name`.
fn option_error(name: &str, message: String) -> PyErr {
    error(FabricError::Value {
        what: name.to_string(),
        message,
    })
}

/// Sets option `name` of `o` (one of [`ROLLOUT_OPTIONS`] or [`SEQUENCE_OPTIONS`]) from `value`.
fn set_option(o: &mut SequenceOptions, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
    if name == "integrator" {
        let text: String = value.extract().map_err(|_| {
            option_error(name, format!("must be a string, got {}", type_name(value)))
        })?;
        o.rollout.integrator = parse_integrator(&text)?;
        return Ok(());
    }
    let v: f64 = value
        .extract()
        .map_err(|_| option_error(name, format!("must be a number, got {}", type_name(value))))?;
    let field = match name {
        "dt" => &mut o.rollout.dt,
        "t_max" => &mut o.rollout.t_max,
        "tol" => &mut o.rollout.tol,
        "stall_window" => &mut o.rollout.stall_window,
        "stall_progress" => &mut o.rollout.stall_progress,
        "capture_tol" => &mut o.rollout.capture_tol,
        "waypoint_tol" => &mut o.waypoint_tol,
        "penalty" => &mut o.penalty,
        "collision_penalty" => &mut o.collision_penalty,
        "collision_tol" => &mut o.collision_tol,
        "distance_penalty" => &mut o.distance_penalty,
        "blend_time" => &mut o.blend_time,
        _ => unreachable!("set_option is called with known names only"),
    };
    *field = v;
    Ok(())
}

fn type_name(value: &Bound<'_, PyAny>) -> String {
    value
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".to_string())
}

/// Validated options of `method` from its `**options` keyword arguments, over the core defaults
/// (`SequenceOptions::default()`; a value of None keeps the default). `sequence`: the method takes
/// [`SEQUENCE_OPTIONS`] too. An unknown keyword is an `InvalidValueError` naming it and listing the
/// method's options.
pub fn options_from_kwargs(
    method: &str,
    kwargs: Option<&Bound<'_, PyDict>>,
    sequence: bool,
    n_commands: usize,
    record: bool,
) -> PyResult<SequenceOptions> {
    let mut o = SequenceOptions {
        n_commands,
        ..SequenceOptions::default()
    };
    o.rollout.record = record;
    let allowed: Vec<&str> = if sequence {
        ROLLOUT_OPTIONS
            .iter()
            .chain(SEQUENCE_OPTIONS.iter())
            .copied()
            .collect()
    } else {
        ROLLOUT_OPTIONS.to_vec()
    };
    for (key, value) in kwargs.into_iter().flat_map(|d| d.iter()) {
        let name: String = key.extract()?;
        if !allowed.contains(&name.as_str()) {
            return Err(option_error(
                &name,
                format!(
                    "is not an option of {method}; its options: {}",
                    allowed.join(", ")
                ),
            ));
        }
        if !value.is_none() {
            set_option(&mut o, &name, &value)?;
        }
    }
    o.validate().map_err(error)?;
    Ok(o)
}

/// The core's default of every rollout option (GFCS eq. 1–8), by keyword name: the one set of
/// defaults the Python settings (`gfcs.planning.RolloutSettings`) start from.
#[pyfunction]
pub fn rollout_option_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = SequenceOptions::default();
    let out = PyDict::new(py);
    let values = [
        ("dt", d.rollout.dt),
        ("t_max", d.rollout.t_max),
        ("tol", d.rollout.tol),
        ("stall_window", d.rollout.stall_window),
        ("stall_progress", d.rollout.stall_progress),
        ("capture_tol", d.rollout.capture_tol),
        ("waypoint_tol", d.waypoint_tol),
        ("penalty", d.penalty),
        ("collision_penalty", d.collision_penalty),
        ("collision_tol", d.collision_tol),
        ("distance_penalty", d.distance_penalty),
        ("blend_time", d.blend_time),
    ];
    for (name, value) in values {
        out.set_item(name, value)?;
    }
    let integrator = match d.rollout.integrator {
        Integrator::SemiImplicitEuler => "euler",
        Integrator::Rk4 => "rk4",
    };
    out.set_item("integrator", integrator)?;
    Ok(out)
}

/// The initial state of a rollout: `q0` (dof,) rad and `qd0` (dof,) rad/s, zeros when None; checked
/// in that order.
pub fn initial_state(
    q0: &Bound<'_, PyAny>,
    qd0: Option<&Bound<'_, PyAny>>,
    dof: usize,
) -> PyResult<(Vec<f64>, Vec<f64>)> {
    let q0 = convert::vector(q0, "q0", dof)?;
    let qd0 = match qd0 {
        Some(v) if !v.is_none() => convert::vector(v, "qd0", dof)?,
        _ => vec![0.0; dof],
    };
    Ok((q0, qd0))
}

/// A core batch evaluation of a policy `P` in a scene (`fabric_core::rollout::evaluate_batch`,
/// `fabric_core::rmpflow::rmp_evaluate_batch`): (policy, scene, q0, qd0, goal, candidates, options, threads).
pub type BatchEvaluation<P> = fn(
    &P,
    &Scene,
    &[f64],
    &[f64],
    &[f64],
    &[f64],
    &SequenceOptions,
    Option<usize>,
) -> fabric_core::Result<Vec<SequenceResult>>;

/// The checked arguments of a policy's `evaluate` (a batch of candidate command sequences).
pub struct BatchInputs {
    /// Initial joint positions (dof,), rad or m.
    pub q0: Vec<f64>,
    /// Initial joint velocities (dof,), rad/s or m/s (zeros when not given).
    pub qd0: Vec<f64>,
    /// The final command (dof,).
    pub goal: Vec<f64>,
    /// The candidates, row-major (N, n·dof).
    pub candidates: Vec<f64>,
    /// Worker threads (None: all cores).
    pub threads: Option<usize>,
    /// The rollout and sequence options of the keyword arguments.
    pub options: SequenceOptions,
}

impl BatchInputs {
    /// Parse the arguments of `method` (e.g. "Fabric.evaluate") for a robot of `dof` joints, in the order
    /// the signature lists them.
    #[allow(clippy::too_many_arguments)]
    pub fn parse(
        method: &str,
        dof: usize,
        q0: &Bound<'_, PyAny>,
        qd0: Option<&Bound<'_, PyAny>>,
        goal: &Bound<'_, PyAny>,
        candidates: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
        return_trajectories: bool,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<BatchInputs> {
        let (q0, qd0) = initial_state(q0, qd0, dof)?;
        let goal = convert::vector(goal, "goal", dof)?;
        let (candidates, _, n_commands) = candidate_rows(candidates, dof)?;
        let threads = convert::threads(threads)?;
        let options = options_from_kwargs(method, options, true, n_commands, return_trajectories)?;
        Ok(BatchInputs {
            q0,
            qd0,
            goal,
            candidates,
            threads,
            options,
        })
    }

    /// Run `evaluate` on these inputs for `policy` in `scene`, with the GIL released.
    pub fn run<P: Send + Sync>(
        self,
        py: Python<'_>,
        policy: Arc<P>,
        scene: Arc<Scene>,
        evaluate: BatchEvaluation<P>,
    ) -> PyResult<Vec<SequenceResult>> {
        detached(py, move || {
            evaluate(
                &policy,
                &scene,
                &self.q0,
                &self.qd0,
                &self.goal,
                &self.candidates,
                &self.options,
                self.threads,
            )
        })
    }
}

/// The candidates (N, n·dof) of an `evaluate` call: (row-major data, N, n), shape and finiteness checked.
fn candidate_rows(candidates: &Bound<'_, PyAny>, dof: usize) -> PyResult<(Vec<f64>, usize, usize)> {
    let cand = convert::array(candidates, "candidates")?;
    let (rows, n_commands) = match cand.shape.as_slice() {
        [r, c] if dof > 0 && c % dof == 0 => (*r, c / dof),
        _ => {
            return Err(convert::shape_error(
                "candidates",
                &format!("(N, n*{dof}) with n >= 0"),
                &cand.shape,
            ))
        }
    };
    convert::finite("candidates", &cand.data)?;
    Ok((cand.data, rows, n_commands))
}

/// What `evaluate` returns for `results` (one per candidate): `(costs (N,), reached (N,) bool,
/// min_clearance (N,))`, plus the list of N `SequenceRollout` when `return_trajectories`.
pub fn evaluate_output<'py>(
    py: Python<'py>,
    results: Vec<SequenceResult>,
    dof: usize,
    return_trajectories: bool,
) -> PyResult<Bound<'py, PyTuple>> {
    let rows = results.len();
    let costs = output(py, results.iter().map(|r| r.cost).collect(), &[rows])?.into_any();
    let reached =
        typed_output(py, results.iter().map(|r| r.reached).collect(), &[rows])?.into_any();
    let clearance = output(
        py,
        results.iter().map(|r| r.min_clearance).collect(),
        &[rows],
    )?
    .into_any();
    let mut items = vec![costs, reached, clearance];
    if return_trajectories {
        let list: Vec<PySequenceRollout> = results
            .into_iter()
            .map(|r| PySequenceRollout::new(dof, r))
            .collect();
        items.push(list.into_pyobject(py)?.into_any());
    }
    PyTuple::new(py, items)
}

/// A recorded trajectory as numpy arrays.
#[derive(Clone)]
struct Recorded {
    dof: usize,
    t: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
}

impl Recorded {
    fn new(dof: usize, tr: Option<Trajectory>) -> Self {
        match tr {
            Some(tr) => Recorded {
                dof,
                t: tr.t,
                q: tr.q,
                qd: tr.qd,
                qdd: tr.qdd,
            },
            None => Recorded {
                dof,
                t: vec![],
                q: vec![],
                qd: vec![],
                qdd: vec![],
            },
        }
    }

    fn rows<'py>(&self, py: Python<'py>, data: &[f64]) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        output(py, data.to_vec(), &[self.t.len(), self.dof])
    }
}

/// The `#[pymethods]` block of a result class holding `rec: Recorded` and a `result` with final `q`, `qd`:
/// the trajectory getters `t` (T,) s (documented by `t_doc`), `q`, `qd` (T, dof), `qdd` (T, dof)
/// (documented by `qdd_doc`), the final state `q_final`, `qd_final` (dof,) and `__len__` (T), followed by
/// the class's own methods.
macro_rules! recorded_pymethods {
    ($class:ident, t_doc = $t_doc:literal, qdd_doc = $qdd_doc:literal, $($methods:tt)*) => {
        #[pymethods]
        impl $class {
            #[doc = $t_doc]
            #[getter]
            fn t<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
                output(py, self.rec.t.clone(), &[self.rec.t.len()])
            }
            /// Configurations (T, dof).
            #[getter]
            fn q<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
                self.rec.rows(py, &self.rec.q)
            }
            /// Velocities (T, dof).
            #[getter]
            fn qd<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
                self.rec.rows(py, &self.rec.qd)
            }
            #[doc = $qdd_doc]
            #[getter]
            fn qdd<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
                self.rec.rows(py, &self.rec.qdd)
            }
            /// Final configuration (dof,).
            #[getter]
            fn q_final<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
                output(py, self.result.q.clone(), &[self.result.q.len()])
            }
            /// Final velocity (dof,).
            #[getter]
            fn qd_final<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
                output(py, self.result.qd.clone(), &[self.result.qd.len()])
            }
            fn __len__(&self) -> usize {
                self.rec.t.len()
            }
            $($methods)*
        }
    };
}

/// One rollout toward one command (GFCS eq. 1–3). Trajectory arrays are empty ((0,), (0, dof)) when the
/// rollout was not recorded.
#[pyclass(frozen, skip_from_py_object, name = "Rollout", module = "gfcs._core")]
#[derive(Clone)]
pub struct PyRollout {
    rec: Recorded,
    result: RolloutResult,
}

impl PyRollout {
    /// Wrap a core result (its trajectory is moved out).
    pub fn new(dof: usize, mut result: RolloutResult) -> Self {
        let rec = Recorded::new(dof, result.trajectory.take());
        PyRollout { rec, result }
    }
}

recorded_pymethods! {
    PyRollout,
    t_doc = "Times (T,), s.",
    qdd_doc = "Accelerations f(q, q̇) (T, dof) applied from each row to the next.",
    /// t* = min(t, t_max), s (eq. 2): the first time ‖q − command‖ < tol, t_max if never.
    #[getter]
    fn t_star(&self) -> f64 {
        self.result.t_star
    }
    /// Time of the final state, s.
    #[getter]
    fn t_end(&self) -> f64 {
        self.result.t_end
    }
    /// Integration steps taken.
    #[getter]
    fn steps(&self) -> usize {
        self.result.steps
    }
    /// "reached", "timeout", "stalled" or "non_finite".
    #[getter]
    fn reason(&self) -> &'static str {
        reason_name(self.result.reason)
    }
    /// Closest approach ‖q − command‖ over the rollout's states (rad; below tol when reached).
    #[getter]
    fn min_distance(&self) -> f64 {
        self.result.min_distance
    }
    /// The command was reached within tol (eq. 3).
    #[getter]
    fn reached(&self) -> bool {
        self.result.reason == StopReason::Reached
    }
    /// Minimum clearance (m) over the rollout's states: the smaller of the sphere–obstacle clearance
    /// (within the obstacle influence radius) and the self-collision sphere-pair clearance; negative =
    /// collision, inf when nothing came close.
    #[getter]
    fn min_clearance(&self) -> f64 {
        self.result.min_clearance
    }
    fn __repr__(&self) -> String {
        format!(
            "Rollout(reason='{}', t_star={}, steps={}, min_clearance={}, rows={})",
            self.reason(),
            self.result.t_star,
            self.result.steps,
            self.result.min_clearance,
            self.rec.t.len()
        )
    }
}

/// One command sequence (one GFCOP candidate, GFCS eq. 4–8): n free commands then the goal. The
/// trajectory is the concatenation of the n + 1 rollouts (empty when not recorded).
#[pyclass(
    frozen,
    skip_from_py_object,
    name = "SequenceRollout",
    module = "gfcs._core"
)]
#[derive(Clone)]
pub struct PySequenceRollout {
    rec: Recorded,
    result: SequenceResult,
}

impl PySequenceRollout {
    /// Wrap a core result (its trajectory is moved out).
    pub fn new(dof: usize, mut result: SequenceResult) -> Self {
        let rec = Recorded::new(dof, result.trajectory.take());
        PySequenceRollout { rec, result }
    }
}

recorded_pymethods! {
    PySequenceRollout,
    t_doc = "Times (T,), s, strictly increasing across the commands.",
    qdd_doc = "Accelerations (T, dof).",
    /// Cost Σ tᵢ* + (p + distance_penalty·goal_distance)·1[goal not reached]
    /// + collision_penalty·1[collided], s (eq. 4, 8).
    #[getter]
    fn cost(&self) -> f64 {
        self.result.cost
    }
    /// Closest approach ‖q − goal‖ (rad) of the final rollout to the goal (below tol when reached).
    #[getter]
    fn goal_distance(&self) -> f64 {
        self.result.goal_distance
    }
    /// tᵢ* of every command, (n + 1,), s (eq. 5).
    #[getter]
    fn t_stars<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        output(
            py,
            self.result.t_stars.clone(),
            &[self.result.t_stars.len()],
        )
    }
    /// Stop reason of every command ("reached", "timeout", "stalled", "non_finite"), length n + 1.
    #[getter]
    fn reasons(&self) -> Vec<&'static str> {
        self.result
            .reasons
            .iter()
            .map(|r| reason_name(*r))
            .collect()
    }
    /// The final rollout reached the goal (eq. 8).
    #[getter]
    fn reached(&self) -> bool {
        self.result.reached
    }
    /// Reached the goal without collision.
    #[getter]
    fn success(&self) -> bool {
        self.result.success()
    }
    /// The minimum clearance dropped below −collision_tol: the sequence went through a collision.
    #[getter]
    fn collided(&self) -> bool {
        self.result.collided
    }
    /// Minimum clearance (m) over every step of every rollout (obstacles and self-collision, as for
    /// `Rollout.min_clearance`); negative = collision.
    #[getter]
    fn min_clearance(&self) -> f64 {
        self.result.min_clearance
    }
    fn __repr__(&self) -> String {
        format!(
            "SequenceRollout(cost={}, reached={}, min_clearance={}, t_stars={:?}, rows={})",
            self.result.cost,
            self.result.reached,
            self.result.min_clearance,
            self.result.t_stars,
            self.rec.t.len()
        )
    }
}
