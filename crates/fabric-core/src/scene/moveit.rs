//! MoveIt `PlanningScene` and `MotionPlanRequest` YAML, as written by MotionBenchMaker.
//!
//! Scene (`world.collision_objects[*]`):
//! * `id` (string, required) becomes the obstacle name; an object with several shapes gives obstacles
//!   named `id/0`, `id/1`, ... in order (primitives first, then meshes).
//! * `primitives[k]` with `type` (`box`, `sphere`, `cylinder`, case-insensitive, or the
//!   `shape_msgs/SolidPrimitive` constants 1, 2, 3) and `dimensions`: box = FULL sizes `[x, y, z]`,
//!   sphere = `[radius]`, cylinder = `[height, radius]` (axis = local z). Cones (type 4) are rejected.
//! * `primitive_poses[k]` (one per primitive): `position` `[x, y, z]` and `orientation` quaternion
//!   `[x, y, z, w]` (lists, or mappings with keys x, y, z, w). Quaternions are normalised; a zero one is
//!   an error.
//! * The object's own `pose`, when present, composes on the left: `world_T_shape = pose · primitive_pose`.
//! * `meshes[k]` (`vertices: [{x, y, z}]`, `triangles: [{vertex_indices: [a, b, c]}]`) with
//!   `mesh_poses[k]` become [`Shape::TriMesh`] obstacles (solid when closed, see
//!   [`crate::scene::meshio::build_mesh`]). `planes` are rejected. `operation`, when present, must be
//!   ADD (`0` or `"add"`).
//! * An object's `header.frame_id`, when present, must name the planning frame (`world`, `/world`,
//!   empty, or the robot's root link when the caller names it: they coincide in MotionBenchMaker's
//!   scenes); `robot_state.attached_collision_objects` must be empty (a held object is not part of the
//!   robot's collision model). A later object with the same `id` replaces an earlier one (MoveIt's ADD).
//!   Everything else is not used; [`parse_scene_str`] lists what would change the problem (an octomap,
//!   collisions the allowed collision matrix allows with objects, frame transforms, link padding) and
//!   fields that are not MoveIt's, for callers to warn about.
//!
//! Request: `group_name`, `start_state.joint_state.{name, position}` and the goal of
//! `goal_constraints[0]`: either `joint_constraints[*].{joint_name, position}` (a joint goal, as
//! MotionBenchMaker writes) or a pose goal ([`PoseGoal`]): one `position_constraints` entry
//! (`link_name`, `target_point_offset`, `constraint_region` box / sphere / cylinder primitives with their
//! poses, `header.frame_id`) and at most one `orientation_constraints` entry on the same link
//! (`orientation`, `absolute_{x,y,z}_axis_tolerance`, `parameterization`). Joint and pose constraints
//! together, an orientation without a position, mesh regions and objects attached in the start state
//! are rejected. Path and trajectory constraints, alternative goals and velocity or acceleration scaling
//! are not applied: [`MotionPlanRequest::ignored`] lists them.
//!
//! Every error is [`FabricError::Format`] naming the file and the field path, e.g.
//! `world.collision_objects[3].primitives[0].dimensions`.

use std::path::Path;

use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde_yaml::Value;

use super::meshio::build_mesh;
use super::scene::Scene;
use super::shape::{Obstacle, Shape};
use crate::error::{FabricError, Result};

/// A planning problem: the group, the start joint state and the joint goal, as `(joint name, position)`
/// pairs in file order (rad or m), or a pose goal.
#[derive(Clone, Debug)]
pub struct MotionPlanRequest {
    /// `group_name` (e.g. `panda_arm`).
    pub group: String,
    /// `start_state.joint_state` names and positions (may include joints outside the group, e.g. fingers).
    pub start: Vec<(String, f64)>,
    /// `goal_constraints[0].joint_constraints[*]` joint names and positions (empty for a pose goal).
    pub goal: Vec<(String, f64)>,
    /// The pose goal of `goal_constraints[0]`, when it has position (and orientation) constraints
    /// instead of joint constraints.
    pub pose_goal: Option<PoseGoal>,
    /// Field paths of constraints and settings the request holds and this reader does not apply:
    /// non-empty `path_constraints.*_constraints`, `trajectory_constraints.constraints`,
    /// `goal_constraints[1..]` (MoveIt's alternative goals; only the first is used),
    /// `max_velocity_scaling_factor` / `max_acceleration_scaling_factor` below 1 (the fabric's speed
    /// control sets the speed), `start_state.multi_dof_joint_state.transforms` other than the identity
    /// (the robot's base stays at the planning frame's origin), and fields that are not part of a
    /// `MotionPlanRequest`. Callers should tell the user.
    pub ignored: Vec<String>,
}

/// A MoveIt pose goal on one link, in the planning frame `frame` (MoveIt `PositionConstraint` and
/// `OrientationConstraint` semantics): the point `offset` fixed in `link` must lie inside one of the
/// `region` shapes, and, when `orientation` is set, the link's rotation must match it within the
/// tolerances. Solving it (inverse kinematics) is left to the caller.
#[derive(Clone, Debug)]
pub struct PoseGoal {
    /// `link_name` of the constraints.
    pub link: String,
    /// `header.frame_id` of the position constraint ("" when absent); the orientation constraint's, when
    /// given, is the same.
    pub frame: String,
    /// `target_point_offset`: the constrained point in the link frame (m).
    pub offset: Vector3<f64>,
    /// `constraint_region.primitives` with their `primitive_poses` in `frame` (m): the point must lie in
    /// one of them. At least one.
    pub region: Vec<(Shape, Isometry3<f64>)>,
    /// The orientation constraint, if any.
    pub orientation: Option<OrientationGoal>,
}

/// A MoveIt orientation constraint: with R* = `rotation` and R the link's rotation in the planning frame,
/// the error rotation D = R*ᵀ R, expressed as XYZ Euler angles (D = Rx(a) Ry(b) Rz(c); MoveIt's
/// `parameterization` 0, the default) or as a rotation vector (`parameterization` 1), must lie within
/// `tolerance` per component (rad).
#[derive(Clone, Debug, PartialEq)]
pub struct OrientationGoal {
    /// Target rotation R* of the link in the planning frame (the `orientation` quaternion, normalised).
    pub rotation: UnitQuaternion<f64>,
    /// `absolute_x_axis_tolerance`, `absolute_y_axis_tolerance`, `absolute_z_axis_tolerance` (rad), ≥ 0.
    pub tolerance: Vector3<f64>,
    /// `parameterization` 1 (rotation vector) instead of 0 (XYZ Euler angles).
    pub rotation_vector: bool,
}

impl MotionPlanRequest {
    /// Start positions in the order of `joint_names` (e.g. [`crate::robot::Robot::joint_names`]).
    /// `Err(MissingJoint)` when one is absent from the request.
    pub fn start_for(&self, joint_names: &[String]) -> Result<Vec<f64>> {
        self.pick(&self.start, joint_names)
    }

    /// Goal positions in the order of `joint_names`. `Err(MissingJoint)` when one is absent.
    pub fn goal_for(&self, joint_names: &[String]) -> Result<Vec<f64>> {
        self.pick(&self.goal, joint_names)
    }

    fn pick(&self, list: &[(String, f64)], joint_names: &[String]) -> Result<Vec<f64>> {
        joint_names
            .iter()
            .map(|n| {
                list.iter()
                    .find(|(m, _)| m == n)
                    .map(|(_, v)| *v)
                    .ok_or_else(|| FabricError::MissingJoint {
                        robot: format!("motion plan request (group '{}')", self.group),
                        joint: n.clone(),
                    })
            })
            .collect()
    }
}

/// Parse a `MotionPlanRequest` YAML string; `source` names it in errors.
pub fn parse_request_str(yaml: &str, source: &str) -> Result<MotionPlanRequest> {
    let doc = Doc { file: source };
    let root = doc.parse(yaml)?;
    let group = doc.string(doc.field(&root, "", "group_name")?, "group_name")?;

    let js_path = "start_state.joint_state";
    let start_state = doc.field(&root, "", "start_state")?;
    doc.no_attached_objects(start_state, "start_state")?;
    let js = doc.field(start_state, "start_state", "joint_state")?;
    let names_path = format!("{js_path}.name");
    let names = doc.seq(doc.field(js, js_path, "name")?, &names_path)?;
    let pos_path = format!("{js_path}.position");
    let positions = doc.numbers(doc.field(js, js_path, "position")?, &pos_path)?;
    if names.len() != positions.len() {
        return Err(doc.err(
            &pos_path,
            format!(
                "{} positions for {} joint names",
                positions.len(),
                names.len()
            ),
        ));
    }
    let mut start = Vec::with_capacity(names.len());
    for (i, (n, v)) in names.iter().zip(positions).enumerate() {
        let name = doc.string(n, &format!("{names_path}[{i}]"))?;
        doc.no_duplicate(&start, &name, &format!("{names_path}[{i}]"))?;
        start.push((name, v));
    }

    let goals = doc.seq(
        doc.field(&root, "", "goal_constraints")?,
        "goal_constraints",
    )?;
    let first = goals
        .first()
        .ok_or_else(|| doc.err("goal_constraints", "is empty"))?;
    let (goal, pose_goal) = doc.goal(first)?;
    let ignored = doc.ignored(&root, goals.len())?;
    Ok(MotionPlanRequest {
        group,
        start,
        goal,
        pose_goal,
        ignored,
    })
}

/// Parse a `MotionPlanRequest` YAML file. `Err(Io)` when it cannot be read.
pub fn parse_request_file(path: &Path) -> Result<MotionPlanRequest> {
    parse_request_str(&read(path)?, &path.display().to_string())
}

/// Read a text file, mapping failures to `FabricError::Io`.
pub(crate) fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| FabricError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

/// The `header.frame_id` values that mean the planning frame (the robot's root frame), besides the root
/// link's own name: for a scene's collision objects here, for pose goals in the Python package.
pub const PLANNING_FRAMES: [&str; 3] = ["", "world", "/world"];

/// Top-level fields of a MoveIt `MotionPlanRequest` message (ROS 1 and ROS 2).
const REQUEST_FIELDS: [&str; 16] = [
    "workspace_parameters",
    "start_state",
    "goal_constraints",
    "path_constraints",
    "trajectory_constraints",
    "reference_trajectories",
    "pipeline_id",
    "planner_id",
    "group_name",
    "num_planning_attempts",
    "allowed_planning_time",
    "max_velocity_scaling_factor",
    "max_acceleration_scaling_factor",
    "cartesian_speed_end_effector_link",
    "max_cartesian_speed",
    "cartesian_speed_limited_link",
];

/// Top-level fields of a MoveIt `PlanningScene` message.
const SCENE_FIELDS: [&str; 10] = [
    "name",
    "robot_state",
    "robot_model_name",
    "fixed_frame_transforms",
    "allowed_collision_matrix",
    "link_padding",
    "link_scale",
    "object_colors",
    "world",
    "is_diff",
];

/// Fields of a MoveIt `CollisionObject` message (`subframe_*` name frames and add no geometry; `type`
/// names an object database entry).
const OBJECT_FIELDS: [&str; 13] = [
    "header",
    "pose",
    "id",
    "type",
    "primitives",
    "primitive_poses",
    "meshes",
    "mesh_poses",
    "planes",
    "plane_poses",
    "subframe_names",
    "subframe_poses",
    "operation",
];

/// Parse a `PlanningScene` YAML string into a [`Scene`] (see the module documentation), with notes on
/// the fields it holds and the scene does not apply, each `"<field path>: <why>"`:
/// * `world.octomap` with data (its occupied cells would be obstacles);
/// * `allowed_collision_matrix` entries that allow collisions with the scene's objects (the motion keeps
///   clear of every object anyway);
/// * `fixed_frame_transforms` that are not the identity, non-empty `link_padding` / `link_scale`;
/// * a collision object replaced by a later one with the same id (MoveIt's ADD replaces an object of
///   that id: only the last is kept);
/// * fields that are not part of the MoveIt messages.
///
/// The robot state's joint positions, the robot model's name, the scene's name and object colours do
/// not change the planning problem and are not reported.
pub fn parse_scene_str(
    yaml: &str,
    source: &str,
    root_frame: Option<&str>,
) -> Result<(Scene, Vec<String>)> {
    let doc = Doc { file: source };
    let root = doc.parse(yaml)?;
    let mut notes = Vec::new();
    if let Some(state) = doc.opt(&root, "robot_state") {
        doc.no_attached_objects(state, "robot_state")?;
    }
    for key in keys(&root) {
        if !SCENE_FIELDS.contains(&key.as_str()) {
            notes.push(format!("{key}: not a PlanningScene field, ignored"));
        }
    }
    doc.scene_settings(&root, &mut notes)?;
    let world = doc.field(&root, "", "world")?;
    for key in keys(world) {
        if key != "collision_objects" && key != "octomap" {
            notes.push(format!("world.{key}: not a PlanningWorld field, ignored"));
        }
    }
    if let Some(octomap) = doc.opt(world, "octomap") {
        if octomap_has_data(octomap) {
            notes.push(
                "world.octomap: octomaps are not supported; its occupied cells are not obstacles"
                    .into(),
            );
        }
    }
    let mut scene = Scene::new();
    let Some(objects) = doc.opt(world, "collision_objects") else {
        return Ok((scene, notes));
    };
    let objects = doc.seq(objects, "world.collision_objects")?;
    // MoveIt's ADD of an id already in the world replaces that object: the last of each id counts
    let mut last_of_id: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
    let mut ids = Vec::with_capacity(objects.len());
    for (i, obj) in objects.iter().enumerate() {
        let path = format!("world.collision_objects[{i}]");
        let id = doc.string(doc.field(obj, &path, "id")?, &format!("{path}.id"))?;
        last_of_id.insert(id.clone(), i);
        ids.push(id);
    }
    doc.collision_matrix(&root, &last_of_id, &mut notes)?;
    for (i, obj) in objects.iter().enumerate() {
        let path = format!("world.collision_objects[{i}]");
        let id = ids[i].clone();
        let last = last_of_id[&id];
        if last != i {
            notes.push(format!(
                "{path}: id '{id}' is added again by world.collision_objects[{last}], which replaces it \
                 (MoveIt semantics)"
            ));
            continue;
        }
        for key in keys(obj) {
            if !OBJECT_FIELDS.contains(&key.as_str()) {
                notes.push(format!(
                    "{path}.{key}: not a CollisionObject field, ignored"
                ));
            }
        }
        let frame = doc.frame(obj, &path)?;
        if !PLANNING_FRAMES.contains(&frame.as_str()) && Some(frame.as_str()) != root_frame {
            return Err(doc.err(
                &format!("{path}.header.frame_id"),
                format!(
                    "frame '{frame}': objects must be given in the planning frame (\"world\" or \
                     the robot's root link{}; or without a header)",
                    root_frame.map_or(String::new(), |r| format!(" '{r}'"))
                ),
            ));
        }
        if let Some(op) = doc.opt(obj, "operation") {
            let is_add = match op {
                Value::Number(n) => n.as_i64() == Some(0),
                Value::String(s) => s.eq_ignore_ascii_case("add"),
                _ => false,
            };
            if !is_add {
                return Err(doc.err(
                    &format!("{path}.operation"),
                    "only ADD (0) is supported in a scene",
                ));
            }
        }
        let object_pose = match doc.opt(obj, "pose") {
            Some(v) => doc.pose(v, &format!("{path}.pose"))?,
            None => Isometry3::identity(),
        };
        if let Some(planes) = doc.opt(obj, "planes") {
            if !doc.seq(planes, &format!("{path}.planes"))?.is_empty() {
                return Err(doc.err(&format!("{path}.planes"), "plane shapes are not supported"));
            }
        }
        let mut shapes: Vec<(Shape, Isometry3<f64>, String)> = Vec::new();
        doc.primitives(obj, &path, &mut shapes)?;
        doc.meshes(obj, &path, &mut shapes)?;
        if shapes.is_empty() {
            return Err(doc.err(&path, "collision object has no primitives or meshes"));
        }
        let several = shapes.len() > 1;
        for (k, (shape, pose, field)) in shapes.into_iter().enumerate() {
            let name = if several {
                format!("{id}/{k}")
            } else {
                id.clone()
            };
            scene
                .add(Obstacle::new(name, shape, object_pose * pose))
                .map_err(|e| doc.err(&field, e.to_string()))?;
        }
    }
    Ok((scene, notes))
}

/// Parse a `PlanningScene` YAML file ([`parse_scene_str`]). `Err(Io)` when it cannot be read.
pub fn parse_scene_file(path: &Path, root_frame: Option<&str>) -> Result<(Scene, Vec<String>)> {
    parse_scene_str(&read(path)?, &path.display().to_string(), root_frame)
}

/// The string keys of mapping `v` (none when `v` is not a mapping), in file order.
fn keys(v: &Value) -> Vec<String> {
    v.as_mapping()
        .map(|m| {
            m.keys()
                .filter_map(|k| k.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default()
}

/// Whether a `world.octomap` value (`octomap_msgs/OctomapWithPose`) holds cells: a non-empty
/// `octomap.data`, or any content in a layout other than that message's.
fn octomap_has_data(v: &Value) -> bool {
    match v.get("octomap") {
        Some(map) if map.is_mapping() => match map.get("data") {
            None | Some(Value::Null) => false,
            Some(Value::Sequence(d)) => !d.is_empty(),
            Some(Value::String(d)) => !d.is_empty(),
            Some(_) => true,
        },
        Some(Value::Null) => false,
        Some(_) => true,
        None => v.as_mapping().is_some_and(|m| !m.is_empty()),
    }
}

/// (joint name, position) pairs of a joint goal, in file order.
type JointGoal = Vec<(String, f64)>;

/// Error context: the file name. Field paths are built by the callers.
struct Doc<'a> {
    file: &'a str,
}

fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    }
}

impl Doc<'_> {
    fn err(&self, field: &str, message: impl Into<String>) -> FabricError {
        FabricError::Format {
            file: self.file.to_string(),
            field: if field.is_empty() {
                "<root>".into()
            } else {
                field.to_string()
            },
            message: message.into(),
        }
    }

    fn parse(&self, yaml: &str) -> Result<Value> {
        crate::limits::check_yaml(yaml).map_err(|m| self.err("", m))?;
        let root: Value =
            serde_yaml::from_str(yaml).map_err(|e| self.err("", format!("invalid YAML: {e}")))?;
        if !root.is_mapping() {
            return Err(self.err("", "expected a mapping at the top level"));
        }
        Ok(root)
    }

    /// Child `key` of mapping `v` (at `path`); missing or null is an error.
    fn field<'v>(&self, v: &'v Value, path: &str, key: &str) -> Result<&'v Value> {
        if !v.is_mapping() {
            return Err(self.err(path, "expected a mapping"));
        }
        self.opt(v, key)
            .ok_or_else(|| self.err(&join(path, key), "missing"))
    }

    /// Child `key` of `v`, `None` when absent or null.
    fn opt<'v>(&self, v: &'v Value, key: &str) -> Option<&'v Value> {
        v.get(key).filter(|c| !c.is_null())
    }

    fn seq<'v>(&self, v: &'v Value, path: &str) -> Result<&'v [Value]> {
        v.as_sequence()
            .map(|s| s.as_slice())
            .ok_or_else(|| self.err(path, "expected a list"))
    }

    fn number(&self, v: &Value, path: &str) -> Result<f64> {
        let x = v
            .as_f64()
            .ok_or_else(|| self.err(path, format!("expected a number, got {}", show(v))))?;
        if !x.is_finite() {
            return Err(self.err(path, "not finite"));
        }
        Ok(x)
    }

    fn numbers(&self, v: &Value, path: &str) -> Result<Vec<f64>> {
        self.seq(v, path)?
            .iter()
            .enumerate()
            .map(|(i, x)| self.number(x, &format!("{path}[{i}]")))
            .collect()
    }

    fn string(&self, v: &Value, path: &str) -> Result<String> {
        v.as_str()
            .map(str::to_string)
            .ok_or_else(|| self.err(path, format!("expected a string, got {}", show(v))))
    }

    fn no_duplicate(&self, list: &[(String, f64)], name: &str, path: &str) -> Result<()> {
        if list.iter().any(|(n, _)| n == name) {
            return Err(self.err(path, format!("joint '{name}' appears twice")));
        }
        Ok(())
    }

    /// `n` numbers from a list `[a, b, ...]` or a mapping with the given `keys`.
    fn components(&self, v: &Value, path: &str, keys: &[&str]) -> Result<Vec<f64>> {
        if v.is_mapping() {
            keys.iter()
                .map(|k| self.number(self.field(v, path, k)?, &join(path, k)))
                .collect()
        } else {
            let xs = self.numbers(v, path)?;
            if xs.len() != keys.len() {
                return Err(self.err(
                    path,
                    format!("expected {} numbers, got {}", keys.len(), xs.len()),
                ));
            }
            Ok(xs)
        }
    }

    fn pose(&self, v: &Value, path: &str) -> Result<Isometry3<f64>> {
        let pp = join(path, "position");
        let p = self.components(self.field(v, path, "position")?, &pp, &["x", "y", "z"])?;
        Ok(Isometry3::from_parts(
            Translation3::new(p[0], p[1], p[2]),
            self.orientation(v, path)?,
        ))
    }

    /// The unit quaternion `orientation` (`[x, y, z, w]` or a mapping) of mapping `v` at `path`,
    /// normalised; a zero one is an error.
    fn orientation(&self, v: &Value, path: &str) -> Result<UnitQuaternion<f64>> {
        let op = join(path, "orientation");
        let q = self.components(
            self.field(v, path, "orientation")?,
            &op,
            &["x", "y", "z", "w"],
        )?;
        let quat = Quaternion::new(q[3], q[0], q[1], q[2]);
        if quat.norm() < 1e-9 {
            return Err(self.err(&op, "zero quaternion"));
        }
        Ok(UnitQuaternion::from_quaternion(quat))
    }

    /// `Err` when the robot state `state` (at `path`) holds attached collision objects: the robot's
    /// collision model would not include them, so no motion would keep them clear.
    fn no_attached_objects(&self, state: &Value, path: &str) -> Result<()> {
        let field = join(path, "attached_collision_objects");
        match self.opt(state, "attached_collision_objects") {
            Some(list) if !self.seq(list, &field)?.is_empty() => Err(self.err(
                &field,
                "objects attached to the robot are not supported: the robot's collision model would not \
                 include them, so no motion would keep them clear",
            )),
            _ => Ok(()),
        }
    }

    /// Notes on the scene-wide settings of `root` that are not applied: `fixed_frame_transforms` other
    /// than the identity, non-empty `link_padding` and `link_scale`.
    fn scene_settings(&self, root: &Value, notes: &mut Vec<String>) -> Result<()> {
        if let Some(list) = self.opt(root, "fixed_frame_transforms") {
            for (i, t) in self.seq(list, "fixed_frame_transforms")?.iter().enumerate() {
                let path = format!("fixed_frame_transforms[{i}]");
                let identity = t.get("transform").is_some_and(|tf| {
                    let near = |key: &str, keys: &[&str], want: &[f64]| {
                        tf.get(key).is_some_and(|v| {
                            self.components(v, key, keys).is_ok_and(|c| {
                                c.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-9)
                            })
                        })
                    };
                    near("translation", &["x", "y", "z"], &[0.0, 0.0, 0.0])
                        && near("rotation", &["x", "y", "z", "w"], &[0.0, 0.0, 0.0, 1.0])
                });
                if !identity {
                    notes.push(format!(
                        "{path}: frame transforms are not applied (objects are placed in the planning \
                         frame as given)"
                    ));
                }
            }
        }
        for key in ["link_padding", "link_scale"] {
            if let Some(list) = self.opt(root, key) {
                if !self.seq(list, key)?.is_empty() {
                    notes.push(format!(
                        "{key}: not applied (the robot's collision spheres keep their size)"
                    ));
                }
            }
        }
        Ok(())
    }

    /// A note when the `allowed_collision_matrix` of `root` allows a collision with one of the scene's
    /// objects (`objects`: ids): the motion keeps clear of every object all the same. Entries among the
    /// robot's links only repeat what the SRDF says and are not reported.
    fn collision_matrix(
        &self,
        root: &Value,
        objects: &std::collections::HashMap<String, usize>,
        notes: &mut Vec<String>,
    ) -> Result<()> {
        let Some(acm) = self.opt(root, "allowed_collision_matrix") else {
            return Ok(());
        };
        let mut allowed = std::collections::BTreeSet::new();
        let names = |key: &str| -> Result<Vec<String>> {
            match self.opt(acm, key) {
                Some(v) => self
                    .seq(v, &format!("allowed_collision_matrix.{key}"))?
                    .iter()
                    .map(|n| Ok(n.as_str().unwrap_or_default().to_string()))
                    .collect(),
                None => Ok(Vec::new()),
            }
        };
        let entry_names = names("entry_names")?;
        let rows = match self.opt(acm, "entry_values") {
            Some(v) => self.seq(v, "allowed_collision_matrix.entry_values")?,
            None => &[],
        };
        for (i, row) in rows.iter().enumerate() {
            let values = row
                .get("enabled")
                .unwrap_or(row)
                .as_sequence()
                .map(|s| s.as_slice())
                .unwrap_or(&[]);
            for (j, v) in values.iter().enumerate() {
                if v.as_bool() == Some(true) {
                    for k in [i, j] {
                        if let Some(n) = entry_names.get(k).filter(|n| objects.contains_key(*n)) {
                            allowed.insert(n.clone());
                        }
                    }
                }
            }
        }
        let defaults = names("default_entry_names")?;
        let default_values = match self.opt(acm, "default_entry_values") {
            Some(v) => self.seq(v, "allowed_collision_matrix.default_entry_values")?,
            None => &[],
        };
        for (n, v) in defaults.iter().zip(default_values) {
            if v.as_bool() == Some(true) && objects.contains_key(n) {
                allowed.insert(n.clone());
            }
        }
        if !allowed.is_empty() {
            let list: Vec<String> = allowed.into_iter().map(|n| format!("'{n}'")).collect();
            notes.push(format!(
                "allowed_collision_matrix: collisions allowed with {} are not applied (the motion keeps \
                 clear of every object)",
                list.join(", ")
            ));
        }
        Ok(())
    }

    /// The constraints and settings of request `root` that are not applied (see
    /// [`MotionPlanRequest::ignored`]); `n_goals` is the length of `goal_constraints`.
    fn ignored(&self, root: &Value, n_goals: usize) -> Result<Vec<String>> {
        let mut out = Vec::new();
        // MoveIt reads 0 (and anything outside (0, 1]) as full speed
        for key in [
            "max_velocity_scaling_factor",
            "max_acceleration_scaling_factor",
        ] {
            if let Some(v) = self.opt(root, key) {
                let factor = self.number(v, key)?;
                if factor > 0.0 && factor < 1.0 {
                    out.push(key.to_string());
                }
            }
        }
        if let Some(constraints) = self.opt(root, "path_constraints") {
            for key in [
                "joint_constraints",
                "position_constraints",
                "orientation_constraints",
                "visibility_constraints",
            ] {
                let field = format!("path_constraints.{key}");
                if let Some(list) = self.opt(constraints, key) {
                    if !self.seq(list, &field)?.is_empty() {
                        out.push(field);
                    }
                }
            }
        }
        if let Some(t) = self.opt(root, "trajectory_constraints") {
            if let Some(list) = self.opt(t, "constraints") {
                let field = "trajectory_constraints.constraints";
                if !self.seq(list, field)?.is_empty() {
                    out.push(field.to_string());
                }
            }
        }
        if n_goals > 1 {
            out.push(format!("goal_constraints[1..{}]", n_goals - 1));
        }
        let multi = self
            .opt(root, "start_state")
            .and_then(|s| self.opt(s, "multi_dof_joint_state"))
            .and_then(|m| self.opt(m, "transforms"))
            .and_then(Value::as_sequence);
        for (i, t) in multi.into_iter().flatten().enumerate() {
            let near = |key: &str, keys: &[&str], want: &[f64]| {
                t.get(key).is_some_and(|v| {
                    self.components(v, key, keys)
                        .is_ok_and(|c| c.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-9))
                })
            };
            if !(near("translation", &["x", "y", "z"], &[0.0; 3])
                && near("rotation", &["x", "y", "z", "w"], &[0.0, 0.0, 0.0, 1.0]))
            {
                out.push(format!("start_state.multi_dof_joint_state.transforms[{i}]"));
            }
        }
        for key in keys(root) {
            if !REQUEST_FIELDS.contains(&key.as_str()) {
                out.push(key);
            }
        }
        Ok(out)
    }

    /// The goal of `goal_constraints[0]` (`c`): joint constraints, or a pose goal.
    fn goal(&self, c: &Value) -> Result<(JointGoal, Option<PoseGoal>)> {
        const PATH: &str = "goal_constraints[0]";
        let list = |key: &str| -> Result<&[Value]> {
            match self.opt(c, key) {
                Some(v) => self.seq(v, &join(PATH, key)),
                None => Ok(&[]),
            }
        };
        if !c.is_mapping() {
            return Err(self.err(PATH, "expected a mapping"));
        }
        let (joints, positions, orientations) = (
            list("joint_constraints")?,
            list("position_constraints")?,
            list("orientation_constraints")?,
        );
        let pose = !(positions.is_empty() && orientations.is_empty());
        if !joints.is_empty() && pose {
            return Err(self.err(
                PATH,
                "joint constraints together with position or orientation constraints are not supported",
            ));
        }
        if !joints.is_empty() {
            return Ok((self.joint_goal(joints)?, None));
        }
        if positions.is_empty() {
            let (field, message) = if orientations.is_empty() {
                (
                    "joint_constraints",
                    "missing or empty (and no position constraint for a pose goal)",
                )
            } else {
                (
                    "position_constraints",
                    "missing: an orientation constraint needs a position constraint on the same link",
                )
            };
            return Err(self.err(&join(PATH, field), message));
        }
        Ok((Vec::new(), Some(self.pose_goal(positions, orientations)?)))
    }

    fn joint_goal(&self, jcs: &[Value]) -> Result<JointGoal> {
        let jc_path = "goal_constraints[0].joint_constraints";
        let mut goal = Vec::with_capacity(jcs.len());
        for (i, jc) in jcs.iter().enumerate() {
            let path = format!("{jc_path}[{i}]");
            let name = self.string(
                self.field(jc, &path, "joint_name")?,
                &format!("{path}.joint_name"),
            )?;
            self.no_duplicate(&goal, &name, &format!("{path}.joint_name"))?;
            let v = self.number(
                self.field(jc, &path, "position")?,
                &format!("{path}.position"),
            )?;
            goal.push((name, v));
        }
        Ok(goal)
    }

    fn pose_goal(&self, positions: &[Value], orientations: &[Value]) -> Result<PoseGoal> {
        const PC: &str = "goal_constraints[0].position_constraints";
        const OC: &str = "goal_constraints[0].orientation_constraints";
        for (list, path, what) in [
            (positions, PC, "position"),
            (orientations, OC, "orientation"),
        ] {
            if list.len() > 1 {
                return Err(self.err(
                    path,
                    format!("one {what} constraint is supported, got {}", list.len()),
                ));
            }
        }
        let pc = &positions[0];
        let path = format!("{PC}[0]");
        let link = self.string(
            self.field(pc, &path, "link_name")?,
            &join(&path, "link_name"),
        )?;
        let frame = self.frame(pc, &path)?;
        let offset = match self.opt(pc, "target_point_offset") {
            Some(v) => {
                let o =
                    self.components(v, &join(&path, "target_point_offset"), &["x", "y", "z"])?;
                Vector3::new(o[0], o[1], o[2])
            }
            None => Vector3::zeros(),
        };
        let rp = join(&path, "constraint_region");
        let region_value = self.field(pc, &path, "constraint_region")?;
        if let Some(m) = self.opt(region_value, "meshes") {
            if !self.seq(m, &join(&rp, "meshes"))?.is_empty() {
                return Err(self.err(
                    &join(&rp, "meshes"),
                    "mesh regions are not supported (use box, sphere or cylinder primitives)",
                ));
            }
        }
        let mut shapes = Vec::new();
        self.primitives(region_value, &rp, &mut shapes)?;
        if shapes.is_empty() {
            return Err(self.err(&join(&rp, "primitives"), "missing or empty"));
        }
        let region = shapes.into_iter().map(|(s, p, _)| (s, p)).collect();
        let orientation = match orientations.first() {
            None => None,
            Some(oc) => {
                let opath = format!("{OC}[0]");
                let olink = self.string(
                    self.field(oc, &opath, "link_name")?,
                    &join(&opath, "link_name"),
                )?;
                if olink != link {
                    return Err(self.err(
                        &join(&opath, "link_name"),
                        format!("'{olink}' differs from the position constraint's link '{link}'"),
                    ));
                }
                let oframe = self.frame(oc, &opath)?;
                if oframe != frame {
                    return Err(self.err(
                        &join(&opath, "header.frame_id"),
                        format!(
                            "'{oframe}' differs from the position constraint's frame '{frame}'"
                        ),
                    ));
                }
                Some(self.orientation_goal(oc, &opath)?)
            }
        };
        Ok(PoseGoal {
            link,
            frame,
            offset,
            region,
            orientation,
        })
    }

    /// `header.frame_id` of a constraint or collision object at `path` ("" when absent).
    fn frame(&self, c: &Value, path: &str) -> Result<String> {
        let Some(header) = self.opt(c, "header") else {
            return Ok(String::new());
        };
        let hp = join(path, "header");
        match self.opt(header, "frame_id") {
            Some(f) => self.string(f, &join(&hp, "frame_id")),
            None => Ok(String::new()),
        }
    }

    fn orientation_goal(&self, oc: &Value, path: &str) -> Result<OrientationGoal> {
        let rotation = self.orientation(oc, path)?;
        let mut tolerance = Vector3::zeros();
        for (k, axis) in ["x", "y", "z"].iter().enumerate() {
            let key = format!("absolute_{axis}_axis_tolerance");
            let tp = join(path, &key);
            let t = self.number(self.field(oc, path, &key)?, &tp)?;
            if t < 0.0 {
                return Err(self.err(&tp, format!("must be >= 0, got {t}")));
            }
            tolerance[k] = t;
        }
        let pp = join(path, "parameterization");
        let rotation_vector = match self.opt(oc, "parameterization") {
            None => false,
            Some(v) => match v.as_i64() {
                Some(0) => false,
                Some(1) => true,
                _ => {
                    return Err(self.err(
                        &pp,
                        format!(
                            "expected 0 (XYZ Euler angles) or 1 (rotation vector), got {}",
                            show(v)
                        ),
                    ))
                }
            },
        };
        Ok(OrientationGoal {
            rotation,
            tolerance,
            rotation_vector,
        })
    }

    fn primitives(
        &self,
        obj: &Value,
        path: &str,
        out: &mut Vec<(Shape, Isometry3<f64>, String)>,
    ) -> Result<()> {
        let Some(prims) = self.opt(obj, "primitives") else {
            return Ok(());
        };
        let prims_path = join(path, "primitives");
        let prims = self.seq(prims, &prims_path)?;
        if prims.is_empty() {
            return Ok(());
        }
        let poses_path = join(path, "primitive_poses");
        let poses = self.seq(self.field(obj, path, "primitive_poses")?, &poses_path)?;
        if poses.len() != prims.len() {
            return Err(self.err(
                &poses_path,
                format!(
                    "{} poses for {} primitives (need one each)",
                    poses.len(),
                    prims.len()
                ),
            ));
        }
        for (k, (prim, pose)) in prims.iter().zip(poses).enumerate() {
            let pp = format!("{prims_path}[{k}]");
            let shape = self.primitive(prim, &pp)?;
            let pose = self.pose(pose, &format!("{poses_path}[{k}]"))?;
            out.push((shape, pose, pp));
        }
        Ok(())
    }

    fn primitive(&self, prim: &Value, path: &str) -> Result<Shape> {
        let tp = join(path, "type");
        let kind = match self.field(prim, path, "type")? {
            Value::String(s) => s.to_ascii_lowercase(),
            Value::Number(n) => match n.as_i64() {
                Some(1) => "box".into(),
                Some(2) => "sphere".into(),
                Some(3) => "cylinder".into(),
                Some(4) => "cone".into(),
                _ => return Err(self.err(&tp, format!("unknown primitive type {n}"))),
            },
            other => return Err(self.err(&tp, format!("expected a string, got {}", show(other)))),
        };
        let dp = join(path, "dimensions");
        let expected = match kind.as_str() {
            "box" => 3,
            "sphere" => 1,
            "cylinder" => 2,
            "cone" => return Err(self.err(&tp, "cone primitives are not supported")),
            _ => {
                return Err(self.err(
                    &tp,
                    format!("unknown primitive type '{kind}' (expected box, sphere or cylinder)"),
                ))
            }
        };
        let dims = self.numbers(self.field(prim, path, "dimensions")?, &dp)?;
        if dims.len() != expected {
            let meaning = match expected {
                3 => "[x, y, z] full sizes",
                2 => "[height, radius]",
                _ => "[radius]",
            };
            return Err(self.err(
                &dp,
                format!(
                    "a {kind} needs {expected} dimensions {meaning}, got {}",
                    dims.len()
                ),
            ));
        }
        if let Some(i) = dims.iter().position(|&d| d <= 0.0) {
            return Err(self.err(
                &format!("{dp}[{i}]"),
                format!("must be > 0, got {}", dims[i]),
            ));
        }
        Ok(match expected {
            3 => Shape::cuboid_from_size(Vector3::new(dims[0], dims[1], dims[2])),
            2 => Shape::Cylinder {
                half_height: 0.5 * dims[0],
                radius: dims[1],
            },
            _ => Shape::Sphere { radius: dims[0] },
        })
    }

    fn meshes(
        &self,
        obj: &Value,
        path: &str,
        out: &mut Vec<(Shape, Isometry3<f64>, String)>,
    ) -> Result<()> {
        let Some(meshes) = self.opt(obj, "meshes") else {
            return Ok(());
        };
        let meshes_path = join(path, "meshes");
        let meshes = self.seq(meshes, &meshes_path)?;
        if meshes.is_empty() {
            return Ok(());
        }
        let poses_path = join(path, "mesh_poses");
        let poses = self.seq(self.field(obj, path, "mesh_poses")?, &poses_path)?;
        if poses.len() != meshes.len() {
            return Err(self.err(
                &poses_path,
                format!(
                    "{} poses for {} meshes (need one each)",
                    poses.len(),
                    meshes.len()
                ),
            ));
        }
        for (k, (mesh, pose)) in meshes.iter().zip(poses).enumerate() {
            let mp = format!("{meshes_path}[{k}]");
            let vp = join(&mp, "vertices");
            let vertices = self
                .seq(self.field(mesh, &mp, "vertices")?, &vp)?
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    let c = self.components(v, &format!("{vp}[{i}]"), &["x", "y", "z"])?;
                    Ok(Point3::new(c[0], c[1], c[2]))
                })
                .collect::<Result<Vec<_>>>()?;
            let tp = join(&mp, "triangles");
            let mut triangles = Vec::new();
            for (i, t) in self
                .seq(self.field(mesh, &mp, "triangles")?, &tp)?
                .iter()
                .enumerate()
            {
                let ip = format!("{tp}[{i}].vertex_indices");
                let idx =
                    self.numbers(self.field(t, &format!("{tp}[{i}]"), "vertex_indices")?, &ip)?;
                if idx.len() != 3 {
                    return Err(self.err(&ip, format!("expected 3 indices, got {}", idx.len())));
                }
                let mut tri = [0u32; 3];
                for (j, &x) in idx.iter().enumerate() {
                    if x < 0.0 || x.fract() != 0.0 || x >= vertices.len() as f64 {
                        return Err(self.err(
                            &format!("{ip}[{j}]"),
                            format!("invalid vertex index {x} ({} vertices)", vertices.len()),
                        ));
                    }
                    tri[j] = x as u32;
                }
                triangles.push(tri);
            }
            let mesh = build_mesh(vertices, triangles, &format!("{}: {mp}", self.file))
                .map_err(|e| self.err(&mp, e.to_string()))?;
            let pose = self.pose(pose, &format!("{poses_path}[{k}]"))?;
            out.push((Shape::TriMesh(std::sync::Arc::new(mesh)), pose, mp));
        }
        Ok(())
    }
}

/// Short rendering of a YAML value for error messages.
fn show(v: &Value) -> String {
    match v {
        Value::Null => "null".into(),
        Value::Bool(b) => b.to_string(),
        Value::Number(n) => n.to_string(),
        Value::String(s) => format!("'{s}'"),
        Value::Sequence(_) => "a list".into(),
        Value::Mapping(_) => "a mapping".into(),
        Value::Tagged(_) => "a tagged value".into(),
    }
}

impl Scene {
    /// Load a MoveIt `PlanningScene` YAML string (MotionBenchMaker format, see [`crate::scene::moveit`]);
    /// `source` names it in errors (`FabricError::Format` with the field path). `root_frame`: the name of
    /// the robot's root link, accepted as an object's `header.frame_id` besides "world" (the two coincide
    /// in MotionBenchMaker's scenes).
    pub fn from_moveit_yaml_str(
        yaml: &str,
        source: &str,
        root_frame: Option<&str>,
    ) -> Result<Scene> {
        parse_scene_str(yaml, source, root_frame).map(|(scene, _)| scene)
    }

    /// Load a MoveIt `PlanningScene` YAML file (see [`Scene::from_moveit_yaml_str`]). `Err(Io)` when it
    /// cannot be read.
    pub fn from_moveit_yaml_file(path: &Path, root_frame: Option<&str>) -> Result<Scene> {
        parse_scene_file(path, root_frame).map(|(scene, _)| scene)
    }
}
