//! `gfcs._core.Scene`: obstacles (primitives, meshes, point clouds) with poses and velocities, and
//! signed-distance queries (positive outside, m; gradients are unit vectors ∂d/∂p in the world frame).
//! Also `load_motion_plan_request` for MoveIt MotionPlanRequest YAML files.

use std::path::PathBuf;
use std::sync::Arc;

use fabric_core::scene::{
    meshio, moveit, DistanceSample, Obstacle, ObstacleId, PointCloud, PoseGoal, Scene, Shape,
};
use fabric_core::FabricError;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::convert::{self, output, output_mat3, output_pose, output_vec3};
use crate::errors::{detached, error, guarded};
use crate::robot::path_arg;

/// A positive finite size, `InvalidValueError` naming `what` otherwise.
fn positive(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<f64> {
    let v = convert::scalar(obj, what)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(error(FabricError::Value {
            what: what.to_string(),
            message: format!("must be > 0, got {v}"),
        }))
    }
}

/// Rotation taking +z to the unit vector `n` (the free side of a half-space).
fn rotation_z_to(n: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::z(), n).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    })
}

/// Obstacle scene. Mutable: obstacles are added, moved and removed by integer id.
///
/// Poses are 4 × 4 homogeneous matrices or `(position (3,), quaternion [x, y, z, w])` pairs, in the world
/// frame (= the robot base frame). Velocities are linear, m/s, world frame.
#[pyclass(skip_from_py_object, name = "Scene", module = "gfcs._core")]
#[derive(Clone)]
pub struct PyScene {
    /// The core scene.
    pub inner: Scene,
}

impl PyScene {
    /// Add one obstacle; returns its id.
    fn add_obstacle(
        &mut self,
        py: Python<'_>,
        shape: Shape,
        pose: Isometry3<f64>,
        name: Option<String>,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let velocity = match velocity {
            Some(v) if !v.is_none() => convert::vector3(v, "velocity")?,
            _ => Vector3::zeros(),
        };
        let name = name.unwrap_or_else(|| format!("{}{}", shape.kind(), self.inner.len()));
        let scene = &mut self.inner;
        let id = guarded(py, || {
            scene.add(Obstacle {
                name,
                shape,
                pose,
                velocity,
            })
        })?;
        Ok(id.0)
    }

    /// Add a cylinder or capsule along the pose's local z axis: `height` (full length, m) and `radius`
    /// (m) must be > 0 (checked in that order, then `pose`); `shape(half_height, radius)` builds it.
    #[allow(clippy::too_many_arguments)]
    fn add_axial(
        &mut self,
        py: Python<'_>,
        height: &Bound<'_, PyAny>,
        radius: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
        velocity: Option<&Bound<'_, PyAny>>,
        shape: impl FnOnce(f64, f64) -> Shape,
    ) -> PyResult<u64> {
        let half_height = positive(height, "height")? / 2.0;
        let radius = positive(radius, "radius")?;
        let pose = convert::pose_or_identity(pose, "pose")?;
        self.add_obstacle(py, shape(half_height, radius), pose, name, velocity)
    }

    /// The obstacle with id `id`; `InvalidValueError` for an unknown id.
    fn obstacle(&self, id: u64) -> PyResult<&Obstacle> {
        self.inner.get(ObstacleId(id)).ok_or_else(|| unknown_id(id))
    }
}

/// One `gfcs.GfcsWarning` per scene field that the MoveIt loader does not apply
/// ([`moveit::parse_scene_str`]), each naming the file and the field.
fn warn_scene_notes(py: Python<'_>, source: &str, notes: &[String]) -> PyResult<()> {
    for note in notes {
        crate::errors::warn(py, &format!("{source}: {note}"))?;
    }
    Ok(())
}

/// An obstacle id argument: an integer >= 0, `InvalidValueError` naming `id` otherwise.
fn obstacle_id(obj: &Bound<'_, PyAny>) -> PyResult<u64> {
    convert::integer(obj, "id", 0, u64::MAX)
}

/// Error for an obstacle id that is not in the scene.
fn unknown_id(id: u64) -> PyErr {
    error(FabricError::Value {
        what: "obstacle id".to_string(),
        message: format!("no obstacle with id {id}"),
    })
}

/// Size of a shape for `obstacles()`: box (3,) full edges; cylinder/capsule (2,) [height, radius];
/// sphere (1,) [radius]; half-space: empty; mesh [vertex count, triangle count]; point cloud
/// [point count, radius].
fn shape_size(shape: &Shape) -> Vec<f64> {
    match shape {
        Shape::Sphere { radius } => vec![*radius],
        Shape::Cuboid { half_extents } => (2.0 * half_extents).iter().copied().collect(),
        Shape::Cylinder {
            half_height,
            radius,
        }
        | Shape::Capsule {
            half_height,
            radius,
        } => {
            vec![2.0 * half_height, *radius]
        }
        Shape::HalfSpace => vec![],
        Shape::TriMesh(m) => vec![m.vertices().len() as f64, m.indices().len() as f64],
        Shape::PointCloud(c) => vec![c.points().len() as f64, c.radius()],
    }
}

/// One distance sample as a dict.
fn sample_dict<'py>(py: Python<'py>, s: &DistanceSample) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("obstacle", s.obstacle.0)?;
    d.set_item("distance", s.distance)?;
    d.set_item("gradient", output_vec3(py, &s.gradient)?)?;
    d.set_item("hessian", output_mat3(py, &s.hessian)?)?;
    d.set_item("velocity", output_vec3(py, &s.velocity)?)?;
    Ok(d)
}

#[pymethods]
impl PyScene {
    /// An empty scene.
    #[new]
    fn py_new() -> Self {
        PyScene {
            inner: Scene::new(),
        }
    }

    /// Load a MoveIt PlanningScene YAML file (MotionBenchMaker `sceneNNNN.yaml`): box sizes are full edges,
    /// cylinders [height, radius], quaternions [x, y, z, w]. Objects must be in the planning frame (no
    /// header, "world", or `root_frame`: the robot's root link); attached objects are refused. A later
    /// object with the same id replaces an earlier one (MoveIt's ADD). Each field that is not applied (an
    /// octomap, collisions the allowed collision matrix allows with objects, frame transforms, link
    /// padding, fields MoveIt does not define) gives a `gfcs.GfcsWarning` naming it.
    #[staticmethod]
    #[pyo3(signature = (path, root_frame=None))]
    fn from_moveit_yaml(
        py: Python<'_>,
        path: &Bound<'_, PyAny>,
        root_frame: Option<&str>,
    ) -> PyResult<Self> {
        let path = path_arg(path)?;
        let (inner, notes) = guarded(py, || moveit::parse_scene_file(&path, root_frame))?;
        warn_scene_notes(py, &path.display().to_string(), &notes)?;
        Ok(PyScene { inner })
    }

    /// Same as `from_moveit_yaml` from the YAML text.
    #[staticmethod]
    #[pyo3(signature = (text, source="<string>", root_frame=None))]
    fn from_moveit_yaml_str(
        py: Python<'_>,
        text: &str,
        source: &str,
        root_frame: Option<&str>,
    ) -> PyResult<Self> {
        let (inner, notes) = guarded(py, || moveit::parse_scene_str(text, source, root_frame))?;
        warn_scene_notes(py, source, &notes)?;
        Ok(PyScene { inner })
    }

    /// A sphere of `radius` m centred at `center` (3,) m. Returns its id.
    #[pyo3(signature = (center, radius, name=None, velocity=None))]
    fn add_sphere(
        &mut self,
        py: Python<'_>,
        center: &Bound<'_, PyAny>,
        radius: &Bound<'_, PyAny>,
        name: Option<String>,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let center = convert::vector3(center, "center")?;
        let radius = positive(radius, "radius")?;
        let pose = Isometry3::from_parts(Translation3::from(center), UnitQuaternion::identity());
        self.add_obstacle(py, Shape::Sphere { radius }, pose, name, velocity)
    }

    /// A box of FULL edge lengths `size` (3,) m, centred at the pose origin. Returns its id.
    #[pyo3(signature = (size, pose=None, name=None, velocity=None))]
    fn add_box(
        &mut self,
        py: Python<'_>,
        size: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let size = convert::vector3(size, "size")?;
        if size.iter().any(|&s| s <= 0.0) {
            return Err(error(FabricError::Value {
                what: "size".to_string(),
                message: format!(
                    "box edges must be > 0, got [{}, {}, {}]",
                    size.x, size.y, size.z
                ),
            }));
        }
        let pose = convert::pose_or_identity(pose, "pose")?;
        self.add_obstacle(
            py,
            Shape::Cuboid {
                half_extents: size / 2.0,
            },
            pose,
            name,
            velocity,
        )
    }

    /// A cylinder of full `height` m along the pose's local z axis and `radius` m, centred at the pose
    /// origin. Returns its id.
    #[pyo3(signature = (height, radius, pose=None, name=None, velocity=None))]
    fn add_cylinder(
        &mut self,
        py: Python<'_>,
        height: &Bound<'_, PyAny>,
        radius: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let shape = |half_height, radius| Shape::Cylinder {
            half_height,
            radius,
        };
        self.add_axial(py, height, radius, pose, name, velocity, shape)
    }

    /// A capsule: a segment of length `height` m along the pose's local z axis (between the two cap
    /// centres), swept by a ball of `radius` m. Returns its id.
    #[pyo3(signature = (height, radius, pose=None, name=None, velocity=None))]
    fn add_capsule(
        &mut self,
        py: Python<'_>,
        height: &Bound<'_, PyAny>,
        radius: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let shape = |half_height, radius| Shape::Capsule {
            half_height,
            radius,
        };
        self.add_axial(py, height, radius, pose, name, velocity, shape)
    }

    /// A half-space {p : n·p <= offset} (free side +n). Give `normal` (3,) (normalised here) and `offset`
    /// m, or a `pose` whose local z axis is the outward normal and whose origin lies on the boundary.
    /// Returns its id.
    #[pyo3(signature = (normal=None, offset=0.0, pose=None, name=None))]
    fn add_halfspace(
        &mut self,
        py: Python<'_>,
        normal: Option<&Bound<'_, PyAny>>,
        offset: f64,
        pose: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<u64> {
        let pose = match (
            normal.filter(|n| !n.is_none()),
            pose.filter(|p| !p.is_none()),
        ) {
            (Some(_), Some(_)) => {
                return Err(error(FabricError::Value {
                    what: "add_halfspace".to_string(),
                    message: "give either normal (and offset) or pose, not both".to_string(),
                }))
            }
            (None, Some(p)) => convert::pose(p, "pose")?,
            (Some(n), None) => {
                let n = convert::vector3(n, "normal")?;
                let norm = n.norm();
                if norm < 1e-12 {
                    return Err(error(FabricError::Value {
                        what: "normal".to_string(),
                        message: "has zero length".to_string(),
                    }));
                }
                convert::finite("offset", &[offset])?;
                let n = n / norm;
                Isometry3::from_parts(Translation3::from(n * offset), rotation_z_to(&n))
            }
            (None, None) => Isometry3::identity(),
        };
        self.add_obstacle(py, Shape::HalfSpace, pose, name, None)
    }

    /// A triangle mesh: `mesh` is a path to a mesh file (.obj, .stl or .dae) or a pair (vertices (V, 3) m,
    /// faces (F, 3) vertex indices). `scale` (3,) multiplies the vertices in the mesh frame. Returns its
    /// id. A closed, consistently oriented mesh is solid (signed distance negative inside); any other mesh
    /// is a thin surface (unsigned distance). `MeshError` for a missing or unreadable file.
    #[pyo3(signature = (mesh, pose=None, name=None, scale=None, velocity=None))]
    #[allow(clippy::too_many_arguments)]
    fn add_mesh(
        &mut self,
        py: Python<'_>,
        mesh: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
        scale: Option<&Bound<'_, PyAny>>,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let scale = match scale {
            Some(s) if !s.is_none() => convert::vector3(s, "scale")?,
            _ => Vector3::repeat(1.0),
        };
        let pose = convert::pose_or_identity(pose, "pose")?;
        let (vertices, triangles, source) = if let Ok(path) = mesh.extract::<PathBuf>() {
            let loaded = guarded(py, || meshio::load_mesh(&path))?;
            let source = path.display().to_string();
            if scale == Vector3::repeat(1.0) {
                return self.add_obstacle(
                    py,
                    Shape::TriMesh(Arc::new(loaded)),
                    pose,
                    name,
                    velocity,
                );
            }
            (
                loaded.vertices().to_vec(),
                loaded.indices().to_vec(),
                source,
            )
        } else {
            let (vertices, faces): (Bound<'_, PyAny>, Bound<'_, PyAny>) =
                mesh.extract().map_err(|_| {
                    error(FabricError::Value {
                        what: "mesh".to_string(),
                        message: "expected a path or a pair (vertices (V, 3), faces (F, 3))"
                            .to_string(),
                    })
                })?;
            let (v, nv) = convert::rows(&vertices, "mesh vertices", 3)?;
            let (f, _) = convert::rows(&faces, "mesh faces", 3)?;
            let mut triangles = Vec::with_capacity(f.len() / 3);
            for tri in f.chunks_exact(3) {
                let mut idx = [0u32; 3];
                for (k, &x) in tri.iter().enumerate() {
                    if x.fract() != 0.0 || x < 0.0 || x >= nv as f64 {
                        return Err(error(FabricError::Value {
                            what: "mesh faces".to_string(),
                            message: format!("index {x} is not an integer in [0, {nv})"),
                        }));
                    }
                    idx[k] = x as u32;
                }
                triangles.push(idx);
            }
            let points: Vec<Point3<f64>> = v
                .chunks_exact(3)
                .map(|c| Point3::new(c[0], c[1], c[2]))
                .collect();
            (points, triangles, "<arrays>".to_string())
        };
        let scaled: Vec<Point3<f64>> = vertices
            .iter()
            .map(|p| Point3::from(p.coords.component_mul(&scale)))
            .collect();
        let trimesh = guarded(py, || meshio::build_mesh(scaled, triangles, &source))?;
        self.add_obstacle(py, Shape::TriMesh(Arc::new(trimesh)), pose, name, velocity)
    }

    /// A point cloud: `points` (P, 3) m in the pose frame (default: world), each thickened by `radius` m
    /// (>= 0; distance = min |p − s_i| − radius). Returns its id.
    #[pyo3(signature = (points, radius=0.0, pose=None, name=None, velocity=None))]
    #[allow(clippy::too_many_arguments)]
    fn add_point_cloud(
        &mut self,
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        radius: f64,
        pose: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
        velocity: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<u64> {
        let (data, _) = convert::rows(points, "points", 3)?;
        let pts: Vec<Vector3<f64>> = data
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect();
        let pose = convert::pose_or_identity(pose, "pose")?;
        let cloud = guarded(py, || PointCloud::new(pts, radius))?;
        self.add_obstacle(py, Shape::PointCloud(Arc::new(cloud)), pose, name, velocity)
    }

    /// Remove the obstacle `id`; returns its description (as in `obstacles()`).
    fn remove<'py>(
        &mut self,
        py: Python<'py>,
        id: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let id = obstacle_id(id)?;
        let scene = &mut self.inner;
        let removed = guarded(py, || scene.remove(ObstacleId(id)))?;
        obstacle_dict(py, id, &removed)
    }

    /// Move the obstacle `id` to `pose` (world frame).
    fn set_pose(
        &mut self,
        py: Python<'_>,
        id: &Bound<'_, PyAny>,
        pose: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let id = obstacle_id(id)?;
        let pose = convert::pose(pose, "pose")?;
        let scene = &mut self.inner;
        guarded(py, || scene.set_pose(ObstacleId(id), pose))
    }

    /// Set the linear velocity (3,) m/s (world frame) of the obstacle `id`.
    fn set_velocity(
        &mut self,
        py: Python<'_>,
        id: &Bound<'_, PyAny>,
        velocity: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let id = obstacle_id(id)?;
        let v = convert::vector3(velocity, "velocity")?;
        let scene = &mut self.inner;
        guarded(py, || scene.set_velocity(ObstacleId(id), v))
    }

    /// Move every obstacle by its velocity for `dt` s.
    fn advance(&mut self, py: Python<'_>, dt: f64) -> PyResult<()> {
        convert::finite("dt", &[dt])?;
        let scene = &mut self.inner;
        guarded(py, || {
            scene.advance(dt);
            Ok(())
        })
    }

    /// Obstacle ids, in insertion order.
    fn ids(&self) -> Vec<u64> {
        self.inner.ids().into_iter().map(|i| i.0).collect()
    }

    /// Every obstacle as a dict: `id`, `name`, `type` ("sphere", "box", "cylinder", "capsule",
    /// "half_space", "mesh", "point_cloud"), `size` (box (3,) full edges; cylinder/capsule [height, radius];
    /// sphere [radius]; mesh [vertex count, triangle count]; point cloud [point count, radius]), `pose` (4, 4),
    /// `velocity` (3,).
    fn obstacles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for id in self.inner.ids() {
            list.append(obstacle_dict(py, id.0, self.obstacle(id.0)?)?)?;
        }
        Ok(list)
    }

    /// Description of the obstacle `id` (as in `obstacles()`).
    fn get<'py>(&self, py: Python<'py>, id: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyDict>> {
        let id = obstacle_id(id)?;
        obstacle_dict(py, id, self.obstacle(id)?)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        format!("Scene({} obstacles)", self.inner.len())
    }

    /// Minimum signed distance (m, positive outside) from each point to the obstacles: (N,) for points
    /// (N, 3), a float for one point (3,). `inf` when the scene is empty. GIL released.
    fn signed_distance<'py>(
        &self,
        py: Python<'py>,
        points: &Bound<'py, PyAny>,
    ) -> PyResult<Py<PyAny>> {
        let (pts, batch) = convert::points(points, "points")?;
        let scene = &self.inner;
        let d: Vec<f64> = detached(py, || {
            Ok(pts
                .iter()
                .map(|p| {
                    scene
                        .signed_distance(p)
                        .map_or(f64::INFINITY, |s| s.distance)
                })
                .collect())
        })?;
        if batch {
            let n = d.len();
            Ok(output(py, d, &[n])?.into_any().unbind())
        } else {
            Ok(d[0].into_pyobject(py)?.into_any().unbind())
        }
    }

    /// Every obstacle within `max_distance` m of `point` (3,): a list of dicts `obstacle` (id), `distance`
    /// (m), `gradient` (3,) ∂d/∂p, `hessian` (3, 3) ∂²d/∂p², `velocity` (3,) obstacle velocity, sorted by
    /// distance.
    #[pyo3(signature = (point, max_distance=f64::INFINITY))]
    fn distance_details<'py>(
        &self,
        py: Python<'py>,
        point: &Bound<'py, PyAny>,
        max_distance: f64,
    ) -> PyResult<Bound<'py, PyList>> {
        let p = convert::vector3(point, "point")?;
        if max_distance.is_nan() {
            return Err(error(FabricError::NonFinite {
                what: "max_distance".to_string(),
            }));
        }
        let scene = &self.inner;
        let mut samples = Vec::new();
        guarded(py, || {
            scene.query(&p, max_distance, &mut samples);
            Ok(())
        })?;
        samples.sort_by(|a, b| a.distance.total_cmp(&b.distance));
        let list = PyList::empty(py);
        for s in &samples {
            list.append(sample_dict(py, s)?)?;
        }
        Ok(list)
    }

    /// Points sampled on the obstacle surfaces about `spacing` m apart, (P, 3), world frame.
    fn surface_points<'py>(
        &self,
        py: Python<'py>,
        spacing: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let spacing = positive(spacing, "spacing")?;
        let scene = &self.inner;
        let pts = detached(py, || Ok(scene.surface_points(spacing)))?;
        let n = pts.len();
        output(
            py,
            pts.iter().flat_map(|p| [p.x, p.y, p.z]).collect(),
            &[n, 3],
        )
    }

    /// An independent copy.
    fn copy(&self) -> Self {
        self.clone()
    }

    fn __copy__(&self) -> Self {
        self.clone()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.clone()
    }
}

/// Description of one obstacle (see `Scene.obstacles`).
fn obstacle_dict<'py>(py: Python<'py>, id: u64, o: &Obstacle) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("id", id)?;
    d.set_item("name", &o.name)?;
    set_shape(py, &d, &o.shape, &o.pose)?;
    d.set_item("velocity", output_vec3(py, &o.velocity)?)?;
    Ok(d)
}

/// `type`, `size` ([`shape_size`]) and `pose` (4, 4) of a posed shape, set in `d`.
fn set_shape(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    shape: &Shape,
    pose: &Isometry3<f64>,
) -> PyResult<()> {
    let size = shape_size(shape);
    let n = size.len();
    d.set_item("type", shape.kind())?;
    d.set_item("size", output(py, size, &[n])?)?;
    d.set_item("pose", output_pose(py, pose)?)
}

/// Read a MoveIt MotionPlanRequest YAML file (MotionBenchMaker `requestNNNN.yaml`): a dict with `group`
/// (str), `start` (dict joint name -> position, rad or m), `goal` (dict joint name -> position; empty for
/// a pose goal) and `pose_goal`: None, or for position (and orientation) constraints a dict with `link`,
/// `frame` (`header.frame_id`, "" when absent), `offset` (3,) m in the link frame, `region` (list of
/// dicts `type` "box" | "sphere" | "cylinder", `size` as `Scene.obstacles` gives it, `pose` (4, 4) in
/// `frame`) and `orientation`: None or a dict `quaternion` (4,) [x, y, z, w] (normalised), `tolerance`
/// (3,) rad, `parameterization` "xyz_euler" | "rotation_vector"; and `ignored`: the field paths of
/// constraints that are not applied (path and trajectory constraints, alternative goals).
#[pyfunction]
pub fn load_motion_plan_request<'py>(
    py: Python<'py>,
    path: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let path = path_arg(path)?;
    let req = guarded(py, || moveit::parse_request_file(&path))?;
    let d = PyDict::new(py);
    d.set_item("group", &req.group)?;
    let start = PyDict::new(py);
    for (name, pos) in &req.start {
        start.set_item(name, pos)?;
    }
    let goal = PyDict::new(py);
    for (name, pos) in &req.goal {
        goal.set_item(name, pos)?;
    }
    d.set_item("start", start)?;
    d.set_item("goal", goal)?;
    let pose_goal = match &req.pose_goal {
        Some(g) => Some(pose_goal_dict(py, g)?),
        None => None,
    };
    d.set_item("pose_goal", pose_goal)?;
    d.set_item("ignored", PyList::new(py, &req.ignored)?)?;
    Ok(d)
}

/// The dict of a request's pose goal (see `load_motion_plan_request`).
fn pose_goal_dict<'py>(py: Python<'py>, g: &PoseGoal) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("link", &g.link)?;
    d.set_item("frame", &g.frame)?;
    d.set_item("offset", output_vec3(py, &g.offset)?)?;
    let region = PyList::empty(py);
    for (shape, pose) in &g.region {
        let r = PyDict::new(py);
        set_shape(py, &r, shape, pose)?;
        region.append(r)?;
    }
    d.set_item("region", region)?;
    let orientation = match &g.orientation {
        Some(o) => {
            let od = PyDict::new(py);
            let q = o.rotation.quaternion();
            od.set_item("quaternion", output(py, vec![q.i, q.j, q.k, q.w], &[4])?)?;
            od.set_item("tolerance", output_vec3(py, &o.tolerance)?)?;
            let kind = if o.rotation_vector {
                "rotation_vector"
            } else {
                "xyz_euler"
            };
            od.set_item("parameterization", kind)?;
            Some(od)
        }
        None => None,
    };
    d.set_item("orientation", orientation)?;
    Ok(d)
}
