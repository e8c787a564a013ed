//! `gfcs._core.Robot`: the immutable robot model (URDF kinematics, limits, collision spheres,
//! self-collision pairs) with forward kinematics and task-point Jacobians.
//!
//! Frames: every pose and position is in the base-link frame (= world frame of the model). Units: m, rad.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use fabric_core::robot::{
    batch, inverse_kinematics, point_ik, CollisionSphere, GeometryKind, IkOptions, IkTarget,
    KinematicsWorkspace, PointIkOptions, PointTarget, Robot, RobotOptions, TaskPoint,
};
use fabric_core::FabricError;
use nalgebra::{Matrix3xX, Vector3};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{self, output, output_pose, output_vec3, typed_output};
use crate::errors::{detached, error, guarded};

/// A link given by name (`str`) or by index (an `int`, as in `Robot.link_names`; anything else is refused
/// when resolved, naming the argument).
#[derive(FromPyObject)]
pub enum LinkRef {
    /// Link name.
    Name(String),
    /// Link index: checked by [`LinkRef::resolve`].
    Index(Py<PyAny>),
}

/// An optional argument that was given: `Some` unless omitted or Python `None`.
fn given<'a, 'py>(v: Option<&'a Bound<'py, PyAny>>) -> Option<&'a Bound<'py, PyAny>> {
    v.filter(|v| !v.is_none())
}

impl LinkRef {
    /// The index of `link`, or of the end-effector link when it is `None` (the default of the IK
    /// methods).
    pub fn resolve_or_ee(link: Option<LinkRef>, robot: &Robot) -> PyResult<usize> {
        link.map_or(Ok(robot.ee_link()), |l| l.resolve(robot))
    }

    /// The link index; `LinkError` for an unknown name or an index out of range.
    pub fn resolve(&self, robot: &Robot) -> PyResult<usize> {
        match self {
            LinkRef::Name(name) => robot.link_index(name).map_err(error),
            LinkRef::Index(obj) => {
                let i = Python::attach(|py| convert::index(obj.bind(py), "link", 0))?;
                if i < robot.link_names().len() {
                    Ok(i)
                } else {
                    Err(error(FabricError::MissingLink {
                        robot: robot.name().to_string(),
                        link: format!("#{i} (the robot has {} links)", robot.link_names().len()),
                    }))
                }
            }
        }
    }
}

/// A path-like argument (`str` or `os.PathLike`) as a `PathBuf`.
pub fn path_arg(obj: &Bound<'_, PyAny>) -> PyResult<PathBuf> {
    obj.extract::<PathBuf>()
}

/// True when a string argument holds XML text rather than a path.
fn looks_like_xml(text: &str) -> bool {
    text.trim_start().starts_with('<')
}

/// Read a text file, `IoError` naming the path on failure.
pub fn read_text(path: &Path) -> PyResult<String> {
    std::fs::read_to_string(path).map_err(|e| {
        error(FabricError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })
    })
}

/// Row-major (3, dof) array from a 3 × dof Jacobian.
fn jacobian_output<'py>(
    py: Python<'py>,
    jac: &Matrix3xX<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let dof = jac.ncols();
    let mut data = Vec::with_capacity(3 * dof);
    for i in 0..3 {
        for j in 0..dof {
            data.push(jac[(i, j)]);
        }
    }
    output(py, data, &[3, dof])
}

/// Robot model. Immutable: methods that change spheres or self-collision pairs return a new `Robot`.
///
/// Build it with `Robot.panda()` (the shipped Franka Emika Panda, no file needed) or
/// `Robot.from_urdf(...)`. Poses are in the base-link frame; q has shape (dof,) in `joint_names` order.
#[pyclass(
    frozen,
    weakref,
    skip_from_py_object,
    name = "Robot",
    module = "gfcs._core"
)]
#[derive(Clone)]
pub struct PyRobot {
    /// Shared model (also held by every `Fabric` built from it).
    pub inner: Arc<Robot>,
}

impl PyRobot {
    /// Wrap a model.
    pub fn new(robot: Robot) -> Self {
        PyRobot {
            inner: Arc::new(robot),
        }
    }

    /// A copy of the model, changed by `f` (spheres, SRDF).
    fn modified(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Robot) -> fabric_core::Result<()>,
    ) -> PyResult<Self> {
        let mut robot = (*self.inner).clone();
        guarded(py, || f(&mut robot))?;
        Ok(PyRobot::new(robot))
    }

    /// Kinematics at q (dof,) with q̇ (dof,), in a fresh workspace.
    fn kinematics(&self, py: Python<'_>, q: &[f64], qd: &[f64]) -> PyResult<KinematicsWorkspace> {
        let robot = &self.inner;
        guarded(py, || {
            let mut ws = KinematicsWorkspace::new(robot);
            robot.update(q, qd, &mut ws)?;
            Ok(ws)
        })
    }
}

/// One `gfcs.GfcsWarning` listing the links an SRDF names and `robot` lacks (their entries were skipped,
/// as MoveIt skips them); nothing when there are none.
fn warn_skipped_links(
    py: Python<'_>,
    robot: &Robot,
    source: &str,
    skipped: &[String],
) -> PyResult<()> {
    if skipped.is_empty() {
        return Ok(());
    }
    crate::errors::warn(
        py,
        &format!(
            "SRDF {source}: {} link(s) not in robot '{}', their <disable_collisions> entries skipped: {}",
            skipped.len(),
            robot.name(),
            skipped.join(", ")
        ),
    )
}

/// Spheres argument: a path to a JSON sphere file, or a list of `(link, centre (3,), radius)`.
fn parse_spheres(robot: &Robot, obj: &Bound<'_, PyAny>) -> PyResult<Vec<CollisionSphere>> {
    if let Ok(path) = obj.extract::<PathBuf>() {
        return robot.load_sphere_file(&path).map_err(error);
    }
    let mut spheres = Vec::new();
    for (i, item) in obj.try_iter()?.enumerate() {
        let item = item?;
        let what = format!("spheres[{i}]");
        let (link, center, radius): (LinkRef, Bound<'_, PyAny>, Bound<'_, PyAny>) =
            item.extract().map_err(|_| {
                error(FabricError::Value {
                    what: what.clone(),
                    message: "expected a tuple (link name or index, centre (3,), radius)"
                        .to_string(),
                })
            })?;
        let link = link.resolve(robot)?;
        let center = convert::vector3(&center, &format!("{what} centre"))?;
        let radius = convert::scalar(&radius, &format!("{what} radius"))?;
        spheres.push(CollisionSphere {
            link,
            center,
            radius,
        });
    }
    Ok(spheres)
}

/// SRDF argument: a path or the XML text. Returns (text, source name).
fn srdf_text(obj: &Bound<'_, PyAny>) -> PyResult<(String, String)> {
    if let Ok(s) = obj.extract::<String>() {
        if looks_like_xml(&s) {
            return Ok((s, "<string>".to_string()));
        }
    }
    let path = path_arg(obj)?;
    Ok((read_text(&path)?, path.display().to_string()))
}

#[pymethods]
impl PyRobot {
    /// The shipped Franka Emika Panda (7 dof, `panda_hand` end effector, collision spheres and the
    /// self-collision pairs of its SRDF). No file needed.
    #[staticmethod]
    fn panda() -> Self {
        PyRobot::new(Robot::panda())
    }

    /// Load a robot from a URDF file path or URDF XML text.
    ///
    /// - `path_or_xml`: path (str or os.PathLike) or XML text (a string starting with `<`).
    /// - `base_link`: world frame link (default: URDF root); `ee_link`: end effector (default: deepest link
    ///   of the active chain); `active_joints`: joint names in q order (default: every movable, non-mimic
    ///   joint from base to ee).
    /// - `mesh_dir`: resolves `package://` and relative mesh paths (default: the URDF's directory).
    /// - `srdf`: path or XML text; its `<disable_collisions>` prune the self-collision pairs.
    /// - `spheres`: path to a JSON sphere file, or a list of `(link, centre (3,) m in the link frame,
    ///   radius m)`; replaces the URDF `<collision><sphere>` elements.
    #[staticmethod]
    #[pyo3(signature = (path_or_xml, base_link=None, ee_link=None, active_joints=None, mesh_dir=None, srdf=None, spheres=None))]
    #[allow(clippy::too_many_arguments)]
    fn from_urdf(
        py: Python<'_>,
        path_or_xml: &Bound<'_, PyAny>,
        base_link: Option<String>,
        ee_link: Option<String>,
        active_joints: Option<Vec<String>>,
        mesh_dir: Option<PathBuf>,
        srdf: Option<&Bound<'_, PyAny>>,
        spheres: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let opts = RobotOptions {
            base_link,
            ee_link,
            active_joints,
            mesh_dir,
            ..RobotOptions::default()
        };
        let xml = path_or_xml
            .extract::<String>()
            .ok()
            .filter(|s| looks_like_xml(s));
        let mut robot = match xml {
            Some(xml) => guarded(py, || Robot::from_urdf_str(&xml, "<string>", &opts))?,
            None => {
                let path = path_arg(path_or_xml)?;
                guarded(py, || Robot::from_urdf_file(&path, &opts))?
            }
        };
        if let Some(obj) = spheres.filter(|o| !o.is_none()) {
            let list = parse_spheres(&robot, obj)?;
            guarded(py, || robot.set_spheres(list))?;
        }
        if let Some(obj) = srdf.filter(|o| !o.is_none()) {
            let (text, source) = srdf_text(obj)?;
            let skipped = guarded(py, || robot.set_self_collision_from_srdf(&text, &source))?;
            warn_skipped_links(py, &robot, &source, &skipped)?;
        }
        Ok(PyRobot::new(robot))
    }

    /// A copy of this robot with other collision spheres (same forms as `from_urdf(spheres=...)`); the
    /// self-collision pairs are recomputed.
    fn with_spheres(&self, py: Python<'_>, spheres: &Bound<'_, PyAny>) -> PyResult<Self> {
        let list = parse_spheres(&self.inner, spheres)?;
        self.modified(py, |r| r.set_spheres(list))
    }

    /// A copy of this robot whose self-collision pairs follow the SRDF `srdf` (path or XML text).
    fn with_srdf(&self, py: Python<'_>, srdf: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (text, source) = srdf_text(srdf)?;
        let mut skipped = Vec::new();
        let out = self.modified(py, |r| {
            skipped = r.set_self_collision_from_srdf(&text, &source)?;
            Ok(())
        })?;
        warn_skipped_links(py, &out.inner, &source, &skipped)?;
        Ok(out)
    }

    /// A copy of this robot whose self-collision checks also leave out the link pairs `pairs` (a sequence of
    /// (link name, link name)), besides those its SRDF disables; `LinkError` for an unknown link.
    fn with_disabled_pairs(&self, py: Python<'_>, pairs: Vec<(String, String)>) -> PyResult<Self> {
        self.modified(py, |r| r.disable_link_pairs(&pairs))
    }

    /// A copy of this robot with inactive joints held at other positions ({joint name: rad or m}), e.g. a
    /// gripper opened as a planning request's start state says; spheres and self-collision pairs kept.
    fn with_locked_positions(
        &self,
        py: Python<'_>,
        positions: std::collections::HashMap<String, f64>,
    ) -> PyResult<Self> {
        let list: Vec<(String, f64)> = positions.into_iter().collect();
        let robot = &self.inner;
        let out = guarded(py, || robot.with_locked_positions(&list))?;
        Ok(PyRobot::new(out))
    }

    /// {joint name: position} of the inactive movable joints (not mimic joints), rad or m, in the core's
    /// order (the same in every process: written requests and results do not depend on hashing).
    #[getter]
    fn locked_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, q) in self.inner.locked_positions() {
            d.set_item(name, q)?;
        }
        Ok(d)
    }

    /// Robot name (URDF `<robot name>`).
    #[getter]
    fn name(&self) -> String {
        self.inner.name().to_string()
    }

    /// Number of active coordinates (length of q).
    #[getter]
    fn dof(&self) -> usize {
        self.inner.dof()
    }

    /// Active joint names, in q order.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.inner.joint_names().to_vec()
    }

    /// Every link name; a link's index in this list is its link index.
    #[getter]
    fn link_names(&self) -> Vec<String> {
        self.inner.link_names().to_vec()
    }

    /// Lower joint limits, (dof,), rad or m.
    #[getter]
    fn lower<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        output(py, self.inner.lower().to_vec(), &[self.inner.dof()])
    }

    /// Upper joint limits, (dof,), rad or m.
    #[getter]
    fn upper<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        output(py, self.inner.upper().to_vec(), &[self.inner.dof()])
    }

    /// Joint velocity limits, (dof,), rad/s or m/s (inf when the URDF gives none).
    #[getter]
    fn velocity_limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        output(
            py,
            self.inner.velocity_limits().to_vec(),
            &[self.inner.dof()],
        )
    }

    /// Per active joint, (dof,) bool: a URDF `continuous` joint (no position limits: `lower` / `upper` of
    /// ∓2π are its sampling range). A revolute joint whose limits happen to be ∓2π is not.
    #[getter]
    fn continuous<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<bool>>> {
        typed_output(py, self.inner.continuous().to_vec(), &[self.inner.dof()])
    }

    /// End-effector link name.
    #[getter]
    fn ee_link(&self) -> String {
        self.inner.link_names()[self.inner.ee_link()].clone()
    }

    /// Base link name (its frame is the world frame of every pose).
    #[getter]
    fn base_link(&self) -> String {
        self.inner.link_names()[self.inner.base_link()].clone()
    }

    /// Index of a link by name (`LinkError` if absent).
    fn link_index(&self, name: &str) -> PyResult<usize> {
        self.inner.link_index(name).map_err(error)
    }

    /// Collision sphere radii, (S,), m.
    #[getter]
    fn sphere_radii<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let s = self.inner.spheres();
        output(py, s.iter().map(|s| s.radius).collect(), &[s.len()])
    }

    /// Link name of each collision sphere, length S.
    #[getter]
    fn sphere_links(&self) -> Vec<String> {
        let names = self.inner.link_names();
        self.inner
            .spheres()
            .iter()
            .map(|s| names[s.link].clone())
            .collect()
    }

    /// Collision sphere centres in their link frames, (S, 3), m.
    #[getter]
    fn sphere_centers_local<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let s = self.inner.spheres();
        output(
            py,
            s.iter()
                .flat_map(|s| [s.center.x, s.center.y, s.center.z])
                .collect(),
            &[s.len(), 3],
        )
    }

    /// Sphere index pairs (i < j) checked for self-collision, (P, 2) int64.
    #[getter]
    fn self_collision_pairs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<i64>>> {
        let p = self.inner.self_collision_pairs();
        typed_output(
            py,
            p.iter().flat_map(|&(i, j)| [i as i64, j as i64]).collect(),
            &[p.len(), 2],
        )
    }

    /// Self-collision clearance (m) of the collision spheres: min over `self_collision_pairs` of
    /// ‖c_a − c_b‖ − r_a − r_b (negative: overlap; +inf without pairs), a 0-d array for q (dof,) or (N,)
    /// for q (N, dof). Batches run in parallel with the GIL released.
    fn self_clearance<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.per_configuration(py, q, &[], |robot, qs, _| batch::self_clearance(robot, qs))
    }

    /// World poses of every link, (L, 4, 4) for q (dof,) or (N, L, 4, 4) for q (N, dof). Link order:
    /// `link_names`. Batches run in parallel with the GIL released.
    fn link_poses<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let links = self.inner.link_names().len();
        self.per_configuration(py, q, &[links, 4, 4], |robot, qs, _| {
            let poses = batch::link_poses(robot, qs)?;
            Ok(convert::flatten_parallel(&poses, 16, |p, out| {
                convert::write_pose(out, p)
            }))
        })
    }

    /// World centres of the collision spheres, (S, 3) for q (dof,) or (N, S, 3) for q (N, dof), m.
    fn sphere_centers<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let s = self.inner.spheres().len();
        self.per_configuration(py, q, &[s, 3], |robot, qs, _| {
            let centers = batch::sphere_centers(robot, qs)?;
            Ok(convert::flatten_parallel(&centers, 3, |c, out| {
                out.copy_from_slice(c.as_slice())
            }))
        })
    }

    /// World position of the end-effector link origin, (3,) for q (dof,) or (N, 3) for q (N, dof), m.
    fn ee_position<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        self.per_configuration(py, q, &[3], |robot, qs, _| {
            let origins = batch::link_origins(robot, qs, robot.ee_link())?;
            Ok(convert::flatten_parallel(&origins, 3, |x, out| {
                out.copy_from_slice(x.as_slice())
            }))
        })
    }

    /// Damped least-squares inverse kinematics of `link`'s origin (default the end-effector link), from
    /// `q_init` (dof,) or (N, dof) to `positions` (3,) or (N, 3) m (world = base frame), optionally with
    /// the link's x and z axes along `axes` (2, 3) or (N, 2, 3) (unit world directions, x first). Each
    /// step is Δq = Jᵀ (J Jᵀ + `damping` I)⁻¹ e on e = [p* − p; w (x* − x); w (z* − z)] (w =
    /// `axis_weight`, m), then q is clipped into the joint limits; at most `iterations` steps, fewer when
    /// ‖e‖ < `tolerance`; None takes the core's `IkOptions::default()` (30 steps, 1e-3 m², 1e-5, 0.3 m).
    /// Returns (dof,) or (N, dof) configurations inside the limits (a target out of reach: the closest
    /// configuration found). Batches run in parallel with the GIL released.
    #[pyo3(signature = (q_init, positions, link=None, axes=None, iterations=None, damping=None,
                        tolerance=None, axis_weight=None))]
    #[allow(clippy::too_many_arguments)]
    fn inverse_kinematics<'py>(
        &self,
        py: Python<'py>,
        q_init: &Bound<'py, PyAny>,
        positions: &Bound<'py, PyAny>,
        link: Option<LinkRef>,
        axes: Option<&Bound<'py, PyAny>>,
        iterations: Option<&Bound<'py, PyAny>>,
        damping: Option<f64>,
        tolerance: Option<f64>,
        axis_weight: Option<f64>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let robot = self.inner.clone();
        let dof = robot.dof();
        let link = LinkRef::resolve_or_ee(link, &robot)?;
        let (qs, q_batch) = convert::vector_or_rows(q_init, "q_init", dof)?;
        let (points, p_batch) = convert::vector_or_rows(positions, "positions", 3)?;
        if q_batch != p_batch {
            return Err(convert::shape_error(
                "positions",
                &match q_batch {
                    Some(n) => format!("({n}, 3), one per row of q_init"),
                    None => "(3,), as q_init is one configuration".into(),
                },
                &match p_batch {
                    Some(n) => vec![n, 3],
                    None => vec![3],
                },
            ));
        }
        let n = q_batch.unwrap_or(1);
        let axes = match axes {
            Some(a) if !a.is_none() => {
                let a = convert::array(a, "axes")?;
                let expected: &[usize] = match q_batch {
                    Some(n) => &[n, 2, 3],
                    None => &[2, 3],
                };
                if a.shape != expected {
                    return Err(convert::shape_error(
                        "axes",
                        &convert::shape_text(expected),
                        &a.shape,
                    ));
                }
                convert::finite("axes", &a.data)?;
                Some(a.data)
            }
            _ => None,
        };
        let targets: Vec<IkTarget> = (0..n)
            .map(|i| IkTarget {
                position: Vector3::from_column_slice(&points[3 * i..3 * i + 3]),
                axes: axes.as_ref().map(|a| {
                    [
                        Vector3::from_column_slice(&a[6 * i..6 * i + 3]),
                        Vector3::from_column_slice(&a[6 * i + 3..6 * i + 6]),
                    ]
                }),
            })
            .collect();
        let default = IkOptions::default();
        let options = IkOptions {
            iterations: match given(iterations) {
                Some(i) => convert::index(i, "iterations", 0)?,
                None => default.iterations,
            },
            damping: damping.unwrap_or(default.damping),
            tolerance: tolerance.unwrap_or(default.tolerance),
            axis_weight: axis_weight.unwrap_or(default.axis_weight),
        };
        let data = detached(py, move || {
            inverse_kinematics(&robot, link, &qs, &targets, &options)
        })?;
        match q_batch {
            None => output(py, data, &[dof]),
            Some(n) => output(py, data, &[n, dof]),
        }
    }

    /// One damped least-squares descent from `q` (dof,) of the point `point` (3,) m of `link` (default
    /// the end-effector link; point default its origin) to `position` (3,) m (world frame), and with
    /// `approach` (3,) of the link axis `axis` (3,) (default z) toward that world direction, met within
    /// `cone_deg` degrees (0-180, default 25): e = [x* − x; w (a* − R·axis)] (w = `axis_weight`), Δq = Jᵀ (J Jᵀ + `damping`
    /// I)⁻¹ e scaled to at most `max_step` rad, q clipped into [`lower`, `upper`] (default the joint
    /// limits), at most `iterations` steps. Returns (q (dof,), converged): converged when the point is
    /// within `tolerance` m and the axis inside the cone (tested before each step). The problem
    /// generators run it from several starts (`gfcs.generators.inverse_kinematics`).
    #[pyo3(signature = (q, position, link=None, point=None, axis=None, approach=None, cone_deg=25.0,
                        lower=None, upper=None, iterations=None, damping=None, tolerance=None,
                        axis_weight=None, max_step=None))]
    #[allow(clippy::too_many_arguments)]
    fn point_ik<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        position: &Bound<'py, PyAny>,
        link: Option<LinkRef>,
        point: Option<&Bound<'py, PyAny>>,
        axis: Option<&Bound<'py, PyAny>>,
        approach: Option<&Bound<'py, PyAny>>,
        cone_deg: f64,
        lower: Option<&Bound<'py, PyAny>>,
        upper: Option<&Bound<'py, PyAny>>,
        iterations: Option<&Bound<'py, PyAny>>,
        damping: Option<f64>,
        tolerance: Option<f64>,
        axis_weight: Option<f64>,
        max_step: Option<f64>,
    ) -> PyResult<(Bound<'py, PyArrayDyn<f64>>, bool)> {
        let robot = &self.inner;
        let dof = robot.dof();
        let link = LinkRef::resolve_or_ee(link, robot)?;
        let mut q = convert::vector(q, "q", dof)?;
        let position = convert::vector3(position, "position")?;
        let point = given(point).map_or(Ok(Vector3::zeros()), |v| convert::vector3(v, "point"))?;
        let axis = given(axis).map_or(Ok(Vector3::z()), |v| convert::vector3(v, "axis"))?;
        if !(0.0..=180.0).contains(&cone_deg) {
            return Err(error(FabricError::Value {
                what: "cone_deg".into(),
                message: format!("must be within [0, 180] degrees, got {cone_deg}"),
            }));
        }
        let approach = given(approach)
            .map(|a| convert::vector3(a, "approach"))
            .transpose()?
            .map(|a| (a, cone_deg.to_radians().cos()));
        let bound = |v, what, default: &[f64]| {
            given(v).map_or(Ok(default.to_vec()), |v| convert::vector(v, what, dof))
        };
        let lower = bound(lower, "lower", robot.lower())?;
        let upper = bound(upper, "upper", robot.upper())?;
        let default = PointIkOptions::default();
        let options = PointIkOptions {
            iterations: match given(iterations) {
                Some(i) => convert::index(i, "iterations", 0)?,
                None => default.iterations,
            },
            damping: damping.unwrap_or(default.damping),
            tolerance: tolerance.unwrap_or(default.tolerance),
            axis_weight: axis_weight.unwrap_or(default.axis_weight),
            max_step: max_step.unwrap_or(default.max_step),
        };
        let target = PointTarget { position, approach };
        let converged = guarded(py, || {
            point_ik(
                robot, link, &point, &axis, &target, &mut q, &lower, &upper, &options,
            )
        })?;
        Ok((output(py, q, &[dof])?, converged))
    }

    /// Jacobian ∂x/∂q (3, dof) of the point `point` (3,) m, fixed in the frame of `link` (name or index),
    /// at q (dof,). x is in the world (base) frame.
    #[pyo3(signature = (q, link, point=None))]
    fn point_jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        link: LinkRef,
        point: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let tp = self.task_point(py, q, None, link, point, false)?;
        jacobian_output(py, &tp.jac)
    }

    /// J̇q̇ (3,) m/s² of the point `point` (3,) fixed on `link`, at (q, q̇): the velocity-product term of
    /// ẍ = J q̈ + J̇q̇ (GF eq. 11-12).
    #[pyo3(signature = (q, qd, link, point=None))]
    fn point_jdot_qdot<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        link: LinkRef,
        point: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let tp = self.task_point(py, q, Some(qd), link, point, false)?;
        output_vec3(py, &tp.jdot_qdot)
    }

    /// Jacobian ∂x/∂q (3, dof) of the world direction x = R_link · `axis` of the link-fixed direction
    /// `axis` (3,), at q (dof,).
    fn axis_jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        link: LinkRef,
        axis: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let tp = self.task_point(py, q, None, link, Some(axis), true)?;
        jacobian_output(py, &tp.jac)
    }

    /// J̇q̇ (3,) of the world direction x = R_link · `axis`, at (q, q̇).
    fn axis_jdot_qdot<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        link: LinkRef,
        axis: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let tp = self.task_point(py, q, Some(qd), link, Some(axis), true)?;
        output_vec3(py, &tp.jdot_qdot)
    }

    /// URDF `<collision>` elements: a list of dicts with keys `link` (name), `type` ("mesh", "box",
    /// "cylinder", "capsule", "sphere"), `origin` (4, 4) pose in the link frame, `size` ((3,) full box
    /// edges; (2,) [length, radius] for cylinders and capsules; (1,) [radius] for spheres; None for meshes),
    /// `path` (resolved mesh path or None), `scale` ((3,) mesh scale or None), `exists` (mesh file found).
    fn collision_geometry<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        let names = self.inner.link_names();
        for g in self.inner.collision_geometry() {
            let d = PyDict::new(py);
            d.set_item("link", &names[g.link])?;
            d.set_item("origin", output_pose(py, &g.origin)?)?;
            d.set_item("path", py.None())?;
            d.set_item("scale", py.None())?;
            d.set_item("exists", true)?;
            let (kind, size) = match &g.kind {
                GeometryKind::Mesh {
                    path,
                    scale,
                    exists,
                } => {
                    d.set_item("path", path.display().to_string())?;
                    d.set_item("scale", output_vec3(py, scale)?)?;
                    d.set_item("exists", *exists)?;
                    ("mesh", None)
                }
                GeometryKind::Box { size } => ("box", Some(vec![size.x, size.y, size.z])),
                GeometryKind::Cylinder { radius, length } => {
                    ("cylinder", Some(vec![*length, *radius]))
                }
                GeometryKind::Capsule { radius, length } => {
                    ("capsule", Some(vec![*length, *radius]))
                }
                GeometryKind::Sphere { radius } => ("sphere", Some(vec![*radius])),
            };
            d.set_item("type", kind)?;
            match size {
                Some(s) => {
                    let n = s.len();
                    d.set_item("size", output(py, s, &[n])?)?
                }
                None => d.set_item("size", py.None())?,
            }
            list.append(d)?;
        }
        Ok(list)
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot(name='{}', dof={}, links={}, spheres={}, ee_link='{}')",
            self.inner.name(),
            self.inner.dof(),
            self.inner.link_names().len(),
            self.inner.spheres().len(),
            self.ee_link()
        )
    }
}

impl PyRobot {
    /// Values per configuration of `q`, (dof,) or (N, dof): `f(robot, qs, n)` gets the n row-major
    /// configurations (n = 1 for a single q), runs with the GIL released, and returns n × prod(`item`)
    /// values; the result has shape `item` for q (dof,) and (N, *item) for q (N, dof).
    fn per_configuration<'py, F>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        item: &[usize],
        f: F,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>>
    where
        F: FnOnce(&Robot, &[f64], usize) -> fabric_core::Result<Vec<f64>> + Send,
    {
        let robot = self.inner.clone();
        let (qs, batch_n) = convert::vector_or_rows(q, "q", robot.dof())?;
        let n = batch_n.unwrap_or(1);
        let data = detached(py, move || f(&robot, &qs, n))?;
        match batch_n {
            None => output(py, data, item),
            Some(n) => output(py, data, &[&[n], item].concat()),
        }
    }

    /// Kinematics of a link-fixed point (`is_axis = false`) or direction (`true`) at (q, q̇); q̇ = 0 when
    /// `qd` is None. `local` defaults to the link origin (only meaningful for points).
    fn task_point(
        &self,
        py: Python<'_>,
        q: &Bound<'_, PyAny>,
        qd: Option<&Bound<'_, PyAny>>,
        link: LinkRef,
        local: Option<&Bound<'_, PyAny>>,
        is_axis: bool,
    ) -> PyResult<TaskPoint> {
        let robot = &self.inner;
        let dof = robot.dof();
        let q = convert::vector(q, "q", dof)?;
        let qd = match qd {
            Some(v) => convert::vector(v, "qd", dof)?,
            None => vec![0.0; dof],
        };
        let link = link.resolve(robot)?;
        let local = match local {
            Some(v) if !v.is_none() => convert::vector3(v, if is_axis { "axis" } else { "point" })?,
            _ => Vector3::zeros(),
        };
        let ws = self.kinematics(py, &q, &qd)?;
        let mut tp = TaskPoint::new(dof);
        guarded(py, || {
            if is_axis {
                robot.axis(&ws, link, &local, &mut tp);
            } else {
                robot.point(&ws, link, &local, &mut tp);
            }
            Ok(())
        })?;
        Ok(tp)
    }
}
