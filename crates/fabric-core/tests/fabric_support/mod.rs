//! Helpers shared by the `fabric_*` integration tests: the shared-data skip rule, MotionBenchMaker loading,
//! a scene built in code, and a plain semi-implicit Euler rollout (independent of `rollout::`).
#![allow(dead_code)]

#[path = "../common/mod.rs"]
mod common;

use std::path::Path;
use std::sync::Arc;

use fabric_core::fabric::{Fabric, FabricWorkspace};
use fabric_core::robot::{Robot, RobotOptions};
use fabric_core::scene::{moveit, Obstacle, Scene, Shape};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// The shared-data skip rule (`tests/common`): `<repo>/../shared` (or `$GFCS_SHARED`), `None` (test
/// skipped, reason printed) when absent, unless `CI=true`: then the test fails.
#[allow(unused_imports)] // not every test crate that includes this module calls them
pub use common::{shared_dir, shared_root};

/// The spherized MotionBenchMaker Panda with its SRDF self-collision pairs.
pub fn mbm_panda(shared: &Path) -> Robot {
    let dir = shared.join("robots/mbm_panda");
    let opts = RobotOptions {
        ee_link: Some("panda_hand".into()),
        ..RobotOptions::default()
    };
    let mut robot =
        Robot::from_urdf_file(&dir.join("panda_spherized.urdf"), &opts).expect("MBM Panda URDF");
    let srdf = std::fs::read_to_string(dir.join("panda.srdf")).expect("MBM Panda SRDF");
    robot
        .set_self_collision_from_srdf(&srdf, "panda.srdf")
        .expect("SRDF");
    robot
}

/// One MotionBenchMaker problem: scene, start and goal (in the robot's joint order).
pub fn mbm_problem(
    shared: &Path,
    robot: &Robot,
    class: &str,
    index: usize,
) -> (Scene, Vec<f64>, Vec<f64>) {
    let dir = shared.join("mbm").join(class);
    let scene = Scene::from_moveit_yaml_file(&dir.join(format!("scene{index:04}.yaml")), None)
        .expect("scene");
    let req =
        moveit::parse_request_file(&dir.join(format!("request{index:04}.yaml"))).expect("request");
    let start = req.start_for(robot.joint_names()).expect("start");
    let goal = req.goal_for(robot.joint_names()).expect("goal");
    (scene, start, goal)
}

fn pose(t: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}

/// A MotionBenchMaker-like "box" scene built in code (like mbm/box/scene0001.yaml): a tray with a back
/// wall, a lid tilted above it, a can inside, a side post.
pub fn box_scene() -> Scene {
    let mut s = Scene::new();
    let mut add = |name: &str, shape: Shape, p: Isometry3<f64>| {
        s.add(Obstacle {
            name: name.into(),
            shape,
            pose: p,
            velocity: Vector3::zeros(),
        })
        .expect("obstacle");
    };
    add(
        "base",
        Shape::Cuboid {
            half_extents: Vector3::new(0.35, 0.35, 0.02),
        },
        pose([0.57, 0.16, -0.49], [0.0, 0.0, 0.15]),
    );
    add(
        "side_back",
        Shape::Cuboid {
            half_extents: Vector3::new(0.02, 0.35, 0.35),
        },
        pose([0.92, 0.21, -0.13], [0.0, 0.0, 0.15]),
    );
    add(
        "side_cap",
        Shape::Cuboid {
            half_extents: Vector3::new(0.35, 0.35, 0.02),
        },
        pose([0.67, 0.18, 0.42], [-0.05, 0.78, 0.15]),
    );
    add(
        "can",
        Shape::Cylinder {
            half_height: 0.07,
            radius: 0.03,
        },
        pose([0.54, 0.36, -0.38], [0.0, 0.0, 0.15]),
    );
    add(
        "post",
        Shape::Cylinder {
            half_height: 0.3,
            radius: 0.04,
        },
        pose([0.3, -0.45, -0.2], [0.0, 0.0, 0.0]),
    );
    s
}

/// Result of [`euler_rollout`].
#[derive(Clone, Debug)]
pub struct Run {
    /// Time when ‖q − q_g‖ < tol first held (None: not reached).
    pub reached: Option<f64>,
    /// Final configuration and velocity.
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    /// Max ‖q̇‖ over the run (rad/s).
    pub max_speed: f64,
    /// Min obstacle clearance (m) from the diagnostics (+∞ if never within influence).
    pub min_clearance: f64,
    /// Min self clearance (m).
    pub min_self_clearance: f64,
    /// Min over time and joints of the distance to the joint limits (rad).
    pub min_joint_margin: f64,
    /// Whether every evaluation succeeded.
    pub ok: bool,
    /// Positions along the run, one row per step.
    pub path: Vec<Vec<f64>>,
}

/// Semi-implicit Euler (q̇ += dt q̈; q += dt q̇) of the fabric toward `goal` for `t_max` s at step `dt`.
pub fn euler_rollout(
    fabric: &Fabric,
    scene: &Scene,
    q0: &[f64],
    goal: &[f64],
    dt: f64,
    t_max: f64,
    tol: f64,
) -> Run {
    let n = q0.len();
    let mut ws = FabricWorkspace::new(fabric);
    let (mut q, mut qd, mut qdd) = (q0.to_vec(), vec![0.0; n], vec![0.0; n]);
    let mut run = Run {
        reached: None,
        q: q.clone(),
        qd: qd.clone(),
        max_speed: 0.0,
        min_clearance: f64::INFINITY,
        min_self_clearance: f64::INFINITY,
        min_joint_margin: f64::INFINITY,
        ok: true,
        path: vec![q.clone()],
    };
    let steps = (t_max / dt).round() as usize;
    for k in 0..steps {
        if fabric
            .acceleration(scene, &q, &qd, goal, &mut ws, &mut qdd)
            .is_err()
        {
            run.ok = false;
            break;
        }
        let d = fabric.diagnostics(&ws);
        run.min_clearance = run.min_clearance.min(d.min_clearance);
        run.min_self_clearance = run.min_self_clearance.min(d.min_self_clearance);
        run.min_joint_margin = run.min_joint_margin.min(d.min_joint_margin);
        for i in 0..n {
            qd[i] += dt * qdd[i];
            q[i] += dt * qd[i];
        }
        run.path.push(q.clone());
        run.max_speed = run
            .max_speed
            .max(qd.iter().map(|v| v * v).sum::<f64>().sqrt());
        let err = q
            .iter()
            .zip(goal)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        if run.reached.is_none() && err < tol {
            run.reached = Some((k + 1) as f64 * dt);
            break;
        }
    }
    run.q = q;
    run.qd = qd;
    run
}

/// An `Arc` of the robot for `Fabric::new`.
pub fn arc(robot: Robot) -> Arc<Robot> {
    Arc::new(robot)
}
