//! One fabric evaluation `Fabric::acceleration` of the Panda (forward kinematics, all collision spheres
//! against a MotionBenchMaker-like "box" scene built in code, self-collision pairs, joint limits, joint
//! attraction, energization and speed control), at states recorded along a rollout so that the number of
//! barrier leaves is representative. Target: ≤ 10 µs on one core.
//!
//! Benchmarks: the shipped Panda (`Robot::panda()`), and the spherized MotionBenchMaker Panda (59 spheres)
//! when the shared data directory is present (`../shared` or `$GFCS_SHARED`; skipped with a message
//! otherwise).
//!
//! Run: `cargo bench -p fabric-core --bench acceleration`.

use std::path::PathBuf;
use std::sync::Arc;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use fabric_core::fabric::{Fabric, FabricConfig, FabricWorkspace};
use fabric_core::robot::{Robot, RobotOptions};
use fabric_core::scene::{Obstacle, Scene, Shape};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

const READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
/// A goal with the hand inside the box (sphere-model clearance of a few cm).
const GOAL: [f64; 7] = [0.45, 0.35, 0.19, -1.9, -0.1, 2.3, 0.8];

fn pose(t: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}

/// Like mbm/box/scene0001.yaml: a tray (base), a back wall, a tilted lid, a can inside, plus a post.
fn box_scene() -> Scene {
    let mut s = Scene::new();
    let mut add = |name: &str, shape: Shape, p: Isometry3<f64>| {
        s.add(Obstacle::new(name, shape, p))
            .expect("valid benchmark obstacle");
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

/// (q, q̇) every 5th step of a 4 s semi-implicit Euler rollout toward GOAL.
fn recorded_states(fabric: &Fabric, scene: &Scene) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut ws = FabricWorkspace::new(fabric);
    let (mut q, mut qd, mut qdd) = (READY.to_vec(), vec![0.0; 7], vec![0.0; 7]);
    let mut out = Vec::new();
    let mut leaves = 0;
    for k in 0..400 {
        if fabric
            .acceleration(scene, &q, &qd, &GOAL, &mut ws, &mut qdd)
            .is_err()
        {
            break;
        }
        leaves += fabric.diagnostics(&ws).leaves;
        if k % 5 == 0 {
            out.push((q.clone(), qd.clone()));
        }
        for i in 0..7 {
            qd[i] += 0.01 * qdd[i];
            q[i] += 0.01 * qd[i];
        }
    }
    eprintln!(
        "{} spheres, {} self-collision pairs; mean leaves per evaluation along the recorded rollout: {:.1}",
        fabric.robot().spheres().len(),
        fabric.robot().self_collision_pairs().len(),
        leaves as f64 / 400.0
    );
    out
}

fn bench_robot(c: &mut Criterion, name: &str, robot: Robot) {
    let fabric = Fabric::new(Arc::new(robot), FabricConfig::default()).expect("default fabric");
    let scene = box_scene();
    let states = recorded_states(&fabric, &scene);
    let mut ws = FabricWorkspace::new(&fabric);
    let mut qdd = vec![0.0; 7];
    let mut i = 0;
    c.bench_function(&format!("acceleration/{name}_box_scene"), |b| {
        b.iter(|| {
            let (q, qd) = &states[i % states.len()];
            i += 1;
            fabric
                .acceleration(
                    black_box(&scene),
                    black_box(q),
                    black_box(qd),
                    black_box(&GOAL),
                    &mut ws,
                    &mut qdd,
                )
                .expect("acceleration");
            black_box(qdd[0])
        })
    });
    let empty = Scene::new();
    c.bench_function(&format!("acceleration/{name}_free_space"), |b| {
        b.iter(|| {
            let (q, qd) = &states[i % states.len()];
            i += 1;
            fabric
                .acceleration(
                    black_box(&empty),
                    black_box(q),
                    black_box(qd),
                    black_box(&GOAL),
                    &mut ws,
                    &mut qdd,
                )
                .expect("acceleration");
            black_box(qdd[0])
        })
    });
}

fn shared_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("GFCS_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")));
    dir.is_dir().then_some(dir)
}

fn acceleration(c: &mut Criterion) {
    bench_robot(c, "panda", Robot::panda());
    match shared_dir() {
        Some(dir) => {
            let dir = dir.join("robots/mbm_panda");
            let opts = RobotOptions { ee_link: Some("panda_hand".into()), ..RobotOptions::default() };
            let mut robot = Robot::from_urdf_file(&dir.join("panda_spherized.urdf"), &opts).expect("MBM Panda");
            let srdf = std::fs::read_to_string(dir.join("panda.srdf")).expect("MBM Panda SRDF");
            robot.set_self_collision_from_srdf(&srdf, "panda.srdf").expect("SRDF");
            bench_robot(c, "mbm_panda", robot);
        }
        None => eprintln!("skipping the MotionBenchMaker Panda: shared data directory not found (set GFCS_SHARED)"),
    }
}

criterion_group!(benches, acceleration);
criterion_main!(benches);
