//! The immutable robot model: a kinematic tree rooted at the base link, its active coordinates q, their
//! limits, the collision spheres and the self-collision pairs.
//!
//! Links are stored in depth-first pre-order from the base link (index 0), so a link's parent always has a
//! smaller index. Each non-base link `i` owns the joint that connects it to its parent (`joints[i]`).
//! When the chosen base link is not the URDF root, the joints on the path from the root to the base are
//! reversed (see [`TreeJoint::post`]), so every link of the URDF still gets a pose.

use std::path::PathBuf;

use nalgebra::{Isometry3, Unit, UnitQuaternion, Vector3};

use super::geometry::LinkGeometry;
use super::spheres::CollisionSphere;
use crate::error::{FabricError, Result};

/// Options for building a [`Robot`] from a URDF. `Default` leaves every choice to the model.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RobotOptions {
    /// Link whose frame is the world frame of the model. Default: the URDF root link.
    pub base_link: Option<String>,
    /// End-effector link. Default: walking from the base, follow the only child, or the only child
    /// subtree that holds a movable joint, or, where several do, the longest arm among them (at least three
    /// joints that move on their own, at least a quarter as long as the path to the branching link: an arm
    /// beside wheels or a head, not a hand's fingers; the first of two equal arms), and stop at a leaf or
    /// at a branching point (for the Panda with its two finger
    /// joints, and for the MotionBenchMaker Panda: `panda_hand`). When `active_joints` is
    /// given, the walk starts at the child link of the deepest active joint and only follows single fixed
    /// children.
    pub ee_link: Option<String>,
    /// Active joints, in the order of q. Default: every revolute, continuous or prismatic joint that is not
    /// a mimic joint, on the path from the base link to the end-effector link, in chain order.
    pub active_joints: Option<Vec<String>>,
    /// Directory `dir` that resolves mesh file names (default: the directory of the URDF file; the
    /// current directory for a URDF string). `package://pkg/rest` tries `dir/pkg/rest`, `dir/rest` and
    /// `dir/../rest`; `file://path` and plain relative names are taken relative to `dir`. The first
    /// existing file wins; a missing file is not an error (the first candidate is kept, flagged).
    pub mesh_dir: Option<PathBuf>,
    /// Positions (rad or m) of inactive movable joints. Joints not listed are locked at 0 clamped into
    /// their limits. Naming an active, fixed or mimic joint is an error.
    pub locked_positions: Vec<(String, f64)>,
}

/// Motion of a joint about or along its unit axis, expressed in the joint frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Motion {
    /// No motion (fixed joints).
    Fixed,
    /// Rotation by the joint position (rad) about the unit axis (right-hand rule).
    Revolute(Unit<Vector3<f64>>),
    /// Translation by the joint position (m) along the unit axis.
    Prismatic(Unit<Vector3<f64>>),
}

/// One edge of the kinematic tree: `T_child = T_parent · pre · motion(θ) · post`, with the joint
/// position `θ = scale · q[coord] + offset`. Joints not driven by q (locked joints and mimics of locked
/// joints) are stored as `Motion::Fixed` with their constant motion folded into `pre`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TreeJoint {
    /// URDF joint name.
    pub name: String,
    /// Parent link index (always smaller than the child index).
    pub parent: usize,
    /// Parent link frame → joint frame (the URDF `<origin>`; identity for reversed joints).
    pub pre: Isometry3<f64>,
    /// Joint frame after the motion → child link frame: `Some(origin⁻¹)` for a joint reversed because the
    /// base is not the URDF root, `None` otherwise.
    pub post: Option<Isometry3<f64>>,
    /// Motion type and axis (negated for reversed joints).
    pub motion: Motion,
    /// Active coordinate driving the joint (`None`: locked).
    pub coord: Option<usize>,
    /// Mimic multiplier (1 for a plain active joint).
    pub scale: f64,
    /// Constant position part: the mimic offset, or the locked position.
    pub offset: f64,
    /// Whether the URDF joint moves (revolute, continuous, prismatic), locked or not: a locked joint is
    /// `Motion::Fixed` here, yet its two links are different bodies of the whole robot.
    pub movable: bool,
}

impl TreeJoint {
    /// Joint position θ (rad or m) for the coordinates q.
    #[inline]
    pub fn position(&self, q: &[f64]) -> f64 {
        match self.coord {
            Some(c) => self.scale * q[c] + self.offset,
            None => self.offset,
        }
    }

    /// Joint velocity θ̇ for the coordinate velocities q̇.
    #[inline]
    pub fn velocity(&self, qd: &[f64]) -> f64 {
        match self.coord {
            Some(c) => self.scale * qd[c],
            None => 0.0,
        }
    }

    /// The transform `pre · motion(θ)` (parent link frame → joint frame after the motion).
    #[inline]
    pub fn moved_frame(&self, theta: f64) -> Isometry3<f64> {
        let (rotation, translation) = self.moved_parts(theta);
        Isometry3::from_parts(translation.into(), rotation)
    }

    /// [`moved_frame`](Self::moved_frame) as (rotation, translation): always inlined, so that
    /// `Robot::update` keeps the parts in registers instead of reading back an isometry returned
    /// through memory.
    #[inline(always)]
    pub(crate) fn moved_parts(&self, theta: f64) -> (UnitQuaternion<f64>, Vector3<f64>) {
        let (rotation, translation) = (self.pre.rotation, self.pre.translation.vector);
        match self.motion {
            Motion::Fixed => (rotation, translation),
            Motion::Revolute(axis) => (
                rotation * UnitQuaternion::from_axis_angle(&axis, theta),
                translation,
            ),
            Motion::Prismatic(axis) => (
                rotation,
                translation + rotation * (axis.into_inner() * theta),
            ),
        }
    }
}

/// An immutable robot model: kinematic tree, active coordinates and limits, collision spheres and
/// self-collision pairs. `Send + Sync + Clone`; evaluate it with a
/// [`KinematicsWorkspace`](super::KinematicsWorkspace) per thread.
#[derive(Clone, Debug)]
pub struct Robot {
    pub(crate) name: String,
    /// File name or `"<string>"`, for error messages.
    pub(crate) source: String,
    pub(crate) link_names: Vec<String>,
    /// `joints[i]` connects link `i` to its parent; `None` only for the base link (index 0).
    pub(crate) joints: Vec<Option<TreeJoint>>,
    /// Rigid body of each link: links joined by fixed or locked joints share a body index.
    pub(crate) bodies: Vec<usize>,
    /// Per link: the number of leading Jacobian columns that may be non-zero for a point on it (one
    /// more than the largest coordinate driving a joint between it and the base; 0 on the base body).
    pub(crate) cols: Vec<usize>,
    pub(crate) ee: usize,
    pub(crate) joint_names: Vec<String>,
    pub(crate) lower: Vec<f64>,
    pub(crate) upper: Vec<f64>,
    pub(crate) velocity_limits: Vec<f64>,
    /// Per active joint: a URDF `continuous` joint (its [`Robot::lower`] / [`Robot::upper`] of ∓2π are a
    /// sampling range, not limits).
    pub(crate) continuous: Vec<bool>,
    pub(crate) spheres: Vec<CollisionSphere>,
    /// Link pairs (i < j) whose collisions are disabled by an SRDF.
    pub(crate) disabled: Vec<(usize, usize)>,
    /// Whether an SRDF was loaded ([`Robot::has_srdf`]).
    pub(crate) srdf: bool,
    pub(crate) self_pairs: Vec<(usize, usize)>,
    pub(crate) geometry: Vec<LinkGeometry>,
    /// Inactive movable joints that are not mimic joints, with the position each is held at (rad or m).
    pub(crate) locked: Vec<(String, f64)>,
    /// The URDF text and build options, to rebuild the model with other locked positions.
    pub(crate) origin: std::sync::Arc<UrdfOrigin>,
}

/// What a [`Robot`] was built from (see [`Robot::with_locked_positions`]).
#[derive(Debug)]
pub(crate) struct UrdfOrigin {
    pub(crate) xml: String,
    pub(crate) opts: RobotOptions,
    pub(crate) mesh_dir: Option<PathBuf>,
}

impl Robot {
    /// Robot name (the URDF `<robot name>`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Where the model came from (the URDF file name, or the `source` given with a URDF string).
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Number of active coordinates (length of q).
    pub fn dof(&self) -> usize {
        self.joint_names.len()
    }

    /// Names of the active joints, in the order of q.
    pub fn joint_names(&self) -> &[String] {
        &self.joint_names
    }

    /// Index in q of an active joint. Errors with `MissingJoint` when the joint is not active.
    pub fn joint_index(&self, name: &str) -> Result<usize> {
        self.joint_names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| FabricError::MissingJoint {
                robot: self.name.clone(),
                joint: name.to_string(),
            })
    }

    /// Lower position limits of the active joints, shape (dof,), rad or m. Continuous joints: -2π (a
    /// full turn each way keeps every angle reachable without wrapping, and stays finite for the
    /// joint-limit fabric terms).
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }

    /// Upper position limits of the active joints, shape (dof,), rad or m. Continuous joints: +2π.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }

    /// Velocity limits of the active joints, shape (dof,), rad/s or m/s (the URDF `<limit velocity>`;
    /// `f64::INFINITY` for a continuous joint without one).
    pub fn velocity_limits(&self) -> &[f64] {
        &self.velocity_limits
    }

    /// Per active joint, shape (dof,): whether it is a URDF `continuous` joint (no position limits; its
    /// ∓2π range is a sampling range). A revolute joint whose limits happen to be ∓2π is not.
    pub fn continuous(&self) -> &[bool] {
        &self.continuous
    }

    /// Every link name, indexed by link index (depth-first order from the base link, index 0).
    pub fn link_names(&self) -> &[String] {
        &self.link_names
    }

    /// `Err(Value)` naming `what` unless `link` is a link index of this robot.
    pub(crate) fn check_link_index(&self, link: usize, what: &str) -> Result<()> {
        let links = self.link_names.len();
        if link < links {
            return Ok(());
        }
        Err(FabricError::Value {
            what: what.to_string(),
            message: format!("link index {link} out of range (robot has {links} links)"),
        })
    }

    /// Index of a link by name. Errors with `MissingLink`.
    pub fn link_index(&self, name: &str) -> Result<usize> {
        self.link_names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| FabricError::MissingLink {
                robot: self.name.clone(),
                link: name.to_string(),
            })
    }

    /// Parent link index of `link` (`None` for the base link or an index out of range).
    pub fn link_parent(&self, link: usize) -> Option<usize> {
        self.joints
            .get(link)
            .and_then(|j| j.as_ref())
            .map(|j| j.parent)
    }

    /// Index of the end-effector link.
    pub fn ee_link(&self) -> usize {
        self.ee
    }

    /// Index of the base link: always 0. Its frame is the world frame of every pose.
    pub fn base_link(&self) -> usize {
        0
    }

    /// Rigid-body label of each link, shape (L,): links joined by fixed joints or by locked joints
    /// (inactive, not driven by q) share a label, the smallest link index of the body.
    pub fn rigid_bodies(&self) -> &[usize] {
        &self.bodies
    }

    /// Link pairs `(i, j)`, `i < j`, whose collisions were disabled by the last SRDF (see
    /// [`Robot::set_self_collision_from_srdf`]).
    pub fn disabled_collisions(&self) -> &[(usize, usize)] {
        &self.disabled
    }

    /// Whether an SRDF was loaded ([`Robot::set_self_collision_from_srdf`]): its `<disable_collisions>`
    /// then list every link pair MoveIt skips, adjacent links included.
    pub fn has_srdf(&self) -> bool {
        self.srdf
    }

    /// Collision spheres (centres in their link frames, m).
    pub fn spheres(&self) -> &[CollisionSphere] {
        &self.spheres
    }

    /// Sphere index pairs `(i, j)`, `i < j`, checked for self-collision: spheres on different rigid
    /// bodies that are not adjacent (joined by one movable joint) and whose links are not disabled by an
    /// SRDF.
    pub fn self_collision_pairs(&self) -> &[(usize, usize)] {
        &self.self_pairs
    }

    /// URDF `<collision>` elements (every geometry, spheres included): for mesh-based validation.
    pub fn collision_geometry(&self) -> &[LinkGeometry] {
        &self.geometry
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Translation3};

    fn joint(motion: Motion, coord: Option<usize>, scale: f64, offset: f64) -> TreeJoint {
        TreeJoint {
            name: "j".into(),
            parent: 0,
            pre: Isometry3::from_parts(
                Translation3::new(0.1, -0.2, 0.3),
                UnitQuaternion::from_euler_angles(0.4, 0.0, 0.0),
            ),
            post: None,
            motion,
            coord,
            scale,
            offset,
            movable: true,
        }
    }

    #[test]
    fn mimic_position_and_velocity() {
        let j = joint(Motion::Fixed, Some(1), -2.0, 0.5);
        assert_eq!(j.position(&[9.0, 0.25]), 0.0);
        assert_eq!(j.velocity(&[9.0, 3.0]), -6.0);
        let locked = joint(Motion::Fixed, None, 1.0, 0.7);
        assert_eq!(locked.position(&[1.0]), 0.7);
        assert_eq!(locked.velocity(&[1.0]), 0.0);
    }

    #[test]
    fn moved_frame_closed_forms() {
        let (c, s) = (0.9_f64.cos(), 0.9_f64.sin());
        let rz = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
        let rev = joint(Motion::Revolute(Vector3::z_axis()), Some(0), 1.0, 0.0);
        let f = rev.moved_frame(0.9);
        let pre = rev.pre.rotation.to_rotation_matrix().into_inner();
        assert!((f.rotation.to_rotation_matrix().into_inner() - pre * rz).norm() < 1e-14);
        assert_eq!(f.translation, rev.pre.translation);
        // Prismatic: the origin moves by θ along the axis expressed in the parent frame.
        let pri = joint(Motion::Prismatic(Vector3::y_axis()), Some(0), 1.0, 0.0);
        let f = pri.moved_frame(0.05);
        let expect = rev.pre.translation.vector + pre * Vector3::new(0.0, 0.05, 0.0);
        assert!((f.translation.vector - expect).norm() < 1e-15);
        assert_eq!(f.rotation, pri.pre.rotation);
    }
}
