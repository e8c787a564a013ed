//! J and J̇q̇ of points, axes and spheres against central finite differences of the forward kinematics,
//! on the shipped Panda, the MotionBenchMaker Panda, a re-rooted Panda and a small mimic robot.

mod robot_support;

use fabric_core::robot::{KinematicsWorkspace, Robot, RobotOptions};
use nalgebra::{Point3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robot_support::{check_task, mbm_panda_dir, mbm_spherized, random_state, Task};

const TOL: f64 = 1e-6;
/// The FK-only second difference (Richardson-extrapolated) is accurate to about 1e-9 m/s².
const TOL_SECOND: f64 = 1e-5;

/// Every sphere, a point on every link, and the three unit axes of every link, at `states` random states.
fn check_robot(robot: &Robot, states: usize, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut worst, mut worst2) = (0.0_f64, 0.0_f64);
    for _ in 0..states {
        let (q, qd) = random_state(robot, &mut rng);
        let mut tasks: Vec<Task> = robot
            .spheres()
            .iter()
            .map(|s| Task::Point(s.link, s.center))
            .collect();
        for l in 0..robot.link_names().len() {
            let p = Vector3::new(
                rng.gen_range(-0.2..0.2),
                rng.gen_range(-0.2..0.2),
                rng.gen_range(-0.2..0.2),
            );
            tasks.push(Task::Point(l, p));
            for u in [Vector3::x(), Vector3::y(), Vector3::z()] {
                tasks.push(Task::Axis(l, u));
            }
        }
        for t in &tasks {
            let (e, e2) = check_task(t, robot, &q, &qd);
            assert!(
                e < TOL,
                "{}: {t:?} at q={q:?} qd={qd:?}: relative error {e}",
                robot.name()
            );
            assert!(
                e2 < TOL_SECOND,
                "{}: {t:?} J̇q̇ vs FK second difference: {e2}",
                robot.name()
            );
            worst = worst.max(e);
            worst2 = worst2.max(e2);
        }
    }
    eprintln!(
        "{}: worst relative error {worst:.2e} (FK second difference {worst2:.2e})",
        robot.name()
    );
}

#[test]
fn sphere_api_matches_point_on_shipped_panda() {
    let robot = Robot::panda();
    let mut ws = KinematicsWorkspace::new(&robot);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (q, qd) = random_state(&robot, &mut rng);
    robot.update(&q, &qd, &mut ws).unwrap();
    let (mut a, mut b) = (
        fabric_core::robot::TaskPoint::new(7),
        fabric_core::robot::TaskPoint::new(7),
    );
    for (i, s) in robot.spheres().iter().enumerate() {
        robot.sphere(&ws, i, &mut a);
        robot.point(&ws, s.link, &s.center, &mut b);
        assert_eq!(a, b);
        assert!((robot.sphere_center(&ws, i) - a.x).norm() < 1e-15);
    }
}

#[test]
fn shipped_panda_derivatives_match_finite_differences() {
    check_robot(&Robot::panda(), 60, 1);
}

#[test]
fn mbm_panda_derivatives_match_finite_differences() {
    let Some(robot) = mbm_spherized() else { return };
    assert_eq!(robot.spheres().len(), 59);
    check_robot(&robot, 40, 2);
}

/// The shipped Panda with its fingers active (a prismatic joint and its mimic, on two branches).
#[test]
fn panda_with_active_fingers_derivatives() {
    let xml = include_str!("../assets/panda.urdf");
    let mut joints: Vec<String> = (1..=7).map(|i| format!("panda_joint{i}")).collect();
    joints.push("panda_finger_joint1".into());
    let opts = RobotOptions {
        active_joints: Some(joints),
        ..Default::default()
    };
    let robot = Robot::from_urdf_str(xml, "panda.urdf", &opts).unwrap();
    assert_eq!(robot.dof(), 8);
    check_robot(&robot, 20, 4);
}

/// `xml` re-rooted at `base` (the joints above it are reversed): every link pose equals the plain
/// model's pose relative to `base`, and the derivatives match finite differences.
fn check_rerooted(xml: &str, base: &str, ee: &str, joints: &[&str], seed: u64) {
    let joints: Vec<String> = joints.iter().map(|j| j.to_string()).collect();
    let opts = RobotOptions {
        base_link: Some(base.into()),
        ee_link: Some(ee.into()),
        active_joints: Some(joints.clone()),
        ..Default::default()
    };
    let rerooted = Robot::from_urdf_str(xml, "r.urdf", &opts).unwrap();
    let plain_opts = RobotOptions {
        active_joints: Some(joints),
        ..Default::default()
    };
    let plain = Robot::from_urdf_str(xml, "r.urdf", &plain_opts).unwrap();
    assert_eq!(rerooted.link_names()[0], base);
    assert_eq!(rerooted.link_names().len(), plain.link_names().len());
    let (mut wr, mut wp) = (
        KinematicsWorkspace::new(&rerooted),
        KinematicsWorkspace::new(&plain),
    );
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let base_p = plain.link_index(base).unwrap();
    for _ in 0..20 {
        let (q, _) = random_state(&plain, &mut rng);
        rerooted.update_positions(&q, &mut wr).unwrap();
        plain.update_positions(&q, &mut wp).unwrap();
        let inv = plain.link_pose(&wp, base_p).inverse();
        for (lr, name) in rerooted.link_names().iter().enumerate() {
            let lp = plain.link_index(name).unwrap();
            let expect = inv * plain.link_pose(&wp, lp);
            let got = rerooted.link_pose(&wr, lr);
            let d = (expect.translation.vector - got.translation.vector).norm()
                + expect.rotation.angle_to(&got.rotation);
            assert!(d < 1e-12, "{name}: {d}");
        }
    }
    check_robot(&rerooted, 20, seed + 100);
}

/// The Panda re-rooted at panda_link3: joints 1-3 are reversed.
#[test]
fn rerooted_panda_derivatives_and_relative_poses() {
    let joints = [
        "panda_joint1",
        "panda_joint2",
        "panda_joint3",
        "panda_joint4",
        "panda_joint5",
        "panda_joint6",
        "panda_joint7",
    ];
    check_rerooted(
        include_str!("../assets/panda.urdf"),
        "panda_link3",
        "panda_hand",
        &joints,
        5,
    );
}

/// The mimic robot re-rooted at its last link: reversed prismatic, revolute and mimic joints.
#[test]
fn rerooted_mimic_robot_derivatives_and_relative_poses() {
    check_rerooted(MIMIC_URDF, "l5", "base", &["a", "b"], 6);
}

const MIMIC_URDF: &str = r#"<robot name="mimic">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/><link name="l5"/>
  <joint name="a" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1"/></joint>
  <joint name="b" type="prismatic"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.2 0 0"/><axis xyz="1 0 0"/><limit lower="-0.1" upper="0.3" velocity="1"/></joint>
  <joint name="m1" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0 0.1 0"/><axis xyz="0 0 1"/><limit lower="-9" upper="9" velocity="1"/>
    <mimic joint="a" multiplier="-2" offset="0.3"/></joint>
  <joint name="m2" type="prismatic"><parent link="l3"/><child link="l4"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" velocity="1"/>
    <mimic joint="b" multiplier="0.5" offset="0.01"/></joint>
  <joint name="m3" type="revolute"><parent link="l4"/><child link="l5"/>
    <origin xyz="0 0 0.05"/><axis xyz="1 0 0"/><limit lower="-9" upper="9" velocity="1"/>
    <mimic joint="m1" multiplier="1.5"/></joint>
</robot>"#;

/// Closed-form position of (0, 0.05, 0) on l5 for q = (a, b) with the mimic relations applied.
fn mimic_closed_form(a: f64, b: f64) -> Vector3<f64> {
    let rz = |t: f64| Rotation3::from_axis_angle(&Vector3::z_axis(), t);
    let l1 = Vector3::new(0.0, 0.0, 0.5);
    let l2 = l1 + rz(a) * Vector3::new(0.2 + b, 0.0, 0.0);
    let l3 = l2 + rz(a) * Vector3::new(0.0, 0.1, 0.0);
    let r3 = rz(a) * rz(-2.0 * a + 0.3);
    let l4 = l3 + r3 * Vector3::new(0.0, 0.5 * b + 0.01, 0.1);
    let l5 = l4 + r3 * Vector3::new(0.0, 0.0, 0.05);
    let r5 = r3 * Rotation3::from_axis_angle(&Vector3::x_axis(), 1.5 * (-2.0 * a + 0.3));
    l5 + r5 * Vector3::new(0.0, 0.05, 0.0)
}

#[test]
fn mimic_joints_follow_their_source_and_fill_its_column() {
    let robot = Robot::from_urdf_str(MIMIC_URDF, "mimic", &RobotOptions::default()).unwrap();
    assert_eq!(robot.joint_names(), ["a", "b"]);
    assert_eq!(robot.link_names()[robot.ee_link()], "l5");
    let l5 = robot.link_index("l5").unwrap();
    let mut ws = KinematicsWorkspace::new(&robot);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..50 {
        let (q, qd) = random_state(&robot, &mut rng);
        robot.update_positions(&q, &mut ws).unwrap();
        let x = robot.link_pose(&ws, l5) * Point3::new(0.0, 0.05, 0.0);
        assert!((x.coords - mimic_closed_form(q[0], q[1])).norm() < 1e-12);
        for l in 0..robot.link_names().len() {
            let (e, e2) = check_task(
                &Task::Point(l, Vector3::new(0.03, -0.02, 0.04)),
                &robot,
                &q,
                &qd,
            );
            assert!(e < TOL && e2 < TOL_SECOND, "link {l}: {e} {e2}");
            let (e, e2) = check_task(&Task::Axis(l, Vector3::new(0.6, 0.0, 0.8)), &robot, &q, &qd);
            assert!(e < TOL && e2 < TOL_SECOND, "axis link {l}: {e} {e2}");
        }
    }
    // Source b locked: the mimic m2 is constant at 0.5 * 0.02 + 0.01.
    let opts = RobotOptions {
        active_joints: Some(vec!["a".into()]),
        locked_positions: vec![("b".into(), 0.02)],
        ..Default::default()
    };
    let locked = Robot::from_urdf_str(MIMIC_URDF, "mimic", &opts).unwrap();
    let mut ws = KinematicsWorkspace::new(&locked);
    let l5 = locked.link_index("l5").unwrap();
    for a in [-1.0, 0.2, 2.5] {
        locked.update_positions(&[a], &mut ws).unwrap();
        let x = locked.link_pose(&ws, l5) * Point3::new(0.0, 0.05, 0.0);
        assert!((x.coords - mimic_closed_form(a, 0.02)).norm() < 1e-12);
        let (e, e2) = check_task(
            &Task::Point(l5, Vector3::new(0.0, 0.05, 0.0)),
            &locked,
            &[a],
            &[0.7],
        );
        assert!(e < TOL && e2 < TOL_SECOND);
    }
}

#[test]
fn mbm_plain_urdf_loads_with_meshes() {
    let Some(dir) = mbm_panda_dir() else { return };
    let robot = Robot::from_urdf_file(&dir.join("panda.urdf"), &RobotOptions::default()).unwrap();
    assert_eq!(robot.dof(), 7);
    assert!(robot.spheres().is_empty());
    check_robot(&robot, 5, 8);
}
