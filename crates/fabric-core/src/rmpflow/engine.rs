//! [`Rmpflow`] (read-only model: robot and gains) and [`RmpWorkspace`] (per-thread scratch): the RMPflow
//! policy q̈ = M_q⁺ f_q of a robot in a scene, with the same command semantics as the fabric (a joint-space
//! command q_g for the posture leaf, the end-effector pose at q_g, or explicit [`EeTargets`], for the
//! target leaf). One evaluation pulls back (see [`root`](super::root)):
//!
//! 1. the posture attractor on x = q − q_g;
//! 2. the end-effector position attractor on the end-effector link's origin (the fabric's point);
//! 3. joint-limit leaves on the buffered limit distances of every joint;
//! 4. self-collision leaves for the robot's sphere pairs within `self_collision.influence`;
//! 5. collision leaves for every (robot sphere, obstacle) pair within `obstacles.influence`, on the
//!    fabric's obstacle task map ([`obstacle_leaf`]; moving obstacles through their velocity);
//! 6. joint damping;
//!
//! then resolves q̈ = M_q⁺ f_q.

use std::sync::Arc;

use nalgebra::Vector3;

use super::config::RmpConfig;
use super::leaves;
use super::root::RmpRoot;
use crate::error::{check_finite, check_policy_inputs, FabricError, Result};
use crate::fabric::leaves::{obstacle_leaf, self_collision_leaf};
use crate::fabric::EeTargets;
use crate::robot::{KinematicsWorkspace, Robot, TaskPoint};
use crate::scene::distance::NearObstacle;
use crate::scene::Scene;

/// Quantities of the last evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RmpDiagnostics {
    /// Minimum of d(c) − r over (sphere, obstacle) pairs within the obstacle influence (m); +∞ if none.
    pub min_clearance: f64,
    /// Minimum of ‖c_a − c_b‖ − r_a − r_b over self-collision pairs within the influence (m); +∞ if none.
    pub min_self_clearance: f64,
    /// Minimum over joints of min(q − q_low, q_up − q) (rad or m).
    pub min_joint_margin: f64,
    /// Number of collision and self-collision leaves in the tree.
    pub leaves: usize,
}

impl Default for RmpDiagnostics {
    fn default() -> Self {
        RmpDiagnostics {
            min_clearance: f64::INFINITY,
            min_self_clearance: f64::INFINITY,
            min_joint_margin: f64::INFINITY,
            leaves: 0,
        }
    }
}

/// An RMPflow policy for one robot: the model shared by every thread (`Send + Sync`).
#[derive(Clone, Debug)]
pub struct Rmpflow {
    robot: Arc<Robot>,
    config: RmpConfig,
}

/// Per-thread scratch of an [`Rmpflow`].
#[derive(Clone, Debug)]
pub struct RmpWorkspace {
    kin: KinematicsWorkspace,
    target_kin: KinematicsWorkspace,
    target_command: Vec<f64>,
    targets: Option<EeTargets>,
    root: RmpRoot,
    centers: Vec<Vector3<f64>>,
    spheres: Vec<TaskPoint>,
    ready: Vec<bool>,
    near: Vec<NearObstacle>,
    task: TaskPoint,
    jrow: Vec<f64>,
    x: Vec<f64>,
    accel: Vec<f64>,
    diag: RmpDiagnostics,
}

impl RmpWorkspace {
    /// Scratch sized for `rmp`'s robot.
    pub fn new(rmp: &Rmpflow) -> Self {
        let robot = &rmp.robot;
        let (n, s) = (robot.dof(), robot.spheres().len());
        RmpWorkspace {
            kin: KinematicsWorkspace::new(robot),
            target_kin: KinematicsWorkspace::new(robot),
            target_command: vec![f64::NAN; n],
            targets: None,
            root: RmpRoot::new(n),
            centers: vec![Vector3::zeros(); s],
            spheres: (0..s).map(|_| TaskPoint::new(n)).collect(),
            ready: vec![false; s],
            near: Vec::with_capacity(16),
            task: TaskPoint::new(n),
            jrow: vec![0.0; n],
            x: vec![0.0; n],
            accel: vec![0.0; n],
            diag: RmpDiagnostics::default(),
        }
    }

    /// The root (M_q, f_q) of the last evaluation.
    pub fn root(&self) -> &RmpRoot {
        &self.root
    }
}

impl Rmpflow {
    /// An RMPflow policy for `robot` with `config` (validated).
    pub fn new(robot: Arc<Robot>, config: RmpConfig) -> Result<Rmpflow> {
        config.validate()?;
        Ok(Rmpflow { robot, config })
    }

    /// The robot model.
    pub fn robot(&self) -> &Arc<Robot> {
        &self.robot
    }

    /// The configuration.
    pub fn config(&self) -> &RmpConfig {
        &self.config
    }

    /// Diagnostics of the last evaluation in `ws`.
    pub fn diagnostics(&self, ws: &RmpWorkspace) -> RmpDiagnostics {
        ws.diag
    }

    fn check(
        &self,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &[f64],
        ws: &RmpWorkspace,
    ) -> Result<()> {
        let n = self.robot.dof();
        check_policy_inputs(n, q, qd, command, qdd)?;
        if ws.root.dim() != n || ws.spheres.len() != self.robot.spheres().len() {
            return Err(FabricError::Shape {
                what: "rmpflow workspace (dof, spheres)".into(),
                expected: format!("({n}, {})", self.robot.spheres().len()),
                got: format!("({}, {})", ws.root.dim(), ws.spheres.len()),
            });
        }
        Ok(())
    }

    /// q̈ (written into `qdd` (dof,)) at (`q`, `qd`) for the joint-space `command` (dof,) in `scene`;
    /// the target leaf aims at the end-effector position at `command`, or at `targets` when given.
    /// Errors: `Shape`, `NonFinite` (inputs, or a non-finite root at this state).
    #[allow(clippy::too_many_arguments)]
    pub fn acceleration(
        &self,
        scene: &Scene,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        targets: Option<&EeTargets>,
        ws: &mut RmpWorkspace,
        qdd: &mut [f64],
    ) -> Result<()> {
        self.check(q, qd, command, qdd, ws)?;
        let goal = match targets {
            Some(t) => {
                check_finite("ee_target", t.position.as_slice())?;
                Some(t.position)
            }
            None if self.config.target.enabled => {
                if ws.targets.is_none() || ws.target_command.as_slice() != command {
                    self.robot.update_positions(command, &mut ws.target_kin)?;
                    let pose = self.robot.link_pose(&ws.target_kin, self.robot.ee_link());
                    ws.targets = Some(EeTargets {
                        position: pose.translation.vector,
                        axes: [Vector3::x(), Vector3::y(), Vector3::z()],
                    });
                    ws.target_command.copy_from_slice(command);
                }
                ws.targets.map(|t| t.position)
            }
            None => None,
        };
        self.robot.update(q, qd, &mut ws.kin)?;
        ws.root.clear();
        let mut diag = RmpDiagnostics::default();
        self.add_joint_leaves(q, qd, command, ws, &mut diag);
        if let (Some(g), true) = (goal, self.config.target.enabled) {
            self.robot.point(
                &ws.kin,
                self.robot.ee_link(),
                &Vector3::zeros(),
                &mut ws.task,
            );
            let (a, m) = leaves::target(&self.config.target, &ws.task.x, &ws.task.xd, &g);
            ws.root.add_point(&ws.task.jac, &ws.task.jdot_qdot, &m, &a);
        }
        let robot = &*self.robot;
        for (k, c) in ws.centers.iter_mut().enumerate() {
            *c = robot.sphere_center(&ws.kin, k);
        }
        ws.ready.iter_mut().for_each(|r| *r = false);
        self.add_self_collision(ws, &mut diag);
        self.add_obstacles(scene, ws, &mut diag);
        ws.root.resolve(qdd).map_err(|e| match e {
            FabricError::NonFinite { what } => FabricError::NonFinite {
                what: format!("{what} (q = {q:?}, qd = {qd:?}, command = {command:?})"),
            },
            other => other,
        })?;
        check_finite("RMPflow acceleration", qdd)?;
        ws.diag = diag;
        Ok(())
    }

    /// Posture, joint limits and damping (all with J = I or ±e_i).
    fn add_joint_leaves(
        &self,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        ws: &mut RmpWorkspace,
        diag: &mut RmpDiagnostics,
    ) {
        let n = q.len();
        let c = &self.config;
        if c.cspace_target.enabled {
            for i in 0..n {
                ws.x[i] = q[i] - command[i];
            }
            let m = leaves::cspace_target(&c.cspace_target, &ws.x, qd, &mut ws.accel);
            ws.root.add_identity(m, &ws.accel);
        }
        let (lower, upper) = (self.robot.lower(), self.robot.upper());
        for i in 0..n {
            diag.min_joint_margin = diag
                .min_joint_margin
                .min(q[i] - lower[i])
                .min(upper[i] - q[i]);
            if !(c.joint_limits.enabled && lower[i].is_finite() && upper[i].is_finite()) {
                continue;
            }
            let b = c.joint_limits.buffer;
            for (sign, x) in [(1.0, q[i] - lower[i] - b), (-1.0, upper[i] - b - q[i])] {
                let r = leaves::joint_limit(&c.joint_limits, x, sign * qd[i]);
                ws.root.add_coordinate(i, sign, r.m, r.a);
            }
        }
        if c.damping.enabled {
            let m = leaves::damping(&c.damping, qd, &mut ws.accel);
            ws.root.add_identity(m, &ws.accel);
        }
    }

    /// Sphere–sphere collision leaves for the robot's self-collision pairs within reach.
    fn add_self_collision(&self, ws: &mut RmpWorkspace, diag: &mut RmpDiagnostics) {
        let c = &self.config.self_collision;
        let robot = &*self.robot;
        let spheres = robot.spheres();
        for &(a, b) in robot.self_collision_pairs() {
            let (ra, rb) = (spheres[a].radius, spheres[b].radius);
            let clearance = (ws.centers[a] - ws.centers[b]).norm() - ra - rb;
            if clearance - c.margin >= c.influence {
                continue;
            }
            diag.min_self_clearance = diag.min_self_clearance.min(clearance);
            if !c.enabled {
                continue;
            }
            ensure_sphere(robot, ws, a);
            ensure_sphere(robot, ws, b);
            let leaf = self_collision_leaf(
                &ws.spheres[a],
                ra,
                &ws.spheres[b],
                rb,
                c.margin,
                c.min_curvature_radius,
                &mut ws.jrow,
            );
            let r = leaves::collision(c, leaf.x, leaf.xd);
            ws.root.add_scalar(&ws.jrow, leaf.jdot_qdot, r.m, r.a);
            diag.leaves += 1;
        }
    }

    /// Sphere–obstacle collision leaves within reach.
    fn add_obstacles(&self, scene: &Scene, ws: &mut RmpWorkspace, diag: &mut RmpDiagnostics) {
        let c = &self.config.obstacles;
        if scene.is_empty() {
            return;
        }
        let robot = &*self.robot;
        for (k, sphere) in robot.spheres().iter().enumerate() {
            let reach = sphere.radius + c.margin + c.influence;
            let center = ws.centers[k];
            ws.near.clear();
            scene.query_near(&center, reach, &mut ws.near);
            for s in 0..ws.near.len() {
                let Some(sample) = scene.sample_near(&ws.near[s], &center, reach) else {
                    continue;
                };
                diag.min_clearance = diag.min_clearance.min(sample.distance - sphere.radius);
                if !c.enabled {
                    continue;
                }
                ensure_sphere(robot, ws, k);
                let leaf = obstacle_leaf(
                    &ws.spheres[k],
                    sphere.radius,
                    c.margin,
                    &sample,
                    c.min_curvature_radius,
                    true,
                    &mut ws.jrow,
                );
                let r = leaves::collision(c, leaf.x, leaf.xd);
                ws.root.add_scalar(&ws.jrow, leaf.jdot_qdot, r.m, r.a);
                diag.leaves += 1;
            }
        }
    }
}

/// Compute the kinematics (J, J̇q̇) of sphere `k` once per evaluation.
fn ensure_sphere(robot: &Robot, ws: &mut RmpWorkspace, k: usize) {
    if !ws.ready[k] {
        robot.sphere(&ws.kin, k, &mut ws.spheres[k]);
        ws.ready[k] = true;
    }
}
