//! URDF (urdf-rs) → [`Robot`]: tree validation, re-rooting at the base link, choice of the end-effector
//! and the active joints, mimic and locked joints, limits, collision spheres and geometry.

use std::collections::HashMap;
use std::f64::consts::TAU;
use std::path::Path;
use std::sync::Arc;

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use urdf_rs::{Geometry, JointType, Pose};

use super::geometry::{resolve_mesh_path, GeometryKind, LinkGeometry};
use super::model::{Motion, Robot, RobotOptions, TreeJoint, UrdfOrigin};
use super::spheres::CollisionSphere;
use super::tree::{
    default_ee, has_zero_range, is_movable, moves_on_its_own, multi_dof_kind, reroot, urdf_err,
    Graph, Rooted,
};
use crate::error::{FabricError, Result};

impl Robot {
    /// Build a robot from URDF text. `source` names the text in errors (a file name or `"<string>"`).
    /// Mesh paths resolve against `opts.mesh_dir` (or the current directory).
    ///
    /// Floating, planar and spherical joints are held at their identity pose ([`multi_dof_kind`]).
    ///
    /// Errors: `Urdf` (malformed XML, inconsistent tree, bad limits), `MissingLink` (base or
    /// end-effector), `MissingJoint` (active or locked joint), `Value` / `NonFinite` (bad options).
    pub fn from_urdf_str(xml: &str, source: &str, opts: &RobotOptions) -> Result<Robot> {
        build(xml, source, opts, opts.mesh_dir.as_deref())
    }

    /// Build a robot from a URDF file. Mesh paths resolve against `opts.mesh_dir`, or else the
    /// directory of the file. Errors as [`Robot::from_urdf_str`], plus `Io` when the file cannot be read.
    pub fn from_urdf_file(path: &Path, opts: &RobotOptions) -> Result<Robot> {
        let source = path.display().to_string();
        let xml = std::fs::read_to_string(path).map_err(|e| FabricError::Io {
            path: source.clone(),
            message: e.to_string(),
        })?;
        let dir = opts
            .mesh_dir
            .clone()
            .or_else(|| path.parent().map(Path::to_path_buf));
        build(&xml, &source, opts, dir.as_deref())
    }
}

/// URDF `<origin>` as an isometry (rpy is fixed-axis: R = Rz(yaw)·Ry(pitch)·Rx(roll)).
fn pose_to_iso(pose: &Pose, what: &str, source: &str) -> Result<Isometry3<f64>> {
    if pose
        .xyz
        .iter()
        .chain(pose.rpy.iter())
        .any(|v| !v.is_finite())
    {
        return Err(urdf_err(
            source,
            format!("{what}: origin contains NaN or infinite values"),
        ));
    }
    let [r, p, y] = pose.rpy.0;
    Ok(Isometry3::from_parts(
        Translation3::new(pose.xyz[0], pose.xyz[1], pose.xyz[2]),
        UnitQuaternion::from_euler_angles(r, p, y),
    ))
}

/// Active joints (URDF joint indices, in q order).
fn choose_active(
    g: &Graph,
    t: &Rooted,
    ee: usize,
    opts: &RobotOptions,
    robot: &str,
) -> Result<Vec<usize>> {
    let joints = &g.urdf.joints;
    let Some(names) = &opts.active_joints else {
        let mut chain = Vec::new();
        let mut i = ee;
        while let Some((j, p, _)) = t.edge[i] {
            if moves_on_its_own(&joints[j]) {
                chain.push(j);
            }
            i = p;
        }
        chain.reverse();
        if chain.is_empty() {
            return Err(FabricError::Value {
                what: "active joints".into(),
                message: format!(
                    "no movable joint between base '{}' and end-effector '{}'",
                    g.urdf.links[t.order[0]].name, g.urdf.links[t.order[ee]].name
                ),
            });
        }
        return Ok(chain);
    };
    if names.is_empty() {
        return Err(FabricError::Value {
            what: "active joints".into(),
            message: "the list is empty".into(),
        });
    }
    let mut out = Vec::with_capacity(names.len());
    for name in names {
        let j = g.joint(name, robot)?;
        let bad = |m: &str| FabricError::Value {
            what: format!("active joint '{name}'"),
            message: m.into(),
        };
        if !is_movable(&joints[j].joint_type) {
            return Err(bad(&not_movable(&joints[j].joint_type)));
        }
        if let Some(m) = &joints[j].mimic {
            return Err(bad(&format!("is a mimic of '{}' and follows it", m.joint)));
        }
        if has_zero_range(&joints[j]) {
            return Err(bad(&format!(
                "has the position limits [{0}, {0}], a zero range no planner moves (MoveIt's too): leave it \
                 out of the active joints and it is held at {0}",
                joints[j].limit.lower
            )));
        }
        if out.contains(&j) {
            return Err(bad("is listed twice"));
        }
        out.push(j);
    }
    Ok(out)
}

/// Why a joint that is not revolute, continuous or prismatic can be neither active nor locked.
fn not_movable(kind: &JointType) -> String {
    match multi_dof_kind(kind) {
        Some(k) => {
            format!("is a {k} joint (several degrees of freedom), held at its identity pose")
        }
        None => "is a fixed joint".to_string(),
    }
}

/// How far (rad or m) a locked joint may be held outside its URDF limits: MoveIt's default
/// `start_state_max_bounds_error`, within which MoveIt accepts a start state (moving it onto the bound) and
/// beyond which it refuses it. Held positions inside this band stay where they are asked to be (a
/// gripper opened slightly wider than its model's limit stays that wide, the conservative choice for
/// collisions).
pub const LOCKED_BOUNDS_TOLERANCE: f64 = 0.05;

/// How each URDF joint is driven: (coordinate, scale, offset); position = scale·q[coord] + offset.
fn drives(
    g: &Graph,
    active: &[usize],
    opts: &RobotOptions,
    robot: &str,
) -> Result<Vec<(Option<usize>, f64, f64)>> {
    let joints = &g.urdf.joints;
    let mut locked: HashMap<usize, f64> = HashMap::new();
    for (name, value) in &opts.locked_positions {
        let j = g.joint(name, robot)?;
        let bad = |m: &str| FabricError::Value {
            what: format!("locked joint '{name}'"),
            message: m.into(),
        };
        if !is_movable(&joints[j].joint_type) {
            return Err(bad(&not_movable(&joints[j].joint_type)));
        }
        if joints[j].mimic.is_some() {
            return Err(bad("is a mimic joint (lock its source joint)"));
        }
        if active.contains(&j) {
            return Err(bad("is an active joint"));
        }
        if !value.is_finite() {
            return Err(FabricError::NonFinite {
                what: format!("locked position of joint '{name}'"),
            });
        }
        let lim = &joints[j].limit;
        if joints[j].joint_type != JointType::Continuous
            && !(*value >= lim.lower - LOCKED_BOUNDS_TOLERANCE
                && *value <= lim.upper + LOCKED_BOUNDS_TOLERANCE)
        {
            return Err(bad(&format!(
                "position {value} lies outside its limits [{}, {}] by more than {LOCKED_BOUNDS_TOLERANCE} \
                 (the joint cannot be there)",
                lim.lower, lim.upper
            )));
        }
        locked.insert(j, *value);
    }
    let own = |j: usize| -> (Option<usize>, f64, f64) {
        if let Some(c) = active.iter().position(|&a| a == j) {
            return (Some(c), 1.0, 0.0);
        }
        let joint = &joints[j];
        let value = locked
            .get(&j)
            .copied()
            .unwrap_or_else(|| match joint.joint_type {
                JointType::Continuous => 0.0,
                _ if joint.limit.lower <= joint.limit.upper => {
                    0.0_f64.clamp(joint.limit.lower, joint.limit.upper)
                }
                _ => 0.0,
            });
        (None, 1.0, value)
    };
    let mut out = Vec::with_capacity(joints.len());
    for (j, joint) in joints.iter().enumerate() {
        if !is_movable(&joint.joint_type) {
            out.push((None, 1.0, 0.0));
            continue;
        }
        // Follow the mimic chain to a non-mimic source, composing q_m = k·q_src + o.
        let (mut k, mut o, mut cur) = (1.0, 0.0, j);
        let mut seen = std::collections::HashSet::from([j]);
        while let Some(m) = &joints[cur].mimic {
            let src = g
                .joint_index
                .get(m.joint.as_str())
                .copied()
                .ok_or_else(|| {
                    urdf_err(
                        g.source,
                        format!(
                            "joint '{}' mimics unknown joint '{}'",
                            joints[cur].name, m.joint
                        ),
                    )
                })?;
            if !is_movable(&joints[src].joint_type) {
                return Err(urdf_err(
                    g.source,
                    format!(
                        "joint '{}' mimics fixed joint '{}'",
                        joints[cur].name, m.joint
                    ),
                ));
            }
            let (mult, off) = (m.multiplier.unwrap_or(1.0), m.offset.unwrap_or(0.0));
            if !mult.is_finite() || !off.is_finite() {
                return Err(urdf_err(
                    g.source,
                    format!(
                        "joint '{}': mimic multiplier/offset not finite",
                        joints[cur].name
                    ),
                ));
            }
            // q_cur = mult·q_src + off, and q_j = k·q_cur + o.
            o += k * off;
            k *= mult;
            cur = src;
            if !seen.insert(cur) {
                // walk the cycle once from the joint met twice
                let mut names = vec![joints[cur].name.as_str()];
                let mut c = cur;
                while let Some(next) = joints[c]
                    .mimic
                    .as_ref()
                    .and_then(|m| g.joint_index.get(m.joint.as_str()).copied())
                {
                    c = next;
                    names.push(joints[c].name.as_str());
                    if c == cur || names.len() > joints.len() {
                        break;
                    }
                }
                return Err(urdf_err(
                    g.source,
                    format!(
                        "mimic joints form a cycle: {} (each mimics the next; a chain of mimic joints \
                         must end at a joint that mimics none)",
                        names.join(" -> ")
                    ),
                ));
            }
        }
        let (c, s, off) = own(cur);
        out.push((c, k * s, k * off + o));
    }
    Ok(out)
}

/// Position and velocity limits of the active joints, and which of them are continuous.
type Limits = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<bool>);

fn limits(g: &Graph, active: &[usize]) -> Result<Limits> {
    let (mut lo, mut hi, mut vel, mut cont) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for &j in active {
        let joint = &g.urdf.joints[j];
        let lim = &joint.limit;
        let continuous = joint.joint_type == JointType::Continuous;
        let (l, u) = if continuous {
            (-TAU, TAU)
        } else {
            (lim.lower, lim.upper)
        };
        if !(l.is_finite() && u.is_finite() && l < u) {
            return Err(urdf_err(
                g.source,
                format!("joint '{}': position limits [{l}, {u}] are not a finite range (missing <limit>?)", joint.name),
            ));
        }
        let v = if lim.velocity.is_finite() && lim.velocity > 0.0 {
            lim.velocity
        } else if continuous && lim.velocity == 0.0 {
            f64::INFINITY
        } else {
            return Err(urdf_err(
                g.source,
                format!(
                    "joint '{}': velocity limit {} is not > 0",
                    joint.name, lim.velocity
                ),
            ));
        };
        lo.push(l);
        hi.push(u);
        vel.push(v);
        cont.push(continuous);
    }
    Ok((lo, hi, vel, cont))
}

/// Tree joints (indexed by child tree link) from the re-rooted graph and the joint drives.
fn tree_joints(
    g: &Graph,
    t: &Rooted,
    drive: &[(Option<usize>, f64, f64)],
) -> Result<Vec<Option<TreeJoint>>> {
    let mut out = Vec::with_capacity(t.order.len());
    for edge in &t.edge {
        let Some((j, parent, reversed)) = *edge else {
            out.push(None);
            continue;
        };
        let joint = &g.urdf.joints[j];
        let origin = pose_to_iso(&joint.origin, &format!("joint '{}'", joint.name), g.source)?;
        let motion = if is_movable(&joint.joint_type) {
            let a = Vector3::from(joint.axis.xyz.0);
            let norm = a.norm();
            if !(norm.is_finite() && norm > 1e-12) {
                return Err(urdf_err(
                    g.source,
                    format!(
                        "joint '{}': axis {:?} has no direction",
                        joint.name, joint.axis.xyz.0
                    ),
                ));
            }
            let axis = Unit::new_unchecked(if reversed { -a / norm } else { a / norm });
            match joint.joint_type {
                JointType::Prismatic => Motion::Prismatic(axis),
                _ => Motion::Revolute(axis),
            }
        } else {
            Motion::Fixed
        };
        let (coord, scale, offset) = drive[j];
        let (pre, post) = if reversed {
            (Isometry3::identity(), Some(origin.inverse()))
        } else {
            (origin, None)
        };
        let mut tj = TreeJoint {
            movable: motion != Motion::Fixed,
            name: joint.name.clone(),
            parent,
            pre,
            post,
            motion,
            coord,
            scale,
            offset,
        };
        if coord.is_none() && motion != Motion::Fixed {
            // A locked joint is a fixed transform: fold its constant motion into `pre`.
            let rigid = tj.moved_frame(offset);
            tj.pre = tj.post.map_or(rigid, |post| rigid * post);
            tj.post = None;
            tj.motion = Motion::Fixed;
        }
        out.push(Some(tj));
    }
    Ok(out)
}

/// Collision spheres and collision geometry of every link.
fn collisions(
    g: &Graph,
    t: &Rooted,
    mesh_dir: Option<&Path>,
) -> Result<(Vec<CollisionSphere>, Vec<LinkGeometry>)> {
    let (mut spheres, mut geometry) = (Vec::new(), Vec::new());
    for (ti, &ul) in t.order.iter().enumerate() {
        let link = &g.urdf.links[ul];
        for (k, c) in link.collision.iter().enumerate() {
            let what = format!("link '{}' collision {k}", link.name);
            let origin = pose_to_iso(&c.origin, &what, g.source)?;
            let positive = |v: f64| v.is_finite() && v > 0.0;
            let kind = match &c.geometry {
                Geometry::Sphere { radius } if positive(*radius) => {
                    spheres.push(CollisionSphere {
                        link: ti,
                        center: origin.translation.vector,
                        radius: *radius,
                    });
                    GeometryKind::Sphere { radius: *radius }
                }
                Geometry::Box { size } if size.iter().all(|&v| positive(v)) => GeometryKind::Box {
                    size: Vector3::from(size.0),
                },
                Geometry::Cylinder { radius, length } if positive(*radius) && positive(*length) => {
                    GeometryKind::Cylinder {
                        radius: *radius,
                        length: *length,
                    }
                }
                Geometry::Capsule { radius, length }
                    if positive(*radius) && length.is_finite() && *length >= 0.0 =>
                {
                    GeometryKind::Capsule {
                        radius: *radius,
                        length: *length,
                    }
                }
                Geometry::Mesh { filename, scale } => {
                    let scale = scale
                        .map(|s| Vector3::from(s.0))
                        .unwrap_or_else(|| Vector3::repeat(1.0));
                    if scale.iter().any(|v| !v.is_finite()) {
                        return Err(urdf_err(
                            g.source,
                            format!("{what}: mesh scale is not finite"),
                        ));
                    }
                    let (path, exists) = resolve_mesh_path(filename, mesh_dir);
                    GeometryKind::Mesh {
                        path,
                        scale,
                        exists,
                    }
                }
                other => {
                    return Err(urdf_err(
                        g.source,
                        format!("{what}: sizes must be finite and > 0, got {other:?}"),
                    ))
                }
            };
            geometry.push(LinkGeometry {
                link: ti,
                origin,
                kind,
            });
        }
    }
    Ok((spheres, geometry))
}

fn build(xml: &str, source: &str, opts: &RobotOptions, mesh_dir: Option<&Path>) -> Result<Robot> {
    crate::limits::check_xml(xml).map_err(|m| urdf_err(source, m))?;
    let urdf = urdf_rs::read_from_string(xml).map_err(|e| {
        let parser = e.to_string();
        match crate::limits::xml_truncation(xml) {
            Some(why) => urdf_err(source, format!("{why} (parser: {parser})")),
            None => urdf_err(source, parser),
        }
    })?;
    let g = Graph::new(&urdf, source)?;
    let name = urdf.name.clone();
    let find_link = |l: &Option<String>, default: usize| -> Result<usize> {
        match l {
            None => Ok(default),
            Some(n) => {
                g.link_index
                    .get(n.as_str())
                    .copied()
                    .ok_or_else(|| FabricError::MissingLink {
                        robot: name.clone(),
                        link: n.clone(),
                    })
            }
        }
    };
    let base = find_link(&opts.base_link, g.root())?;
    let t = reroot(&g, base);
    let mut tree_of = vec![0; t.order.len()];
    for (ti, &ul) in t.order.iter().enumerate() {
        tree_of[ul] = ti;
    }
    let explicit_active = match &opts.active_joints {
        Some(names) => Some(
            names
                .iter()
                .map(|n| g.joint(n, &name))
                .collect::<Result<Vec<_>>>()?,
        ),
        None => None,
    };
    let ee = match &opts.ee_link {
        Some(_) => tree_of[find_link(&opts.ee_link, base)?],
        None => default_ee(&g, &t, explicit_active.as_deref()),
    };
    let active = choose_active(&g, &t, ee, opts, &name)?;
    let drive = drives(&g, &active, opts, &name)?;
    let (lower, upper, velocity_limits, continuous) = limits(&g, &active)?;
    let joints = tree_joints(&g, &t, &drive)?;
    let (spheres, geometry) = collisions(&g, &t, mesh_dir)?;
    let locked = g
        .urdf
        .joints
        .iter()
        .zip(&drive)
        .filter(|(j, d)| is_movable(&j.joint_type) && j.mimic.is_none() && d.0.is_none())
        .map(|(j, d)| (j.name.clone(), d.2))
        .collect();

    let n = t.order.len();
    let (mut bodies, mut cols) = (vec![0; n], vec![0; n]);
    for i in 1..n {
        if let Some(j) = &joints[i] {
            (bodies[i], cols[i]) = match (j.coord, j.motion) {
                (Some(c), Motion::Revolute(_) | Motion::Prismatic(_)) => {
                    (i, cols[j.parent].max(c + 1))
                }
                _ => (bodies[j.parent], cols[j.parent]),
            };
        }
    }
    let mut robot = Robot {
        name,
        source: source.to_string(),
        link_names: t
            .order
            .iter()
            .map(|&l| urdf.links[l].name.clone())
            .collect(),
        joints,
        bodies,
        cols,
        ee,
        joint_names: active
            .iter()
            .map(|&j| urdf.joints[j].name.clone())
            .collect(),
        lower,
        upper,
        velocity_limits,
        continuous,
        spheres,
        disabled: Vec::new(),
        srdf: false,
        self_pairs: Vec::new(),
        geometry,
        locked,
        origin: Arc::new(UrdfOrigin {
            xml: xml.to_string(),
            opts: opts.clone(),
            mesh_dir: mesh_dir.map(Path::to_path_buf),
        }),
    };
    robot.recompute_self_pairs();
    Ok(robot)
}

impl Robot {
    /// The inactive movable joints (not mimic joints) and the position each is held at (rad or m): the
    /// `locked_positions` of [`RobotOptions`], else 0 clamped into the joint's limits.
    pub fn locked_positions(&self) -> &[(String, f64)] {
        &self.locked
    }

    /// A copy with some inactive joints held elsewhere (e.g. a gripper opened as a planning request's start
    /// state says): rebuilt from the same URDF and options, keeping this model's collision spheres,
    /// SRDF-disabled link pairs and self-collision pairs. A position may lie outside the joint's URDF
    /// limits by up to [`LOCKED_BOUNDS_TOLERANCE`] (continuous joints: anywhere). Errors: those of
    /// [`Robot::from_urdf_str`] for a joint that is unknown, active, fixed or a mimic joint, a position
    /// that is not finite (`NonFinite`), or one further outside the limits (`Value` naming the joint).
    pub fn with_locked_positions(&self, positions: &[(String, f64)]) -> Result<Robot> {
        let mut opts = self.origin.opts.clone();
        for (name, value) in positions {
            opts.locked_positions.retain(|(n, _)| n != name);
            opts.locked_positions.push((name.clone(), *value));
        }
        let mut robot = build(
            &self.origin.xml,
            &self.source,
            &opts,
            self.origin.mesh_dir.as_deref(),
        )?;
        robot.spheres = self.spheres.clone();
        robot.disabled = self.disabled.clone();
        robot.srdf = self.srdf;
        robot.self_pairs = self.self_pairs.clone();
        Ok(robot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CHAIN: &str = r#"<robot name="chain">
      <link name="a"/><link name="b"/><link name="c"/>
      <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 0.1"/>
        <axis xyz="0 0 2"/><limit lower="-1" upper="1" velocity="1"/></joint>
      <joint name="j2" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.2 0 0"/>
        <axis xyz="1 0 0"/><limit lower="0.3" upper="1" velocity="1"/></joint>
    </robot>"#;

    #[test]
    fn locked_joints_fold_into_fixed_transforms() {
        let opts = RobotOptions {
            active_joints: Some(vec!["j1".into()]),
            ..Default::default()
        };
        let robot = Robot::from_urdf_str(CHAIN, "chain", &opts).unwrap();
        let j1 = robot.joints[1].as_ref().unwrap();
        assert_eq!(j1.motion, Motion::Revolute(Vector3::z_axis())); // axis normalised
        let j2 = robot.joints[2].as_ref().unwrap();
        assert_eq!((j2.motion, j2.coord), (Motion::Fixed, None));
        // Locked at 0 clamped into [0.3, 1]: a rotation of 0.3 rad about x after the origin.
        let expect = Isometry3::from_parts(
            Translation3::new(0.2, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.3),
        );
        assert!((j2.pre.to_homogeneous() - expect.to_homogeneous()).norm() < 1e-15);
        assert_eq!(robot.bodies, [0, 1, 1]);
        // Link 2 moves with j1 only: its origin turns about z through (0, 0, 0.1) at radius 0.2.
        let mut ws = crate::robot::KinematicsWorkspace::new(&robot);
        robot.update_positions(&[0.4], &mut ws).unwrap();
        let mut tp = crate::robot::TaskPoint::new(1);
        robot.point(&ws, 2, &Vector3::zeros(), &mut tp);
        let (s, c) = 0.4_f64.sin_cos();
        assert!((tp.x - Vector3::new(0.2 * c, 0.2 * s, 0.1)).norm() < 1e-15);
        assert!((tp.jac.column(0) - Vector3::new(-0.2 * s, 0.2 * c, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn a_joint_of_zero_range_is_held_at_its_one_position() {
        // j2: limits 0.3 and 0.3 (a wheel written as a revolute joint without lower/upper reads [0, 0])
        let xml = CHAIN.replace(r#"lower="0.3" upper="1""#, r#"lower="0.3" upper="0.3""#);
        let robot = Robot::from_urdf_str(&xml, "chain", &RobotOptions::default()).unwrap();
        assert_eq!(robot.joint_names(), ["j1"]);
        assert_eq!(robot.locked_positions(), [("j2".to_string(), 0.3)]);
        let opts = RobotOptions {
            active_joints: Some(vec!["j1".into(), "j2".into()]),
            ..Default::default()
        };
        let err = Robot::from_urdf_str(&xml, "chain", &opts)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("active joint 'j2'") && err.contains("[0.3, 0.3], a zero range"),
            "{err}"
        );
    }

    #[test]
    fn relocking_moves_the_held_joint_and_keeps_spheres_and_pairs() {
        let opts = RobotOptions {
            active_joints: Some(vec!["j1".into()]),
            ..Default::default()
        };
        let mut robot = Robot::from_urdf_str(CHAIN, "chain", &opts).unwrap();
        robot
            .set_spheres(vec![
                CollisionSphere {
                    link: 0,
                    center: Vector3::zeros(),
                    radius: 0.05,
                },
                CollisionSphere {
                    link: 2,
                    center: Vector3::new(0.0, 0.1, 0.0),
                    radius: 0.05,
                },
            ])
            .unwrap();
        assert_eq!(robot.locked_positions(), [("j2".to_string(), 0.3)]);
        // Outside j2's limits [0.3, 1] within the tolerance: held where asked.
        let moved = robot.with_locked_positions(&[("j2".into(), 1.04)]).unwrap();
        assert_eq!(moved.locked_positions(), [("j2".to_string(), 1.04)]);
        assert_eq!(
            (moved.spheres(), moved.self_collision_pairs()),
            (robot.spheres(), robot.self_collision_pairs())
        );
        let expect = Isometry3::from_parts(
            Translation3::new(0.2, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1.04),
        );
        let j2 = moved.joints[2].as_ref().unwrap();
        assert!((j2.pre.to_homogeneous() - expect.to_homogeneous()).norm() < 1e-15);
        assert!(robot.with_locked_positions(&[("j1".into(), 0.1)]).is_err()); // active
        assert!(robot.with_locked_positions(&[("j3".into(), 0.1)]).is_err()); // unknown
        assert!(robot
            .with_locked_positions(&[("j2".into(), f64::NAN)])
            .is_err());
    }

    #[test]
    fn reversed_joints_swap_origin_and_negate_axis() {
        let opts = RobotOptions {
            base_link: Some("c".into()),
            ee_link: Some("a".into()),
            ..Default::default()
        };
        let robot = Robot::from_urdf_str(CHAIN, "chain", &opts).unwrap();
        assert_eq!(robot.link_names(), ["c", "b", "a"]);
        assert_eq!(robot.joint_names(), ["j2", "j1"]);
        let j = robot.joints[1].as_ref().unwrap();
        assert_eq!(j.motion, Motion::Revolute(-Vector3::x_axis()));
        assert_eq!(j.pre, Isometry3::identity());
        assert_eq!(j.post, Some(Isometry3::translation(-0.2, 0.0, 0.0)));
    }
}
