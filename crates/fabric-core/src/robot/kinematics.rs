//! Recursive forward kinematics, link velocities and velocity-product ("bias") accelerations, and the
//! task-space quantities (x, ẋ = J q̇, J, J̇ q̇) of points and directions fixed on links.
//!
//! These are the ingredients of the pullback of a fabric component through a task map x = φ(q)
//! (GF eq. 11–12 and 16): `M_q = JᵀMJ`, `f_q = Jᵀ(f + M J̇q̇)`. All vectors are in the world frame, which
//! is the base link frame. `J̇q̇` is `d/dt (J(q + t q̇)) q̇` at t = 0, i.e. the task acceleration ẍ for q̈ = 0.
//!
//! Recursion (parent p, joint of unit world axis a, position θ and rate θ̇, child c), with ω angular
//! velocity, v origin velocity, α and a_b the bias angular and linear accelerations (q̈ = 0):
//! * revolute: ω_c = ω_p + a θ̇, α_c = α_p + ω_p × (a θ̇);
//! * prismatic: ω_c = ω_p, α_c = α_p, and the joint origin gains a θ̇ in velocity and 2 ω_p × (a θ̇)
//!   (Coriolis) in acceleration;
//! * a point rigidly attached at offset r from a moving origin: v = v_o + ω × r,
//!   a_b = a_b,o + α × r + ω × (ω × r).
//!
//! No function here allocates once the workspace exists.

use nalgebra::{Isometry3, Matrix3, Matrix3xX, UnitQuaternion, Vector3};

use super::model::{Motion, Robot};
use crate::error::{check_finite, check_len, FabricError, Result};
use crate::linalg::rotate;

/// Kinematic quantities of one task point or one task axis, in the world (base) frame:
/// `x` (m, or unitless for an axis), `xd = J q̇`, `jac = ∂x/∂q` (3 × dof), `jdot_qdot = J̇ q̇`.
/// Create it with the robot's dof; [`Robot::point`] and [`Robot::axis`] resize a Jacobian of another
/// width (allocating only then).
#[derive(Clone, Debug, PartialEq)]
pub struct TaskPoint {
    /// Position (m) of the point, or the world direction of the axis.
    pub x: Vector3<f64>,
    /// Velocity ẋ = J q̇ (m/s, or 1/s for an axis).
    pub xd: Vector3<f64>,
    /// Jacobian J = ∂x/∂q, shape 3 × dof (columns in q order).
    pub jac: Matrix3xX<f64>,
    /// Velocity-product term J̇ q̇ (m/s², or 1/s² for an axis).
    pub jdot_qdot: Vector3<f64>,
    /// Number of leading columns of `jac` that may be non-zero: the columns from `width` on are zero
    /// (coordinates that do not move the point: [`Robot::point`] and [`Robot::axis`] set it from the
    /// link's chain; dof when unknown).
    pub width: usize,
}

impl TaskPoint {
    /// A zeroed task point for a robot with `dof` coordinates.
    pub fn new(dof: usize) -> Self {
        TaskPoint {
            x: Vector3::zeros(),
            xd: Vector3::zeros(),
            jac: Matrix3xX::zeros(dof),
            jdot_qdot: Vector3::zeros(),
            width: dof,
        }
    }
}

/// Per-thread scratch for one robot: every link's pose and motion after [`Robot::update`].
/// Create it once with [`KinematicsWorkspace::new`]; it is reused without allocation.
#[derive(Clone, Debug)]
pub struct KinematicsWorkspace {
    /// Number of active coordinates (columns of the per-link Jacobian terms below).
    dof: usize,
    /// World pose of each link.
    pose: Vec<Isometry3<f64>>,
    /// World rotation matrix of each link (same as `pose`, cached for fast point transforms).
    rot: Vec<Matrix3<f64>>,
    /// Angular velocity ω (rad/s) of each link.
    omega: Vec<Vector3<f64>>,
    /// Velocity (m/s) of each link origin.
    vel: Vec<Vector3<f64>>,
    /// Bias angular acceleration α_b (rad/s², q̈ = 0) of each link.
    alpha: Vec<Vector3<f64>>,
    /// Bias linear acceleration a_b (m/s², q̈ = 0) of each link origin.
    acc: Vec<Vector3<f64>>,
    /// Angular Jacobian of each rigid body (see [`Robot::rigid_bodies`]), `dof` columns stored at the
    /// body's label link `b` (entry `b · dof + c`; entries of other links are unused; only the first
    /// `Robot::cols[b]` columns are maintained, the others are zero), unitless: the
    /// sum of `scale · a` (a the unit world axis, scale the mimic multiplier) over the revolute joints
    /// driven by coordinate `c` on the path from the base, so that ω = Σ_c `jw_c` q̇_c.
    jw: Vec<Vector3<f64>>,
    /// Jacobian "moments" of each rigid body (m), laid out as `jw`: the sum of `scale · a × o` (o a
    /// world point on the joint axis) over the same revolute joints, minus the sum of `scale · a` over
    /// the prismatic ones. Column `c` of the Jacobian of a world point x fixed on the body is
    /// `jw_c × x − jm_c`.
    jm: Vec<Vector3<f64>>,
    /// Each joint's transform `pre · motion(θ)` as (rotation, translation), computed for all joints before
    /// the pass down the tree: their sines and cosines do not depend on the parents, and computed out of
    /// the chain of parent-to-child products they do not hold it up (the same values bit for bit).
    local: Vec<(UnitQuaternion<f64>, Vector3<f64>)>,
}

impl KinematicsWorkspace {
    /// Scratch sized for `robot` (one entry per link, `dof` Jacobian terms per link).
    pub fn new(robot: &Robot) -> Self {
        let n = robot.link_names.len();
        let dof = robot.dof();
        KinematicsWorkspace {
            dof,
            pose: vec![Isometry3::identity(); n],
            rot: vec![Matrix3::identity(); n],
            omega: vec![Vector3::zeros(); n],
            vel: vec![Vector3::zeros(); n],
            alpha: vec![Vector3::zeros(); n],
            acc: vec![Vector3::zeros(); n],
            jw: vec![Vector3::zeros(); n * dof],
            jm: vec![Vector3::zeros(); n * dof],
            local: vec![(UnitQuaternion::identity(), Vector3::zeros()); n],
        }
    }
}

/// `a × x − m`, written out in the order of nalgebra's `cross`.
#[inline(always)]
fn cross_minus(a: &Vector3<f64>, x: &Vector3<f64>, m: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        a.y * x.z - a.z * x.y - m.x,
        a.z * x.x - a.x * x.z - m.y,
        a.x * x.y - a.y * x.x - m.z,
    )
}

/// The Jacobian storage of `out`, resized to 3 × dof first when needed (allocates only then).
#[inline]
fn jacobian_of_width(out: &mut TaskPoint, dof: usize) -> &mut [f64] {
    if out.jac.ncols() != dof {
        out.jac = Matrix3xX::zeros(dof);
    }
    out.jac.as_mut_slice()
}

impl Robot {
    fn check_state(&self, q: &[f64], qd: Option<&[f64]>, ws: &KinematicsWorkspace) -> Result<()> {
        check_len("q", q.len(), self.dof())?;
        check_finite("q", q)?;
        if let Some(qd) = qd {
            check_len("qd", qd.len(), self.dof())?;
            check_finite("qd", qd)?;
        }
        if ws.pose.len() != self.link_names.len() || ws.dof != self.dof() {
            return Err(FabricError::Shape {
                what: "kinematics workspace (links, dof)".into(),
                expected: format!("({}, {})", self.link_names.len(), self.dof()),
                got: format!("({}, {})", ws.pose.len(), ws.dof),
            });
        }
        Ok(())
    }

    /// Forward kinematics, link velocities and bias accelerations for q (dof,) in rad or m and q̇ (dof,)
    /// in rad/s or m/s. Errors: `Shape` (wrong lengths, or a workspace of another robot), `NonFinite`.
    pub fn update(&self, q: &[f64], qd: &[f64], ws: &mut KinematicsWorkspace) -> Result<()> {
        self.check_state(q, Some(qd), ws)?;
        self.propagate::<true>(q, qd, ws);
        Ok(())
    }

    /// Forward kinematics only (q̇ = 0: velocities and bias accelerations are set to zero). Errors as
    /// [`Robot::update`].
    pub fn update_positions(&self, q: &[f64], ws: &mut KinematicsWorkspace) -> Result<()> {
        self.check_state(q, None, ws)?;
        self.forward_positions(q, ws);
        Ok(())
    }

    /// Forward kinematics only, without the checks of [`Robot::update_positions`], for callers that
    /// checked q (length dof, finite) and sized `ws` for this robot themselves.
    pub(super) fn forward_positions(&self, q: &[f64], ws: &mut KinematicsWorkspace) {
        self.propagate::<false>(q, q, ws);
    }

    fn propagate<const VEL: bool>(&self, q: &[f64], qd: &[f64], ws: &mut KinematicsWorkspace) {
        let dof = ws.dof;
        for (slot, joint) in ws.local.iter_mut().zip(&self.joints) {
            if let Some(j) = joint {
                *slot = j.moved_parts(j.position(q));
            }
        }
        for (i, joint) in self.joints.iter().enumerate() {
            let Some(j) = joint else {
                ws.pose[i] = Isometry3::identity();
                ws.rot[i] = Matrix3::identity();
                ws.omega[i] = Vector3::zeros();
                ws.vel[i] = Vector3::zeros();
                ws.alpha[i] = Vector3::zeros();
                ws.acc[i] = Vector3::zeros();
                continue;
            };
            let p = j.parent;
            let (parent_rot, parent_q) = (ws.rot[p], ws.pose[p].rotation);
            let parent_o = ws.pose[p].translation.vector;
            // Joint frame after the motion (its origin lies on the joint axis); offsets are rotated
            // with the parent's rotation matrix, which is cheaper than with its quaternion.
            let (local_q, local_o) = ws.local[i];
            let frame_q = parent_q * local_q;
            let frame_rot = *frame_q.to_rotation_matrix().matrix();
            let frame_o = parent_o + rotate(&parent_rot, &local_o);
            let (child_q, child_rot, child_o) = match &j.post {
                Some(post) => {
                    let q = frame_q * post.rotation;
                    let o = frame_o + rotate(&frame_rot, &post.translation.vector);
                    (q, *q.to_rotation_matrix().matrix(), o)
                }
                None => (frame_q, frame_rot, frame_o),
            };
            let axis = match j.motion {
                Motion::Fixed => Vector3::zeros(),
                // The rotation about a (revolute) or the translation (prismatic) leaves a unchanged.
                Motion::Revolute(a) | Motion::Prismatic(a) => rotate(&frame_rot, &a),
            };
            ws.pose[i] = Isometry3::from_parts(child_o.into(), child_q);
            ws.rot[i] = child_rot;
            // Jacobian terms of a body: those of the parent's body, zero up to this joint's column,
            // plus this joint's column (links on the same rigid body share them). One pass, without
            // library copies (the runs are a few columns long).
            if let (Some(c), true) = (j.coord, self.bodies[i] == i) {
                let (pb, np, n) = (self.bodies[p] * dof, self.cols[p], self.cols[i]);
                let scaled = axis * j.scale;
                // The parent body's block lies before this one (pb <= p < i).
                let (parent_w, own_w) = ws.jw.split_at_mut(i * dof);
                let (parent_m, own_m) = ws.jm.split_at_mut(i * dof);
                let (parent_w, parent_m) = (&parent_w[pb..pb + np], &parent_m[pb..pb + np]);
                for (k, (w, m)) in own_w[..n].iter_mut().zip(&mut own_m[..n]).enumerate() {
                    (*w, *m) = match (parent_w.get(k), parent_m.get(k)) {
                        (Some(&pw), Some(&pm)) => (pw, pm),
                        _ => (Vector3::zeros(), Vector3::zeros()),
                    };
                    if k == c {
                        match j.motion {
                            Motion::Revolute(_) => {
                                *w += scaled;
                                *m += scaled.cross(&frame_o);
                            }
                            Motion::Prismatic(_) => *m -= scaled,
                            Motion::Fixed => {}
                        }
                    }
                }
            }
            if !VEL {
                ws.omega[i] = Vector3::zeros();
                ws.vel[i] = Vector3::zeros();
                ws.alpha[i] = Vector3::zeros();
                ws.acc[i] = Vector3::zeros();
                continue;
            }
            let rate = axis * j.velocity(qd);
            let (wp, ap) = (ws.omega[p], ws.alpha[p]);
            // Joint-frame origin as a point of the parent body...
            let r = frame_o - parent_o;
            let mut v = ws.vel[p] + wp.cross(&r);
            let mut acc = ws.acc[p] + ap.cross(&r) + wp.cross(&wp.cross(&r));
            let (mut w, mut al) = (wp, ap);
            match j.motion {
                Motion::Revolute(_) => {
                    w += rate;
                    al += wp.cross(&rate);
                }
                Motion::Prismatic(_) => {
                    // ... plus its sliding along the axis and the Coriolis term.
                    v += rate;
                    acc += 2.0 * wp.cross(&rate);
                }
                Motion::Fixed => {}
            }
            if j.post.is_some() {
                // Child origin as a point of the child body.
                let s = child_o - frame_o;
                v += w.cross(&s);
                acc += al.cross(&s) + w.cross(&w.cross(&s));
            }
            ws.omega[i] = w;
            ws.vel[i] = v;
            ws.alpha[i] = al;
            ws.acc[i] = acc;
        }
    }

    /// World pose of `link` after the last update (world = base link frame).
    ///
    /// # Panics
    /// When `link` is not a valid link index (use [`Robot::link_index`]) or `ws` belongs to another robot.
    pub fn link_pose<'a>(&self, ws: &'a KinematicsWorkspace, link: usize) -> &'a Isometry3<f64> {
        &ws.pose[link]
    }

    /// Angular velocity ω (rad/s) and origin velocity (m/s) of `link`, world frame.
    ///
    /// # Panics
    /// As [`Robot::link_pose`].
    pub fn link_velocity(
        &self,
        ws: &KinematicsWorkspace,
        link: usize,
    ) -> (Vector3<f64>, Vector3<f64>) {
        (ws.omega[link], ws.vel[link])
    }

    /// A point fixed on `link` at `local` (link frame, m): x = T_link · local; J column j is
    /// `a_j × (x − o_j)` for a revolute joint and `a_j` for a prismatic one (a_j scaled by the mimic
    /// multiplier), and `J̇q̇ = a_b + α_b × r + ω × (ω × r)` with r = x − o_link.
    ///
    /// # Panics
    /// As [`Robot::link_pose`].
    pub fn point(
        &self,
        ws: &KinematicsWorkspace,
        link: usize,
        local: &Vector3<f64>,
        out: &mut TaskPoint,
    ) {
        let r = rotate(&ws.rot[link], local);
        let x = ws.pose[link].translation.vector + r;
        let w = ws.omega[link];
        out.x = x;
        out.xd = ws.vel[link] + w.cross(&r);
        out.jdot_qdot = ws.acc[link] + ws.alpha[link].cross(&r) + w.cross(&w.cross(&r));
        let b = self.bodies[link] * ws.dof;
        let cols = self.cols[link];
        let terms = b..b + cols;
        out.width = cols;
        let (jac, zero) = jacobian_of_width(out, ws.dof).split_at_mut(3 * cols);
        for ((col, a), m) in jac
            .chunks_exact_mut(3)
            .zip(&ws.jw[terms.clone()])
            .zip(&ws.jm[terms])
        {
            let v = cross_minus(a, &x, m);
            col[0] = v.x;
            col[1] = v.y;
            col[2] = v.z;
        }
        zero.fill(0.0);
    }

    /// A direction fixed on `link`: x = R_link · local_axis (unitless); J column j is `a_j × x` for a
    /// revolute joint and 0 for a prismatic one, and `J̇q̇ = α_b × x + ω × (ω × x)`.
    ///
    /// # Panics
    /// As [`Robot::link_pose`].
    pub fn axis(
        &self,
        ws: &KinematicsWorkspace,
        link: usize,
        local_axis: &Vector3<f64>,
        out: &mut TaskPoint,
    ) {
        let u = rotate(&ws.rot[link], local_axis);
        let w = ws.omega[link];
        out.x = u;
        out.xd = w.cross(&u);
        out.jdot_qdot = ws.alpha[link].cross(&u) + w.cross(&w.cross(&u));
        let b = self.bodies[link];
        let terms = b * ws.dof..b * ws.dof + self.cols[link];
        out.width = self.cols[link];
        let (jac, zero) = jacobian_of_width(out, ws.dof).split_at_mut(3 * self.cols[link]);
        for (col, a) in jac.chunks_exact_mut(3).zip(&ws.jw[terms]) {
            col.copy_from_slice(a.cross(&u).as_slice());
        }
        zero.fill(0.0);
    }

    /// Centre of collision sphere `i` (world, m) and its kinematics: [`Robot::point`] on the sphere's
    /// link at its centre.
    ///
    /// # Panics
    /// When `i >= spheres().len()`, or as [`Robot::link_pose`].
    pub fn sphere(&self, ws: &KinematicsWorkspace, i: usize, out: &mut TaskPoint) {
        let s = &self.spheres[i];
        self.point(ws, s.link, &s.center, out);
    }

    /// Centre of collision sphere `i` in the world frame (m), without derivatives.
    ///
    /// # Panics
    /// As [`Robot::sphere`].
    pub fn sphere_center(&self, ws: &KinematicsWorkspace, i: usize) -> Vector3<f64> {
        let s = &self.spheres[i];
        ws.pose[s.link].translation.vector + rotate(&ws.rot[s.link], &s.center)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::RobotOptions;

    const PENDULUM: &str = r#"<robot name="pendulum">
      <link name="base"/><link name="bob"/>
      <joint name="swing" type="revolute"><parent link="base"/><child link="bob"/>
        <origin xyz="0 0 1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1"/></joint>
    </robot>"#;

    /// A point at radius ρ on a link turning at rate θ̇ about z: x = o + Rz(θ) p, J = z × (x − o),
    /// J̇q̇ = −θ̇² (x − o)⊥ (centripetal), and the axis x̂ of the link turns as Rz(θ) x̂.
    #[test]
    fn single_revolute_closed_form() {
        let robot = Robot::from_urdf_str(PENDULUM, "pendulum", &RobotOptions::default()).unwrap();
        let mut ws = KinematicsWorkspace::new(&robot);
        let (theta, rate) = (0.7_f64, -1.3_f64);
        robot.update(&[theta], &[rate], &mut ws).unwrap();
        let mut tp = TaskPoint::new(3); // wrong width: resized
        let p = Vector3::new(0.4, 0.0, 0.2);
        robot.point(&ws, 1, &p, &mut tp);
        let r = Vector3::new(0.4 * theta.cos(), 0.4 * theta.sin(), 0.0);
        assert!((tp.x - (Vector3::new(0.0, 0.0, 1.2) + r)).norm() < 1e-15);
        assert_eq!(tp.jac.ncols(), 1);
        let j = Vector3::new(-r.y, r.x, 0.0);
        assert!((tp.jac.column(0) - j).norm() < 1e-15);
        assert!((tp.xd - j * rate).norm() < 1e-15);
        assert!((tp.jdot_qdot + r * rate * rate).norm() < 1e-15);
        robot.axis(&ws, 1, &Vector3::x(), &mut tp);
        let u = Vector3::new(theta.cos(), theta.sin(), 0.0);
        assert!((tp.x - u).norm() < 1e-15);
        assert!((tp.jdot_qdot + u * rate * rate).norm() < 1e-15);
        let (w, v) = robot.link_velocity(&ws, 1);
        assert_eq!((w, v), (Vector3::new(0.0, 0.0, rate), Vector3::zeros()));
        // update_positions zeroes the motion.
        robot.update_positions(&[theta], &mut ws).unwrap();
        robot.point(&ws, 1, &p, &mut tp);
        assert_eq!((tp.xd, tp.jdot_qdot), (Vector3::zeros(), Vector3::zeros()));
    }
}
