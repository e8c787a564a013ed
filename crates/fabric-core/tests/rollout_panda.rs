//! Rollouts of the Panda fabric (GFCS eq. 1–8): joint limits over long rollouts, reaching in free space,
//! the clearance monitor against a brute-force distance computation, and batch determinism.

use std::sync::Arc;

use fabric_core::fabric::{Fabric, FabricConfig, FabricWorkspace};
use fabric_core::robot::{batch, Robot};
use fabric_core::rollout::{
    evaluate_batch, rollout, rollout_sequence, RolloutOptions, SequenceOptions, SequenceResult, StopReason,
};
use fabric_core::scene::{Obstacle, Scene, Shape};
use nalgebra::{Isometry3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];

fn panda_fabric() -> Fabric {
    Fabric::new(Arc::new(Robot::panda()), FabricConfig::default()).unwrap()
}

/// Minimum over the self-collision sphere pairs of ‖c_a − c_b‖ − r_a − r_b at each of the N
/// configurations in `qs` (N × dof), computed from the batch forward kinematics.
fn self_clearances(robot: &Robot, qs: &[f64]) -> Vec<f64> {
    let s = robot.spheres().len();
    let centers = batch::sphere_centers(robot, qs).unwrap();
    centers
        .chunks(s)
        .map(|c| {
            robot
                .self_collision_pairs()
                .iter()
                .map(|&(a, b)| (c[a] - c[b]).norm() - robot.spheres()[a].radius - robot.spheres()[b].radius)
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// A table top in front of the robot, its surface at z = 0.3 m.
fn table_scene() -> Scene {
    let mut scene = Scene::new();
    let pose = Isometry3::translation(0.55, 0.0, 0.275);
    scene.add(Obstacle::new("table", Shape::Cuboid { half_extents: Vector3::new(0.25, 0.5, 0.025) }, pose)).unwrap();
    scene
}

#[test]
fn joint_limits_hold_over_long_rollouts() {
    let fabric = panda_fabric();
    let robot = fabric.robot().clone();
    let (lo, up) = (robot.lower().to_vec(), robot.upper().to_vec());
    let scene = Scene::new();
    let mut ws = FabricWorkspace::new(&fabric);
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    let opts = RolloutOptions { t_max: 10.0, record: true, ..RolloutOptions::default() };
    // Valid starts: outside the joint-limit barrier margins and free of self-collision.
    let margin = fabric.config().joint_limits.margin;
    let mut runs = 0;
    let mut reached = 0;
    while runs < 60 {
        let q0: Vec<f64> = (0..7).map(|i| rng.gen_range(lo[i] + margin..up[i] - margin)).collect();
        if self_clearances(&robot, &q0)[0] < fabric.config().self_collision.margin {
            continue;
        }
        let qd0: Vec<f64> = (0..7).map(|_| rng.gen_range(-0.5..0.5)).collect();
        // Commands up to 0.3 rad beyond the limits: the limit barriers must hold against the attractor.
        let command: Vec<f64> = (0..7).map(|i| rng.gen_range(lo[i] - 0.3..up[i] + 0.3)).collect();
        let r = rollout(&fabric, &scene, &q0, &qd0, &command, &opts, &mut ws).unwrap();
        assert_ne!(r.reason, StopReason::NonFinite, "q0 {q0:?} qd0 {qd0:?} command {command:?}");
        let tr = r.trajectory.unwrap();
        for k in 0..tr.len() {
            let q = tr.q_row(k).unwrap();
            for i in 0..7 {
                assert!(
                    q[i] >= lo[i] && q[i] <= up[i],
                    "joint {i} = {} outside [{}, {}] at t = {}",
                    q[i],
                    lo[i],
                    up[i],
                    tr.t[k]
                );
            }
        }
        reached += usize::from(r.reason == StopReason::Reached);
        runs += 1;
    }
    assert!(reached > 0, "no rollout reached its command");
}

/// A start inside the joint-limit barrier margin (joint 2 at 0.0039 rad from its lower limit, margin
/// 0.01 rad) moving toward the limit at 0.44 rad/s. MotionBenchMaker starts can sit exactly on a limit
/// (table_under_pick), so the fabric must stay finite there at dt = 0.01 s.
#[test]
#[ignore = "fabric diverges at dt = 0.01 s from starts inside the joint-limit margin (q̈ ≈ 6e3 rad/s² at the start); run with --ignored once fixed"]
fn start_inside_the_joint_limit_margin_stays_finite() {
    let fabric = panda_fabric();
    let (lo, up) = (fabric.robot().lower().to_vec(), fabric.robot().upper().to_vec());
    let q0 = [
        -2.020942649826434,
        -1.7589195031101879,
        2.03952456737755,
        -1.897662497382436,
        2.7103742052398814,
        3.09583235350066,
        1.492220924912218,
    ];
    let qd0 = [-0.0938, -0.4375, -0.0746, 0.4667, -0.3338, 0.2499, 0.3490];
    let command = [0.7966, -0.9874, -2.1507, -0.0186, 0.1404, 1.4506, 0.2168];
    let opts = RolloutOptions { record: true, ..RolloutOptions::default() };
    let r = rollout(&fabric, &Scene::new(), &q0, &qd0, &command, &opts, &mut FabricWorkspace::new(&fabric)).unwrap();
    assert_ne!(r.reason, StopReason::NonFinite);
    let tr = r.trajectory.unwrap();
    assert!(tr.q.iter().enumerate().all(|(k, q)| *q >= lo[k % 7] && *q <= up[k % 7]));
}

#[test]
fn reaches_goals_in_free_space() {
    let fabric = panda_fabric();
    let scene = Scene::new();
    let mut ws = FabricWorkspace::new(&fabric);
    let opts = RolloutOptions { record: true, ..RolloutOptions::default() };
    for goal in [
        [0.5, -0.3, 0.3, -1.8, 0.2, 1.9, 0.5],
        [-1.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.0],
        [1.2, -0.2, -0.5, -2.6, 0.4, 1.2, 1.5],
    ] {
        let r = rollout(&fabric, &scene, &READY, &[0.0; 7], &goal, &opts, &mut ws).unwrap();
        assert_eq!(r.reason, StopReason::Reached, "goal {goal:?}");
        assert!(r.t_star > 0.1 && r.t_star < 7.0);
        let d = r.q.iter().zip(&goal).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
        assert!(d < opts.tol);
        let tr = r.trajectory.unwrap();
        assert_eq!(tr.len(), r.steps + 1);
        assert!((tr.t[tr.len() - 1] - r.t_star).abs() < 1e-12);
        assert!(r.min_clearance > 0.0, "self-collision on the way to {goal:?}");
    }
}

#[test]
fn clearance_monitor_matches_brute_force() {
    let fabric = panda_fabric();
    let robot = fabric.robot().clone();
    let scene = table_scene();
    let mut ws = FabricWorkspace::new(&fabric);
    // Reach down toward the table: the hand gets close to its surface.
    let goal = [0.0, 0.6, 0.0, -1.6, 0.0, 2.2, 0.785];
    let opts = RolloutOptions { record: true, ..RolloutOptions::default() };
    let r = rollout(&fabric, &scene, &READY, &[0.0; 7], &goal, &opts, &mut ws).unwrap();
    let tr = r.trajectory.unwrap();

    let s = robot.spheres().len();
    let centers = batch::sphere_centers(&robot, &tr.q).unwrap();
    let obstacle = centers
        .iter()
        .enumerate()
        .map(|(k, c)| scene.signed_distance(c).unwrap().distance - robot.spheres()[k % s].radius)
        .fold(f64::INFINITY, f64::min);
    let own = self_clearances(&robot, &tr.q).into_iter().fold(f64::INFINITY, f64::min);
    let ob = &fabric.config().obstacles;
    assert!(obstacle < ob.margin + ob.influence, "the scenario must come within the influence radius");
    assert!(obstacle < 0.1);
    assert!(
        (r.min_clearance - obstacle.min(own)).abs() < 1e-9,
        "monitor {} brute force {}",
        r.min_clearance,
        obstacle.min(own)
    );
}

fn bits(r: &SequenceResult) -> Vec<u64> {
    let mut v = vec![r.cost.to_bits(), r.min_clearance.to_bits()];
    v.extend(r.t_stars.iter().chain(&r.q).chain(&r.qd).map(|x| x.to_bits()));
    v
}

#[test]
fn batch_is_identical_on_one_and_two_threads() {
    let fabric = panda_fabric();
    let robot = fabric.robot().clone();
    let scene = table_scene();
    let goal = [0.4, 0.5, 0.2, -1.7, 0.0, 2.2, 0.9];
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let n = 12;
    let candidates: Vec<f64> = (0..n * 7).map(|k| rng.gen_range(robot.lower()[k % 7]..robot.upper()[k % 7])).collect();
    let opts = SequenceOptions {
        rollout: RolloutOptions { t_max: 3.0, ..RolloutOptions::default() },
        ..SequenceOptions::default()
    };
    let one = evaluate_batch(&fabric, &scene, &READY, &[0.0; 7], &goal, &candidates, &opts, Some(1)).unwrap();
    let two = evaluate_batch(&fabric, &scene, &READY, &[0.0; 7], &goal, &candidates, &opts, Some(2)).unwrap();
    assert_eq!(one.len(), n);
    let mut ws = FabricWorkspace::new(&fabric);
    for j in 0..n {
        let single = rollout_sequence(
            &fabric,
            &scene,
            &READY,
            &[0.0; 7],
            &candidates[j * 7..(j + 1) * 7],
            &goal,
            &opts,
            &mut ws,
        )
        .unwrap();
        assert_eq!(bits(&one[j]), bits(&single), "candidate {j}");
        assert_eq!(bits(&two[j]), bits(&single), "candidate {j}");
    }
    assert!(one.iter().any(|r| r.cost != one[0].cost));
}
