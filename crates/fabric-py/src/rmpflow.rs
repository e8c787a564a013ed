//! `gfcs._core.Rmpflow`: RMPflow (Cheng et al. 2018) for a robot in a scene, the second controller of the
//! GF Sec. VII comparison: the same command semantics, rollouts and batches as `Fabric`, the heavy calls
//! with the GIL released.

use std::sync::{Arc, Mutex, PoisonError, RwLock};

use fabric_core::fabric::EeTargets;
use fabric_core::rmpflow::{
    rmp_evaluate_batch, rmp_rollout, RmpConfig, RmpDiagnostics, RmpWorkspace, Rmpflow,
};
use fabric_core::scene::{ObstacleId, Scene};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

use crate::config::{to_json, to_python};
use crate::convert::{self, output};
use crate::errors::{detached, error, guarded};
use crate::fabric::ee_targets;
use crate::robot::PyRobot;
use crate::rollout::{evaluate_output, initial_state, options_from_kwargs, BatchInputs, PyRollout};
use crate::scene::PyScene;

/// RMPflow policy for one robot in one scene.
///
/// `Rmpflow(robot, scene=None, config=None)`: `config` is a nested dict merged over the defaults
/// (sections `cspace_target`, `joint_limits`, `target`, `obstacles`, `self_collision`, `damping`; see
/// `Rmpflow.defaults()`), or None. q, q̇, commands have shape (dof,), rad (or m), rad/s.
#[pyclass(frozen, skip_from_py_object, name = "Rmpflow", module = "gfcs._core")]
pub struct PyRmpflow {
    rmp: Arc<Rmpflow>,
    robot: Py<PyRobot>,
    scene: RwLock<Arc<Scene>>,
    last: Mutex<Option<RmpDiagnostics>>,
    ws: Mutex<RmpWorkspace>,
}

impl PyRmpflow {
    fn dof(&self) -> usize {
        self.rmp.robot().dof()
    }

    fn scene_snapshot(&self) -> Arc<Scene> {
        self.scene
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }
}

fn parse_config(config: Option<&Bound<'_, PyAny>>) -> PyResult<RmpConfig> {
    match config {
        Some(c) if !c.is_none() => {
            let json = to_json(c, "")?.to_string();
            RmpConfig::from_json_str(&json).map_err(error)
        }
        _ => Ok(RmpConfig::default()),
    }
}

fn config_dict<'py>(py: Python<'py>, config: &RmpConfig) -> PyResult<Bound<'py, PyAny>> {
    let v = serde_json::to_value(config).map_err(|e| {
        error(fabric_core::FabricError::Value {
            what: "rmpflow config".into(),
            message: e.to_string(),
        })
    })?;
    to_python(py, &v)
}

#[pymethods]
impl PyRmpflow {
    #[new]
    #[pyo3(signature = (robot, scene=None, config=None))]
    fn py_new(
        py: Python<'_>,
        robot: Bound<'_, PyRobot>,
        scene: Option<PyRef<'_, PyScene>>,
        config: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let config = parse_config(config)?;
        let model = robot.get().inner.clone();
        let rmp = guarded(py, || Rmpflow::new(model, config))?;
        let scene = scene.map(|s| s.inner.clone()).unwrap_or_default();
        let ws = Mutex::new(RmpWorkspace::new(&rmp));
        Ok(PyRmpflow {
            rmp: Arc::new(rmp),
            robot: robot.unbind(),
            scene: RwLock::new(Arc::new(scene)),
            last: Mutex::new(None),
            ws,
        })
    }

    /// Every gain with its default, as a nested dict.
    #[staticmethod]
    fn defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
        config_dict(py, &RmpConfig::default())
    }

    /// The configuration, as a nested dict.
    #[getter]
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        config_dict(py, self.rmp.config())
    }

    /// The robot model.
    #[getter]
    fn robot(&self, py: Python<'_>) -> Py<PyRobot> {
        self.robot.clone_ref(py)
    }

    /// Number of robot coordinates.
    #[getter]
    #[pyo3(name = "dof")]
    fn py_dof(&self) -> usize {
        self.dof()
    }

    /// A copy of the scene the policy evaluates in.
    #[getter]
    fn scene(&self) -> PyScene {
        PyScene {
            inner: (*self.scene_snapshot()).clone(),
        }
    }

    /// Replace the scene (copied).
    fn set_scene(&self, scene: PyRef<'_, PyScene>) {
        *self.scene.write().unwrap_or_else(PoisonError::into_inner) = Arc::new(scene.inner.clone());
    }

    /// Move the obstacle `id` to `pose` and/or set its `velocity` (3,) m/s.
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
        guarded(py, || {
            let mut guard = self.scene.write().unwrap_or_else(PoisonError::into_inner);
            let scene = Arc::make_mut(&mut guard);
            if let Some(p) = pose {
                scene.set_pose(ObstacleId(id), p)?;
            }
            if let Some(v) = velocity {
                scene.set_velocity(ObstacleId(id), v)?;
            }
            Ok(())
        })
    }

    /// q̈ (dof,) rad/s² at (q, q̇) for the joint-space command: the posture leaf aims at `command`, the
    /// target leaf at the position of `ee_target` (a pose, 4 × 4 or (position, quaternion xyzw)) or, by
    /// default, at the end-effector position at `command`. Diagnostics are kept (`diagnostics()`).
    #[pyo3(signature = (q, qd, command, ee_target=None))]
    fn acceleration<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        command: &Bound<'py, PyAny>,
        ee_target: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let n = self.dof();
        let q = convert::vector(q, "q", n)?;
        let qd = convert::vector(qd, "qd", n)?;
        let command = convert::vector(command, "command", n)?;
        let targets = ee_target
            .filter(|t| !t.is_none())
            .map(ee_targets)
            .transpose()?;
        let rmp = &self.rmp;
        let scene = self.scene_snapshot();
        let mut ws = self.ws.lock().unwrap_or_else(|poisoned| {
            let mut ws = poisoned.into_inner();
            *ws = RmpWorkspace::new(rmp);
            self.ws.clear_poison();
            ws
        });
        let ws = &mut *ws;
        let (qdd, diag) = guarded(py, || {
            let mut qdd = vec![0.0; n];
            rmp.acceleration(&scene, &q, &qd, &command, targets.as_ref(), ws, &mut qdd)?;
            Ok((qdd, rmp.diagnostics(ws)))
        })?;
        *self.last.lock().unwrap_or_else(PoisonError::into_inner) = Some(diag);
        output(py, qdd, &[n])
    }

    /// Diagnostics of the last `acceleration` call (dict: min_clearance, min_self_clearance,
    /// min_joint_margin, leaves), or None before the first call.
    fn diagnostics<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(d) = *self.last.lock().unwrap_or_else(PoisonError::into_inner) else {
            return Ok(None);
        };
        let out = PyDict::new(py);
        out.set_item("min_clearance", d.min_clearance)?;
        out.set_item("min_self_clearance", d.min_self_clearance)?;
        out.set_item("min_joint_margin", d.min_joint_margin)?;
        out.set_item("leaves", d.leaves)?;
        Ok(Some(out))
    }

    /// rollout_t (GFCS eq. 1–3) from (q0, qd0) toward `command` until ‖q − command‖ < tol or t_max, the
    /// target leaf aiming at `ee_target` when given. Options as in `Fabric.rollout`. GIL released.
    #[pyo3(signature = (q0, qd0, command, ee_target=None, record=true, **options))]
    #[allow(clippy::too_many_arguments)]
    fn rollout(
        &self,
        py: Python<'_>,
        q0: &Bound<'_, PyAny>,
        qd0: Option<&Bound<'_, PyAny>>,
        command: &Bound<'_, PyAny>,
        ee_target: Option<&Bound<'_, PyAny>>,
        record: bool,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<PyRollout> {
        let n = self.dof();
        let (q0, qd0) = initial_state(q0, qd0, n)?;
        let command = convert::vector(command, "command", n)?;
        let targets: Option<EeTargets> = ee_target
            .filter(|t| !t.is_none())
            .map(ee_targets)
            .transpose()?;
        let opts = options_from_kwargs("Rmpflow.rollout", options, false, 0, record)?.rollout;
        let (rmp, scene) = (self.rmp.clone(), self.scene_snapshot());
        let result = detached(py, move || {
            let mut ws = RmpWorkspace::new(&rmp);
            rmp_rollout(
                &rmp,
                &scene,
                targets.as_ref(),
                &q0,
                &qd0,
                &command,
                &opts,
                &mut ws,
            )
        })?;
        Ok(PyRollout::new(n, result))
    }

    /// Evaluate N candidate command sequences in parallel (GFCS eq. 4, Alg. 1) under RMPflow:
    /// `candidates` (N, n·dof), then `goal`; options and returns as in `Fabric.evaluate`. GIL released.
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
            "Rmpflow.evaluate",
            n,
            q0,
            qd0,
            goal,
            candidates,
            threads,
            return_trajectories,
            options,
        )?;
        let results = b.run(
            py,
            self.rmp.clone(),
            self.scene_snapshot(),
            rmp_evaluate_batch,
        )?;
        evaluate_output(py, results, n, return_trajectories)
    }

    fn __repr__(&self) -> String {
        format!(
            "Rmpflow(robot='{}', dof={}, obstacles={})",
            self.robot.get().inner.name(),
            self.dof(),
            self.scene_snapshot().len()
        )
    }
}
