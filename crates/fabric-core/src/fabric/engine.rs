//! The robot fabric (GF Sec. V, VII-A): [`Fabric`] (read-only model: robot, gains, components) and
//! [`FabricWorkspace`] (per-thread scratch), with [`Fabric::acceleration`] evaluating the policy
//! q̈ = f(q, q̇; q_g) of GFCS eq. 1.
//!
//! One evaluation builds the transform tree at the root (GF Sec. V, eq. 15-17; see [`root`](super::root)):
//!
//! 1. joint attraction to the command q_g on x = q − q_g (VII-A1);
//! 2. optional end-effector position and axis attraction towards the end-effector pose at q_g (VII-A3,
//!    App. G), or towards explicit [`EeTargets`];
//! 3. joint-limit barriers, x = q − q_low − margin and q_up − margin − q (VII-A2);
//! 4. self-collision barriers for the robot's sphere pairs closer than the influence radius;
//! 5. obstacle barriers for every (robot sphere, obstacle) pair returned by [`Scene::query`] within the
//!    influence radius (task maps in [`leaves`](super::leaves));
//!
//! then resolves π̃ = −M̃⁻¹f̃ (Cholesky), energizes it (eq. 7), forces and damps it with speed control
//! (eq. 40-46). [`Mode::Unbent`](super::config::Mode::Unbent) drops the geometries (classical Lagrangian system, GF Sec. VI).
//!
//! Sphere Jacobians are computed only for spheres that own at least one leaf. Nothing allocates per call
//! once the workspace exists (the scene query appends into a reused buffer).

use std::sync::Arc;

use nalgebra::Vector3;

use super::components::{Attractor, Barrier};
use super::config::FabricConfig;
use super::energy::{ConstantMass, TanhMass};
use super::leaves::{obstacle_leaf, self_collision_leaf};
use super::root::RootSystem;
use crate::error::{check_finite, check_len, FabricError, Result};
use crate::robot::{KinematicsWorkspace, Robot, TaskPoint};
use crate::scene::{point_distance, DistanceSample, Scene};

/// End-effector targets in the world (base) frame: the position of the end-effector link origin (m) and
/// its three unit axes (columns of its rotation), as used by the VII-A3 / App. G attractors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EeTargets {
    /// Target position p_d (m).
    pub position: Vector3<f64>,
    /// Target unit axes R_d e_x, R_d e_y, R_d e_z.
    pub axes: [Vector3<f64>; 3],
}

/// Quantities of the last evaluation (see [`Fabric::diagnostics`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diagnostics {
    /// Fabric energy L̃_e = ½ q̇ᵀ M̃ q̇ (the summed Finsler energies).
    pub energy: f64,
    /// Execution energy L_ex = ½ ‖q̇‖² (rad²/s²).
    pub exec_energy: f64,
    /// Total forcing potential ψ (the Lyapunov function is L̃_e + ψ, GF Thm IV.4).
    pub potential: f64,
    /// Minimum over (robot sphere, obstacle) pairs within the obstacle influence radius (plus margin) of
    /// d(c) − r (m, negative in collision); +∞ when no sphere is that close to any obstacle.
    pub min_clearance: f64,
    /// Minimum over self-collision sphere pairs within the self-collision influence radius (plus margin)
    /// of ‖c_a − c_b‖ − r_a − r_b (m); +∞ when no pair is that close.
    pub min_self_clearance: f64,
    /// Minimum over joints of min(q − q_low, q_up − q) (rad or m), without margin; +∞ without limits.
    pub min_joint_margin: f64,
    /// α_Le: energization coefficient of π̃ w.r.t. L̃_e (eq. 7); 0 when unbent.
    pub alpha_le: f64,
    /// α_ex^0 (eq. 41).
    pub alpha_ex0: f64,
    /// α_ex^ψ (eq. 42).
    pub alpha_expsi: f64,
    /// η (eq. 46).
    pub eta: f64,
    /// s_β (eq. 45).
    pub s_beta: f64,
    /// β_reg (eq. 44), or s_β B + B̲ with speed control disabled.
    pub beta: f64,
    /// α_boost.
    pub alpha_boost: f64,
    /// α_reg, the coefficient of q̇ in eq. 40.
    pub alpha_reg: f64,
    /// Number of barrier leaves (joint limits + self-collision + obstacles) in the tree.
    pub leaves: usize,
}

impl Default for Diagnostics {
    fn default() -> Self {
        Diagnostics {
            energy: 0.0,
            exec_energy: 0.0,
            potential: 0.0,
            min_clearance: f64::INFINITY,
            min_self_clearance: f64::INFINITY,
            min_joint_margin: f64::INFINITY,
            alpha_le: 0.0,
            alpha_ex0: 0.0,
            alpha_expsi: 0.0,
            eta: 0.0,
            s_beta: 0.0,
            beta: 0.0,
            alpha_boost: 0.0,
            alpha_reg: 0.0,
            leaves: 0,
        }
    }
}

/// The collision spheres of one link and a sphere bounding them all (link frame), used to cull obstacle
/// queries: an obstacle within distance δ of a sphere is within R + δ of the bounding centre.
#[derive(Clone, Debug)]
struct SphereGroup {
    link: usize,
    center: Vector3<f64>,
    radius: f64,
    spheres: Vec<usize>,
}

fn sphere_groups(robot: &Robot) -> Vec<SphereGroup> {
    let mut groups: Vec<SphereGroup> = Vec::new();
    for (k, s) in robot.spheres().iter().enumerate() {
        match groups.iter_mut().find(|g| g.link == s.link) {
            Some(g) => g.spheres.push(k),
            None => groups.push(SphereGroup {
                link: s.link,
                center: Vector3::zeros(),
                radius: 0.0,
                spheres: vec![k],
            }),
        }
    }
    for g in &mut groups {
        let sp = robot.spheres();
        g.center = g
            .spheres
            .iter()
            .map(|&k| sp[k].center)
            .sum::<Vector3<f64>>()
            / g.spheres.len() as f64;
        g.radius = g
            .spheres
            .iter()
            .map(|&k| (sp[k].center - g.center).norm() + sp[k].radius)
            .fold(0.0, f64::max);
    }
    groups
}

/// A geometric fabric for one robot: the model shared by every thread (`Send + Sync`).
#[derive(Clone, Debug)]
pub struct Fabric {
    robot: Arc<Robot>,
    groups: Vec<SphereGroup>,
    config: FabricConfig,
    joint: Attractor<ConstantMass>,
    ee_position: Attractor<TanhMass>,
    ee_axis: Attractor<TanhMass>,
    joint_limits: Barrier,
    self_collision: Barrier,
    obstacles: Barrier,
}

/// Per-thread scratch of a [`Fabric`]; create once with [`FabricWorkspace::new`] and reuse.
#[derive(Clone, Debug)]
pub struct FabricWorkspace {
    kin: KinematicsWorkspace,
    target_kin: KinematicsWorkspace,
    target_command: Vec<f64>,
    targets: Option<EeTargets>,
    root: RootSystem,
    centers: Vec<Vector3<f64>>,
    spheres: Vec<TaskPoint>,
    sphere_ready: Vec<bool>,
    samples: Vec<DistanceSample>,
    task: TaskPoint,
    jrow: Vec<f64>,
    x: Vec<f64>,
    scratch: Vec<f64>,
    xi: Vec<f64>,
    f: Vec<f64>,
    grad: Vec<f64>,
    diag: Diagnostics,
}

impl FabricWorkspace {
    /// Scratch sized for `fabric`'s robot (dof, links, spheres).
    pub fn new(fabric: &Fabric) -> Self {
        let robot = &fabric.robot;
        let n = robot.dof();
        let s = robot.spheres().len();
        FabricWorkspace {
            kin: KinematicsWorkspace::new(robot),
            target_kin: KinematicsWorkspace::new(robot),
            target_command: vec![f64::NAN; n],
            targets: None,
            root: RootSystem::new(n),
            centers: vec![Vector3::zeros(); s],
            spheres: (0..s).map(|_| TaskPoint::new(n)).collect(),
            sphere_ready: vec![false; s],
            samples: Vec::with_capacity(16),
            task: TaskPoint::new(n),
            jrow: vec![0.0; n],
            x: vec![0.0; n],
            scratch: vec![0.0; n.max(3)],
            xi: vec![0.0; n.max(3)],
            f: vec![0.0; n.max(3)],
            grad: vec![0.0; n.max(3)],
            diag: Diagnostics::default(),
        }
    }

    /// The root system of the last evaluation: M̃, ξ̃, f̃, ∂ψ, π̃ and M̃⁻¹∂ψ (for analysis and tests).
    pub fn root(&self) -> &RootSystem {
        &self.root
    }

    /// The kinematics of the last evaluation.
    pub fn kinematics(&self) -> &KinematicsWorkspace {
        &self.kin
    }
}

impl Fabric {
    /// Build a fabric for `robot` with `config` (validated; `Err(Format)` naming the bad field).
    pub fn new(robot: Arc<Robot>, config: FabricConfig) -> Result<Fabric> {
        config.validate()?;
        let n = robot.dof();
        Ok(Fabric {
            joint: Attractor::joint(&config.joint_attraction, n),
            ee_position: Attractor::end_effector(&config.ee_position, 3),
            ee_axis: Attractor::end_effector(&config.ee_orientation, 3),
            joint_limits: Barrier::from_config(&config.joint_limits),
            self_collision: Barrier::from_config(&config.self_collision),
            obstacles: Barrier::from_config(&config.obstacles),
            groups: sphere_groups(&robot),
            robot,
            config,
        })
    }

    /// The robot model.
    pub fn robot(&self) -> &Arc<Robot> {
        &self.robot
    }

    /// The configuration.
    pub fn config(&self) -> &FabricConfig {
        &self.config
    }

    /// The end-effector targets implied by a joint command: the pose of the end-effector link at
    /// `command` (dof,). Errors on wrong length / non-finite values.
    pub fn ee_targets(&self, command: &[f64], ws: &mut FabricWorkspace) -> Result<EeTargets> {
        self.check_workspace(ws)?;
        self.robot.update_positions(command, &mut ws.target_kin)?;
        let pose = self.robot.link_pose(&ws.target_kin, self.robot.ee_link());
        let r = pose.rotation.to_rotation_matrix();
        Ok(EeTargets {
            position: pose.translation.vector,
            axes: [
                r.matrix().column(0).into_owned(),
                r.matrix().column(1).into_owned(),
                r.matrix().column(2).into_owned(),
            ],
        })
    }

    fn check_workspace(&self, ws: &FabricWorkspace) -> Result<()> {
        let n = self.robot.dof();
        let s = self.robot.spheres().len();
        if ws.root.dim() != n || ws.spheres.len() != s {
            return Err(FabricError::Shape {
                what: "fabric workspace (dof, spheres)".to_string(),
                expected: format!("({n}, {s})"),
                got: format!("({}, {})", ws.root.dim(), ws.spheres.len()),
            });
        }
        Ok(())
    }

    /// q̈ (rad/s², written into `qdd` (dof,)) for the state (`q`, `qd`) (dof,) attracted to the joint-space
    /// command `command` (dof,) in `scene` (GFCS eq. 1). End-effector attractors, when enabled, aim at
    /// the end-effector pose at `command` (cached while the command does not change).
    ///
    /// Errors: `Shape` (wrong lengths, foreign workspace), `NonFinite` (NaN/∞ in inputs, or a non-finite
    /// result at this state), `Value` (root metric not positive definite). Never returns NaN.
    pub fn acceleration(
        &self,
        scene: &Scene,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        ws: &mut FabricWorkspace,
        qdd: &mut [f64],
    ) -> Result<()> {
        self.check_inputs(q, qd, command, qdd, ws)?;
        let targets = if self.config.ee_position.enabled || self.config.ee_orientation.enabled {
            if ws.targets.is_none() || ws.target_command.as_slice() != command {
                let t = self.ee_targets(command, ws)?;
                ws.target_command.copy_from_slice(command);
                ws.targets = Some(t);
            }
            ws.targets
        } else {
            None
        };
        self.evaluate(scene, q, qd, command, targets.as_ref(), ws, qdd)
    }

    /// As [`Fabric::acceleration`] but with explicit end-effector targets (used only by the end-effector
    /// attractors; the joint attractor still aims at `command`).
    #[allow(clippy::too_many_arguments)]
    pub fn acceleration_with_targets(
        &self,
        scene: &Scene,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        targets: &EeTargets,
        ws: &mut FabricWorkspace,
        qdd: &mut [f64],
    ) -> Result<()> {
        self.check_inputs(q, qd, command, qdd, ws)?;
        let finite = targets
            .position
            .iter()
            .chain(targets.axes.iter().flat_map(|a| a.iter()))
            .all(|v| v.is_finite());
        if !finite {
            return Err(FabricError::NonFinite {
                what: "end-effector targets".to_string(),
            });
        }
        self.evaluate(scene, q, qd, command, Some(targets), ws, qdd)
    }

    /// Diagnostics of the last evaluation in `ws`.
    pub fn diagnostics(&self, ws: &FabricWorkspace) -> Diagnostics {
        ws.diag
    }

    fn check_inputs(
        &self,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        qdd: &[f64],
        ws: &FabricWorkspace,
    ) -> Result<()> {
        let n = self.robot.dof();
        check_len("q", q.len(), n)?;
        check_len("qd", qd.len(), n)?;
        check_len("command", command.len(), n)?;
        check_len("qdd (output)", qdd.len(), n)?;
        check_finite("q", q)?;
        check_finite("qd", qd)?;
        check_finite("command", command)?;
        self.check_workspace(ws)
    }

    #[allow(clippy::too_many_arguments)]
    fn evaluate(
        &self,
        scene: &Scene,
        q: &[f64],
        qd: &[f64],
        command: &[f64],
        targets: Option<&EeTargets>,
        ws: &mut FabricWorkspace,
        qdd: &mut [f64],
    ) -> Result<()> {
        let robot = &*self.robot;
        let n = robot.dof();
        robot.update(q, qd, &mut ws.kin)?;
        ws.root.clear();
        let mut diag = Diagnostics::default();

        // 1. joint attraction on x = q − q_g (J = I)
        for i in 0..n {
            ws.x[i] = q[i] - command[i];
        }
        let e = self.joint.eval(
            &ws.x,
            qd,
            &mut ws.scratch[..n],
            &mut ws.xi[..n],
            &mut ws.f[..n],
            &mut ws.grad[..n],
        );
        ws.root
            .add_identity(e.mass, &ws.xi[..n], &ws.f[..n], &ws.grad[..n], e.psi);

        // 2. end-effector attraction (VII-A3, App. G)
        if let Some(t) = targets {
            let ee = robot.ee_link();
            if self.config.ee_position.enabled {
                robot.point(&ws.kin, ee, &Vector3::zeros(), &mut ws.task);
                self.add_ee(ws, &t.position);
            }
            if self.config.ee_orientation.enabled {
                for (k, target) in t.axes.iter().enumerate() {
                    robot.axis(&ws.kin, ee, &Vector3::ith(k, 1.0), &mut ws.task);
                    self.add_ee_axis(ws, target);
                }
            }
        }

        // 3. joint limits
        let mut leaves = 0;
        let (lower, upper) = (robot.lower(), robot.upper());
        let jl = &self.config.joint_limits;
        for i in 0..n {
            diag.min_joint_margin = diag
                .min_joint_margin
                .min(q[i] - lower[i])
                .min(upper[i] - q[i]);
            if !jl.enabled {
                continue;
            }
            for (sign, x) in [
                (1.0, q[i] - lower[i] - jl.margin),
                (-1.0, upper[i] - jl.margin - q[i]),
            ] {
                if x < jl.influence {
                    let b = self.joint_limits.eval(x, sign * qd[i]);
                    ws.root
                        .add_coordinate(i, sign, b.m, b.xi, b.f, b.grad, b.psi);
                    leaves += 1;
                }
            }
        }

        // sphere centres (cheap) and lazy sphere kinematics
        let spheres = robot.spheres();
        for (k, c) in ws.centers.iter_mut().enumerate() {
            *c = robot.sphere_center(&ws.kin, k);
        }
        ws.sphere_ready.iter_mut().for_each(|r| *r = false);

        // 4. self-collision pairs
        let sc = &self.config.self_collision;
        let reach = sc.margin + sc.influence;
        for &(a, b) in robot.self_collision_pairs() {
            let (ra, rb) = (spheres[a].radius, spheres[b].radius);
            let d2 = (ws.centers[a] - ws.centers[b]).norm_squared();
            let far = ra + rb + reach;
            if d2 >= far * far {
                continue;
            }
            let clearance = d2.sqrt() - ra - rb;
            diag.min_self_clearance = diag.min_self_clearance.min(clearance);
            if !sc.enabled {
                continue;
            }
            ensure_sphere(robot, ws, a);
            ensure_sphere(robot, ws, b);
            let leaf = self_collision_leaf(
                &ws.spheres[a],
                ra,
                &ws.spheres[b],
                rb,
                sc.margin,
                sc.min_curvature_radius,
                &mut ws.jrow,
            );
            let bv = self.self_collision.eval(leaf.x, leaf.xd);
            ws.root
                .add_scalar(&ws.jrow, leaf.jdot_qdot, bv.m, bv.xi, bv.f, bv.grad, bv.psi);
            leaves += 1;
        }

        // 5. obstacles: one broadphase query per link group, then exact distances per sphere
        let ob = &self.config.obstacles;
        if ob.enabled && !scene.is_empty() {
            let reach = ob.margin + ob.influence;
            for g in &self.groups {
                let gc = robot.link_pose(&ws.kin, g.link) * nalgebra::Point3::from(g.center);
                ws.samples.clear();
                scene.query(&gc.coords, g.radius + reach, &mut ws.samples);
                if ws.samples.is_empty() {
                    continue;
                }
                for &k in &g.spheres {
                    let r = spheres[k].radius;
                    let center = ws.centers[k];
                    let offset = (center - gc.coords).norm();
                    for s in 0..ws.samples.len() {
                        // 1-Lipschitz lower bound of the centre's distance from the group query
                        if ws.samples[s].distance - offset > r + reach {
                            continue;
                        }
                        let id = ws.samples[s].obstacle;
                        let Some(obstacle) = scene.get(id) else {
                            continue;
                        };
                        let Some(sd) =
                            point_distance(&obstacle.shape, &obstacle.pose, &center, r + reach)
                        else {
                            continue;
                        };
                        diag.min_clearance = diag.min_clearance.min(sd.distance - r);
                        let sample = DistanceSample {
                            obstacle: id,
                            distance: sd.distance,
                            gradient: sd.gradient,
                            hessian: sd.hessian,
                            velocity: obstacle.velocity,
                        };
                        ensure_sphere(robot, ws, k);
                        let leaf = obstacle_leaf(
                            &ws.spheres[k],
                            r,
                            ob.margin,
                            &sample,
                            ob.min_curvature_radius,
                            &mut ws.jrow,
                        );
                        if leaf.x >= ob.influence {
                            continue;
                        }
                        let bv = self.obstacles.eval(leaf.x, leaf.xd);
                        ws.root.add_scalar(
                            &ws.jrow,
                            leaf.jdot_qdot,
                            bv.m,
                            bv.xi,
                            bv.f,
                            bv.grad,
                            bv.psi,
                        );
                        leaves += 1;
                    }
                }
            }
        }

        // resolve: π̃, energization, forcing, speed control (eq. 7, 17, 40-46)
        let goal_distance = q
            .iter()
            .zip(command)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        let terms = ws
            .root
            .solve(
                self.config.mode,
                &self.config.speed,
                qd,
                goal_distance,
                self.config.joint_attraction.mass,
                qdd,
            )
            .map_err(|e| match e {
                FabricError::NonFinite { what } => FabricError::NonFinite {
                    what: format!("{what} (q = {q:?}, qd = {qd:?}, command = {command:?})"),
                },
                FabricError::Value { what, message } => FabricError::Value {
                    what,
                    message: format!("{message} (q = {q:?}, qd = {qd:?}, command = {command:?})"),
                },
                other => other,
            })?;
        diag.energy = terms.energy;
        diag.exec_energy = terms.speed.exec_energy;
        diag.potential = terms.potential;
        diag.alpha_le = terms.alpha_le;
        diag.alpha_ex0 = terms.speed.alpha_ex0;
        diag.alpha_expsi = terms.speed.alpha_expsi;
        diag.eta = terms.speed.eta;
        diag.s_beta = terms.speed.s_beta;
        diag.beta = terms.speed.beta;
        diag.alpha_boost = terms.speed.alpha_boost;
        diag.alpha_reg = terms.speed.alpha_reg;
        diag.leaves = leaves;
        ws.diag = diag;
        Ok(())
    }

    /// Add the end-effector position attractor for the task point in `ws.task` towards `target`.
    fn add_ee(&self, ws: &mut FabricWorkspace, target: &Vector3<f64>) {
        add_attractor_3d(&self.ee_position, ws, target);
    }

    /// Add one end-effector axis attractor for the axis in `ws.task` towards the unit vector `target`.
    fn add_ee_axis(&self, ws: &mut FabricWorkspace, target: &Vector3<f64>) {
        add_attractor_3d(&self.ee_axis, ws, target);
    }
}

/// Pull back a 3-D attractor living on the task point / axis stored in `ws.task`, on x = task.x − target.
fn add_attractor_3d(att: &Attractor<TanhMass>, ws: &mut FabricWorkspace, target: &Vector3<f64>) {
    let x = [
        ws.task.x.x - target.x,
        ws.task.x.y - target.y,
        ws.task.x.z - target.z,
    ];
    let xd = [ws.task.xd.x, ws.task.xd.y, ws.task.xd.z];
    let e = att.eval(
        &x,
        &xd,
        &mut ws.scratch[..3],
        &mut ws.xi[..3],
        &mut ws.f[..3],
        &mut ws.grad[..3],
    );
    let jdqd = [
        ws.task.jdot_qdot.x,
        ws.task.jdot_qdot.y,
        ws.task.jdot_qdot.z,
    ];
    ws.root.add_isotropic(
        &ws.task.jac,
        &jdqd,
        e.mass,
        &ws.xi[..3],
        &ws.f[..3],
        &ws.grad[..3],
        e.psi,
    );
}

/// Compute the kinematics (J, J̇q̇) of sphere `k` once per evaluation.
fn ensure_sphere(robot: &Robot, ws: &mut FabricWorkspace, k: usize) {
    if !ws.sphere_ready[k] {
        robot.sphere(&ws.kin, k, &mut ws.spheres[k]);
        ws.sphere_ready[k] = true;
    }
}
