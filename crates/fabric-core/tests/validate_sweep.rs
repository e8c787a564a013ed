//! `MeshChecker::sweep` (continuous verdict along a joint path) against closed forms and dense
//! sampling: a link that swings through an obstacle between two clear states, a path that clears
//! it, the motion bounds against the displacement of every shape's box corners, and a two-link
//! chain whose self-collision only happens between states.

use fabric_core::robot::{Robot, RobotOptions};
use fabric_core::scene::{Obstacle, Scene, Shape};
use fabric_core::validate::MeshChecker;
use nalgebra::{Isometry3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A planar two-joint arm about z: link1 (a 0.4 × 0.04 × 0.04 m box from the base axis along x),
/// link2 (the same box, its joint at the end of link1), and a box on the base at x = 0.1..0.3,
/// y = −0.3 (no SRDF: the base and link2 are the one non-adjacent pair).
fn arm() -> Robot {
    let link = |name: &str| {
        format!(
            r#"<link name="{name}"><collision><origin xyz="0.2 0 0"/><geometry><box size="0.4 0.04 0.04"/></geometry></collision></link>"#
        )
    };
    let xml = format!(
        r#"<robot name="arm">
          <link name="base"><collision><origin xyz="0.2 -0.3 0"/><geometry><box size="0.2 0.04 0.04"/></geometry></collision></link>
          {l1}{l2}
          <joint name="j1" type="revolute"><parent link="base"/><child link="link1"/>
            <axis xyz="0 0 1"/><limit lower="-3.1" upper="3.1" velocity="1" effort="1"/></joint>
          <joint name="j2" type="revolute"><parent link="link1"/><child link="link2"/>
            <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/><limit lower="-3.1" upper="3.1" velocity="1" effort="1"/></joint>
        </robot>"#,
        l1 = link("link1"),
        l2 = link("link2"),
    );
    Robot::from_urdf_str(&xml, "<test>", &RobotOptions::default()).unwrap()
}

/// A thin post (0.02 m square, tall) at (x, y).
fn post(x: f64, y: f64) -> Scene {
    let mut scene = Scene::new();
    scene
        .add(Obstacle::new(
            "post",
            Shape::cuboid_from_size(Vector3::new(0.02, 0.02, 1.0)),
            Isometry3::translation(x, y, 0.0),
        ))
        .unwrap();
    scene
}

/// The least of per-state distances.
fn least(values: Vec<f64>) -> f64 {
    values.into_iter().fold(f64::INFINITY, f64::min)
}

/// j1 swung from `from` to `to` rad with j2 = 0, as `samples` + 1 evenly spaced states (row-major).
fn swing(from: f64, to: f64, samples: usize) -> Vec<f64> {
    (0..=samples)
        .flat_map(|k| [from + (to - from) * k as f64 / samples as f64, 0.0])
        .collect()
}

#[test]
fn a_swing_through_a_post_fails_between_clear_states() {
    let robot = arm();
    let checker = MeshChecker::new(&robot).unwrap();
    // The post at 0.6 m along +x: link2 (straight) sweeps through it when j1 goes from -0.3 to 0.3.
    let scene = post(0.6, 0.0);
    let qs = swing(-0.3, 0.3, 1);
    let states = checker.trajectory_clearance(&scene, &qs, None).unwrap();
    assert!(
        states.iter().all(|d| *d > 0.1),
        "both states clear: {states:?}"
    );
    let sweep = checker.sweep(&scene, &qs, 0.001, None, None).unwrap();
    assert!(!sweep.ok && sweep.complete, "{sweep:?}");
    assert!(sweep.clearance <= 0.001, "{sweep:?}");
    // Densely sampled, the same path touches the post.
    let dense = least(
        checker
            .trajectory_clearance(&scene, &swing(-0.3, 0.3, 600), None)
            .unwrap(),
    );
    assert!(dense <= 0.0, "{dense}");
}

#[test]
fn a_path_past_a_post_is_certified_and_a_near_miss_depends_on_the_margin() {
    let robot = arm();
    let checker = MeshChecker::new(&robot).unwrap();
    // The post beyond the arm's reach in x (0.9 m): clear along the whole swing, by 0.09 m at least.
    let scene = post(0.9, 0.0);
    let qs = swing(-0.3, 0.3, 1);
    let sweep = checker.sweep(&scene, &qs, 0.001, Some(2), None).unwrap();
    assert!(sweep.ok && sweep.complete, "{sweep:?}");
    // A post 3 mm beyond the tip's arc: certified at a 1 mm margin, refused at 5 mm.
    let tip = (0.8f64.powi(2) + 0.02f64.powi(2)).sqrt();
    let near = post(tip + 0.01 + 0.003, 0.0);
    let ok = checker.sweep(&near, &qs, 0.001, None, None).unwrap();
    assert!(ok.ok, "{ok:?}");
    assert!(ok.measured > 2, "midpoints were measured: {ok:?}");
    let strict = checker.sweep(&near, &qs, 0.005, None, None).unwrap();
    assert!(!strict.ok && strict.complete, "{strict:?}");
}

#[test]
fn self_collision_between_states_is_found() {
    let robot = arm();
    let checker = MeshChecker::new(&robot).unwrap();
    let empty = Scene::new();
    // Straight arm (j2 = 0): link2 spans 0.4-0.8 m from the base axis, and the base box's outer end
    // (0.3, -0.3) lies 0.42 m from it at -45°. Swinging j1 from -1.2 to -0.2 rad carries link2's
    // inner end across that corner, while both end states keep it clear.
    let qs = swing(-1.2, -0.2, 1);
    let states = checker.trajectory_self_clearance(&qs, None).unwrap();
    assert!(states.iter().all(|d| *d > 0.0), "{states:?}");
    let dense = least(
        checker
            .trajectory_self_clearance(&swing(-1.2, -0.2, 800), None)
            .unwrap(),
    );
    assert!(dense <= 0.0, "the path crosses the base box: {dense}");
    let sweep = checker.sweep(&empty, &qs, 0.001, None, None).unwrap();
    assert!(
        !sweep.ok && sweep.complete,
        "dense min {dense}, states {states:?}, {sweep:?}"
    );
}

#[test]
fn motion_bounds_hold_for_random_steps() {
    let robot = arm();
    let checker = MeshChecker::new(&robot).unwrap();
    let bounds = checker.motion_bounds();
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    // Corners of each box in its shape frame (half sizes 0.2, 0.02, 0.02; the base box 0.1).
    let corners = |half: [f64; 3]| -> Vec<Vector3<f64>> {
        (0..8)
            .map(|k| {
                let s = |b: usize| if k & b == 0 { -1.0 } else { 1.0 };
                Vector3::new(s(1) * half[0], s(2) * half[1], s(4) * half[2])
            })
            .collect()
    };
    let halves = [[0.1, 0.02, 0.02], [0.2, 0.02, 0.02], [0.2, 0.02, 0.02]];
    for _ in 0..200 {
        let qa = [rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0)];
        let dq = [rng.gen_range(-0.5..0.5), rng.gen_range(-0.5..0.5)];
        let bound = bounds.obstacle_bound(&dq);
        let pa = checker.shape_poses(&qa).unwrap();
        // Along the straight segment: every corner's displacement from qa stays within the bound.
        for k in 1..=20 {
            let t = k as f64 / 20.0;
            let q = [qa[0] + t * dq[0], qa[1] + t * dq[1]];
            let pq = checker.shape_poses(&q).unwrap();
            for (s, half) in halves.iter().enumerate() {
                for c in corners(*half) {
                    let moved = (pq[s] * nalgebra::Point3::from(c)
                        - pa[s] * nalgebra::Point3::from(c))
                    .norm();
                    assert!(
                        moved <= t * bound + 1e-12,
                        "shape {s}: {moved} > {}",
                        t * bound
                    );
                }
            }
        }
    }
}

#[test]
fn bad_margin_and_empty_paths() {
    let robot = arm();
    let checker = MeshChecker::new(&robot).unwrap();
    let scene = post(0.9, 0.0);
    assert!(checker
        .sweep(&scene, &[0.0, 0.0], -1.0, None, None)
        .is_err());
    assert!(checker
        .sweep(&scene, &[0.0, 0.0, 0.1], 0.0, None, None)
        .is_err());
    let empty = checker.sweep(&scene, &[], 0.001, None, None).unwrap();
    assert!(empty.ok && empty.measured == 0);
    let one = checker
        .sweep(&scene, &[0.0, 0.0], 0.001, None, None)
        .unwrap();
    assert!(one.ok && one.measured == 1);
}
