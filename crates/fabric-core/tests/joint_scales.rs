//! The joint attractor on scaled coordinates x = S (q − q_g) (`Fabric::with_joint_scales`): unit scales
//! change no bit of q̈, the scaled fabric is the unscaled one in the coordinates y = S q (the pullback
//! through the constant Jacobian S), and bad scales are refused with the field and joint named.

use std::sync::Arc;

use fabric_core::error::FabricError;
use fabric_core::fabric::{Fabric, FabricConfig, FabricWorkspace};
use fabric_core::robot::Robot;
use fabric_core::scene::{Obstacle, Scene, Shape};
use nalgebra::{Isometry3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn acceleration(fabric: &Fabric, scene: &Scene, q: &[f64], qd: &[f64], goal: &[f64]) -> Vec<f64> {
    let mut ws = FabricWorkspace::new(fabric);
    let mut qdd = vec![0.0; q.len()];
    fabric
        .acceleration(scene, q, qd, goal, &mut ws, &mut qdd)
        .expect("acceleration");
    qdd
}

fn random(rng: &mut ChaCha8Rng, n: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..n).map(|_| rng.gen_range(lo..hi)).collect()
}

/// Scales of 1 give the same q̈ bit for bit as no scales, with every component on and obstacles near.
#[test]
fn unit_scales_change_no_bit() {
    let robot = Arc::new(Robot::panda());
    let fabric = Fabric::new(robot.clone(), FabricConfig::default()).unwrap();
    let scaled = fabric
        .clone()
        .with_joint_scales(Some(vec![1.0; 7]))
        .unwrap();
    let mut scene = Scene::new();
    scene
        .add(Obstacle::new(
            "box",
            Shape::Cuboid {
                half_extents: Vector3::new(0.1, 0.3, 0.2),
            },
            Isometry3::translation(0.5, 0.0, 0.4),
        ))
        .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..200 {
        let q: Vec<f64> = (0..7)
            .map(|j| rng.gen_range(robot.lower()[j]..robot.upper()[j]))
            .collect();
        let qd = random(&mut rng, 7, -1.0, 1.0);
        let goal = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
        assert_eq!(
            acceleration(&fabric, &scene, &q, &qd, &goal),
            acceleration(&scaled, &scene, &q, &qd, &goal)
        );
    }
}

/// With only the joint attractor, energization and a constant damping (no task-space leaves, no
/// coordinate-dependent switches), the fabric with scales S at (q, q̇; q_g) is the plain fabric at
/// (S q, S q̇; S q_g) seen through y = S q: S q̈ = ÿ (GF Sec. V: a fabric pulled back through a constant
/// Jacobian).
#[test]
fn scaled_attractor_is_the_plain_one_in_scaled_coordinates() {
    let robot = Arc::new(Robot::panda());
    let mut cfg = FabricConfig::default();
    cfg.ee_position.enabled = false;
    cfg.ee_orientation.enabled = false;
    cfg.joint_limits.enabled = false;
    cfg.self_collision.enabled = false;
    cfg.speed.enabled = false;
    cfg.speed.goal_damping = 0.0;
    let plain = Fabric::new(robot, cfg).unwrap();
    let empty = Scene::new();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for _ in 0..200 {
        let s = random(&mut rng, 7, 0.2, 5.0);
        let scaled = plain.clone().with_joint_scales(Some(s.clone())).unwrap();
        let (q, qd, goal) = (
            random(&mut rng, 7, -2.0, 2.0),
            random(&mut rng, 7, -1.5, 1.5),
            random(&mut rng, 7, -2.0, 2.0),
        );
        let scale = |v: &[f64]| v.iter().zip(&s).map(|(a, b)| a * b).collect::<Vec<_>>();
        let got = scale(&acceleration(&scaled, &empty, &q, &qd, &goal));
        let want = acceleration(&plain, &empty, &scale(&q), &scale(&qd), &scale(&goal));
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (g - w).abs() <= 1e-9 * (1.0 + w.abs()),
                "{got:?} vs {want:?}"
            );
        }
    }
}

/// Wrong length, non-finite and non-positive scales are errors naming the field (and the joint).
#[test]
fn bad_scales_are_refused() {
    let fabric = Fabric::new(Arc::new(Robot::panda()), FabricConfig::default()).unwrap();
    assert!(matches!(
        fabric.clone().with_joint_scales(Some(vec![1.0; 6])),
        Err(FabricError::Shape { .. })
    ));
    let mut nan = vec![1.0; 7];
    nan[3] = f64::NAN;
    assert!(matches!(
        fabric.clone().with_joint_scales(Some(nan)),
        Err(FabricError::NonFinite { .. })
    ));
    let mut zero = vec![1.0; 7];
    zero[2] = 0.0;
    match fabric.clone().with_joint_scales(Some(zero)) {
        Err(FabricError::Value { what, message }) => {
            assert_eq!(what, "joint_scales[2]");
            assert!(message.contains("panda_joint3"), "{message}");
        }
        other => panic!("expected a Value error, got {other:?}"),
    }
    let cleared = fabric
        .with_joint_scales(Some(vec![2.0; 7]))
        .unwrap()
        .with_joint_scales(None)
        .unwrap();
    assert!(cleared.joint_scales().is_none());
}
