//! Every bad input to the robot model returns the right `FabricError` variant (and never panics).

use std::path::Path;

use fabric_core::robot::{batch, CollisionSphere, KinematicsWorkspace, Robot, RobotOptions};
use fabric_core::FabricError;
use nalgebra::Vector3;

const TWO_LINK: &str = r#"<robot name="two">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="1"/></joint>
  <joint name="j2" type="fixed"><parent link="a"/><child link="b"/><origin xyz="0 0 0.1"/></joint>
</robot>"#;

fn load(xml: &str) -> Result<Robot, FabricError> {
    Robot::from_urdf_str(xml, "test.urdf", &RobotOptions::default())
}

fn two() -> Robot {
    load(TWO_LINK).unwrap()
}

#[track_caller]
fn assert_urdf_err(xml: &str, needle: &str) {
    match load(xml) {
        Err(FabricError::Urdf { file, message }) => {
            assert_eq!(file, "test.urdf");
            assert!(
                message.contains(needle),
                "message '{message}' lacks '{needle}'"
            );
        }
        other => panic!("expected Urdf error containing '{needle}', got {other:?}"),
    }
}

#[test]
fn malformed_and_inconsistent_urdf() {
    assert_urdf_err("<robot name='x'><link name='a'></robot>", "");
    assert_urdf_err("not xml at all", "");
    assert_urdf_err("", "");
    assert_urdf_err("<robot name='x'/>", "no <link>");
    assert_urdf_err(&TWO_LINK.replace("<parent link=\"a\"/>", ""), "");
    assert_urdf_err(&TWO_LINK.replace("velocity=\"1\"", "velocity=\"fast\""), "");
    assert_urdf_err(&TWO_LINK.replace("type=\"fixed\"", "type=\"bogus\""), "");
    assert_urdf_err(
        &TWO_LINK.replace("<link name=\"b\"/>", "<link name=\"b\"/><link name=\"a\"/>"),
        "duplicate link",
    );
    assert_urdf_err(
        &TWO_LINK.replace("<child link=\"b\"/>", "<child link=\"zz\"/>"),
        "unknown link 'zz'",
    );
    assert_urdf_err(
        &TWO_LINK.replace("<link name=\"b\"/>", "<link name=\"b\"/><link name=\"c\"/>"),
        "one root",
    );
    // A second parent for link a.
    assert_urdf_err(
        &TWO_LINK.replace(
            "</robot>",
            "<joint name='j3' type='fixed'><parent link='b'/><child link='a'/></joint></robot>",
        ),
        "several joints",
    );
    // Revolute without <limit>.
    assert_urdf_err(
        &TWO_LINK.replace("<limit lower=\"-1\" upper=\"1\" velocity=\"1\"/>", ""),
        "limits",
    );
    // Zero velocity limit, zero axis, NaN origin.
    assert_urdf_err(
        &TWO_LINK.replace("velocity=\"1\"", "velocity=\"0\""),
        "velocity",
    );
    assert_urdf_err(
        &TWO_LINK.replace("<axis xyz=\"0 0 1\"/>", "<axis xyz=\"0 0 0\"/>"),
        "axis",
    );
    assert_urdf_err(
        &TWO_LINK.replace("xyz=\"0 0 0.1\"", "xyz=\"0 nan 0.1\""),
        "NaN",
    );
    // Mimic of an unknown joint.
    assert_urdf_err(
        &TWO_LINK.replace(
            "</robot>",
            "<link name='c'/><joint name='m' type='revolute'><parent link='b'/><child link='c'/>\
             <limit lower='-1' upper='1' velocity='1'/><mimic joint='nope'/></joint></robot>",
        ),
        "mimics unknown joint 'nope'",
    );
    // Non-positive sphere radius.
    assert_urdf_err(
        &TWO_LINK.replace("<link name=\"b\"/>", "<link name=\"b\"><collision><geometry><sphere radius=\"-0.1\"/></geometry></collision></link>"),
        "sizes",
    );
    assert!(matches!(
        Robot::from_urdf_file(
            Path::new("/nonexistent/robot.urdf"),
            &RobotOptions::default()
        ),
        Err(FabricError::Io { .. })
    ));
}

#[test]
fn multi_dof_joints_are_held_at_their_identity_pose() {
    // j2 as a floating, planar or spherical joint: the same model as the fixed joint at its origin
    let fixed = two();
    let mut ws = fabric_core::robot::KinematicsWorkspace::new(&fixed);
    fixed.update_positions(&[0.3], &mut ws).unwrap();
    let b = fixed.link_pose(&ws, 2);
    for kind in ["planar", "floating", "spherical"] {
        let xml = TWO_LINK.replace("type=\"fixed\"", &format!("type=\"{kind}\""));
        let robot = load(&xml).unwrap_or_else(|e| panic!("{kind}: {e}"));
        assert_eq!(robot.joint_names(), ["j1"], "{kind}");
        assert!(robot.locked_positions().is_empty(), "{kind}");
        let mut ws = fabric_core::robot::KinematicsWorkspace::new(&robot);
        robot.update_positions(&[0.3], &mut ws).unwrap();
        assert_eq!(robot.link_pose(&ws, 2), b, "{kind}");
        // it can be neither planned nor locked, and the message says why
        for opts in [
            RobotOptions {
                active_joints: Some(vec!["j1".into(), "j2".into()]),
                ..Default::default()
            },
            RobotOptions {
                locked_positions: vec![("j2".into(), 0.0)],
                ..Default::default()
            },
        ] {
            let err = Robot::from_urdf_str(&xml, "test.urdf", &opts)
                .unwrap_err()
                .to_string();
            assert!(
                err.contains(&format!(
                    "is a {kind} joint (several degrees of freedom), held at its identity pose"
                )),
                "{kind}: {err}"
            );
        }
    }
}

#[test]
fn bad_options() {
    let with = |opts: RobotOptions| Robot::from_urdf_str(TWO_LINK, "test.urdf", &opts);
    let missing_link = |r: Result<Robot, FabricError>, name: &str| {
        assert_eq!(
            r.err(),
            Some(FabricError::MissingLink {
                robot: "two".into(),
                link: name.into()
            })
        );
    };
    missing_link(
        with(RobotOptions {
            base_link: Some("nope".into()),
            ..Default::default()
        }),
        "nope",
    );
    missing_link(
        with(RobotOptions {
            ee_link: Some("gone".into()),
            ..Default::default()
        }),
        "gone",
    );
    assert_eq!(
        with(RobotOptions {
            active_joints: Some(vec!["jx".into()]),
            ..Default::default()
        })
        .err(),
        Some(FabricError::MissingJoint {
            robot: "two".into(),
            joint: "jx".into()
        })
    );
    let value = |r: Result<Robot, FabricError>| {
        assert!(matches!(r, Err(FabricError::Value { .. })), "{r:?}")
    };
    value(with(RobotOptions {
        active_joints: Some(vec!["j2".into()]),
        ..Default::default()
    }));
    value(with(RobotOptions {
        active_joints: Some(vec!["j1".into(), "j1".into()]),
        ..Default::default()
    }));
    value(with(RobotOptions {
        active_joints: Some(vec![]),
        ..Default::default()
    }));
    // The end-effector is the base: no joint between them.
    value(with(RobotOptions {
        ee_link: Some("base".into()),
        ..Default::default()
    }));
    // Locking an active joint, a fixed joint, an unknown joint, or at NaN.
    value(with(RobotOptions {
        locked_positions: vec![("j1".into(), 0.0)],
        ..Default::default()
    }));
    value(with(RobotOptions {
        active_joints: Some(vec!["j1".into()]),
        locked_positions: vec![("j2".into(), 0.0)],
        ..Default::default()
    }));
    assert!(matches!(
        with(RobotOptions {
            locked_positions: vec![("zz".into(), 0.0)],
            ..Default::default()
        }),
        Err(FabricError::MissingJoint { .. })
    ));
    let xml = TWO_LINK.replace(
        "</robot>",
        "<link name='c'/><joint name='j3' type='prismatic'><parent link='b'/><child link='c'/>\
         <limit lower='0' upper='1' velocity='1'/></joint></robot>",
    );
    let opts = RobotOptions {
        active_joints: Some(vec!["j1".into()]),
        locked_positions: vec![("j3".into(), f64::NAN)],
        ..Default::default()
    };
    assert!(matches!(
        Robot::from_urdf_str(&xml, "t", &opts),
        Err(FabricError::NonFinite { .. })
    ));
    assert_eq!(
        two().link_index("zz").err(),
        Some(FabricError::MissingLink {
            robot: "two".into(),
            link: "zz".into()
        })
    );
    assert!(matches!(
        two().joint_index("j2"),
        Err(FabricError::MissingJoint { .. })
    ));
}

#[test]
fn bad_states() {
    let robot = two();
    let mut ws = KinematicsWorkspace::new(&robot);
    assert!(matches!(
        robot.update(&[0.0, 0.0], &[0.0], &mut ws),
        Err(FabricError::Shape { .. })
    ));
    assert!(matches!(
        robot.update(&[0.0], &[], &mut ws),
        Err(FabricError::Shape { .. })
    ));
    assert!(matches!(
        robot.update(&[f64::NAN], &[0.0], &mut ws),
        Err(FabricError::NonFinite { .. })
    ));
    assert!(matches!(
        robot.update(&[0.0], &[f64::INFINITY], &mut ws),
        Err(FabricError::NonFinite { .. })
    ));
    assert!(matches!(
        robot.update_positions(&[], &mut ws),
        Err(FabricError::Shape { .. })
    ));
    // A workspace made for another robot.
    let mut other = KinematicsWorkspace::new(&Robot::panda());
    assert!(matches!(
        robot.update(&[0.0], &[0.0], &mut other),
        Err(FabricError::Shape { .. })
    ));
    // Batches: length not a multiple of dof, NaN.
    let panda = Robot::panda();
    assert!(matches!(
        batch::link_poses(&panda, &[0.0; 8]),
        Err(FabricError::Shape { .. })
    ));
    let mut qs = vec![0.0; 14];
    qs[9] = f64::NAN;
    assert!(matches!(
        batch::sphere_centers(&panda, &qs),
        Err(FabricError::NonFinite { .. })
    ));
    assert_eq!(batch::sphere_centers(&panda, &[]).unwrap().len(), 0);
    // A link index beyond the robot's links.
    let links = panda.link_names().len();
    assert!(matches!(
        batch::link_origins(&panda, &[0.0; 7], links),
        Err(FabricError::Value { .. })
    ));
}

#[test]
fn bad_sphere_files_and_lists() {
    let robot = two();
    let format_field = |json: &str| match robot.parse_sphere_json(json, "s.json") {
        Err(FabricError::Format { file, field, .. }) => {
            assert_eq!(file, "s.json");
            field
        }
        other => panic!("{json}: {other:?}"),
    };
    assert_eq!(format_field("{"), "(document)");
    assert_eq!(format_field("{}"), "spheres");
    assert_eq!(format_field(r#"{"spheres": 3}"#), "spheres");
    assert_eq!(
        format_field(r#"{"spheres": [{"link": "a", "center": [0, 0, 0]}]}"#),
        "spheres[0].radius"
    );
    assert_eq!(
        format_field(r#"{"spheres": [{"link": "a", "radius": 0.1}]}"#),
        "spheres[0].center"
    );
    assert_eq!(
        format_field(
            r#"{"spheres": [{"link": "a", "center": [0, 0, 0], "radius": 0.1}, {"link": "a", "center": [0, 0], "radius": 0.1}]}"#
        ),
        "spheres[1].center"
    );
    assert_eq!(
        format_field(r#"{"spheres": [{"link": 3, "center": [0, 0, 0], "radius": 0.1}]}"#),
        "spheres[0].link"
    );
    assert_eq!(
        robot
            .parse_sphere_json(
                r#"{"spheres": [{"link": "zz", "center": [0, 0, 0], "radius": 0.1}]}"#,
                "s.json"
            )
            .err(),
        Some(FabricError::MissingLink {
            robot: "two".into(),
            link: "zz".into()
        })
    );
    for r in ["-0.1", "0"] {
        let json =
            format!(r#"{{"spheres": [{{"link": "a", "center": [0, 0, 0], "radius": {r}}}]}}"#);
        assert!(
            matches!(
                robot.parse_sphere_json(&json, "s.json"),
                Err(FabricError::Value { .. })
            ),
            "radius {r}"
        );
    }
    let ok = robot
        .parse_sphere_json(r#"{"spheres": [{"link": "b", "center": [0.1, 0.2, 0.3], "radius": 0.05}], "note": "x"}"#, "s")
        .unwrap();
    assert_eq!(
        ok,
        vec![CollisionSphere {
            link: 2,
            center: Vector3::new(0.1, 0.2, 0.3),
            radius: 0.05
        }]
    );
    assert!(matches!(
        robot.load_sphere_file(Path::new("/nonexistent.json")),
        Err(FabricError::Io { .. })
    ));

    let mut robot = robot;
    let bad = |link, center, radius| {
        vec![CollisionSphere {
            link,
            center,
            radius,
        }]
    };
    for spheres in [
        bad(9, Vector3::zeros(), 0.1),
        bad(1, Vector3::new(f64::NAN, 0.0, 0.0), 0.1),
        bad(1, Vector3::zeros(), -1.0),
        bad(1, Vector3::zeros(), f64::INFINITY),
    ] {
        assert!(matches!(
            robot.set_spheres(spheres),
            Err(FabricError::Value { .. })
        ));
    }
    assert!(robot.spheres().is_empty());
}

#[test]
fn bad_srdf() {
    let mut robot = Robot::panda();
    let pairs = robot.self_collision_pairs().to_vec();
    let field = |r: Result<Vec<String>, FabricError>| match r {
        Err(FabricError::Format { file, field, .. }) => {
            assert_eq!(file, "bad.srdf");
            field
        }
        other => panic!("{other:?}"),
    };
    assert_eq!(
        field(robot.set_self_collision_from_srdf("<robot><disable_collisions", "bad.srdf")),
        "(xml)"
    );
    assert_eq!(
        field(robot.set_self_collision_from_srdf("<srdf/>", "bad.srdf")),
        "(root)"
    );
    let f = field(robot.set_self_collision_from_srdf(
        "<robot>\n<disable_collisions link1=\"panda_link0\" link2=\"panda_link1\"/>\n<disable_collisions link1=\"panda_link0\"/>\n</robot>",
        "bad.srdf",
    ));
    assert_eq!(f, "disable_collisions[1] (line 3).link2");
    // Failed calls leave the model unchanged.
    assert_eq!(robot.self_collision_pairs(), pairs.as_slice());
    // A link the robot does not have skips its entry (MoveIt warns and skips) and is reported once.
    let skipped = robot
        .set_self_collision_from_srdf(
            "<robot><disable_collisions link1=\"panda_link0\" link2=\"elbow\"/>\
             <disable_collisions link1=\"elbow\" link2=\"wrist\"/></robot>",
            "bad.srdf",
        )
        .unwrap();
    assert_eq!(skipped, ["elbow", "wrist"]);
}
