//! Hostile and unusual input: nesting and size limits of the XML and YAML readers, locked joints outside
//! their limits, SRDF entries for links the robot lacks, MoveIt scene fields that are not applied,
//! configuration consistency, thread pools and the cost of building a fabric for a long robot.

#[path = "common/mod.rs"]
mod common;

use std::sync::Arc;
use std::time::{Duration, Instant};

use fabric_core::fabric::{Fabric, FabricConfig};
use fabric_core::limits::{check_xml, check_yaml, XML_MAX_DEPTH, YAML_MAX_DEPTH};
use fabric_core::robot::{CollisionSphere, Robot, RobotOptions};
use fabric_core::rollout::{max_threads, pool_threads, shared_pool};
use fabric_core::scene::moveit::{parse_request_str, parse_scene_str};
use fabric_core::FabricError;
use nalgebra::Vector3;

fn message(r: Result<impl std::fmt::Debug, FabricError>) -> String {
    match r {
        Err(e) => e.to_string(),
        Ok(v) => panic!("expected an error, got {v:?}"),
    }
}

/// A URDF whose first link's `<visual>` holds `depth` nested elements.
fn deep_urdf(depth: usize) -> String {
    format!(
        "<robot name='r'><link name='a'><visual><geometry><box size='1 1 1'/></geometry>{}{}</visual>\
         </link><link name='b'/>\
         <joint name='j' type='revolute'><parent link='a'/><child link='b'/>\
         <limit lower='-1' upper='1' velocity='1'/></joint></robot>",
        "<g>".repeat(depth),
        "</g>".repeat(depth)
    )
}

#[test]
fn deep_xml_is_refused_with_a_named_error_not_a_crash() {
    let t = Instant::now();
    let e = Robot::from_urdf_str(&deep_urdf(25_000), "deep.urdf", &RobotOptions::default());
    assert!(matches!(e, Err(FabricError::Urdf { .. })), "{e:?}");
    let m = message(e);
    assert!(
        m.starts_with("URDF deep.urdf: ") && m.contains(&format!("more than {XML_MAX_DEPTH} deep")),
        "{m}"
    );
    let srdf = format!(
        "<robot>{}{}</robot>",
        "<group>".repeat(25_000),
        "</group>".repeat(25_000)
    );
    let mut robot = Robot::panda();
    let e = robot.set_self_collision_from_srdf(&srdf, "deep.srdf");
    assert!(
        matches!(&e, Err(FabricError::Format { file, field, .. }) if file == "deep.srdf" && field == "(xml)"),
        "{e:?}"
    );
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    // nesting as deep as real files, and a little deeper, still parses
    let ok = Robot::from_urdf_str(&deep_urdf(40), "ok.urdf", &RobotOptions::default());
    assert!(ok.is_ok(), "{ok:?}");
}

#[test]
fn oversized_xml_is_refused() {
    let big = format!(
        "<robot name='r'><link name='a'/>{}</robot>",
        " ".repeat(33 << 20)
    );
    let m = message(Robot::from_urdf_str(
        &big,
        "big.urdf",
        &RobotOptions::default(),
    ));
    assert!(m.contains("exceed the limit"), "{m}");
}

#[test]
fn deep_yaml_is_refused_at_once() {
    let t = Instant::now();
    let flow = format!("world: {}1{}\n", "[".repeat(100_000), "]".repeat(100_000));
    let m = message(parse_scene_str(&flow, "deep.yaml", None));
    assert!(
        m.starts_with("deep.yaml: field '<root>': ")
            && m.contains(&format!("more than {YAML_MAX_DEPTH} levels")),
        "{m}"
    );
    let m = message(parse_request_str(&flow, "deep.yaml"));
    assert!(m.contains("levels deep (line 1)"), "{m}");
    // block nesting: a mapping per line, each indented one column more
    let block: String = (0..5_000)
        .map(|i| format!("{}k{i}:\n", " ".repeat(i)))
        .collect();
    let m = message(parse_scene_str(&block, "block.yaml", None));
    assert!(m.contains("levels deep"), "{m}");
    // compact sequences on one line
    let dashes = format!("{}1\n", "- ".repeat(10_000));
    assert!(message(parse_request_str(&dashes, "dash.yaml")).contains("levels deep"));
    let m = message(FabricConfig::from_yaml_str(&flow, "deep_config.yaml"));
    assert!(m.contains("levels deep"), "{m}");
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
}

#[test]
fn real_files_are_within_the_limits() {
    let Some(shared) = common::shared_dir() else {
        return;
    };
    let mut seen = 0;
    let mut visit = vec![shared.clone()];
    while let Some(dir) = visit.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                visit.push(path);
                continue;
            }
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            let text = match ext {
                "urdf" | "srdf" | "yaml" => std::fs::read_to_string(&path).unwrap(),
                _ => continue,
            };
            let r = if ext == "yaml" {
                check_yaml(&text)
            } else {
                check_xml(&text)
            };
            assert!(r.is_ok(), "{}: {r:?}", path.display());
            seen += 1;
        }
    }
    assert!(seen > 100, "only {seen} files under {}", shared.display());
}

#[test]
fn locked_joints_far_outside_their_limits_are_refused() {
    let panda = Robot::panda();
    let e = panda.with_locked_positions(&[("panda_finger_joint1".into(), -0.5)]);
    assert!(matches!(e, Err(FabricError::Value { .. })), "{e:?}");
    let m = message(e);
    assert!(
        m.contains("locked joint 'panda_finger_joint1'") && m.contains("[0, 0.04]"),
        "{m}"
    );
    let opts = RobotOptions {
        locked_positions: vec![("panda_finger_joint1".into(), 0.5)],
        ..Default::default()
    };
    let urdf = fabric_core::robot::PANDA_URDF;
    assert!(Robot::from_urdf_str(urdf, "panda.urdf", &opts).is_err());
    // within MoveIt's bounds tolerance: held where asked (the MotionBenchMaker requests' open fingers)
    let held = panda
        .with_locked_positions(&[("panda_finger_joint1".into(), 0.065)])
        .unwrap();
    assert_eq!(held.locked_positions()[0].1, 0.065);
}

#[test]
fn a_mimic_cycle_is_named() {
    let urdf = "<robot name='m'><link name='a'/><link name='b'/><link name='c'/><link name='d'/>\
        <joint name='j0' type='revolute'><parent link='a'/><child link='b'/>\
          <limit lower='-1' upper='1' velocity='1'/></joint>\
        <joint name='j1' type='revolute'><parent link='b'/><child link='c'/>\
          <limit lower='-1' upper='1' velocity='1'/><mimic joint='j2'/></joint>\
        <joint name='j2' type='revolute'><parent link='c'/><child link='d'/>\
          <limit lower='-1' upper='1' velocity='1'/><mimic joint='j1'/></joint></robot>";
    let m = message(Robot::from_urdf_str(
        urdf,
        "m.urdf",
        &RobotOptions::default(),
    ));
    assert!(
        m.contains("mimic joints form a cycle: j1 -> j2 -> j1"),
        "{m}"
    );
}

#[test]
fn a_truncated_urdf_says_it_ends_early() {
    let whole = fabric_core::robot::PANDA_URDF;
    let cut = &whole[..whole.len() / 2];
    let m = message(Robot::from_urdf_str(
        cut,
        "cut.urdf",
        &RobotOptions::default(),
    ));
    assert!(
        m.contains("cut.urdf") && m.contains("looks truncated"),
        "{m}"
    );
}

#[test]
fn srdf_links_the_robot_lacks_are_skipped_and_reported() {
    let Some(dir) = common::shared_subdir("robots/mbm_fetch") else {
        return;
    };
    let urdf = std::fs::read_to_string(dir.join("fetch.urdf")).unwrap();
    let srdf = std::fs::read_to_string(dir.join("fetch.srdf")).unwrap();
    let mut robot = Robot::from_urdf_str(&urdf, "fetch.urdf", &RobotOptions::default()).unwrap();
    let skipped = robot
        .set_self_collision_from_srdf(&srdf, "fetch.srdf")
        .unwrap();
    assert!(
        skipped.contains(&"bellows_link2".to_string()),
        "{skipped:?}"
    );
    assert!(!robot.disabled_collisions().is_empty());
}

const SCENE: &str = "
world:
  collision_objects:
    - id: box
      primitives: [{type: box, dimensions: [1, 1, 1]}]
      primitive_poses: [{position: [2, 0, 0], orientation: [0, 0, 0, 1]}]
    - id: ball
      primitives: [{type: sphere, dimensions: [0.1]}]
      primitive_poses: [{position: [0, 2, 0], orientation: [0, 0, 0, 1]}]
      colour: red
    - id: box
      primitives: [{type: box, dimensions: [0.2, 0.2, 0.2]}]
      primitive_poses: [{position: [3, 0, 0], orientation: [0, 0, 0, 1]}]
  octomap:
    origin: {position: [0, 0, 0], orientation: [0, 0, 0, 1]}
    octomap: {binary: true, id: OcTree, resolution: 0.02, data: [1, 2, 3]}
allowed_collision_matrix:
  entry_names: [panda_link0, ball]
  entry_values: [[false, true], [true, false]]
fixed_frame_transforms:
  - {child_frame_id: world, transform: {translation: [0, 0, 0], rotation: [0, 0, 0, 1]}}
  - {child_frame_id: table, transform: {translation: [1, 0, 0], rotation: [0, 0, 0, 1]}}
link_padding: [{link_name: panda_hand, padding: 0.01}]
weather: sunny
";

#[test]
fn scene_fields_not_applied_are_named_and_duplicate_ids_replace() {
    let (scene, notes) = parse_scene_str(SCENE, "s.yaml", None).unwrap();
    // the second 'box' replaces the first: one box, at x = 3 with half-size 0.1
    let names: Vec<String> = scene.iter().map(|(_, o)| o.name.clone()).collect();
    assert_eq!(names, ["ball", "box"]);
    let d = scene.signed_distance(&Vector3::new(3.0, 0.0, 0.5)).unwrap();
    assert!((d.distance - 0.4).abs() < 1e-12, "{d:?}");
    let joined = notes.join("\n");
    for expected in [
        "world.octomap: ",
        "world.collision_objects[0]: id 'box' is added again by world.collision_objects[2]",
        "world.collision_objects[1].colour: not a CollisionObject field",
        "allowed_collision_matrix: collisions allowed with 'ball'",
        "fixed_frame_transforms[1]: ",
        "link_padding: ",
        "weather: not a PlanningScene field",
    ] {
        assert!(joined.contains(expected), "{expected:?} not in\n{joined}");
    }
    assert_eq!(notes.len(), 7, "{joined}");
    // an empty octomap and identity transforms are not reported
    let quiet = "world:\n  octomap: {octomap: {data: []}}\n  collision_objects: []\n\
                 fixed_frame_transforms: [{transform: {translation: [0, 0, 0], rotation: [0, 0, 0, 1]}}]\n";
    assert_eq!(
        parse_scene_str(quiet, "q.yaml", None).unwrap().1,
        Vec::<String>::new()
    );
}

#[test]
fn request_fields_not_applied_are_listed() {
    let request = "group_name: arm
start_state:
  joint_state: {name: [j1], position: [0]}
  multi_dof_joint_state: {joint_names: [v], transforms: [{translation: [1, 0, 0], rotation: [0, 0, 0, 1]}]}
goal_constraints:
  - joint_constraints: [{joint_name: j1, position: 0.5}]
planner_id: RRT
speed_of_light: 3e8
";
    let r = parse_request_str(request, "r.yaml").unwrap();
    assert_eq!(
        r.ignored,
        [
            "start_state.multi_dof_joint_state.transforms[0]",
            "speed_of_light"
        ]
    );
}

#[test]
fn config_refuses_mass_min_above_mass_max() {
    let m = message(FabricConfig::from_toml_str(
        "[ee_position]\nmass_min = 3.0\nmass_max = 2.0\n",
        "c.toml",
    ));
    assert!(
        m.contains("c.toml") && m.contains("ee_position.mass_min") && m.contains("mass_max"),
        "{m}"
    );
}

#[test]
fn thread_pools_are_shared_and_capped() {
    let a = shared_pool(2).unwrap();
    let b = shared_pool(2).unwrap();
    assert!(Arc::ptr_eq(&a, &b));
    assert_eq!(a.current_num_threads(), 2);
    let huge = shared_pool(1 << 20).unwrap();
    assert_eq!(huge.current_num_threads(), max_threads());
    assert_eq!(pool_threads(1 << 20).unwrap(), max_threads());
    assert!(Arc::ptr_eq(&huge, &shared_pool(max_threads()).unwrap()));
    assert!(shared_pool(0).is_err());
}

/// A chain of `n` links (one revolute joint each) with one sphere per link.
fn chain(n: usize) -> Robot {
    let mut xml = String::from("<robot name='chain'><link name='l0'/>");
    for i in 1..n {
        xml.push_str(&format!(
            "<link name='l{i}'/><joint name='j{i}' type='revolute'><parent link='l{}'/>\
             <child link='l{i}'/><origin xyz='0 0 0.1'/><axis xyz='0 1 0'/>\
             <limit lower='-1' upper='1' velocity='1'/></joint>",
            i - 1
        ));
    }
    xml.push_str("</robot>");
    let mut robot = Robot::from_urdf_str(&xml, "chain.urdf", &RobotOptions::default()).unwrap();
    let spheres = (0..n)
        .map(|link| CollisionSphere {
            link,
            center: Vector3::zeros(),
            radius: 0.02,
        })
        .collect();
    robot.set_spheres(spheres).unwrap();
    robot
}

/// Seconds to build a fabric for `robot` (best of `repeats`).
fn build_seconds(robot: &Arc<Robot>, repeats: usize) -> f64 {
    (0..repeats)
        .map(|_| {
            let t = Instant::now();
            Fabric::new(Arc::clone(robot), FabricConfig::default()).unwrap();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn building_a_fabric_grows_with_the_pairs_not_their_square() {
    // 500 -> 2,000 links: 16x the self-collision pairs (about 2 million)
    let (small, large) = (Arc::new(chain(500)), Arc::new(chain(2_000)));
    let pairs = |r: &Robot| r.self_collision_pairs().len() as f64;
    let growth = pairs(&large) / pairs(&small);
    assert!((15.0..17.0).contains(&growth), "{growth}");
    let (ts, tl) = (build_seconds(&small, 3), build_seconds(&large, 1));
    eprintln!("Fabric::new: 500 links {ts:.4} s, 2000 links {tl:.4} s");
    // ~0.2 s here; grouping the pairs by a linear search over link pairs took minutes
    assert!(tl < 10.0, "500 links {ts} s, 2000 links {tl} s");
}
