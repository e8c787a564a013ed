//! One fabric evaluation `Fabric::acceleration` of the Panda (forward kinematics, all collision spheres
//! against a MotionBenchMaker-like "box" scene built in code, self-collision pairs, joint limits, joint
//! attraction, energization and speed control), at states recorded along a rollout so that the number of
//! barrier leaves is representative. Targets on one core (BENCHMARKS.md "Speed"): ≤ 2 µs for the MBM Panda
//! in free space, ≤ 5 µs in the cage scene.
//!
//! Benchmarks: the shipped Panda (`Robot::panda()`), and the spherized MotionBenchMaker Panda (59 spheres)
//! when the shared data directory is present (`../shared` or `$GFCS_SHARED`; skipped with a message
//! otherwise), in the box scene, in free space and (MBM Panda only) in the dense MotionBenchMaker cage
//! scene 0001 (8 boxes: a cube inside a cage of base, cap, back, left and right walls and two front
//! bars, the hand reaching in), at states recorded from its start toward its goal.
//!
//! Where a cluttered step's time goes: the cage states are also timed with the obstacle barrier off
//! (`mbm_panda_cage_scene_obstacles_off_no_psi`: kinematics, self-collision, attractors and the solve;
//! the difference is the obstacle leaves with their broadphase and distances), and one obstacle
//! `Barrier::eval` is timed alone (`barrier/obstacle_eval`, 64 leaf states across the influence
//! radius, half approaching); the mean leaves per evaluation are printed with the recorded states, and
//! a digest of the bits of their rollout's q̈ (a speed change that claims the same q̈ bit for bit leaves
//! the digests unchanged; `cargo bench -p fabric-core --bench acceleration -- --test` prints them alone).
//!
//! Each case runs twice: with a `FabricWorkspace::new` (diagnostics with the forcing potential ψ) and,
//! suffixed `_no_psi`, with `FabricWorkspace::for_rollouts` (ψ off: what a rollout step and
//! `gfcs.Fabric.acceleration` evaluate; the same q̈ bit for bit).
//!
//! Run: `cargo bench -p fabric-core --bench acceleration`.

use std::sync::Arc;

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use fabric_core::fabric::components::Barrier;
use fabric_core::fabric::{Fabric, FabricConfig, FabricWorkspace};
use fabric_core::robot::Robot;
use fabric_core::scene::Scene;

/// The box scene, the MBM Panda loader and the shared-data root are the integration tests' own.
#[path = "../tests/fabric_support/mod.rs"]
mod fabric_support;
use fabric_support::{box_scene, mbm_panda, mbm_problem, shared_root};

/// The 64-bit FNV-1a offset basis and prime, for the q̈ digest of [`recorded_states`].
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

const READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
/// A goal with the hand inside the box (sphere-model clearance of a few cm).
const GOAL: [f64; 7] = [0.45, 0.35, 0.19, -1.9, -0.1, 2.3, 0.8];

/// (q, q̇) every 5th step of a 4 s semi-implicit Euler rollout from `start` toward `goal`; prints the mean
/// leaves per evaluation and the digest of the bits of every q̈ of the rollout (FNV-1a over 64-bit words).
fn recorded_states(
    fabric: &Fabric,
    scene: &Scene,
    start: &[f64],
    goal: &[f64],
) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut ws = FabricWorkspace::new(fabric);
    let (mut q, mut qd, mut qdd) = (start.to_vec(), vec![0.0; 7], vec![0.0; 7]);
    let mut out = Vec::new();
    let mut leaves = 0;
    let mut digest = FNV_OFFSET;
    for k in 0..400 {
        if fabric
            .acceleration(scene, &q, &qd, goal, &mut ws, &mut qdd)
            .is_err()
        {
            break;
        }
        leaves += fabric.diagnostics(&ws).leaves;
        for v in &qdd {
            digest = (digest ^ v.to_bits()).wrapping_mul(FNV_PRIME);
        }
        if k % 5 == 0 {
            out.push((q.clone(), qd.clone()));
        }
        for i in 0..7 {
            qd[i] += 0.01 * qdd[i];
            q[i] += 0.01 * qd[i];
        }
    }
    eprintln!(
        "{} spheres, {} self-collision pairs; mean leaves per evaluation along the recorded rollout: {:.1}; \
         q̈ digest {digest:016x}",
        fabric.robot().spheres().len(),
        fabric.robot().self_collision_pairs().len(),
        leaves as f64 / 400.0
    );
    out
}

/// Time `Fabric::acceleration` in `scene` toward `goal`, cycling through the recorded `states`.
fn bench_states(
    c: &mut Criterion,
    name: &str,
    fabric: &Fabric,
    scene: &Scene,
    states: &[(Vec<f64>, Vec<f64>)],
    goal: &[f64],
) {
    for (suffix, mut ws) in [
        ("", FabricWorkspace::new(fabric)),
        ("_no_psi", FabricWorkspace::for_rollouts(fabric)),
    ] {
        bench_workspace(
            c,
            &format!("{name}{suffix}"),
            fabric,
            scene,
            states,
            goal,
            &mut ws,
        );
    }
}

/// [`bench_states`] with one workspace: `FabricWorkspace::new` (diagnostics with ψ) or
/// `FabricWorkspace::for_rollouts` (ψ off, as in rollouts and `gfcs.Fabric.acceleration`; same q̈).
fn bench_workspace(
    c: &mut Criterion,
    name: &str,
    fabric: &Fabric,
    scene: &Scene,
    states: &[(Vec<f64>, Vec<f64>)],
    goal: &[f64],
    ws: &mut FabricWorkspace,
) {
    let mut qdd = vec![0.0; 7];
    let mut i = 0;
    c.bench_function(&format!("acceleration/{name}"), |b| {
        b.iter(|| {
            let (q, qd) = &states[i % states.len()];
            i += 1;
            fabric
                .acceleration(
                    black_box(scene),
                    black_box(q),
                    black_box(qd),
                    black_box(goal),
                    ws,
                    &mut qdd,
                )
                .expect("acceleration");
            black_box(qdd[0])
        })
    });
}

fn bench_robot(c: &mut Criterion, name: &str, robot: Robot) -> Fabric {
    let fabric = Fabric::new(Arc::new(robot), FabricConfig::default()).expect("default fabric");
    let scene = box_scene();
    let states = recorded_states(&fabric, &scene, &READY, &GOAL);
    bench_states(
        c,
        &format!("{name}_box_scene"),
        &fabric,
        &scene,
        &states,
        &GOAL,
    );
    let empty = Scene::new();
    bench_states(
        c,
        &format!("{name}_free_space"),
        &fabric,
        &empty,
        &states,
        &GOAL,
    );
    fabric
}

fn acceleration(c: &mut Criterion) {
    bench_robot(c, "panda", Robot::panda());
    // A benchmark never fails for missing data (unlike the tests under CI): it only skips.
    let shared = shared_root();
    if shared.is_dir() {
        let fabric = bench_robot(c, "mbm_panda", mbm_panda(&shared));
        let (scene, start, goal) = mbm_problem(&shared, fabric.robot(), "cage", 1);
        let states = recorded_states(&fabric, &scene, &start, &goal);
        if states.is_empty() {
            eprintln!("skipping the cage scene: the fabric fails at its start state");
        } else {
            bench_states(c, "mbm_panda_cage_scene", &fabric, &scene, &states, &goal);
            let mut config = FabricConfig::default();
            config.obstacles.enabled = false;
            let without = Fabric::new(fabric.robot().clone(), config).expect("fabric");
            bench_workspace(
                c,
                "mbm_panda_cage_scene_obstacles_off_no_psi",
                &without,
                &scene,
                &states,
                &goal,
                &mut FabricWorkspace::for_rollouts(&without),
            );
        }
    } else {
        eprintln!("skipping the MotionBenchMaker Panda: shared data directory not found (set GFCS_SHARED)");
    }
}

/// One obstacle barrier evaluation (GF VII-A2: metric, geometry, forcing; ψ off as in rollouts) at 64
/// leaf states: x across the default influence radius from inside the margin, ẋ alternating sign.
fn barrier(c: &mut Criterion) {
    let cfg = FabricConfig::default().obstacles;
    let b = Barrier::from_config(&cfg);
    let leaves: Vec<(f64, f64)> = (0..64)
        .map(|k| {
            let x = -0.002 + (cfg.influence + 0.002) * k as f64 / 64.0;
            let xd = if k % 2 == 0 { -0.4 } else { 0.3 };
            (x, xd)
        })
        .collect();
    let mut i = 0;
    c.bench_function("barrier/obstacle_eval", |bench| {
        bench.iter(|| {
            let (x, xd) = leaves[i % leaves.len()];
            i += 1;
            black_box(b.eval(black_box(x), black_box(xd), false))
        })
    });
}

criterion_group!(benches, acceleration, barrier);
criterion_main!(benches);
