//! `gfcs._core.MeshChecker`: exact clearance of a robot's URDF collision meshes and primitives against a
//! scene and against itself (fabric-core `validate`), for judging trajectories the way independent
//! validators do (GFCS Sec. V success criterion) rather than with the fabric's collision spheres.
//!
//! Frames: q in the robot's joint order, the scene in the robot base frame. Units: m, rad.

use std::sync::Arc;
use std::time::{Duration, Instant};

use fabric_core::validate::{MeshChecker, DEFAULT_MAX_DISTANCE};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{self, output};
use crate::errors::{detached, guarded};
use crate::robot::PyRobot;
use crate::scene::PyScene;

/// A float for q (dof,) or a (T,) array for q (T, dof).
/// The `cutoff` argument of the trajectory minima: None is +∞; NaN is an `InvalidValueError` naming it.
fn cutoff_arg(cutoff: Option<f64>) -> PyResult<f64> {
    match cutoff {
        None => Ok(f64::INFINITY),
        Some(c) if c.is_nan() => Err(crate::errors::error(fabric_core::FabricError::Value {
            what: "cutoff".to_string(),
            message: "must be a number of metres, got NaN".to_string(),
        })),
        Some(c) => Ok(c),
    }
}

/// `values` (T × width row-major) as a (width,) array for one state (`batch` None) or (T, width).
fn rows_output<'py>(
    py: Python<'py>,
    values: Vec<f64>,
    batch: Option<usize>,
    width: usize,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    match batch {
        None => output(py, values, &[width]),
        Some(t) => output(py, values, &[t, width]),
    }
}

/// The arguments of a per-state query, checked in this order: the thread count, the cutoff (m; None:
/// +∞), and q (dof,) or (T, dof) as row-major states with the batch size T (None for one state).
struct Query {
    qs: Vec<f64>,
    batch: Option<usize>,
    threads: Option<usize>,
    cutoff: f64,
}

fn scalar_or_array(py: Python<'_>, values: Vec<f64>, batch: Option<usize>) -> PyResult<Py<PyAny>> {
    match (batch, values.first()) {
        (None, Some(v)) => Ok(v.into_pyobject(py)?.into_any().unbind()),
        _ => {
            let n = values.len();
            let array: Bound<'_, PyArrayDyn<f64>> = output(py, values, &[n])?;
            Ok(array.into_any().unbind())
        }
    }
}

/// Clearance of a robot's URDF collision geometry (meshes scaled by their URDF scale; boxes, cylinders,
/// capsules, spheres), independent of its collision spheres.
///
/// `MeshChecker(robot, max_distance=0.5)`: loads every `<collision>` element of `robot` once (the robot
/// must come from a URDF with collision geometry, e.g. the MotionBenchMaker `panda.urdf` with
/// `mesh_dir`). `max_distance` (m) keeps queries local: clearances above it are reported as `inf`.
/// Raises `MeshError` naming the file and link for a missing or malformed mesh, `InvalidValueError`
/// for a robot without collision geometry or a negative `max_distance`.
#[pyclass(
    frozen,
    skip_from_py_object,
    name = "MeshChecker",
    module = "gfcs._core"
)]
pub struct PyMeshChecker {
    inner: Arc<MeshChecker>,
}

impl PyMeshChecker {
    /// The [`Query`] of a call's `q`, `threads` and `cutoff`.
    fn query(
        &self,
        q: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
        cutoff: Option<f64>,
    ) -> PyResult<Query> {
        let threads = convert::threads(threads)?;
        let cutoff = cutoff_arg(cutoff)?;
        let (qs, batch) = convert::vector_or_rows(q, "q", self.inner.robot().dof())?;
        Ok(Query {
            qs,
            batch,
            threads,
            cutoff,
        })
    }

    /// The link names of the collision shapes `i` and `j`.
    fn pair_links(&self, i: usize, j: usize) -> (String, String) {
        let (names, shapes) = (self.inner.robot().link_names(), self.inner.shapes());
        let name = |k: usize| names.get(shapes[k].link).cloned().unwrap_or_default();
        (name(i), name(j))
    }

    /// `contacts(checker, q, within)` (the self or the held pairs) with the link names of each pair.
    fn named_contacts(
        &self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        (within, depth): (f64, bool),
        contacts: ContactQuery,
    ) -> PyResult<Vec<(String, String, f64)>> {
        let checker = &self.inner;
        let q = convert::vector(q, "q", checker.robot().dof())?;
        let found = guarded(py, || contacts(checker, &q, within, depth))?;
        Ok(found
            .into_iter()
            .map(|(i, j, d)| {
                let (a, b) = self.pair_links(i, j);
                (a, b, d)
            })
            .collect())
    }
}

/// A contact query of the checker (`MeshChecker::self_contacts`, `held_contacts`, `adjacent_contacts`):
/// (shape i, shape j, m).
type ContactQuery =
    fn(&MeshChecker, &[f64], f64, bool) -> fabric_core::Result<Vec<(usize, usize, f64)>>;

#[pymethods]
impl PyMeshChecker {
    #[new]
    #[pyo3(signature = (robot, max_distance=DEFAULT_MAX_DISTANCE))]
    fn py_new(py: Python<'_>, robot: PyRef<'_, PyRobot>, max_distance: f64) -> PyResult<Self> {
        let robot = robot.inner.clone();
        let checker = detached(py, move || {
            MeshChecker::new(&robot)?.with_max_distance(max_distance)
        })?;
        Ok(PyMeshChecker {
            inner: Arc::new(checker),
        })
    }

    /// Number of collision shapes S (one per URDF `<collision>` element).
    #[getter]
    fn num_shapes(&self) -> usize {
        self.inner.num_shapes()
    }

    /// Link name of each collision shape, (S,) in URDF order.
    #[getter]
    fn shape_links(&self) -> Vec<String> {
        let names = self.inner.robot().link_names();
        self.inner
            .shapes()
            .iter()
            .map(|s| names.get(s.link).cloned().unwrap_or_default())
            .collect()
    }

    /// Number of shape pairs checked by `self_clearance` (links on different, non-adjacent rigid bodies
    /// not disabled by the SRDF).
    #[getter]
    fn num_self_pairs(&self) -> usize {
        self.inner.self_pairs().len()
    }

    /// Cutoff (m): clearances above it are reported as `inf`.
    #[getter]
    fn max_distance(&self) -> f64 {
        self.inner.max_distance()
    }

    /// Number of joints (length of q).
    #[getter]
    fn dof(&self) -> usize {
        self.inner.robot().dof()
    }

    /// Joint names, in q order.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.robot().joint_names().to_vec()
    }

    /// A copy of the robot the checker was built from.
    #[getter]
    fn robot(&self) -> PyRobot {
        PyRobot::new(self.inner.robot().clone())
    }

    /// Clearance (m) of the collision geometry against `scene`: float for q (dof,), (T,) array for
    /// q (T, dof). Positive when separated, ≤ 0 in contact (negative: penetration depth), `inf` when no
    /// obstacle is within `max_distance`. Trajectories run in parallel (`threads`, None: all cores) with
    /// the GIL released. With `cutoff` (m) a value is exact only where it is below the cutoff and some
    /// value at or above it otherwise (shape pairs beyond it are not measured: cheaper away from
    /// contact).
    #[pyo3(signature = (scene, q, threads=None, cutoff=None))]
    fn clearance(
        &self,
        py: Python<'_>,
        scene: PyRef<'_, PyScene>,
        q: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
        cutoff: Option<f64>,
    ) -> PyResult<Py<PyAny>> {
        let a = self.query(q, threads, cutoff)?;
        let checker = &self.inner;
        let scene = &scene.inner;
        let values = detached(py, || {
            checker.trajectory_clearance_within(scene, &a.qs, a.threads, a.cutoff)
        })?;
        scalar_or_array(py, values, a.batch)
    }

    /// Self-clearance (m) over the checked shape pairs: float for q (dof,), (T,) array for q (T, dof);
    /// ≤ 0 in contact (negative: penetration depth), `inf` when no pair is within `max_distance`.
    /// Parallel, and `cutoff` as in `clearance`.
    #[pyo3(signature = (q, threads=None, cutoff=None))]
    fn self_clearance(
        &self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
        cutoff: Option<f64>,
    ) -> PyResult<Py<PyAny>> {
        let a = self.query(q, threads, cutoff)?;
        let checker = &self.inner;
        let values = detached(py, || {
            checker.trajectory_self_clearance_within(&a.qs, a.threads, a.cutoff)
        })?;
        scalar_or_array(py, values, a.batch)
    }

    /// Clearance (m) of each collision shape (`shape_links` order) to `scene`: (S,) for q (dof,), (T, S)
    /// for q (T, dof); exact below `cutoff` (None: `max_distance`), `inf` where no obstacle lies that
    /// near; the minimum over the shapes is `clearance`. Parallel, GIL released.
    #[pyo3(signature = (scene, q, threads=None, cutoff=None))]
    fn shape_clearances<'py>(
        &self,
        py: Python<'py>,
        scene: PyRef<'_, PyScene>,
        q: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
        cutoff: Option<f64>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let a = self.query(q, threads, cutoff)?;
        let checker = &self.inner;
        let scene = &scene.inner;
        let values = detached(py, || {
            checker.trajectory_shape_clearances(scene, &a.qs, a.threads, a.cutoff)
        })?;
        rows_output(py, values, a.batch, checker.num_shapes())
    }

    /// Distance (m) of each checked self-collision shape pair (`self_pair_links` order): (P,) for q
    /// (dof,), (T, P) for q (T, dof); exact below `cutoff`, `inf` beyond; in contact, the negative
    /// penetration depth, or with `depth=False` 0 for two meshes not both convex (a contact verdict without the
    /// costly depth); the minimum over the pairs is `self_clearance`. Parallel, GIL released.
    #[pyo3(signature = (q, threads=None, cutoff=None, depth=true))]
    fn pair_clearances<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
        cutoff: Option<f64>,
        depth: bool,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let a = self.query(q, threads, cutoff)?;
        let checker = &self.inner;
        let values = detached(py, || {
            checker.trajectory_pair_clearances(&a.qs, a.threads, a.cutoff, depth)
        })?;
        rows_output(py, values, a.batch, checker.self_pairs().len())
    }

    /// The links of each checked self-collision shape pair, in `pair_clearances` order: [(link a, link b)].
    #[getter]
    fn self_pair_links(&self) -> Vec<(String, String)> {
        self.inner
            .self_pairs()
            .iter()
            .map(|&(i, j)| self.pair_links(i, j))
            .collect()
    }

    /// The checked self-collision shape pairs nearer than `within` m (≥ 0) at q (dof,): a list of
    /// (link a, link b, distance m), nearest first; ≤ 0 in contact (negative: penetration depth; with
    /// `depth=False`, 0 for two meshes in contact that are not both convex, without the costly depth).
    #[pyo3(signature = (q, within=0.0, depth=true))]
    fn self_contacts(
        &self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        within: f64,
        depth: bool,
    ) -> PyResult<Vec<(String, String, f64)>> {
        self.named_contacts(py, q, (within, depth), MeshChecker::self_contacts)
    }

    /// The link pairs that joints outside the robot's active joints (locked at their held values) hold
    /// still relative to each other, nearer than `within` m (≥ 0) at q (dof,): a list of (link a, link b,
    /// distance m), nearest first, as `self_contacts`. These pairs are on one rigid body of this robot, so
    /// the fabric and the trajectory checks never measure them; MoveIt checks them like any other, and a
    /// pair in contact puts every state of every motion in collision.
    #[pyo3(signature = (q, within=0.0, depth=true))]
    fn held_contacts(
        &self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        within: f64,
        depth: bool,
    ) -> PyResult<Vec<(String, String, f64)>> {
        self.named_contacts(py, q, (within, depth), MeshChecker::held_contacts)
    }

    /// The link pairs on adjacent rigid bodies (one movable joint between them) that the robot's SRDF
    /// leaves enabled, nearer than `within` m (≥ 0) at q (dof,): a list of (link a, link b, distance m),
    /// nearest first, as `self_contacts`. The planner never measures adjacent links; MoveIt checks every
    /// pair its SRDF leaves enabled (MoveIt Setup Assistant disables adjacent ones). Empty without an SRDF.
    #[pyo3(signature = (q, within=0.0, depth=true))]
    fn adjacent_contacts(
        &self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        within: f64,
        depth: bool,
    ) -> PyResult<Vec<(String, String, f64)>> {
        self.named_contacts(py, q, (within, depth), MeshChecker::adjacent_contacts)
    }

    /// min over the states of q (T, dof) (or one state (dof,)) of `clearance`, m: the same value as
    /// `clearance(scene, q).min()` where that is ≤ `cutoff` (m; None: always), faster (states farther
    /// from the scene than the closest of every eighth state are culled, and so are shape pairs whose
    /// bounds lie beyond the cutoff); `inf` when no state comes within the cutoff, and for T = 0.
    /// Parallel, GIL released.
    #[pyo3(signature = (scene, q, threads=None, cutoff=None))]
    fn min_clearance(
        &self,
        py: Python<'_>,
        scene: PyRef<'_, PyScene>,
        q: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
        cutoff: Option<f64>,
    ) -> PyResult<f64> {
        let a = self.query(q, threads, cutoff)?;
        let checker = &self.inner;
        let scene = &scene.inner;
        detached(py, || {
            checker.min_trajectory_clearance(scene, &a.qs, a.threads, a.cutoff)
        })
    }

    /// min over the states of q (T, dof) (or (dof,)) of `self_clearance`, m, as `min_clearance` (exact
    /// where ≤ `cutoff`, `inf` when nothing is that near).
    #[pyo3(signature = (q, threads=None, cutoff=None))]
    fn min_self_clearance(
        &self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        threads: Option<&Bound<'_, PyAny>>,
        cutoff: Option<f64>,
    ) -> PyResult<f64> {
        let a = self.query(q, threads, cutoff)?;
        let checker = &self.inner;
        detached(py, || {
            checker.min_trajectory_self_clearance(&a.qs, a.threads, a.cutoff)
        })
    }

    /// Continuous verdict on the path through the states of q (T, dof), straight in joint space between
    /// them (fabric-core `validate::sweep`): whether every configuration on it keeps the collision
    /// geometry more than `margin` m from the scene and from itself, with a motion bound certifying
    /// each segment and uncertified segments halved until they are. Returns a dict: `ok`, `complete`
    /// (False when `time_limit` s ran out first; `ok` is then False), `clearance` and
    /// `self_clearance` (m, the least measured at the states and midpoints; inf when nothing came
    /// within the range a certificate needed), `measured` (configurations measured). Parallel, GIL
    /// released.
    #[pyo3(signature = (scene, q, margin=0.001, threads=None, time_limit=None))]
    fn sweep<'py>(
        &self,
        py: Python<'py>,
        scene: PyRef<'_, PyScene>,
        q: &Bound<'_, PyAny>,
        margin: f64,
        threads: Option<&Bound<'_, PyAny>>,
        time_limit: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let threads = convert::threads(threads)?;
        let deadline = match time_limit {
            None => None,
            Some(t) if t.is_finite() && t >= 0.0 => {
                Some(Instant::now() + Duration::from_secs_f64(t))
            }
            Some(t) => {
                return Err(crate::errors::error(fabric_core::FabricError::Value {
                    what: "time_limit".to_string(),
                    message: format!("must be a finite number of seconds >= 0, got {t}"),
                }))
            }
        };
        let checker = &self.inner;
        let (qs, _) = convert::vector_or_rows(q, "q", checker.robot().dof())?;
        let scene = &scene.inner;
        let sweep = detached(py, || checker.sweep(scene, &qs, margin, threads, deadline))?;
        let out = PyDict::new(py);
        out.set_item("ok", sweep.ok)?;
        out.set_item("complete", sweep.complete)?;
        out.set_item("clearance", sweep.clearance)?;
        out.set_item("self_clearance", sweep.self_clearance)?;
        out.set_item("measured", sweep.measured)?;
        Ok(out)
    }

    fn __repr__(&self) -> String {
        format!(
            "MeshChecker(robot='{}', shapes={}, self_pairs={}, max_distance={})",
            self.inner.robot().name(),
            self.inner.num_shapes(),
            self.inner.self_pairs().len(),
            self.inner.max_distance()
        )
    }
}
