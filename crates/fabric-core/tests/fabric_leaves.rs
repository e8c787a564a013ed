//! Finite-difference checks of the distance-leaf task maps (x, ẋ, J, J̇q̇) on the shipped Panda
//! (fabric::leaves): the J̇q̇ sign is the classic bug of fabric implementations, so it is checked against
//! d²/dt² x(q + t q̇) for static and moving obstacles and for self-collision pairs.
#![allow(clippy::needless_range_loop)]

use fabric_core::fabric::leaves::{obstacle_leaf, obstacle_value, self_collision_leaf};
use fabric_core::fabric::root::RootSystem;
use fabric_core::robot::{KinematicsWorkspace, Robot, TaskPoint};
use fabric_core::scene::{DistanceSample, Obstacle, Scene, Shape};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn random_state(robot: &Robot, rng: &mut ChaCha8Rng) -> (Vec<f64>, Vec<f64>) {
    let q = robot
        .lower()
        .iter()
        .zip(robot.upper())
        .map(|(&l, &u)| rng.gen_range(l + 0.1..u - 0.1))
        .collect();
    let qd = (0..robot.dof()).map(|_| rng.gen_range(-1.5..1.5)).collect();
    (q, qd)
}

fn sphere_point(
    robot: &Robot,
    ws: &mut KinematicsWorkspace,
    k: usize,
    q: &[f64],
    qd: &[f64],
) -> TaskPoint {
    robot.update(q, qd, ws).unwrap();
    let mut tp = TaskPoint::new(robot.dof());
    robot.sphere(ws, k, &mut tp);
    tp
}

fn center(robot: &Robot, ws: &mut KinematicsWorkspace, k: usize, q: &[f64]) -> Vector3<f64> {
    robot.update_positions(q, ws).unwrap();
    robot.sphere_center(ws, k)
}

fn shifted(q: &[f64], d: &[f64], t: f64) -> Vec<f64> {
    q.iter().zip(d).map(|(a, b)| a + t * b).collect()
}

/// A single obstacle placed 2-12 cm beyond sphere `k` of the arm (so the map is smooth nearby).
fn obstacle_near(
    c: &Vector3<f64>,
    r: f64,
    shape: Shape,
    rng: &mut ChaCha8Rng,
    velocity: Vector3<f64>,
) -> Scene {
    let dir = Vector3::new(
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
    )
    .normalize();
    let size = match &shape {
        Shape::Sphere { radius } => *radius,
        Shape::Capsule { radius, .. } => *radius,
        _ => 0.1,
    };
    let p = c + dir * (r + size + rng.gen_range(0.02..0.12));
    let rot = UnitQuaternion::from_euler_angles(
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
    );
    let mut s = Scene::new();
    s.add(Obstacle {
        name: "o".into(),
        shape,
        pose: Isometry3::from_parts(Translation3::from(p), rot),
        velocity,
    })
    .unwrap();
    s
}

#[test]
fn obstacle_leaf_matches_finite_differences_static_and_moving() {
    let robot = Robot::panda();
    let mut ws = KinematicsWorkspace::new(&robot);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let n = robot.dof();
    let mut checked = 0;
    for case in 0..120 {
        let (q, qd) = random_state(&robot, &mut rng);
        let k = rng.gen_range(0..robot.spheres().len());
        let r = robot.spheres()[k].radius;
        let c = center(&robot, &mut ws, k, &q);
        let shape = match case % 3 {
            0 => Shape::Sphere {
                radius: rng.gen_range(0.03..0.15),
            },
            1 => Shape::Capsule {
                half_height: rng.gen_range(0.05..0.3),
                radius: rng.gen_range(0.02..0.08),
            },
            _ => Shape::Sphere {
                radius: rng.gen_range(0.01..0.05),
            },
        };
        let v = if case % 2 == 0 {
            Vector3::zeros()
        } else {
            Vector3::new(
                rng.gen_range(-0.5..0.5),
                rng.gen_range(-0.5..0.5),
                rng.gen_range(-0.5..0.5),
            )
        };
        let scene = obstacle_near(&c, r, shape, &mut rng, v);
        // x(t) along q(t) = q + t q̇ with the obstacle translated by t v
        let mut fd_ws = KinematicsWorkspace::new(&robot);
        let mut x_at = |t: f64, dq: Option<(usize, f64)>| -> f64 {
            let mut qq = shifted(&q, &qd, t);
            if let Some((a, h)) = dq {
                qq[a] += h;
            }
            let p = center(&robot, &mut fd_ws, k, &qq) - v * t;
            scene.signed_distance(&p).unwrap().distance - r
        };
        let tp = sphere_point(&robot, &mut ws, k, &q, &qd);
        let mut samples = Vec::new();
        scene.query(&tp.x, f64::INFINITY, &mut samples);
        assert_eq!(samples.len(), 1);
        let mut jac = vec![0.0; n];
        let leaf = obstacle_leaf(&tp, r, 0.0, &samples[0], 0.0, true, &mut jac);
        assert_bare_leaf_changes_no_bit(&tp, r, &samples[0], n);
        let h = 1e-4;
        let (xm, x0, xp) = (x_at(-h, None), x_at(0.0, None), x_at(h, None));
        assert!((leaf.x - x0).abs() < 1e-12);
        let xd_fd = (xp - xm) / (2.0 * h);
        let xdd_fd = (xp - 2.0 * x0 + xm) / (h * h);
        assert!(
            (leaf.xd - xd_fd).abs() < 1e-6 * (1.0 + xd_fd.abs()),
            "ẋ {} vs {}",
            leaf.xd,
            xd_fd
        );
        assert!(
            (leaf.jdot_qdot - xdd_fd).abs() < 2e-3 * (1.0 + xdd_fd.abs()),
            "case {case}: J̇q̇ {} vs finite differences {} (sign!)",
            leaf.jdot_qdot,
            xdd_fd
        );
        for a in 0..n {
            let g = (x_at(0.0, Some((a, h))) - x_at(0.0, Some((a, -h)))) / (2.0 * h);
            assert!((jac[a] - g).abs() < 1e-6, "J[{a}] {} vs {}", jac[a], g);
        }
        checked += 1;
    }
    assert_eq!(checked, 120);
}

#[test]
fn curvature_bound_only_scales_the_hessian_term() {
    let robot = Robot::panda();
    let mut ws = KinematicsWorkspace::new(&robot);
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let (q, qd) = random_state(&robot, &mut rng);
    let k = robot.spheres().len() - 1;
    let r = robot.spheres()[k].radius;
    let c = center(&robot, &mut ws, k, &q);
    let scene = obstacle_near(
        &c,
        r,
        Shape::Sphere { radius: 0.02 },
        &mut rng,
        Vector3::zeros(),
    );
    let tp = sphere_point(&robot, &mut ws, k, &q, &qd);
    let mut samples = Vec::new();
    scene.query(&tp.x, f64::INFINITY, &mut samples);
    let s = samples[0];
    let mut jac = vec![0.0; robot.dof()];
    let exact = obstacle_leaf(&tp, r, 0.0, &s, 0.0, true, &mut jac);
    let flat = obstacle_leaf(&tp, r, 0.0, &s, 1e12, true, &mut jac);
    let rho = 1.0 / s.hessian.norm() * 2.0; // halves the Hessian term
    let half = obstacle_leaf(&tp, r, 0.0, &s, rho, true, &mut jac);
    let hess_term = exact.jdot_qdot - flat.jdot_qdot;
    assert!(hess_term.abs() > 1e-6, "the test needs a curved field");
    assert!((half.jdot_qdot - (flat.jdot_qdot + 0.5 * hess_term)).abs() < 1e-12);
    assert_eq!((exact.x, exact.xd), (half.x, half.xd));
}

#[test]
fn self_collision_leaf_matches_finite_differences() {
    let robot = Robot::panda();
    let mut ws = KinematicsWorkspace::new(&robot);
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let n = robot.dof();
    let pairs = robot.self_collision_pairs().to_vec();
    assert!(!pairs.is_empty());
    for _ in 0..80 {
        let (q, qd) = random_state(&robot, &mut rng);
        let (a, b) = pairs[rng.gen_range(0..pairs.len())];
        let (ra, rb) = (robot.spheres()[a].radius, robot.spheres()[b].radius);
        let mut fd_ws = KinematicsWorkspace::new(&robot);
        let mut x_at = |qq: &[f64]| {
            let ca = center(&robot, &mut fd_ws, a, qq);
            (ca - robot.sphere_center(&fd_ws, b)).norm() - ra - rb
        };
        let ta = sphere_point(&robot, &mut ws, a, &q, &qd);
        let tb = sphere_point(&robot, &mut ws, b, &q, &qd);
        let mut jac = vec![0.0; n];
        let leaf = self_collision_leaf(&ta, ra, &tb, rb, 0.0, 0.0, &mut jac);
        let h = 1e-4;
        let (xm, x0, xp) = (
            x_at(&shifted(&q, &qd, -h)),
            x_at(&q),
            x_at(&shifted(&q, &qd, h)),
        );
        assert!((leaf.x - x0).abs() < 1e-12);
        assert!((leaf.xd - (xp - xm) / (2.0 * h)).abs() < 1e-6);
        let xdd = (xp - 2.0 * x0 + xm) / (h * h);
        assert!(
            (leaf.jdot_qdot - xdd).abs() < 2e-3 * (1.0 + xdd.abs()),
            "J̇q̇ {} vs {}",
            leaf.jdot_qdot,
            xdd
        );
        for k in 0..n {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[k] += h;
            qm[k] -= h;
            let g = (x_at(&qp) - x_at(&qm)) / (2.0 * h);
            assert!((jac[k] - g).abs() < 1e-6);
        }
    }
}

/// `obstacle_leaf` without curvature (the engine's path for a leaf of zero metric) gives the same x, ẋ and
/// J as with it, J̇q̇ = 0, and the root it builds with m = 0 is the same to the bit as with the full J̇q̇:
/// the root uses J̇q̇ only multiplied by m.
fn assert_bare_leaf_changes_no_bit(tp: &TaskPoint, r: f64, sample: &DistanceSample, n: usize) {
    let (mut jac_full, mut jac_bare) = (vec![0.0; n], vec![0.0; n]);
    let full = obstacle_leaf(tp, r, 0.002, sample, 0.01, true, &mut jac_full);
    let bare = obstacle_leaf(tp, r, 0.002, sample, 0.01, false, &mut jac_bare);
    assert_eq!((full.x, full.xd, full.width), (bare.x, bare.xd, bare.width));
    assert_eq!((full.x, full.xd), obstacle_value(tp, r, 0.002, sample));
    assert_eq!(jac_full, jac_bare);
    assert_eq!(bare.jdot_qdot, 0.0);
    let (mut a, mut b) = (RootSystem::new(n), RootSystem::new(n));
    for (root, leaf) in [(&mut a, &full), (&mut b, &bare)] {
        // a zero-metric barrier: ξ = f = 0, only the forcing slope
        root.add_scalar(
            &jac_full[..leaf.width],
            leaf.jdot_qdot,
            0.0,
            0.0,
            0.0,
            -0.3,
            0.0,
        );
    }
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(a.m.as_slice()), bits(b.m.as_slice()));
    assert_eq!(bits(a.xi.as_slice()), bits(b.xi.as_slice()));
    assert_eq!(bits(a.f.as_slice()), bits(b.f.as_slice()));
    assert_eq!(bits(a.grad.as_slice()), bits(b.grad.as_slice()));
}
