//! `gfcs._core.Fabric`: the geometric fabric of a robot in a scene (GF Sec. VII-A), its acceleration
//! q̈ = f(q, q̇; q_g) (GFCS eq. 1), rollouts (eq. 1–3), command sequences (eq. 4–8) and batched candidate
//! evaluation (Alg. 1), the heavy calls with the GIL released.
//!
//! The fabric holds its scene by value (a copy taken at construction or by `set_scene`); obstacles can be
//! moved between calls with `update_obstacle` without rebuilding the fabric.

use std::sync::{Arc, Mutex, PoisonError, RwLock};

use fabric_core::fabric::{Diagnostics, EeTargets, Fabric, FabricWorkspace};
use fabric_core::rollout::{self as core_rollout};
use fabric_core::scene::{ObstacleId, Scene};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::config::PyFabricConfig;
use crate::convert::{self, output};
use crate::errors::{detached, error, guarded};
use crate::robot::PyRobot;
use crate::rollout::{
    evaluate_output, initial_state, options_from_kwargs, BatchInputs, PyRollout, PySequenceRollout,
};
use crate::scene::PyScene;

/// Geometric fabric for one robot in one scene.
///
/// `Fabric(robot, scene=None, config=None)`: `config` is a `FabricConfig`, a nested dict, a path to a
/// TOML/YAML/JSON file, or None (defaults). q, q̇, commands have shape (dof,), rad (or m), rad/s.
#[pyclass(frozen, skip_from_py_object, name = "Fabric", module = "gfcs._core")]
pub struct PyFabric {
    fabric: Arc<Fabric>,
    robot: Py<PyRobot>,
    scene: RwLock<Arc<Scene>>,
    last: Mutex<Option<LastCall>>,
    /// Scratch of `acceleration` (ψ off: see `LastCall`), kept between calls: building it (kinematics
    /// workspaces, one task point per sphere) costs about as much as an evaluation.
    ws: Mutex<FabricWorkspace>,
}

/// The last successful `acceleration` call: its inputs (the scene it saw included), diagnostics and root
/// metric (a failed call leaves it as it was, so `diagnostics()` and `metric()` describe one call). The call
/// evaluates with the forcing potential ψ off (`FabricWorkspace::set_potential`; ψ only reports energy,
/// and its soft-plus terms are a measurable part of a cluttered step, BENCHMARKS.md "Speed"), so
/// `diagnostics()` evaluates ψ when asked for it, at these inputs: q̈ and every other diagnostic are the
/// same bit for bit with ψ on or off (fabric-core's engine tests).
struct LastCall {
    scene: Arc<Scene>,
    q: Vec<f64>,
    qd: Vec<f64>,
    command: Vec<f64>,
    targets: Option<EeTargets>,
    diag: Diagnostics,
    /// The root metric M̃ (dof × dof; symmetric, so its column-major storage is also row-major).
    metric: Vec<f64>,
}

/// Robots up to this many coordinates get `acceleration`'s q̈ in a stack buffer (no allocation).
const MAX_STACK_DOF: usize = 32;

impl PyFabric {
    /// The current scene (shared, immutable snapshot).
    fn scene_snapshot(&self) -> Arc<Scene> {
        self.scene
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    fn dof(&self) -> usize {
        self.fabric.robot().dof()
    }

    /// A fabric object for `fabric` (a variant of this one's model) on the same robot object and scene.
    fn derived(&self, py: Python<'_>, fabric: Fabric) -> PyFabric {
        let ws = Mutex::new(FabricWorkspace::for_rollouts(&fabric));
        PyFabric {
            fabric: Arc::new(fabric),
            robot: self.robot.clone_ref(py),
            scene: RwLock::new(self.scene_snapshot()),
            last: Mutex::new(None),
            ws,
        }
    }

    /// One evaluation of `Fabric::acceleration` in `scene` (with explicit end-effector `targets` when given)
    /// in the kept workspace, ψ on or off (`potential`); q̈ into `qdd` (dof,), the diagnostics returned and,
    /// with `metric`, the root metric M̃ (dof × dof) written into it.
    #[allow(clippy::too_many_arguments)]
    fn evaluate_once(
        &self,
        py: Python<'_>,
        scene: &Scene,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        targets: Option<&EeTargets>,
        potential: bool,
        qdd: &mut [f64],
        metric: Option<&mut Vec<f64>>,
    ) -> PyResult<Diagnostics> {
        let fabric = &self.fabric;
        // the GIL is held throughout, so the lock is never contended; after a panic inside (poisoned
        // lock) the workspace is built afresh rather than trusted
        let mut ws = self.ws.lock().unwrap_or_else(|poisoned| {
            let mut ws = poisoned.into_inner();
            *ws = FabricWorkspace::for_rollouts(fabric);
            self.ws.clear_poison();
            ws
        });
        let ws = &mut *ws;
        ws.set_potential(potential);
        let result = guarded(py, || {
            match targets {
                Some(t) => fabric.acceleration_with_targets(scene, q, qd, command, t, ws, qdd)?,
                None => fabric.acceleration(scene, q, qd, command, ws, qdd)?,
            }
            Ok(fabric.diagnostics(ws))
        });
        ws.set_potential(false);
        if let (Ok(_), Some(metric)) = (&result, metric) {
            metric.clear();
            metric.extend_from_slice(ws.root().m.as_slice());
        }
        result
    }

    /// The fabric and a snapshot of its current scene, to move into a GIL-free computation.
    fn shared(&self) -> (Arc<Fabric>, Arc<Scene>) {
        (self.fabric.clone(), self.scene_snapshot())
    }
}

/// End-effector targets from a pose (4 × 4 or (position, quaternion xyzw)).
pub(crate) fn ee_targets(obj: &Bound<'_, PyAny>) -> PyResult<EeTargets> {
    let pose = convert::pose(obj, "ee_target")?;
    let r = pose.rotation.to_rotation_matrix();
    let m = r.matrix();
    Ok(EeTargets {
        position: pose.translation.vector,
        axes: [
            m.column(0).into_owned(),
            m.column(1).into_owned(),
            m.column(2).into_owned(),
        ],
    })
}

/// Diagnostics as a dict of floats (and `leaves` as int).
fn diagnostics_dict<'py>(py: Python<'py>, d: &Diagnostics) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    let fields: [(&str, f64); 14] = [
        ("energy", d.energy),
        ("exec_energy", d.exec_energy),
        ("potential", d.potential),
        ("min_clearance", d.min_clearance),
        ("min_self_clearance", d.min_self_clearance),
        ("min_joint_margin", d.min_joint_margin),
        ("alpha_le", d.alpha_le),
        ("alpha_ex0", d.alpha_ex0),
        ("alpha_expsi", d.alpha_expsi),
        ("eta", d.eta),
        ("s_beta", d.s_beta),
        ("beta", d.beta),
        ("alpha_boost", d.alpha_boost),
        ("alpha_reg", d.alpha_reg),
    ];
    for (k, v) in fields {
        out.set_item(k, v)?;
    }
    out.set_item("leaves", d.leaves)?;
    Ok(out)
}

#[pymethods]
impl PyFabric {
    #[new]
    #[pyo3(signature = (robot, scene=None, config=None))]
    fn py_new(
        py: Python<'_>,
        robot: Bound<'_, PyRobot>,
        scene: Option<PyRef<'_, PyScene>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let config = PyFabricConfig::from_any(py, config)?;
        let model = robot.get().inner.clone();
        let fabric = guarded(py, || Fabric::new(model, config))?;
        let scene = scene.map(|s| s.inner.clone()).unwrap_or_default();
        fabric.check_scene(&scene).map_err(error)?;
        let ws = Mutex::new(FabricWorkspace::for_rollouts(&fabric));
        Ok(PyFabric {
            fabric: Arc::new(fabric),
            robot: robot.unbind(),
            scene: RwLock::new(Arc::new(scene)),
            last: Mutex::new(None),
            ws,
        })
    }

    /// The robot model.
    #[getter]
    fn robot(&self, py: Python<'_>) -> Py<PyRobot> {
        self.robot.clone_ref(py)
    }

    /// The configuration.
    #[getter]
    fn config(&self) -> PyFabricConfig {
        PyFabricConfig {
            inner: self.fabric.config().clone(),
        }
    }

    /// Number of robot coordinates.
    #[getter]
    #[pyo3(name = "dof")]
    fn py_dof(&self) -> usize {
        self.dof()
    }

    /// A copy of this fabric (same robot, configuration and scene) whose obstacle barrier uses one margin
    /// per robot sphere: `margins` (S,) m in the order of `robot.sphere_radii`, each > −radius (negative:
    /// the sphere may sink into obstacles by that much), replacing `config.obstacles.margin`; None: the
    /// configured margin. `ShapeError` / `NonFiniteError` / `InvalidValueError` (naming the sphere).
    #[pyo3(signature = (margins))]
    fn with_obstacle_margins(
        &self,
        py: Python<'_>,
        margins: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let margins =
            convert::optional_vector(margins, "margins", self.fabric.robot().spheres().len())?;
        let fabric = (*self.fabric).clone();
        let fabric = guarded(py, || fabric.with_obstacle_margins(margins))?;
        Ok(self.derived(py, fabric))
    }

    /// A copy of this fabric whose self-collision barrier uses one margin per sphere pair: `margins` (P,) m
    /// in the order of `robot.self_collision_pairs`, each > −(r_a + r_b), replacing
    /// `config.self_collision.margin`; None: the configured margin. `ShapeError` / `NonFiniteError` /
    /// `InvalidValueError` (naming the pair's links).
    #[pyo3(signature = (margins))]
    fn with_self_margins(
        &self,
        py: Python<'_>,
        margins: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let pairs = self.fabric.robot().self_collision_pairs().len();
        let margins = convert::optional_vector(margins, "margins", pairs)?;
        let fabric = (*self.fabric).clone();
        let fabric = guarded(py, || fabric.with_self_margins(margins))?;
        Ok(self.derived(py, fabric))
    }

    /// A copy of this fabric whose joint attractor acts on x = S (q − q_g): `scales` (dof,) positive, one
    /// per joint (units of x per rad or per m; `gfcs.joints.velocity_scales` gives v_ref / v_i from the
    /// velocity limits); None: S = I (the paper's). `ShapeError` / `NonFiniteError` /
    /// `InvalidValueError` (naming the joint).
    #[pyo3(signature = (scales))]
    fn with_joint_scales(
        &self,
        py: Python<'_>,
        scales: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let scales = convert::optional_vector(scales, "scales", self.dof())?;
        let fabric = (*self.fabric).clone();
        let fabric = guarded(py, || fabric.with_joint_scales(scales))?;
        Ok(self.derived(py, fabric))
    }

    /// The joint attractor's per-joint scales (dof,) of `with_joint_scales`, or None (S = I).
    #[getter]
    fn joint_scales<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArrayDyn<f64>>>> {
        self.fabric
            .joint_scales()
            .map(|s| output(py, s.to_vec(), &[s.len()]))
            .transpose()
    }

    /// The per-pair self-collision margins (P,) m of `with_self_margins`, or None (the configured margin).
    #[getter]
    fn self_margins<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArrayDyn<f64>>>> {
        self.fabric
            .self_margins()
            .map(|m| output(py, m.to_vec(), &[m.len()]))
            .transpose()
    }

    /// The per-sphere obstacle margins (S,) m of `with_obstacle_margins`, or None (the configured margin).
    #[getter]
    fn obstacle_margins<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, PyArrayDyn<f64>>>> {
        self.fabric
            .obstacle_margins()
            .map(|m| output(py, m.to_vec(), &[m.len()]))
            .transpose()
    }

    /// A copy of the scene the fabric evaluates in.
    #[getter]
    fn scene(&self) -> PyScene {
        PyScene {
            inner: (*self.scene_snapshot()).clone(),
        }
    }

    /// Replace the scene (copied). Raises `InvalidValueError` for a robot without collision spheres in
    /// a scene with obstacles (see `Fabric(...)`).
    fn set_scene(&self, scene: PyRef<'_, PyScene>) -> PyResult<()> {
        self.fabric.check_scene(&scene.inner).map_err(error)?;
        let new = Arc::new(scene.inner.clone());
        *self.scene.write().unwrap_or_else(PoisonError::into_inner) = new;
        Ok(())
    }

    /// Move the obstacle `id` of the fabric's scene to `pose` and/or set its `velocity` (3,) m/s.
    #[pyo3(signature = (id, pose=None, velocity=None))]
    fn update_obstacle(
        &self,
        py: Python<'_>,
        id: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let id = convert::integer(id, "id", 0, u64::MAX)?;
        let pose = pose
            .filter(|p| !p.is_none())
            .map(|p| convert::pose(p, "pose"))
            .transpose()?;
        let velocity = velocity
            .filter(|v| !v.is_none())
            .map(|v| convert::vector3(v, "velocity"))
            .transpose()?;
        // The lock is taken and released inside the closure: no Python code runs while it is held.
        guarded(py, || {
            let mut guard = self.scene.write().unwrap_or_else(PoisonError::into_inner);
            let scene = Arc::make_mut(&mut guard);
            let id = ObstacleId(id);
            if let Some(p) = pose {
                scene.set_pose(id, p)?;
            }
            if let Some(v) = velocity {
                scene.set_velocity(id, v)?;
            }
            Ok(())
        })
    }

    /// q̈ (dof,) rad/s² at (q, q̇) attracted to the joint-space command (GFCS eq. 1). `ee_target` (a pose,
    /// 4 × 4 or (position, quaternion xyzw)) overrides the end-effector attractor targets, which default
    /// to the end-effector pose at `command`. The diagnostics of this evaluation are kept
    /// (`diagnostics()`).
    #[pyo3(signature = (q, qd, command, ee_target=None))]
    fn acceleration<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        command: &Bound<'py, PyAny>,
        ee_target: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        let n = self.dof();
        let q = convert::vector(q, "q", n)?;
        let qd = convert::vector(qd, "qd", n)?;
        let command = convert::vector(command, "command", n)?;
        let targets = ee_target
            .filter(|t| !t.is_none())
            .map(ee_targets)
            .transpose()?;
        let mut qdd = [0.0; MAX_STACK_DOF];
        let mut heap = Vec::new();
        let qdd: &mut [f64] = if n <= MAX_STACK_DOF {
            &mut qdd[..n]
        } else {
            heap.resize(n, 0.0);
            &mut heap
        };
        let scene = self.scene_snapshot();
        let mut metric = Vec::with_capacity(n * n);
        let diag = self.evaluate_once(
            py,
            &scene,
            &q,
            &qd,
            &command,
            targets.as_ref(),
            false,
            qdd,
            Some(&mut metric),
        )?;
        *self.last.lock().unwrap_or_else(PoisonError::into_inner) = Some(LastCall {
            scene,
            q,
            qd,
            command,
            targets,
            diag,
            metric,
        });
        Ok(numpy::PyArray1::from_slice(py, qdd))
    }

    /// Diagnostics of the last `acceleration` call (dict: energy, exec_energy, potential, min_clearance,
    /// min_self_clearance, min_joint_margin, alpha_le, alpha_ex0, alpha_expsi, eta, s_beta, beta,
    /// alpha_boost, alpha_reg, leaves), or None before the first call. The forcing potential ψ is
    /// evaluated here, at the last call's state and scene (one more fabric evaluation); `potential=False`
    /// skips it (`potential` is then NaN) for callers that read the other fields every step.
    #[pyo3(signature = (potential=true))]
    fn diagnostics<'py>(
        &self,
        py: Python<'py>,
        potential: bool,
    ) -> PyResult<Option<Bound<'py, PyDict>>> {
        let last = self.last.lock().unwrap_or_else(PoisonError::into_inner);
        let Some(call) = last.as_ref() else {
            return Ok(None);
        };
        let mut diag = call.diag;
        if potential {
            let mut qdd = vec![0.0; call.q.len()];
            let with_psi = self.evaluate_once(
                py,
                &call.scene,
                &call.q,
                &call.qd,
                &call.command,
                call.targets.as_ref(),
                true,
                &mut qdd,
                None,
            )?;
            diag.potential = with_psi.potential;
        }
        diagnostics_dict(py, &diag).map(Some)
    }

    /// The root metric M̃ (dof, dof) of the last successful `acceleration` call (GF eq. 17: the summed
    /// pulled-back Finsler metrics, which weight a constrained fabric's projection, Lemma IV.3), or None
    /// before it.
    fn metric<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArrayDyn<f64>>>> {
        let m = match &*self.last.lock().unwrap_or_else(PoisonError::into_inner) {
            Some(call) => call.metric.clone(),
            None => return Ok(None),
        };
        let n = self.dof();
        output(py, m, &[n, n]).map(Some)
    }

    /// rollout_t (GFCS eq. 1–3): integrate from (q0, qd0) toward `command` until ‖q − command‖ < tol or
    /// t_max. `qd0` None = rest. `**options`: dt [s], t_max [s], tol [rad], stall_window [s],
    /// stall_progress [rad], capture_tol [rad], integrator ("euler", the papers' semi-implicit scheme, or
    /// "rk4"); defaults:
    /// `rollout_option_defaults()`. GIL released.
    #[pyo3(signature = (q0, qd0, command, record=true, **options))]
    fn rollout(
        &self,
        py: Python<'_>,
        q0: &Bound<'_, PyAny>,
        qd0: Option<&Bound<'_, PyAny>>,
        command: &Bound<'_, PyAny>,
        record: bool,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<PyRollout> {
        let n = self.dof();
        let (q0, qd0) = initial_state(q0, qd0, n)?;
        let command = convert::vector(command, "command", n)?;
        let opts = options_from_kwargs("Fabric.rollout", options, false, 0, record)?.rollout;
        let (fabric, scene) = self.shared();
        let result = detached(py, move || {
            let mut ws = FabricWorkspace::for_rollouts(&fabric);
            core_rollout::rollout(&fabric, &scene, &q0, &qd0, &command, &opts, &mut ws)
        })?;
        Ok(PyRollout::new(n, result))
    }

    /// One command sequence (GFCS eq. 4–8): `commands` (n, dof) free commands (n may be 0), then `goal`
    /// (dof,). Intermediate commands hand over at ‖q − q_gⁱ‖ < waypoint_tol; the goal at tol. Cost =
    /// Σ tᵢ* + penalty + distance_penalty × the closest approach to the goal, both if the goal is not
    /// reached, + collision_penalty if the minimum clearance drops below −collision_tol. At each handover
    /// the fabric's command moves to the next one over blend_time (0 = a jump, the paper's).
    /// `**options`: those of `rollout` and waypoint_tol [rad], penalty [s], collision_penalty [s],
    /// collision_tol [m], distance_penalty [s/rad], blend_time [s]; defaults:
    /// `rollout_option_defaults()`. GIL released.
    #[pyo3(signature = (q0, qd0, commands, goal, record=true, **options))]
    #[allow(clippy::too_many_arguments)]
    fn rollout_sequence(
        &self,
        py: Python<'_>,
        q0: &Bound<'_, PyAny>,
        qd0: Option<&Bound<'_, PyAny>>,
        commands: &Bound<'_, PyAny>,
        goal: &Bound<'_, PyAny>,
        record: bool,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<PySequenceRollout> {
        let n = self.dof();
        let (q0, qd0) = initial_state(q0, qd0, n)?;
        let (commands, n_commands) = convert::rows(commands, "commands", n)?;
        let goal = convert::vector(goal, "goal", n)?;
        let opts =
            options_from_kwargs("Fabric.rollout_sequence", options, true, n_commands, record)?;
        let (fabric, scene) = self.shared();
        let result = detached(py, move || {
            let mut ws = FabricWorkspace::for_rollouts(&fabric);
            core_rollout::rollout_sequence(
                &fabric, &scene, &q0, &qd0, &commands, &goal, &opts, &mut ws,
            )
        })?;
        Ok(PySequenceRollout::new(n, result))
    }

    /// Evaluate N candidate command sequences in parallel (GFCS eq. 4, Alg. 1): `candidates`
    /// (N, n·dof), each row n free commands, then `goal`; `**options` as in `rollout_sequence`. Returns
    /// `(costs (N,), reached (N,) bool, min_clearance (N,))`, plus a list of N `SequenceRollout` (with
    /// trajectories) when `return_trajectories`. Results are in candidate order and do not depend on
    /// `threads` (None: all cores). GIL released.
    #[pyo3(signature = (q0, qd0, goal, candidates, threads=None, return_trajectories=false, **options))]
    #[allow(clippy::too_many_arguments)]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        q0: &Bound<'py, PyAny>,
        qd0: Option<&Bound<'py, PyAny>>,
        goal: &Bound<'py, PyAny>,
        candidates: &Bound<'py, PyAny>,
        threads: Option<&Bound<'py, PyAny>>,
        return_trajectories: bool,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let n = self.dof();
        let b = BatchInputs::parse(
            "Fabric.evaluate",
            n,
            q0,
            qd0,
            goal,
            candidates,
            threads,
            return_trajectories,
            options,
        )?;
        let (fabric, scene) = self.shared();
        let results = b.run(py, fabric, scene, core_rollout::evaluate_batch)?;
        evaluate_output(py, results, n, return_trajectories)
    }

    fn __repr__(&self) -> String {
        let mode = match self.fabric.config().mode {
            fabric_core::fabric::Mode::Bent => "bent",
            fabric_core::fabric::Mode::Unbent => "unbent",
        };
        format!(
            "Fabric(robot='{}', dof={}, obstacles={}, mode='{mode}')",
            self.robot.get().inner.name(),
            self.dof(),
            self.scene_snapshot().len(),
        )
    }
}
