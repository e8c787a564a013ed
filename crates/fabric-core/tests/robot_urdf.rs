//! URDF loading: branches, continuous and locked joints, the rpy convention, default choices, collision
//! geometry and mesh paths, spheres and pairs, and the batch helpers.

mod robot_support;

use std::f64::consts::TAU;

use fabric_core::robot::{
    batch, CollisionSphere, GeometryKind, KinematicsWorkspace, Robot, RobotOptions,
};
use nalgebra::{Matrix3, Point3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use robot_support::{mbm_panda_dir, random_state};

/// A base with a fixed camera, an arm (continuous, revolute) and a two-finger gripper: the second
/// finger's joint mimics the first. Collision geometry of every kind.
const TREE: &str = r#"<robot name="tree">
  <link name="base"><collision><origin xyz="0 0 0.05"/><geometry><box size="0.2 0.3 0.1"/></geometry></collision></link>
  <link name="camera"/>
  <link name="arm"><collision><origin xyz="0 0 0.2" rpy="0 0.1 0"/><geometry><cylinder radius="0.04" length="0.4"/></geometry></collision>
    <collision><geometry><mesh filename="package://robot_pkg/meshes/arm.obj" scale="2 2 2"/></geometry></collision></link>
  <link name="forearm"><collision><origin xyz="0.1 0 0"/><geometry><sphere radius="0.05"/></geometry></collision>
    <collision><origin xyz="0.2 0 0"/><geometry><sphere radius="0.04"/></geometry></collision></link>
  <link name="palm"><collision><origin xyz="0 0 0.02"/><geometry><sphere radius="0.03"/></geometry></collision></link>
  <link name="left"><collision><geometry><sphere radius="0.01"/></geometry></collision></link>
  <link name="right"><collision><geometry><sphere radius="0.01"/></geometry></collision></link>
  <joint name="cam" type="fixed"><parent link="base"/><child link="camera"/><origin xyz="0.3 0 0.5"/></joint>
  <joint name="yaw" type="continuous"><parent link="base"/><child link="arm"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/></joint>
  <joint name="elbow" type="revolute"><parent link="arm"/><child link="forearm"/><origin xyz="0 0 0.4" rpy="0.3 -0.7 1.1"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="1.5"/></joint>
  <joint name="wrist" type="fixed"><parent link="forearm"/><child link="palm"/><origin xyz="0.25 0 0"/></joint>
  <joint name="f1" type="prismatic"><parent link="palm"/><child link="left"/><origin xyz="0 0.01 0.05"/>
    <axis xyz="0 1 0"/><limit lower="0.005" upper="0.03" velocity="0.1"/></joint>
  <joint name="f2" type="prismatic"><parent link="palm"/><child link="right"/><origin xyz="0 -0.01 0.05"/>
    <axis xyz="0 -1 0"/><limit lower="0.005" upper="0.03" velocity="0.1"/><mimic joint="f1"/></joint>
</robot>"#;

fn tree(opts: &RobotOptions) -> Robot {
    Robot::from_urdf_str(TREE, "tree.urdf", opts).unwrap()
}

#[test]
fn robot_is_send_sync_clone() {
    fn check<T: Send + Sync + Clone>() {}
    check::<Robot>();
    check::<KinematicsWorkspace>();
}

#[test]
fn branches_defaults_and_limits() {
    let robot = tree(&RobotOptions::default());
    // Every link has a pose and a parent of smaller index.
    assert_eq!(robot.link_names().len(), 7);
    for l in 1..7 {
        assert!(robot.link_parent(l).unwrap() < l);
    }
    assert_eq!(robot.link_parent(0), None);
    // The default end-effector skips the camera branch and stops where the fingers branch.
    assert_eq!(robot.link_names()[robot.ee_link()], "palm");
    assert_eq!(robot.joint_names(), ["yaw", "elbow"]);
    // Continuous joint: [-2π, 2π] and no velocity limit given.
    assert_eq!(robot.lower(), [-TAU, -2.0]);
    assert_eq!(robot.upper(), [TAU, 2.0]);
    assert_eq!(robot.velocity_limits(), [f64::INFINITY, 1.5]);
    // Fingers are locked at 0 clamped into [0.005, 0.03]; the mimic follows.
    let mut ws = KinematicsWorkspace::new(&robot);
    robot.update_positions(&[0.4, -0.3], &mut ws).unwrap();
    let palm = *robot.link_pose(&ws, robot.link_index("palm").unwrap());
    let rel = |n: &str| {
        (palm.inverse() * robot.link_pose(&ws, robot.link_index(n).unwrap()))
            .translation
            .vector
    };
    assert!((rel("left") - Vector3::new(0.0, 0.015, 0.05)).norm() < 1e-12);
    assert!((rel("right") - Vector3::new(0.0, -0.015, 0.05)).norm() < 1e-12);
    // Camera: fixed on the base.
    let cam = robot.link_pose(&ws, robot.link_index("camera").unwrap());
    assert!((cam.translation.vector - Vector3::new(0.3, 0.0, 0.5)).norm() < 1e-15);

    // Explicit active joints: q order as given, end-effector below the deepest one.
    let opts = RobotOptions {
        active_joints: Some(vec!["f1".into(), "yaw".into()]),
        ..Default::default()
    };
    let r2 = tree(&opts);
    assert_eq!(r2.joint_names(), ["f1", "yaw"]);
    assert_eq!(r2.link_names()[r2.ee_link()], "left");
    assert_eq!(r2.lower(), [0.005, -TAU]);
    let panda = Robot::from_urdf_str(
        include_str!("../assets/panda.urdf"),
        "p",
        &RobotOptions {
            active_joints: Some((1..=4).map(|i| format!("panda_joint{i}")).collect()),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(panda.link_names()[panda.ee_link()], "panda_link4");
    // The locked elbow (joint 4) defaults to its upper limit, the value closest to 0.
    let p2 = Robot::from_urdf_str(
        include_str!("../assets/panda.urdf"),
        "p",
        &RobotOptions {
            active_joints: Some(vec!["panda_joint1".into()]),
            ..Default::default()
        },
    )
    .unwrap();
    let full = Robot::panda();
    let (mut wa, mut wb) = (
        KinematicsWorkspace::new(&p2),
        KinematicsWorkspace::new(&full),
    );
    p2.update_positions(&[0.3], &mut wa).unwrap();
    full.update_positions(&[0.3, 0.0, 0.0, -0.0698, 0.0, 0.0, 0.0], &mut wb)
        .unwrap();
    let l7 = |r: &Robot| r.link_index("panda_link7").unwrap();
    assert!(
        (p2.link_pose(&wa, l7(&p2)).translation.vector
            - full.link_pose(&wb, l7(&full)).translation.vector)
            .norm()
            < 1e-12
    );
}

/// URDF rpy is fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll).
#[test]
fn rpy_convention() {
    let robot = tree(&RobotOptions::default());
    let mut ws = KinematicsWorkspace::new(&robot);
    robot.update_positions(&[0.0, 0.0], &mut ws).unwrap();
    let (r, p, y) = (0.3_f64, -0.7_f64, 1.1_f64);
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, r.cos(), -r.sin(), 0.0, r.sin(), r.cos());
    let ry = Matrix3::new(p.cos(), 0.0, p.sin(), 0.0, 1.0, 0.0, -p.sin(), 0.0, p.cos());
    let rz = Matrix3::new(y.cos(), -y.sin(), 0.0, y.sin(), y.cos(), 0.0, 0.0, 0.0, 1.0);
    let forearm = robot.link_pose(&ws, robot.link_index("forearm").unwrap());
    let got = forearm.rotation.to_rotation_matrix().into_inner();
    assert!((got - rz * ry * rx).norm() < 1e-12);
    assert!((forearm.translation.vector - Vector3::new(0.0, 0.0, 0.5)).norm() < 1e-12);
}

#[test]
fn collision_geometry_and_mesh_paths() {
    let dir = std::env::temp_dir().join(format!("gfcs_robot_urdf_{}", std::process::id()));
    std::fs::create_dir_all(dir.join("robot_pkg/meshes")).unwrap();
    std::fs::write(dir.join("robot_pkg/meshes/arm.obj"), "").unwrap();
    let with_dir = tree(&RobotOptions {
        mesh_dir: Some(dir.clone()),
        ..Default::default()
    });
    let without = tree(&RobotOptions::default());
    std::fs::remove_dir_all(&dir).unwrap();

    let geo = with_dir.collision_geometry();
    assert_eq!(geo.len(), 8);
    let arm = with_dir.link_index("arm").unwrap();
    assert!(
        matches!(geo[0].kind, GeometryKind::Box { size } if size == Vector3::new(0.2, 0.3, 0.1))
    );
    assert_eq!(geo[0].link, 0);
    assert!((geo[0].origin.translation.vector - Vector3::new(0.0, 0.0, 0.05)).norm() < 1e-15);
    assert!(
        matches!(geo[1].kind, GeometryKind::Cylinder { radius, length } if radius == 0.04 && length == 0.4)
    );
    assert_eq!(geo[1].link, arm);
    match &geo[2].kind {
        GeometryKind::Mesh {
            path,
            scale,
            exists,
        } => {
            assert_eq!(path, &dir.join("robot_pkg/meshes/arm.obj"));
            assert_eq!(*scale, Vector3::repeat(2.0));
            assert!(exists);
        }
        other => panic!("{other:?}"),
    }
    // No mesh directory: not an error, flagged as missing.
    assert!(matches!(
        &without.collision_geometry()[2].kind,
        GeometryKind::Mesh { exists: false, .. }
    ));
    // Spheres become collision spheres too.
    let forearm = with_dir.link_index("forearm").unwrap();
    assert_eq!(with_dir.spheres().len(), 5);
    assert_eq!(
        with_dir.spheres()[0],
        CollisionSphere {
            link: forearm,
            center: Vector3::new(0.1, 0.0, 0.0),
            radius: 0.05
        }
    );
    assert!(matches!(geo[3].kind, GeometryKind::Sphere { radius } if radius == 0.05));
}

#[test]
fn mbm_meshes_resolve_next_to_the_urdf() {
    let Some(dir) = mbm_panda_dir() else { return };
    let robot = Robot::from_urdf_file(&dir.join("panda.urdf"), &RobotOptions::default()).unwrap();
    let meshes: Vec<_> = robot
        .collision_geometry()
        .iter()
        .filter_map(|g| match &g.kind {
            GeometryKind::Mesh { path, exists, .. } => Some((path.clone(), *exists)),
            _ => None,
        })
        .collect();
    assert!(meshes.len() >= 10);
    for (path, exists) in meshes {
        assert!(exists && path.is_file(), "{}", path.display());
    }
}

#[test]
fn self_collision_pairs_follow_bodies_and_srdf() {
    let mut robot = tree(&RobotOptions::default());
    let names = robot.link_names().to_vec();
    let id = |n: &str| names.iter().position(|x| x == n).unwrap();
    // Rigid bodies: the fingers are locked onto the palm, the palm is fixed to the forearm.
    let bodies = robot.rigid_bodies().to_vec();
    assert_eq!(bodies[id("palm")], bodies[id("forearm")]);
    assert_eq!(bodies[id("left")], bodies[id("forearm")]);
    assert_eq!(bodies[id("camera")], bodies[id("base")]);
    assert_ne!(bodies[id("arm")], bodies[id("base")]);
    // Spheres: forearm ×2, palm, left, right — one body: no pairs. Add one on the base (adjacent to the
    // arm's body, but not to the forearm's) and one on the arm (adjacent to both).
    assert!(robot.self_collision_pairs().is_empty());
    let mut spheres = robot.spheres().to_vec();
    spheres.push(CollisionSphere {
        link: id("camera"),
        center: Vector3::zeros(),
        radius: 0.1,
    });
    spheres.push(CollisionSphere {
        link: id("arm"),
        center: Vector3::zeros(),
        radius: 0.1,
    });
    robot.set_spheres(spheres).unwrap();
    assert_eq!(
        robot.self_collision_pairs(),
        [(0, 5), (1, 5), (2, 5), (3, 5), (4, 5)]
    );
    robot
        .set_self_collision_from_srdf(
            "<robot><disable_collisions link1='camera' link2='palm'/></robot>",
            "t.srdf",
        )
        .unwrap();
    assert_eq!(
        robot.self_collision_pairs(),
        [(0, 5), (1, 5), (3, 5), (4, 5)]
    );
    assert_eq!(robot.disabled_collisions(), [(id("camera"), id("palm"))]);
    // A new SRDF replaces the previous one.
    robot
        .set_self_collision_from_srdf("<robot/>", "t.srdf")
        .unwrap();
    assert_eq!(robot.self_collision_pairs().len(), 5);
    // Spheres from a file.
    let path = std::env::temp_dir().join(format!("gfcs_spheres_{}.json", std::process::id()));
    std::fs::write(
        &path,
        r#"{"spheres": [{"link": "arm", "center": [0, 0, 0.1], "radius": 0.05}]}"#,
    )
    .unwrap();
    let loaded = robot.load_sphere_file(&path);
    std::fs::remove_file(&path).unwrap();
    assert_eq!(
        loaded.unwrap(),
        [CollisionSphere {
            link: id("arm"),
            center: Vector3::new(0.0, 0.0, 0.1),
            radius: 0.05
        }]
    );
}

#[test]
fn batches_match_single_evaluations_for_any_thread_count() {
    // 1 and 5 configurations run on the calling thread, 257 in parallel
    for n in [1, 5, 257] {
        batch_matches_single_evaluations(n);
    }
}

fn batch_matches_single_evaluations(n: usize) {
    let robot = Robot::panda();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let qs: Vec<f64> = (0..n)
        .flat_map(|_| random_state(&robot, &mut rng).0)
        .collect();
    let (l, s) = (robot.link_names().len(), robot.spheres().len());
    let mut ws = KinematicsWorkspace::new(&robot);
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let ee = robot.ee_link();
        let (poses, centers, origins) = pool.install(|| {
            (
                batch::link_poses(&robot, &qs).unwrap(),
                batch::sphere_centers(&robot, &qs).unwrap(),
                batch::link_origins(&robot, &qs, ee).unwrap(),
            )
        });
        assert_eq!(
            (poses.len(), centers.len(), origins.len()),
            (n * l, n * s, n)
        );
        for k in 0..n {
            robot
                .update_positions(&qs[k * 7..(k + 1) * 7], &mut ws)
                .unwrap();
            for li in 0..l {
                assert_eq!(poses[k * l + li], *robot.link_pose(&ws, li));
            }
            assert_eq!(origins[k], robot.link_pose(&ws, ee).translation.vector);
            for si in 0..s {
                let sp = robot.spheres()[si];
                let expect = robot.link_pose(&ws, sp.link) * Point3::from(sp.center);
                assert!((centers[k * s + si] - expect.coords).norm() < 1e-14);
            }
        }
    }
}

/// A URDF joint `name` of `kind` from `parent` to `child` (revolute and prismatic limited to ±1).
fn joint(name: &str, kind: &str, parent: &str, child: &str, extra: &str) -> String {
    format!(
        r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>
        <origin xyz="0.1 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1"/>{extra}</joint>"#
    )
}

/// An arm of `n` revolute joints from `parent`, ending in a hand with two fingers (one a mimic):
/// (links, joints).
fn arm(prefix: &str, parent: &str, n: usize) -> (Vec<String>, Vec<String>) {
    let mut links = Vec::new();
    let mut joints = Vec::new();
    let mut last = parent.to_string();
    for k in 1..=n {
        let link = format!("{prefix}link{k}");
        joints.push(joint(
            &format!("{prefix}j{k}"),
            "revolute",
            &last,
            &link,
            "",
        ));
        links.push(link.clone());
        last = link;
    }
    let hand = format!("{prefix}hand");
    joints.push(joint(
        &format!("{prefix}hand_joint"),
        "fixed",
        &last,
        &hand,
        "",
    ));
    for (f, mimic) in [("left", ""), ("right", "<mimic joint=\"FIRST\"/>")] {
        let finger = format!("{prefix}{f}");
        let mimic = mimic.replace("FIRST", &format!("{prefix}left_joint"));
        joints.push(joint(
            &format!("{prefix}{f}_joint"),
            "prismatic",
            &hand,
            &finger,
            &mimic,
        ));
        links.push(finger);
    }
    links.push(hand);
    (links, joints)
}

fn urdf(links: &[String], joints: &[String]) -> String {
    let links: String = links
        .iter()
        .map(|l| format!(r#"<link name="{l}"/>"#))
        .collect();
    format!(r#"<robot name="r">{links}{}</robot>"#, joints.concat())
}

#[test]
fn the_default_end_effector_of_a_mobile_manipulator_is_its_arms_hand() {
    // base: two continuous wheels, a torso lift; torso: a two-joint head and a six-joint arm
    let mut links: Vec<String> = ["base", "wheel_l", "wheel_r", "torso", "head1", "head2"]
        .map(String::from)
        .to_vec();
    let mut joints = vec![
        joint("wheel_l_joint", "continuous", "base", "wheel_l", ""),
        joint("wheel_r_joint", "continuous", "base", "wheel_r", ""),
        joint("lift", "prismatic", "base", "torso", ""),
        joint("head_pan", "revolute", "torso", "head1", ""),
        joint("head_tilt", "revolute", "head1", "head2", ""),
    ];
    let (l, j) = arm("arm_", "torso", 6);
    links.extend(l);
    joints.extend(j);
    let robot = Robot::from_urdf_str(&urdf(&links, &joints), "m.urdf", &RobotOptions::default())
        .expect("a mobile manipulator loads without an end-effector named");
    assert_eq!(robot.link_names()[robot.ee_link()], "arm_hand");
    let expected: Vec<String> = std::iter::once("lift".to_string())
        .chain((1..=6).map(|k| format!("arm_j{k}")))
        .collect();
    assert_eq!(robot.joint_names(), expected);
}

#[test]
fn the_default_end_effector_of_two_equal_arms_is_the_first_arms_hand() {
    let mut links = vec!["torso".to_string()];
    let mut joints = Vec::new();
    for prefix in ["left_", "right_"] {
        let (l, j) = arm(prefix, "torso", 7);
        links.extend(l);
        joints.extend(j);
    }
    let robot = Robot::from_urdf_str(&urdf(&links, &joints), "two.urdf", &RobotOptions::default())
        .expect("two arms on a torso load without an end-effector named");
    assert_eq!(robot.link_names()[robot.ee_link()], "left_hand");
    assert_eq!(robot.dof(), 7);
    // short branches (one joint and a gripper, a one-joint head) are no arm: the walk stops where they
    // branch
    let (l, j) = arm("", "torso", 1);
    let mut short = vec!["torso".to_string()];
    short.extend(l);
    let mut jj = j;
    jj.push(joint("head_pan", "revolute", "torso", "head", ""));
    short.push("head".into());
    let err = Robot::from_urdf_str(&urdf(&short, &jj), "short.urdf", &RobotOptions::default());
    assert!(
        err.is_err(),
        "no branch of three joints: no default end-effector below the torso"
    );
}

#[test]
fn a_hand_of_many_jointed_fingers_is_not_taken_for_an_arm() {
    // an arm of six 0.1 m links, then a palm with two fingers of three 1 cm joints each
    let (mut links, mut joints) = arm("", "base", 6);
    links.push("base".into());
    for f in ["index", "thumb"] {
        let mut last = "hand".to_string();
        for k in 1..=3 {
            let link = format!("{f}{k}");
            joints.push(
                joint(&format!("{f}_j{k}"), "revolute", &last, &link, "")
                    .replace(r#"<origin xyz="0.1 0 0"/>"#, r#"<origin xyz="0.01 0 0"/>"#),
            );
            links.push(link.clone());
            last = link;
        }
    }
    let robot = Robot::from_urdf_str(
        &urdf(&links, &joints),
        "hand.urdf",
        &RobotOptions::default(),
    )
    .expect("loads");
    assert_eq!(robot.link_names()[robot.ee_link()], "hand");
    assert_eq!(robot.dof(), 6);
}
