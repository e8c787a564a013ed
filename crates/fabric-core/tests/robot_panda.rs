//! The shipped Panda against the MotionBenchMaker Panda, and self-collision pairs.

mod robot_support;

use std::collections::{HashMap, HashSet};

use fabric_core::robot::{KinematicsWorkspace, Robot, RobotOptions};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use robot_support::{mbm_panda_dir, mbm_spherized, random_state};

#[test]
fn shipped_panda_model() {
    let robot = Robot::panda();
    assert_eq!(robot.name(), "panda");
    assert_eq!(robot.dof(), 7);
    let names: Vec<String> = (1..=7).map(|i| format!("panda_joint{i}")).collect();
    assert_eq!(robot.joint_names(), names.as_slice());
    assert_eq!(
        robot.lower(),
        [-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973]
    );
    assert_eq!(
        robot.upper(),
        [2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973]
    );
    assert_eq!(
        robot.velocity_limits(),
        [2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61]
    );
    assert_eq!(robot.link_names()[robot.base_link()], "panda_link0");
    assert_eq!(robot.link_names()[robot.ee_link()], "panda_hand");
    assert_eq!(robot.link_names().len(), 13);
    assert!(!robot.spheres().is_empty());
    assert!(!robot.self_collision_pairs().is_empty());
    assert!(robot.collision_geometry().is_empty());
    // The same URDF with default options chooses the same base, end-effector and active joints.
    let default = Robot::from_urdf_str(
        include_str!("../assets/panda.urdf"),
        "p",
        &RobotOptions::default(),
    )
    .unwrap();
    assert_eq!(default.link_names()[default.ee_link()], "panda_hand");
    assert_eq!(default.joint_names(), robot.joint_names());
}

/// Closed-form FK of the shipped Panda at q = 0 from the published kinematics: the flange (link8) sits at
/// x = 0.088, z = 0.333 + 0.316 + 0.384 − 0.107 = 0.926 pointing down, and the TCP 0.1034 m below it.
#[test]
fn shipped_panda_zero_configuration() {
    let robot = Robot::panda();
    let mut ws = KinematicsWorkspace::new(&robot);
    let q = [0.0; 7];
    robot.update_positions(&q, &mut ws).unwrap();
    let pose = |n: &str| *robot.link_pose(&ws, robot.link_index(n).unwrap());
    let flange = pose("panda_link8");
    assert!((flange.translation.vector - Vector3::new(0.088, 0.0, 0.926)).norm() < 1e-12);
    assert!((flange.rotation * Vector3::z() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    let tcp = pose("panda_hand_tcp");
    assert!((tcp.translation.vector - Vector3::new(0.088, 0.0, 0.926 - 0.1034)).norm() < 1e-12);
    // Fingers locked open at 0.04 m on either side of the hand's y axis, 0.0584 m down from the flange.
    let hand = pose("panda_hand");
    let left = hand.inverse() * pose("panda_leftfinger");
    let right = hand.inverse() * pose("panda_rightfinger");
    assert!((left.translation.vector - Vector3::new(0.0, 0.04, 0.0584)).norm() < 1e-12);
    assert!((right.translation.vector - Vector3::new(0.0, -0.04, 0.0584)).norm() < 1e-12);
    // The hand is the flange turned by -π/4 about z.
    let expect = flange
        * Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_euler_angles(0.0, 0.0, -std::f64::consts::FRAC_PI_4),
        );
    assert!(hand.rotation.angle_to(&expect.rotation) < 1e-12);
}

#[test]
fn shipped_panda_fk_equals_mbm_panda_fk() {
    let Some(dir) = mbm_panda_dir() else { return };
    let mbm = Robot::from_urdf_file(&dir.join("panda.urdf"), &RobotOptions::default()).unwrap();
    let ours = Robot::panda();
    assert_eq!(mbm.joint_names(), ours.joint_names());
    assert_eq!(mbm.link_names()[mbm.ee_link()], "panda_hand");
    let (mut wa, mut wb) = (
        KinematicsWorkspace::new(&ours),
        KinematicsWorkspace::new(&mbm),
    );
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut links: Vec<String> = (0..=8).map(|i| format!("panda_link{i}")).collect();
    links.push("panda_hand".into());
    for _ in 0..500 {
        let (q, _) = random_state(&ours, &mut rng);
        ours.update_positions(&q, &mut wa).unwrap();
        mbm.update_positions(&q, &mut wb).unwrap();
        for name in &links {
            let a = ours.link_pose(&wa, ours.link_index(name).unwrap());
            let b = mbm.link_pose(&wb, mbm.link_index(name).unwrap());
            let d = (a.translation.vector - b.translation.vector).norm();
            let r = a.rotation.angle_to(&b.rotation);
            assert!(d < 1e-9 && r < 1e-9, "{name} at {q:?}: {d} m, {r} rad");
        }
    }
}

/// Independent rigid-body labels from the raw URDF: links joined by fixed joints (union-find).
fn rigid_labels(urdf: &urdf_rs::Robot) -> HashMap<String, String> {
    let mut parent: HashMap<String, String> = urdf
        .links
        .iter()
        .map(|l| (l.name.clone(), l.name.clone()))
        .collect();
    fn find(p: &HashMap<String, String>, x: &str) -> String {
        let mut x = x.to_string();
        while p[&x] != x {
            x = p[&x].clone();
        }
        x
    }
    for j in urdf
        .joints
        .iter()
        .filter(|j| j.joint_type == urdf_rs::JointType::Fixed)
    {
        let (a, b) = (find(&parent, &j.parent.link), find(&parent, &j.child.link));
        parent.insert(a, b);
    }
    urdf.links
        .iter()
        .map(|l| (l.name.clone(), find(&parent, &l.name)))
        .collect()
}

#[test]
fn mbm_self_collision_pairs_skip_adjacent_and_disabled_links() {
    let Some(dir) = mbm_panda_dir() else { return };
    let mut robot = mbm_spherized().unwrap();
    let before = robot.self_collision_pairs().len();
    let srdf = std::fs::read_to_string(dir.join("panda.srdf")).unwrap();
    robot
        .set_self_collision_from_srdf(&srdf, "panda.srdf")
        .unwrap();
    assert!(robot.self_collision_pairs().len() < before);

    // Brute force from the raw files.
    let xml = std::fs::read_to_string(dir.join("panda_spherized.urdf")).unwrap();
    let urdf = urdf_rs::read_from_string(&xml).unwrap();
    let body = rigid_labels(&urdf);
    let mut adjacent: HashSet<(String, String)> = HashSet::new();
    for j in urdf
        .joints
        .iter()
        .filter(|j| j.joint_type != urdf_rs::JointType::Fixed)
    {
        let (a, b) = (body[&j.parent.link].clone(), body[&j.child.link].clone());
        adjacent.insert((a.clone(), b.clone()));
        adjacent.insert((b, a));
    }
    let doc = roxmltree::Document::parse(&srdf).unwrap();
    let disabled: HashSet<(String, String)> = doc
        .descendants()
        .filter(|n| n.has_tag_name("disable_collisions"))
        .flat_map(|n| {
            let (a, b) = (
                n.attribute("link1").unwrap().to_string(),
                n.attribute("link2").unwrap().to_string(),
            );
            [(a.clone(), b.clone()), (b, a)]
        })
        .collect();
    let names = robot.link_names();
    let link_of = |i: usize| names[robot.spheres()[i].link].clone();
    let mut expected = Vec::new();
    for i in 0..robot.spheres().len() {
        for j in i + 1..robot.spheres().len() {
            let (a, b) = (link_of(i), link_of(j));
            let (ba, bb) = (body[&a].clone(), body[&b].clone());
            if ba != bb && !adjacent.contains(&(ba, bb)) && !disabled.contains(&(a, b)) {
                expected.push((i, j));
            }
        }
    }
    assert_eq!(robot.self_collision_pairs(), expected.as_slice());
    assert!(!expected.is_empty());
    for &(i, j) in robot.self_collision_pairs() {
        let (a, b) = (robot.spheres()[i].link, robot.spheres()[j].link);
        assert!(i < j && a != b);
        assert_ne!(robot.link_parent(a), Some(b), "{} / {}", names[a], names[b]);
        assert_ne!(robot.link_parent(b), Some(a), "{} / {}", names[a], names[b]);
    }
}

#[test]
fn shipped_panda_self_collision_pairs_are_free_at_rest() {
    // At the "ready" configuration no checked pair of the shipped spheres overlaps.
    let robot = Robot::panda();
    let mut ws = KinematicsWorkspace::new(&robot);
    robot
        .update_positions(&[0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], &mut ws)
        .unwrap();
    for &(i, j) in robot.self_collision_pairs() {
        let (si, sj) = (robot.spheres()[i], robot.spheres()[j]);
        let d = (robot.sphere_center(&ws, i) - robot.sphere_center(&ws, j)).norm()
            - si.radius
            - sj.radius;
        assert!(
            d > 0.0,
            "{} / {} overlap by {d}",
            robot.link_names()[si.link],
            robot.link_names()[sj.link]
        );
    }
}
