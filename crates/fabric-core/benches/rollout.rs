//! Rollout benchmarks on the shipped Panda in a MotionBenchMaker-like bookshelf scene built in code:
//! * one rollout from the ready pose toward a goal at a shelf compartment (t_max = 7 s, dt = 0.01 s);
//! * a batch of 64 two-command candidates (one free command, then the goal: GFCS eq. 4–8) with 1 and
//!   2 rayon threads (the speed-up of Alg. 1's parallel evaluation).
//!
//! Run: `cargo bench -p fabric-core --bench rollout`.

use std::sync::Arc;

use criterion::{black_box, criterion_group, criterion_main, BenchmarkId, Criterion};
use fabric_core::fabric::{Fabric, FabricConfig, FabricWorkspace};
use fabric_core::robot::Robot;
use fabric_core::rollout::{evaluate_batch, rollout, RolloutOptions, SequenceOptions};
use fabric_core::scene::{Obstacle, Scene, Shape};
use nalgebra::{Isometry3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
/// A collision-free goal with the hand at the opening of the shelf's bottom compartment (reached in
/// about 2.8 s from the ready pose with the default fabric).
const GOAL: [f64; 7] = [0.0, 0.2, 0.0, -2.2, 0.0, 1.6, 0.785];

fn cuboid(scene: &mut Scene, name: &str, size: [f64; 3], at: [f64; 3]) {
    let shape = Shape::Cuboid {
        half_extents: Vector3::new(size[0], size[1], size[2]) * 0.5,
    };
    let pose = Isometry3::translation(at[0], at[1], at[2]);
    scene
        .add(Obstacle::new(name, shape, pose))
        .expect("valid benchmark obstacle");
}

/// A bookshelf 0.7 m in front of the robot (boards, sides, back: boxes, full sizes in m) and three cans
/// (cylinders) on its bottom board, in the style of MotionBenchMaker's bookshelf_small.
fn bookshelf_scene() -> Scene {
    let mut scene = Scene::new();
    let (x, depth, width) = (0.75, 0.35, 1.0);
    for (k, z) in [0.2, 0.55, 0.9].into_iter().enumerate() {
        cuboid(
            &mut scene,
            &format!("board{k}"),
            [depth, width, 0.03],
            [x, 0.0, z],
        );
    }
    for (k, y) in [-0.5, 0.5].into_iter().enumerate() {
        cuboid(
            &mut scene,
            &format!("side{k}"),
            [depth, 0.03, 0.75],
            [x, y, 0.55],
        );
    }
    cuboid(
        &mut scene,
        "back",
        [0.03, width, 0.75],
        [x + depth * 0.5, 0.0, 0.55],
    );
    for (k, y) in [-0.3, 0.1, 0.35].into_iter().enumerate() {
        let shape = Shape::Cylinder {
            half_height: 0.07,
            radius: 0.03,
        };
        let pose = Isometry3::translation(x, y, 0.2 + 0.015 + 0.07);
        scene
            .add(Obstacle::new(format!("can{k}"), shape, pose))
            .expect("valid benchmark obstacle");
    }
    scene
}

fn single_rollout(c: &mut Criterion) {
    let fabric =
        Fabric::new(Arc::new(Robot::panda()), FabricConfig::default()).expect("default fabric");
    let scene = bookshelf_scene();
    let mut ws = FabricWorkspace::for_rollouts(&fabric);
    let opts = RolloutOptions::default();
    let r = rollout(&fabric, &scene, &READY, &[0.0; 7], &GOAL, &opts, &mut ws).expect("rollout");
    eprintln!(
        "rollout/panda_bookshelf: {:?} after {} steps (t* = {:.2} s), min clearance {:.4} m",
        r.reason, r.steps, r.t_star, r.min_clearance
    );
    let mut group = c.benchmark_group("rollout");
    group.sample_size(20);
    group.bench_function("panda_bookshelf_7s", |b| {
        b.iter(|| {
            rollout(
                &fabric,
                &scene,
                black_box(&READY),
                &[0.0; 7],
                black_box(&GOAL),
                &opts,
                &mut ws,
            )
        })
    });
    group.finish();
}

fn batch(c: &mut Criterion) {
    let robot = Arc::new(Robot::panda());
    let fabric = Fabric::new(robot.clone(), FabricConfig::default()).expect("default fabric");
    let scene = bookshelf_scene();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    // 64 candidates: one free command each, uniform within the joint limits (a first, unguided CMA-ES
    // batch of Alg. 1).
    let candidates: Vec<f64> = (0..64 * 7)
        .map(|k| rng.gen_range(robot.lower()[k % 7]..robot.upper()[k % 7]))
        .collect();
    let opts = SequenceOptions::default();
    let results = evaluate_batch(
        &fabric,
        &scene,
        &READY,
        &[0.0; 7],
        &GOAL,
        &candidates,
        &opts,
        Some(1),
    )
    .expect("batch");
    let steps: f64 = results.iter().flat_map(|r| r.t_stars.iter()).sum::<f64>() / 0.01;
    let reached = results.iter().filter(|r| r.reached).count();
    eprintln!("batch64: {reached}/64 candidates reach the goal, about {steps:.0} integration steps per batch");
    let mut group = c.benchmark_group("batch64_two_commands");
    group.sample_size(10);
    for threads in [1usize, 2] {
        group.bench_with_input(
            BenchmarkId::from_parameter(format!("threads={threads}")),
            &threads,
            |b, &t| {
                b.iter(|| {
                    evaluate_batch(
                        &fabric,
                        &scene,
                        &READY,
                        &[0.0; 7],
                        &GOAL,
                        black_box(&candidates),
                        &opts,
                        Some(t),
                    )
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, single_rollout, batch);
criterion_main!(benches);
