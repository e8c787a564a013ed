//! MoveIt PlanningScene / MotionPlanRequest YAML: every MotionBenchMaker problem, conventions (full box
//! sizes, cylinder [height, radius], quaternions [x, y, z, w], object pose composition) and errors that
//! name the file and the field.

mod scene_support;

use std::path::Path;

use fabric_core::scene::moveit::{parse_request_file, parse_request_str};
use fabric_core::scene::{Scene, Shape};
use fabric_core::FabricError;
use nalgebra::{Point3, Vector3};
use scene_support::shared_dir;

const CLASSES: [&str; 7] = [
    "bookshelf_small",
    "bookshelf_tall",
    "bookshelf_thin",
    "box",
    "cage",
    "table_pick",
    "table_under_pick",
];

fn files(dir: &Path, prefix: &str) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy();
            n.starts_with(prefix) && n.ends_with(".yaml")
        })
        .collect();
    v.sort();
    v
}

#[test]
fn every_motionbenchmaker_scene_loads() {
    let Some(mbm) = shared_dir("mbm") else { return };
    let mut total = 0;
    for class in CLASSES {
        let scenes = files(&mbm.join(class), "scene");
        assert!(scenes.len() >= 50, "{class}: {} scenes", scenes.len());
        for path in scenes {
            let scene = Scene::from_moveit_yaml_file(&path, None).unwrap_or_else(|e| panic!("{e}"));
            // Independent count and first box sizes from the raw YAML.
            let raw: serde_yaml::Value =
                serde_yaml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
            let objects = raw["world"]["collision_objects"].as_sequence().unwrap();
            let n: usize = objects
                .iter()
                .map(|o| o["primitives"].as_sequence().unwrap().len())
                .sum();
            assert_eq!(scene.len(), n, "{}", path.display());
            for o in objects {
                let prim = &o["primitives"][0];
                let dims: Vec<f64> = prim["dimensions"]
                    .as_sequence()
                    .unwrap()
                    .iter()
                    .map(|d| d.as_f64().unwrap())
                    .collect();
                let id = scene.find(o["id"].as_str().unwrap()).unwrap();
                let obstacle = scene.get(id).unwrap();
                let pos: Vec<f64> = o["primitive_poses"][0]["position"]
                    .as_sequence()
                    .unwrap()
                    .iter()
                    .map(|d| d.as_f64().unwrap())
                    .collect();
                assert!(
                    (obstacle.pose.translation.vector - Vector3::new(pos[0], pos[1], pos[2]))
                        .norm()
                        < 1e-12
                );
                match (prim["type"].as_str().unwrap(), &obstacle.shape) {
                    ("box", Shape::Cuboid { half_extents }) => {
                        assert!(
                            (half_extents * 2.0 - Vector3::new(dims[0], dims[1], dims[2])).norm()
                                < 1e-12
                        )
                    }
                    (
                        "cylinder",
                        Shape::Cylinder {
                            half_height,
                            radius,
                        },
                    ) => {
                        assert!(
                            (2.0 * half_height - dims[0]).abs() < 1e-12
                                && (radius - dims[1]).abs() < 1e-12
                        )
                    }
                    ("sphere", Shape::Sphere { radius }) => {
                        assert!((radius - dims[0]).abs() < 1e-12)
                    }
                    (t, s) => panic!("{}: type {t} loaded as {s:?}", path.display()),
                }
            }
            total += 1;
        }
    }
    assert!(total >= 350, "{total} scenes");
}

#[test]
fn every_motionbenchmaker_request_parses() {
    let Some(mbm) = shared_dir("mbm") else { return };
    let arm: Vec<String> = (1..=7).map(|i| format!("panda_joint{i}")).collect();
    let mut total = 0;
    for class in CLASSES {
        for path in files(&mbm.join(class), "request") {
            let req = parse_request_file(&path).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(req.group, "panda_arm");
            let start = req.start_for(&arm).unwrap();
            let goal = req.goal_for(&arm).unwrap();
            assert_eq!((start.len(), goal.len()), (7, 7));
            assert_eq!(req.goal.len(), 7, "{}", path.display());
            assert!(start.iter().chain(&goal).all(|v| v.is_finite()));
            total += 1;
        }
    }
    assert!(total >= 350, "{total} requests");
}

const SCENE: &str = r#"
world:
  collision_objects:
    - id: table
      primitive_poses:
        - position: [1.0, 2.0, 3.0]
          orientation: [0, 0, 0.7071067811865476, 0.7071067811865476]
      primitives:
        - type: box
          dimensions: [0.4, 0.2, 0.1]
    - id: can
      pose:
        position: {x: 0.0, y: 0.0, z: 1.0}
        orientation: {x: 0, y: 0, z: 0, w: 1}
      primitives:
        - type: cylinder
          dimensions: [0.3, 0.05]
        - type: SPHERE
          dimensions: [0.1]
      primitive_poses:
        - position: [0.5, 0, 0]
          orientation: [0, 0, 0, 2]
        - position: {x: 0, y: 0.5, z: 0}
          orientation: {x: 0, y: 0, z: 0, w: 1}
"#;

#[test]
fn conventions_of_the_scene_format() {
    let scene = Scene::from_moveit_yaml_str(SCENE, "inline.yaml", None).unwrap();
    assert_eq!(scene.len(), 3);
    let table = scene.get(scene.find("table").unwrap()).unwrap();
    let Shape::Cuboid { half_extents } = table.shape else {
        panic!()
    };
    assert!((half_extents - Vector3::new(0.2, 0.1, 0.05)).norm() < 1e-15);
    // [x, y, z, w] = 90° about z: local x maps to world y.
    assert!((table.pose.rotation * Vector3::x() - Vector3::y()).norm() < 1e-12);
    // The box's long side (x, 0.4 m) now lies along world y: a point 0.15 m off the centre along y
    // is inside, along x it is outside.
    assert!(
        scene
            .signed_distance(&Vector3::new(1.0, 2.15, 3.0))
            .unwrap()
            .distance
            < 0.0
    );
    assert!(
        scene
            .signed_distance(&Vector3::new(1.15, 2.0, 3.0))
            .unwrap()
            .distance
            > 0.0
    );

    let cyl = scene.get(scene.find("can/0").unwrap()).unwrap();
    let Shape::Cylinder {
        half_height,
        radius,
    } = cyl.shape
    else {
        panic!()
    };
    assert_eq!((half_height, radius), (0.15, 0.05));
    // Object pose composes with the primitive pose; quaternions are normalised.
    assert!((cyl.pose.translation.vector - Vector3::new(0.5, 0.0, 1.0)).norm() < 1e-15);
    assert!((cyl.pose.rotation.angle()).abs() < 1e-15);
    let ball = scene.get(scene.find("can/1").unwrap()).unwrap();
    assert!((ball.pose * Point3::origin() - Point3::new(0.0, 0.5, 1.0)).norm() < 1e-15);
    let d = scene
        .signed_distance(&Vector3::new(0.0, 0.5, 1.3))
        .unwrap()
        .distance;
    assert!((d - 0.2).abs() < 1e-12);
}

#[test]
fn meshes_in_yaml_become_solid_meshes() {
    let yaml = r#"
world:
  collision_objects:
    - id: tet
      meshes:
        - vertices: [{x: 0, y: 0, z: 0}, {x: 1, y: 0, z: 0}, {x: 0, y: 1, z: 0}, {x: 0, y: 0, z: 1}]
          triangles:
            - vertex_indices: [0, 2, 1]
            - vertex_indices: [0, 1, 3]
            - vertex_indices: [0, 3, 2]
            - vertex_indices: [1, 2, 3]
      mesh_poses:
        - position: [0, 0, 0]
          orientation: [0, 0, 0, 1]
"#;
    let scene = Scene::from_moveit_yaml_str(yaml, "mesh.yaml", None).unwrap();
    let tet = scene.get(scene.find("tet").unwrap()).unwrap();
    assert!(matches!(tet.shape, Shape::TriMesh(_)) && tet.shape.is_solid());
    let d = scene
        .signed_distance(&Vector3::new(0.1, 0.1, 0.1))
        .unwrap()
        .distance;
    assert!((d + 0.1).abs() < 1e-12, "{d}");
}

/// Replace `from` by `to` in the inline scene and expect a Format error on `field`.
fn expect_scene_error(from: &str, to: &str, field: &str) {
    assert!(SCENE.contains(from), "{from}");
    let yaml = SCENE.replacen(from, to, 1);
    match Scene::from_moveit_yaml_str(&yaml, "bad.yaml", None) {
        Err(FabricError::Format {
            file,
            field: f,
            message,
        }) => {
            assert_eq!(file, "bad.yaml");
            assert_eq!(f, field, "{message}");
        }
        other => panic!("expected a Format error on {field}, got {other:?}"),
    }
}

#[test]
fn bad_scene_inputs_name_the_field() {
    let p0 = "world.collision_objects[0]";
    expect_scene_error(
        "          dimensions: [0.4, 0.2, 0.1]\n",
        "",
        &format!("{p0}.primitives[0].dimensions"),
    );
    expect_scene_error(
        "[0.4, 0.2, 0.1]",
        "[0.4, 0.2]",
        &format!("{p0}.primitives[0].dimensions"),
    );
    expect_scene_error(
        "[0.4, 0.2, 0.1]",
        "[0.4, -0.2, 0.1]",
        &format!("{p0}.primitives[0].dimensions[1]"),
    );
    expect_scene_error(
        "[0.4, 0.2, 0.1]",
        "[0.4, 0.2, abc]",
        &format!("{p0}.primitives[0].dimensions[2]"),
    );
    expect_scene_error(
        "type: box",
        "type: pyramid",
        &format!("{p0}.primitives[0].type"),
    );
    expect_scene_error(
        "type: box",
        "type: cone",
        &format!("{p0}.primitives[0].type"),
    );
    expect_scene_error("- id: table", "- name: table", &format!("{p0}.id"));
    expect_scene_error(
        "orientation: [0, 0, 0.7071067811865476, 0.7071067811865476]",
        "orientation: [0, 0, 0]",
        &format!("{p0}.primitive_poses[0].orientation"),
    );
    expect_scene_error(
        "orientation: [0, 0, 0.7071067811865476, 0.7071067811865476]",
        "orientation: [0, 0, 0, 0]",
        &format!("{p0}.primitive_poses[0].orientation"),
    );
    expect_scene_error(
        "position: [1.0, 2.0, 3.0]",
        "place: [1.0, 2.0, 3.0]",
        &format!("{p0}.primitive_poses[0].position"),
    );
    expect_scene_error(
        "position: {x: 0, y: 0.5, z: 0}",
        "position: {x: 0, y: 0.5}",
        "world.collision_objects[1].primitive_poses[1].position.z",
    );
    expect_scene_error(
        "        - position: {x: 0, y: 0.5, z: 0}\n          orientation: {x: 0, y: 0, z: 0, w: 1}\n",
        "",
        "world.collision_objects[1].primitive_poses",
    );
    expect_scene_error(
        "dimensions: [0.1]",
        "dimensions: [0.1, 0.2]",
        "world.collision_objects[1].primitives[1].dimensions",
    );
    expect_scene_error("world:", "universe:", "world");
    // objects outside the planning frame, and objects attached to the robot, are refused
    expect_scene_error(
        "    - id: can\n",
        "    - id: can\n      header: {frame_id: panda_hand}\n",
        "world.collision_objects[1].header.frame_id",
    );
    expect_scene_error(
        "world:\n",
        "robot_state:\n  attached_collision_objects:\n    - link_name: panda_hand\nworld:\n",
        "robot_state.attached_collision_objects",
    );
    expect_scene_error(
        "  collision_objects:",
        "  collision_objects: 3\n  ignored:",
        "world.collision_objects",
    );
    // Invalid YAML and a non-mapping document.
    assert!(matches!(
        Scene::from_moveit_yaml_str("world: [", "x.yaml", None),
        Err(FabricError::Format { .. })
    ));
    assert!(matches!(
        Scene::from_moveit_yaml_str("- 1\n- 2\n", "x.yaml", None),
        Err(FabricError::Format { .. })
    ));
    assert!(matches!(
        Scene::from_moveit_yaml_file(Path::new("/nonexistent/scene.yaml"), None),
        Err(FabricError::Io { .. })
    ));
    // The planning frame by any of its names, and an empty list of attached objects, are accepted.
    for frame in ["world", "/world", "''"] {
        let yaml = SCENE.replacen(
            "    - id: can\n",
            &format!("    - id: can\n      header: {{frame_id: {frame}}}\n"),
            1,
        );
        assert_eq!(
            Scene::from_moveit_yaml_str(&yaml, "ok.yaml", None)
                .unwrap()
                .len(),
            3
        );
    }
    let yaml = SCENE.replacen(
        "world:\n",
        "robot_state:\n  attached_collision_objects: []\nworld:\n",
        1,
    );
    assert_eq!(
        Scene::from_moveit_yaml_str(&yaml, "ok.yaml", None)
            .unwrap()
            .len(),
        3
    );
    // An empty world is a valid, empty scene.
    assert!(
        Scene::from_moveit_yaml_str("world: {}\n", "empty.yaml", None)
            .unwrap()
            .is_empty()
    );
}

const REQUEST: &str = r#"
group_name: panda_arm
goal_constraints:
  - joint_constraints:
      - joint_name: panda_joint1
        position: 0.5
      - position: -0.25
        joint_name: panda_joint2
start_state:
  joint_state:
    position: [0.1, 0.2, 0.04]
    name: [panda_joint2, panda_joint1, panda_finger_joint1]
"#;

#[test]
fn requests_parse_and_map_to_joint_order() {
    let req = parse_request_str(REQUEST, "req.yaml").unwrap();
    assert_eq!(req.group, "panda_arm");
    assert_eq!(req.start[2], ("panda_finger_joint1".to_string(), 0.04));
    let names = vec!["panda_joint1".to_string(), "panda_joint2".to_string()];
    assert_eq!(req.start_for(&names).unwrap(), vec![0.2, 0.1]);
    assert_eq!(req.goal_for(&names).unwrap(), vec![0.5, -0.25]);
    let missing = vec!["panda_joint3".to_string()];
    assert!(matches!(
        req.goal_for(&missing),
        Err(FabricError::MissingJoint { .. })
    ));
}

#[test]
fn bad_requests_name_the_field() {
    let cases = [
        ("group_name: panda_arm\n", "", "group_name"),
        (
            "[0.1, 0.2, 0.04]",
            "[0.1, 0.2]",
            "start_state.joint_state.position",
        ),
        (
            "      - joint_name: panda_joint1\n        position: 0.5\n",
            "      - joint_name: panda_joint1\n",
            "goal_constraints[0].joint_constraints[0].position",
        ),
        (
            "  - joint_constraints:",
            "  - position_constraints:",
            "goal_constraints[0].position_constraints",
        ),
        (
            "  - joint_constraints:",
            "  - other_constraints:",
            "goal_constraints[0].joint_constraints",
        ),
        (
            "name: [panda_joint2, panda_joint1,",
            "name: [panda_joint2, panda_joint2,",
            "start_state.joint_state.name[1]",
        ),
        (
            "position: -0.25",
            "position: fast",
            "goal_constraints[0].joint_constraints[1].position",
        ),
    ];
    for (from, to, field) in cases {
        assert!(REQUEST.contains(from), "{from}");
        match parse_request_str(&REQUEST.replacen(from, to, 1), "req.yaml") {
            Err(FabricError::Format { file, field: f, .. }) => {
                assert_eq!((file.as_str(), f.as_str()), ("req.yaml", field));
            }
            other => panic!("expected Format on {field}, got {other:?}"),
        }
    }
    let empty_goals = "group_name: g\nstart_state: {joint_state: {name: [], position: []}}\ngoal_constraints: []\n";
    assert!(matches!(
        parse_request_str(empty_goals, "r.yaml"),
        Err(FabricError::Format { field, .. }) if field == "goal_constraints"
    ));
}

const POSE_REQUEST: &str = r#"
group_name: panda_arm
goal_constraints:
  - name: pose
    joint_constraints: []
    position_constraints:
      - header: {frame_id: panda_link0}
        link_name: panda_hand
        target_point_offset: {x: 0, y: 0, z: 0.1034}
        constraint_region:
          primitives:
            - type: 2
              dimensions: [0.001]
            - {type: box, dimensions: [0.02, 0.04, 0.06]}
          primitive_poses:
            - position: {x: 0.5, y: -0.1, z: 0.4}
              orientation: {x: 0, y: 0, z: 0, w: 1}
            - position: [0.5, -0.1, 0.4]
              orientation: [0, 0, 0.7071067811865476, 0.7071067811865476]
        weight: 1
    orientation_constraints:
      - header: {frame_id: panda_link0}
        link_name: panda_hand
        orientation: {x: 1, y: 0, z: 0, w: 0}
        absolute_x_axis_tolerance: 0.01
        absolute_y_axis_tolerance: 0.02
        absolute_z_axis_tolerance: 0.03
        parameterization: 1
        weight: 1
start_state:
  joint_state:
    position: [0.1, 0.2]
    name: [panda_joint1, panda_joint2]
"#;

#[test]
fn pose_goal_requests_parse() {
    let req = parse_request_str(POSE_REQUEST, "pose.yaml").unwrap();
    assert!(req.goal.is_empty());
    let g = req.pose_goal.expect("a pose goal");
    assert_eq!(
        (g.link.as_str(), g.frame.as_str()),
        ("panda_hand", "panda_link0")
    );
    assert_eq!(g.offset, Vector3::new(0.0, 0.0, 0.1034));
    assert_eq!(g.region.len(), 2);
    assert!(matches!(g.region[0].0, Shape::Sphere { radius } if radius == 0.001));
    match &g.region[1].0 {
        Shape::Cuboid { half_extents } => {
            assert_eq!(*half_extents, Vector3::new(0.01, 0.02, 0.03))
        }
        other => panic!("expected a box, got {other:?}"),
    }
    assert_eq!(
        g.region[1].1.translation.vector,
        Vector3::new(0.5, -0.1, 0.4)
    );
    let o = g.orientation.expect("an orientation");
    assert!(o.rotation_vector);
    assert_eq!(o.tolerance, Vector3::new(0.01, 0.02, 0.03));
    // quaternion (x, y, z, w) = (1, 0, 0, 0): a half turn about x
    let r = o.rotation.to_rotation_matrix();
    assert!((r * Vector3::y() + Vector3::y()).norm() < 1e-12);

    // position only, no header, no offset: the point is the link origin in the planning frame ""
    let start = POSE_REQUEST.find("    orientation_constraints:").unwrap();
    let end = POSE_REQUEST.find("start_state:").unwrap();
    let position_only = format!("{}{}", &POSE_REQUEST[..start], &POSE_REQUEST[end..])
        .replace(
            "      - header: {frame_id: panda_link0}\n        link_name",
            "      - link_name",
        )
        .replace("        target_point_offset: {x: 0, y: 0, z: 0.1034}\n", "");
    let g = parse_request_str(&position_only, "p.yaml")
        .unwrap()
        .pose_goal
        .unwrap();
    assert_eq!((g.frame.as_str(), g.offset), ("", Vector3::zeros()));
    assert!(g.orientation.is_none());
}

#[test]
fn bad_pose_goals_name_the_field() {
    let cases = [
        (
            "    joint_constraints: []",
            "    joint_constraints: [{joint_name: panda_joint1, position: 0.1}]",
            "goal_constraints[0]",
        ),
        (
            "        link_name: panda_hand\n        orientation:",
            "        link_name: panda_link7\n        orientation:",
            "goal_constraints[0].orientation_constraints[0].link_name",
        ),
        (
            "      - header: {frame_id: panda_link0}\n        link_name: panda_hand\n        orientation:",
            "      - header: {frame_id: world}\n        link_name: panda_hand\n        orientation:",
            "goal_constraints[0].orientation_constraints[0].header.frame_id",
        ),
        (
            "absolute_y_axis_tolerance: 0.02",
            "absolute_y_axis_tolerance: -0.02",
            "goal_constraints[0].orientation_constraints[0].absolute_y_axis_tolerance",
        ),
        (
            "        absolute_z_axis_tolerance: 0.03\n",
            "",
            "goal_constraints[0].orientation_constraints[0].absolute_z_axis_tolerance",
        ),
        (
            "parameterization: 1",
            "parameterization: 2",
            "goal_constraints[0].orientation_constraints[0].parameterization",
        ),
        (
            "orientation: {x: 1, y: 0, z: 0, w: 0}",
            "orientation: {x: 0, y: 0, z: 0, w: 0}",
            "goal_constraints[0].orientation_constraints[0].orientation",
        ),
        (
            "            - type: 2\n              dimensions: [0.001]",
            "            - type: 4\n              dimensions: [0.001, 0.1]",
            "goal_constraints[0].position_constraints[0].constraint_region.primitives[0].type",
        ),
        (
            "            - position: [0.5, -0.1, 0.4]",
            "            - position: [0.5, -0.1]",
            "goal_constraints[0].position_constraints[0].constraint_region.primitive_poses[1].position",
        ),
        (
            "target_point_offset: {x: 0, y: 0, z: 0.1034}",
            "target_point_offset: {x: 0, y: 0}",
            "goal_constraints[0].position_constraints[0].target_point_offset.z",
        ),
        (
            "    position_constraints:\n",
            "    other_constraints:\n",
            "goal_constraints[0].position_constraints",
        ),
    ];
    for (from, to, field) in cases {
        assert!(POSE_REQUEST.contains(from), "{from}");
        match parse_request_str(&POSE_REQUEST.replacen(from, to, 1), "pose.yaml") {
            Err(FabricError::Format { file, field: f, .. }) => {
                assert_eq!((file.as_str(), f.as_str()), ("pose.yaml", field));
            }
            other => panic!("expected Format on {field}, got {other:?}"),
        }
    }
    // two position constraints
    let pc = POSE_REQUEST.find("      - header: {frame_id: panda_link0}\n        link_name: panda_hand\n        target").unwrap();
    let oc = POSE_REQUEST.find("    orientation_constraints:").unwrap();
    let twice = format!("{}{}", &POSE_REQUEST[..oc], &POSE_REQUEST[pc..]);
    assert!(matches!(
        parse_request_str(&twice, "pose.yaml"),
        Err(FabricError::Format { field, message, .. })
            if field == "goal_constraints[0].position_constraints" && message.contains("one position")
    ));
    // mesh regions
    let meshy = POSE_REQUEST.replacen(
        "        constraint_region:\n",
        "        constraint_region:\n          meshes: [{vertices: [], triangles: []}]\n",
        1,
    );
    assert!(matches!(
        parse_request_str(&meshy, "pose.yaml"),
        Err(FabricError::Format { field, .. })
            if field == "goal_constraints[0].position_constraints[0].constraint_region.meshes"
    ));
}

#[test]
fn constraints_not_applied_are_listed() {
    assert!(parse_request_str(REQUEST, "r.yaml")
        .unwrap()
        .ignored
        .is_empty());
    let extra = format!(
        "{REQUEST}path_constraints:\n  name: upright\n  joint_constraints: []\n  orientation_constraints:\n    - {{link_name: panda_hand}}\ntrajectory_constraints:\n  constraints: []\n"
    );
    let req = parse_request_str(&extra, "r.yaml").unwrap();
    assert_eq!(
        req.ignored,
        vec!["path_constraints.orientation_constraints"]
    );
    let second = REQUEST.replacen(
        "goal_constraints:\n",
        "goal_constraints:\n  - joint_constraints: [{joint_name: panda_joint1, position: 0.0}, {joint_name: panda_joint2, position: 0.0}]\n",
        1,
    );
    let req = parse_request_str(&second, "r.yaml").unwrap();
    assert_eq!(req.ignored, vec!["goal_constraints[1..1]"]);
    assert_eq!(req.goal[0], ("panda_joint1".to_string(), 0.0));
    let bad = format!("{REQUEST}trajectory_constraints:\n  constraints: 3\n");
    assert!(matches!(
        parse_request_str(&bad, "r.yaml"),
        Err(FabricError::Format { field, .. }) if field == "trajectory_constraints.constraints"
    ));
    // speed scaling: 0 and 1 mean full speed in MoveIt (MotionBenchMaker writes 0); below 1 it is listed
    let full =
        format!("{REQUEST}max_velocity_scaling_factor: 0\nmax_acceleration_scaling_factor: 1.0\n");
    assert!(parse_request_str(&full, "r.yaml")
        .unwrap()
        .ignored
        .is_empty());
    let slow = format!(
        "{REQUEST}max_velocity_scaling_factor: 0.5\nmax_acceleration_scaling_factor: 0.1\n"
    );
    assert_eq!(
        parse_request_str(&slow, "r.yaml").unwrap().ignored,
        vec![
            "max_velocity_scaling_factor",
            "max_acceleration_scaling_factor"
        ]
    );
    // a start state holding an object is refused (an empty list is not)
    let held = REQUEST.replacen(
        "start_state:\n",
        "start_state:\n  attached_collision_objects: [{link_name: panda_hand}]\n",
        1,
    );
    assert!(matches!(
        parse_request_str(&held, "r.yaml"),
        Err(FabricError::Format { field, .. }) if field == "start_state.attached_collision_objects"
    ));
    let empty = REQUEST.replacen(
        "start_state:\n",
        "start_state:\n  attached_collision_objects: []\n",
        1,
    );
    assert!(parse_request_str(&empty, "r.yaml").is_ok());
}
