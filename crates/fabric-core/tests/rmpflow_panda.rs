//! RMPflow on the shipped Panda: the engine's pullback against finite-difference task maps, reaching in
//! free space, avoiding a table, and batch determinism.

use std::sync::Arc;

use fabric_core::rmpflow::{
    leaves, rmp_evaluate_batch, rmp_rollout, rmp_rollout_sequence, RmpConfig, RmpWorkspace, Rmpflow,
};
use fabric_core::robot::{KinematicsWorkspace, Robot};
use fabric_core::rollout::{RolloutOptions, SequenceOptions, StopReason};
use fabric_core::scene::{Obstacle, Scene, Shape};
use nalgebra::{DMatrix, DVector, Isometry3, Vector3};

const READY: [f64; 7] = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];

fn rmp(config: RmpConfig) -> Rmpflow {
    Rmpflow::new(Arc::new(Robot::panda()), config).unwrap()
}

fn hand(robot: &Robot, q: &[f64]) -> Vector3<f64> {
    let mut ws = KinematicsWorkspace::new(robot);
    robot.update_positions(q, &mut ws).unwrap();
    robot.link_pose(&ws, robot.ee_link()).translation.vector
}

/// Hand Jacobian (3 × n) by central differences of the forward kinematics.
fn fd_jacobian(robot: &Robot, q: &[f64]) -> DMatrix<f64> {
    let h = 1e-6;
    let mut j = DMatrix::zeros(3, q.len());
    for i in 0..q.len() {
        let (mut a, mut b) = (q.to_vec(), q.to_vec());
        a[i] += h;
        b[i] -= h;
        let d = (hand(robot, &a) - hand(robot, &b)) / (2.0 * h);
        j.set_column(i, &d);
    }
    j
}

fn table_scene() -> Scene {
    let mut scene = Scene::new();
    let shape = Shape::Cuboid {
        half_extents: Vector3::new(0.25, 0.5, 0.025),
    };
    scene
        .add(Obstacle::new(
            "table",
            shape,
            Isometry3::translation(0.55, 0.0, 0.275),
        ))
        .unwrap();
    scene
}

#[test]
fn target_leaf_pullback_matches_finite_difference_task_map() {
    // only the end-effector target leaf: M_q = JᵀMJ, f_q = JᵀM(a − J̇q̇) with J and J̇q̇ by differences
    let mut cfg = RmpConfig::default();
    cfg.cspace_target.enabled = false;
    cfg.joint_limits.enabled = false;
    cfg.damping.enabled = false;
    cfg.self_collision.enabled = false;
    let policy = rmp(cfg.clone());
    let robot = policy.robot().clone();
    let q = [0.1, -0.5, 0.2, -2.0, 0.3, 1.8, 0.5];
    let qd = [0.3, -0.2, 0.4, 0.1, -0.5, 0.2, 0.6];
    let command = [0.4, -0.3, -0.1, -1.8, 0.2, 1.5, 0.9];
    let mut ws = RmpWorkspace::new(&policy);
    let mut qdd = [0.0; 7];
    policy
        .acceleration(&Scene::new(), &q, &qd, &command, None, &mut ws, &mut qdd)
        .unwrap();
    let j = fd_jacobian(&robot, &q);
    let h = 1e-5;
    let step = |s: f64| -> Vec<f64> { q.iter().zip(&qd).map(|(a, b)| a + s * h * b).collect() };
    let qdv = DVector::from_row_slice(&qd);
    let jdqd =
        (fd_jacobian(&robot, &step(1.0)) - fd_jacobian(&robot, &step(-1.0))) / (2.0 * h) * &qdv;
    let x = hand(&robot, &q);
    let xd = &j * &qdv;
    let (a, m) = leaves::target(
        &cfg.target,
        &x,
        &Vector3::new(xd[0], xd[1], xd[2]),
        &hand(&robot, &command),
    );
    let m = DMatrix::from_column_slice(3, 3, m.as_slice());
    let want_m = j.transpose() * &m * &j;
    let want_f = j.transpose() * &m * (DVector::from_column_slice(a.as_slice()) - jdqd);
    let root = ws.root();
    assert!(
        (root.metric() - &want_m).norm() < 1e-6 * want_m.norm(),
        "{}\n{want_m}",
        root.metric()
    );
    assert!(
        (root.force() - &want_f).norm() < 1e-5 * want_f.norm().max(1.0),
        "{}\n{want_f}",
        root.force()
    );
    // the resolved acceleration realises the leaf's acceleration along the hand (J q̈ + J̇q̇ = a)
    let hand_acc = &j * DVector::from_row_slice(&qdd);
    let realised = hand_acc
        + (fd_jacobian(&robot, &step(1.0)) - fd_jacobian(&robot, &step(-1.0))) / (2.0 * h) * &qdv;
    assert!((realised - DVector::from_column_slice(a.as_slice())).norm() < 1e-4 * a.norm());
}

#[test]
fn reaches_the_hand_target_in_free_space() {
    let policy = rmp(RmpConfig::default());
    let robot = policy.robot().clone();
    let command = [0.5, -0.3, 0.0, -2.0, 0.0, 1.9, 0.785];
    let opts = RolloutOptions {
        t_max: 6.0,
        tol: 1e-9,
        record: false,
        ..RolloutOptions::default()
    };
    let mut ws = RmpWorkspace::new(&policy);
    let r = rmp_rollout(
        &policy,
        &Scene::new(),
        None,
        &READY,
        &[0.0; 7],
        &command,
        &opts,
        &mut ws,
    )
    .unwrap();
    assert_ne!(r.reason, StopReason::NonFinite);
    let error = (hand(&robot, &r.q) - hand(&robot, &command)).norm();
    assert!(error < 1e-3, "hand error {error} m");
    assert!(r.qd.iter().all(|v| v.abs() < 0.2), "{:?}", r.qd);
}

#[test]
fn avoids_a_table_between_start_and_target() {
    // a command whose hand lies inside the table top: the collision leaves hold the spheres off it
    let policy = rmp(RmpConfig::default());
    let command = [0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.785];
    let opts = RolloutOptions {
        t_max: 5.0,
        tol: 1e-9,
        record: true,
        ..RolloutOptions::default()
    };
    let mut ws = RmpWorkspace::new(&policy);
    let r = rmp_rollout(
        &policy,
        &table_scene(),
        None,
        &READY,
        &[0.0; 7],
        &command,
        &opts,
        &mut ws,
    )
    .unwrap();
    assert_ne!(r.reason, StopReason::NonFinite);
    assert!(
        r.min_clearance > -0.01,
        "min clearance {} m",
        r.min_clearance
    );
    assert!(
        r.min_clearance < 0.05,
        "the table was never approached: {} m",
        r.min_clearance
    );
}

#[test]
fn batches_match_sequential_rollouts_whatever_the_threads() {
    let policy = rmp(RmpConfig::default());
    let scene = table_scene();
    let goal = [0.3, -0.2, 0.1, -2.1, 0.0, 1.9, 0.6];
    let candidates: Vec<f64> = (0..4)
        .flat_map(|k| {
            READY
                .iter()
                .map(move |v| v + 0.1 * k as f64)
                .collect::<Vec<_>>()
        })
        .collect();
    let opts = SequenceOptions {
        n_commands: 1,
        ..SequenceOptions::default()
    };
    let one = rmp_evaluate_batch(
        &policy,
        &scene,
        &READY,
        &[0.0; 7],
        &goal,
        &candidates,
        &opts,
        Some(1),
    )
    .unwrap();
    let two = rmp_evaluate_batch(
        &policy,
        &scene,
        &READY,
        &[0.0; 7],
        &goal,
        &candidates,
        &opts,
        Some(2),
    )
    .unwrap();
    let mut ws = RmpWorkspace::new(&policy);
    for (k, (a, b)) in one.iter().zip(&two).enumerate() {
        assert_eq!(a.cost.to_bits(), b.cost.to_bits());
        let c = &candidates[7 * k..7 * k + 7];
        let s = rmp_rollout_sequence(&policy, &scene, &READY, &[0.0; 7], c, &goal, &opts, &mut ws)
            .unwrap();
        assert_eq!(s.cost.to_bits(), a.cost.to_bits());
    }
}

#[test]
fn bad_inputs_are_errors() {
    let policy = rmp(RmpConfig::default());
    let mut ws = RmpWorkspace::new(&policy);
    let mut qdd = [0.0; 7];
    let nan = [f64::NAN; 7];
    assert!(policy
        .acceleration(
            &Scene::new(),
            &nan,
            &[0.0; 7],
            &READY,
            None,
            &mut ws,
            &mut qdd
        )
        .is_err());
    assert!(policy
        .acceleration(
            &Scene::new(),
            &READY[..3],
            &[0.0; 7],
            &READY,
            None,
            &mut ws,
            &mut qdd
        )
        .is_err());
}
