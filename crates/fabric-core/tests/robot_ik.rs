//! Inverse kinematics: reached targets checked with the forward kinematics, limits, thread-count
//! independence and input errors.

mod robot_support;

use fabric_core::robot::{inverse_kinematics, IkOptions, IkTarget, KinematicsWorkspace, Robot};
use fabric_core::FabricError;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robot_support::random_state;

/// Targets from the forward kinematics of random configurations, and starts perturbed from them by up
/// to `spread` rad per joint (inside the limits).
fn reachable(robot: &Robot, n: usize, spread: f64, axes: bool) -> (Vec<f64>, Vec<IkTarget>) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut ws = KinematicsWorkspace::new(robot);
    let ee = robot.ee_link();
    let (mut starts, mut targets) = (Vec::new(), Vec::new());
    for _ in 0..n {
        let q = random_state(robot, &mut rng).0;
        robot.update_positions(&q, &mut ws).unwrap();
        let pose = robot.link_pose(&ws, ee);
        let r = pose.rotation.to_rotation_matrix();
        targets.push(IkTarget {
            position: pose.translation.vector,
            axes: axes.then(|| [r.matrix().column(0).into(), r.matrix().column(2).into()]),
        });
        for (j, v) in q.iter().enumerate() {
            let s = v + rng.gen_range(-spread..spread);
            starts.push(s.clamp(robot.lower()[j], robot.upper()[j]));
        }
    }
    (starts, targets)
}

#[test]
fn reaches_positions_and_poses_inside_the_limits() {
    let robot = Robot::panda();
    let ee = robot.ee_link();
    let mut ws = KinematicsWorkspace::new(&robot);
    for axes in [false, true] {
        let (starts, targets) = reachable(&robot, 40, 0.3, axes);
        let options = IkOptions {
            iterations: 100,
            ..IkOptions::default()
        };
        let qs = inverse_kinematics(&robot, ee, &starts, &targets, &options).unwrap();
        let mut reached = 0;
        for (q, t) in qs.chunks(7).zip(&targets) {
            assert!(q
                .iter()
                .zip(robot.lower().iter().zip(robot.upper()))
                .all(|(v, (l, u))| l <= v && v <= u));
            robot.update_positions(q, &mut ws).unwrap();
            let pose = robot.link_pose(&ws, ee);
            let mut err = (pose.translation.vector - t.position).norm();
            if let Some([x, z]) = t.axes {
                let r = pose.rotation.to_rotation_matrix();
                let (px, pz): (Vector3<f64>, Vector3<f64>) =
                    (r.matrix().column(0).into(), r.matrix().column(2).into());
                err = err.max((px - x).norm()).max((pz - z).norm());
            }
            reached += usize::from(err < 1e-4);
        }
        // starts within 0.3 rad of a solution: nearly all converge (a few stall on a joint limit)
        assert!(reached >= 36, "axes {axes}: {reached}/40 reached");
    }
}

#[test]
fn same_result_on_any_thread_count_and_zero_iterations_only_clip() {
    let robot = Robot::panda();
    let (starts, targets) = reachable(&robot, 33, 0.5, true);
    let options = IkOptions::default();
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| inverse_kinematics(&robot, robot.ee_link(), &starts, &targets, &options))
            .unwrap()
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
    let mut outside = starts[..7].to_vec();
    outside[3] = 1.0; // above joint 4's upper limit
    let none = IkOptions {
        iterations: 0,
        ..options
    };
    let clipped = inverse_kinematics(&robot, 0, &outside, &targets[..1], &none).unwrap();
    assert_eq!(clipped[3], robot.upper()[3]);
    assert_eq!(clipped[..3], outside[..3]);
}

#[test]
fn bad_input_is_reported() {
    let robot = Robot::panda();
    let (starts, targets) = reachable(&robot, 2, 0.1, false);
    let ee = robot.ee_link();
    let ok = IkOptions::default();
    assert!(matches!(
        inverse_kinematics(&robot, ee, &starts[..13], &targets, &ok),
        Err(FabricError::Shape { ref what, .. }) if what == "q_init"
    ));
    let mut nan = starts.clone();
    nan[4] = f64::NAN;
    assert!(matches!(
        inverse_kinematics(&robot, ee, &nan, &targets, &ok),
        Err(FabricError::NonFinite { .. })
    ));
    assert!(matches!(
        inverse_kinematics(&robot, 999, &starts, &targets, &ok),
        Err(FabricError::Value { ref what, .. }) if what == "link"
    ));
    let zero_axis = vec![
        IkTarget {
            axes: Some([Vector3::zeros(), Vector3::z()]),
            ..targets[0].clone()
        };
        2
    ];
    assert!(matches!(
        inverse_kinematics(&robot, ee, &starts, &zero_axis, &ok),
        Err(FabricError::Value { ref what, .. }) if what == "target axes"
    ));
    for bad in [
        IkOptions { damping: 0.0, ..ok },
        IkOptions {
            tolerance: f64::NAN,
            ..ok
        },
        IkOptions {
            axis_weight: -1.0,
            ..ok
        },
    ] {
        assert!(matches!(
            inverse_kinematics(&robot, ee, &starts, &targets, &bad),
            Err(FabricError::Value { .. })
        ));
    }
}

/// `point_ik` (the generators' descent): from starts near random configurations it brings the hand's
/// tool point to the configuration's and the hand z axis into a 20° cone about the configuration's
/// axis, inside the bounds it is given; a start that already meets the target is returned as it is.
#[test]
fn point_ik_reaches_tool_points_and_approach_cones() {
    use fabric_core::robot::{point_ik, PointIkOptions, PointTarget};
    let robot = Robot::panda();
    let ee = robot.ee_link();
    let tcp = Vector3::new(0.0, 0.0, 0.1034);
    let (starts, targets) = reachable(&robot, 20, 0.3, true);
    let options = PointIkOptions::default();
    let (lo, up) = (robot.lower().to_vec(), robot.upper().to_vec());
    let mut ws = KinematicsWorkspace::new(&robot);
    let mut reached = 0;
    for (start, t) in starts.chunks(7).zip(&targets) {
        let z = t.axes.unwrap()[1];
        let tool = t.position + z * 0.1034; // the tool point of the target configuration
        let target = PointTarget {
            position: tool,
            approach: Some((z, 20f64.to_radians().cos())),
        };
        let solve = |q: &mut [f64]| {
            point_ik(
                &robot,
                ee,
                &tcp,
                &Vector3::z(),
                &target,
                q,
                &lo,
                &up,
                &options,
            )
            .unwrap()
        };
        let mut q = start.to_vec();
        if solve(&mut q) {
            reached += 1;
            robot.update_positions(&q, &mut ws).unwrap();
            let pose = robot.link_pose(&ws, ee);
            assert!((pose.transform_point(&tcp.into()).coords - tool).norm() < options.tolerance);
            assert!((pose.rotation * Vector3::z()).dot(&z) >= 20f64.to_radians().cos());
            let again = q.clone();
            assert!(solve(&mut q));
            assert_eq!(q, again);
        }
        assert!(q
            .iter()
            .zip(&lo)
            .zip(&up)
            .all(|((v, l), u)| l <= v && v <= u));
    }
    assert!(reached >= 18, "{reached} of 20");
    let bad = PointTarget {
        position: Vector3::new(0.4, 0.0, 0.5),
        approach: Some((Vector3::zeros(), 0.9)),
    };
    let mut q = starts[..7].to_vec();
    let err = point_ik(
        &robot,
        ee,
        &tcp,
        &Vector3::z(),
        &bad,
        &mut q,
        &lo,
        &up,
        &options,
    );
    assert!(matches!(err, Err(FabricError::Value { .. })));
}
