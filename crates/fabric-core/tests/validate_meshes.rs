//! `validate::MeshChecker` against independent references: closed-form box-box, cylinder-box and
//! cube-sphere distances, a brute-force minimum over every shape (no branch and bound), and the
//! MotionBenchMaker Panda's collision meshes in an MBM scene (skipped without `../shared`, failing under
//! CI=true).

mod fabric_support;

use std::f64::consts::FRAC_PI_4;
use std::path::{Path, PathBuf};

use fabric_core::robot::{Robot, RobotOptions};
use fabric_core::scene::{Obstacle, Scene, Shape};
use fabric_core::validate::{MeshChecker, DEFAULT_MAX_DISTANCE};
use fabric_core::FabricError;
use fabric_support::{mbm_problem, shared_dir};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const TOL: f64 = 1e-9;

/// A one-joint robot: `joint` ("prismatic" along x or "revolute" about z) moves `link`, which carries
/// the collision element `collision` (inner XML of `<collision>`).
fn one_joint_robot(joint: &str, collision: &str, mesh_dir: Option<&Path>) -> Robot {
    let xml = format!(
        r#"<robot name="one">
          <link name="base"/>
          <link name="link"><collision>{collision}</collision></link>
          <joint name="j" type="{joint}"><parent link="base"/><child link="link"/>
            <axis xyz="{axis}"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
        </robot>"#,
        axis = if joint == "prismatic" {
            "1 0 0"
        } else {
            "0 0 1"
        }
    );
    let opts = RobotOptions {
        mesh_dir: mesh_dir.map(Path::to_path_buf),
        ..RobotOptions::default()
    };
    Robot::from_urdf_str(&xml, "<test>", &opts).expect("test URDF")
}

fn at(x: f64, y: f64, z: f64) -> Isometry3<f64> {
    Isometry3::translation(x, y, z)
}

fn scene_with(obstacles: Vec<(Shape, Isometry3<f64>)>) -> Scene {
    let mut scene = Scene::new();
    for (k, (shape, pose)) in obstacles.into_iter().enumerate() {
        scene
            .add(Obstacle::new(format!("o{k}"), shape, pose))
            .unwrap();
    }
    scene
}

fn cube_box(size: f64) -> Shape {
    Shape::cuboid_from_size(Vector3::repeat(size))
}

#[test]
fn box_link_against_box_obstacle_closed_form() {
    // Link: a 0.2 m cube whose element origin sits 0.05 m above the link frame, sliding along x.
    let robot = one_joint_robot(
        "prismatic",
        r#"<origin xyz="0 0 0.05"/><geometry><box size="0.2 0.2 0.2"/></geometry>"#,
        None,
    );
    let checker = MeshChecker::new(&robot)
        .unwrap()
        .with_max_distance(f64::INFINITY)
        .unwrap();
    assert_eq!(checker.num_shapes(), 1);
    // Obstacle: a 0.4 m cube centred at (1, 0, 0.05): faces at x = 0.8; the link spans [q-0.1, q+0.1].
    let face = scene_with(vec![(cube_box(0.4), at(1.0, 0.0, 0.05))]);
    for q in [-0.5, 0.0, 0.3, 0.6, 0.69] {
        let d = checker.clearance(&face, &[q]).unwrap();
        assert!((d - (0.7 - q)).abs() < TOL, "q={q}: {d} vs {}", 0.7 - q);
    }
    // Penetration by 0.05 along x (the overlap across y and z is 0.3): depth -0.05.
    let d = checker.clearance(&face, &[0.75]).unwrap();
    assert!((d + 0.05).abs() < 1e-6, "penetration {d}");
    // Corner-to-corner: gaps 0.7 - q in x, 0.2 in y, 0.15 in z.
    let corner = scene_with(vec![(cube_box(0.4), at(1.0, 0.5, 0.5))]);
    for q in [0.0, 0.4] {
        let expect = ((0.7f64 - q).powi(2) + 0.2f64.powi(2) + 0.15f64.powi(2)).sqrt();
        let d = checker.clearance(&corner, &[q]).unwrap();
        assert!((d - expect).abs() < TOL, "q={q}: {d} vs {expect}");
    }
    // The default cutoff (0.5 m) reports far states as +inf, near ones exactly.
    let local = MeshChecker::new(&robot).unwrap();
    assert_eq!(local.max_distance(), DEFAULT_MAX_DISTANCE);
    assert_eq!(local.clearance(&face, &[0.0]).unwrap(), f64::INFINITY);
    assert!((local.clearance(&face, &[0.3]).unwrap() - 0.4).abs() < TOL);
}

#[test]
fn rotated_box_and_cylinder_links_closed_form() {
    // A 0.2 m cube turned by q about z: its corner reaches x = 0.1·√2 at q = π/4.
    let robot = one_joint_robot(
        "revolute",
        r#"<geometry><box size="0.2 0.2 0.2"/></geometry>"#,
        None,
    );
    let checker = MeshChecker::new(&robot).unwrap();
    let wall = scene_with(vec![(cube_box(0.4), at(0.7, 0.0, 0.0))]);
    let d = checker.clearance(&wall, &[FRAC_PI_4]).unwrap();
    assert!((d - (0.5 - 0.1 * 2f64.sqrt())).abs() < TOL, "{d}");
    assert!((checker.clearance(&wall, &[0.0]).unwrap() - 0.4).abs() < TOL);

    // URDF cylinders lie along z (parry's along y): radius 0.05, length 0.4.
    let robot = one_joint_robot(
        "prismatic",
        r#"<geometry><cylinder radius="0.05" length="0.4"/></geometry>"#,
        None,
    );
    let checker = MeshChecker::new(&robot).unwrap();
    let above = scene_with(vec![(cube_box(0.2), at(0.0, 0.0, 0.6))]); // bottom face z = 0.5
    assert!((checker.clearance(&above, &[0.0]).unwrap() - 0.3).abs() < TOL);
    let side = scene_with(vec![(cube_box(0.2), at(0.4, 0.0, 0.0))]); // face x = 0.3
    assert!((checker.clearance(&side, &[0.0]).unwrap() - 0.25).abs() < TOL);
    assert!((checker.clearance(&side, &[0.1]).unwrap() - 0.15).abs() < TOL);
}

/// A temporary folder holding a unit cube OBJ (centred on the origin, outward faces).
fn cube_obj_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("gfcs_validate_{tag}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut obj = String::new();
    for x in [-0.5, 0.5] {
        for y in [-0.5, 0.5] {
            for z in [-0.5, 0.5] {
                obj += &format!("v {x} {y} {z}\n");
            }
        }
    }
    // Vertex (i,j,k) of {-,+}³ is 1 + 4i + 2j + k; quads counter-clockwise seen from outside.
    for face in [
        [1, 2, 4, 3], // x = -0.5
        [5, 7, 8, 6], // x = +0.5
        [1, 5, 6, 2], // y = -0.5
        [3, 4, 8, 7], // y = +0.5
        [1, 3, 7, 5], // z = -0.5
        [2, 6, 8, 4], // z = +0.5
    ] {
        obj += &format!("f {} {} {} {}\n", face[0], face[1], face[2], face[3]);
    }
    std::fs::write(dir.join("cube.obj"), obj).unwrap();
    dir
}

/// Closed-form signed distance from p to the box of half extents h centred at the origin.
fn box_sdf(p: &Vector3<f64>, h: &Vector3<f64>) -> f64 {
    let q = p.abs() - h;
    let outside = q.map(|v| v.max(0.0)).norm();
    outside + q.max().min(0.0)
}

#[test]
fn cube_mesh_link_against_sphere_closed_form() {
    let dir = cube_obj_dir("cube");
    let element =
        r#"<geometry><mesh filename="package://pkg/cube.obj" scale="0.5 2 1"/></geometry>"#;
    let robot = one_joint_robot("prismatic", element, Some(&dir));
    let checker = MeshChecker::new(&robot)
        .unwrap()
        .with_max_distance(f64::INFINITY)
        .unwrap();
    assert_eq!(checker.num_shapes(), 1);
    // Scaled cube: half extents (0.25, 1, 0.5), carried to x = q.
    let h = Vector3::new(0.25, 1.0, 0.5);
    let r = 0.1;
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut outside = 0;
    while outside < 200 {
        let c = Vector3::new(
            rng.gen_range(-1.5..1.5),
            rng.gen_range(-2.0..2.0),
            rng.gen_range(-1.2..1.2),
        );
        let q = rng.gen_range(-0.3..0.3);
        let local = c - Vector3::new(q, 0.0, 0.0);
        let sdf = box_sdf(&local, &h);
        if sdf < 1e-3 {
            continue; // centre inside (or on) the cube: covered below
        }
        outside += 1;
        let scene = scene_with(vec![(Shape::Sphere { radius: r }, at(c.x, c.y, c.z))]);
        let d = checker.clearance(&scene, &[q]).unwrap();
        assert!(
            (d - (sdf - r)).abs() < 1e-7,
            "centre {c:?}, q={q}: {d} vs {}",
            sdf - r
        );
    }
    // The cube is convex: measured as its hull, a convex polyhedron (its triangle tree stays, for
    // distances to non-convex meshes).
    let shape = &checker.shapes()[0];
    assert!(shape.hull.is_none() && shape.tree.is_some());
    assert!(shape.shape.as_convex_polyhedron().is_some());
    // A ball wholly inside the solid cube is a contact of two solids: -(penetration depth), the depth of
    // its centre plus its radius.
    let inside = scene_with(vec![(Shape::Sphere { radius: r }, at(0.05, 0.3, 0.1))]);
    let d = checker.clearance(&inside, &[0.0]).unwrap();
    assert!(
        (d - (box_sdf(&Vector3::new(0.05, 0.3, 0.1), &h) - r)).abs() < 1e-9,
        "enclosed: {d}"
    );
    // A ball whose centre is inside and which crosses a face: contact (≤ 0).
    let crossing = scene_with(vec![(Shape::Sphere { radius: r }, at(0.2, 0.0, 0.0))]);
    assert!(checker.clearance(&crossing, &[0.0]).unwrap() <= 0.0);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The OBJ text of [`cube_obj_dir`]'s cube in `dir` without its top face (z = 0.5): an open mesh.
fn cube_without_top(dir: &Path) -> String {
    let cube = std::fs::read_to_string(dir.join("cube.obj")).unwrap();
    cube.lines()
        .filter(|l| *l != "f 2 6 8 4")
        .map(|l| format!("{l}\n"))
        .collect()
}

/// A temporary folder holding `dented.obj`: the unit cube of [`cube_obj_dir`] with its top face (z = 0.5)
/// replaced by four triangles meeting at (0, 0, `apex`) inside: a closed, outward, non-convex mesh.
fn dented_obj_dir(tag: &str, apex: f64) -> PathBuf {
    let dir = cube_obj_dir(tag);
    let mut obj = cube_without_top(&dir);
    obj += &format!("v 0 0 {apex}\nf 2 6 9\nf 6 8 9\nf 8 4 9\nf 4 2 9\n");
    std::fs::write(dir.join("dented.obj"), obj).unwrap();
    dir
}

#[test]
fn convex_meshes_alone_are_measured_as_their_hulls() {
    let element = r#"<geometry><mesh filename="package://pkg/dented.obj"/></geometry>"#;
    // A dent 0.2 deep: not convex. The mesh stays a mesh behind its hull bound, an enclosed ball reads
    // -(depth of its centre), and a ball in the dent, inside the hull, is clear of the mesh.
    let dir = dented_obj_dir("dent", 0.3);
    let robot = one_joint_robot("prismatic", element, Some(&dir));
    let checker = MeshChecker::new(&robot).unwrap();
    let shape = &checker.shapes()[0];
    assert!(shape.hull.is_some() && shape.tree.is_some());
    let enclosed = scene_with(vec![(Shape::Sphere { radius: 0.1 }, at(0.0, 0.0, -0.3))]);
    let d = checker.clearance(&enclosed, &[0.0]).unwrap();
    assert!((d + 0.2).abs() < 1e-9, "enclosed: {d}");
    let in_dent = scene_with(vec![(Shape::Sphere { radius: 0.02 }, at(0.0, 0.0, 0.45))]);
    let d = checker.clearance(&in_dent, &[0.0]).unwrap();
    assert!(d > 0.02, "a ball in the dent touches only the hull: {d}");
    std::fs::remove_dir_all(&dir).unwrap();
    // A dent of 10⁻⁹ m (within the convexity tolerance): convex, measured as its hull.
    let dir = dented_obj_dir("flat_dent", 0.5 - 1e-9);
    let robot = one_joint_robot("prismatic", element, Some(&dir));
    let checker = MeshChecker::new(&robot).unwrap();
    assert!(checker.shapes()[0].hull.is_none());
    std::fs::remove_dir_all(&dir).unwrap();
    // An open mesh (the cube without its top face) is a surface, not a solid: never its hull.
    let dir = cube_obj_dir("open");
    std::fs::write(dir.join("dented.obj"), cube_without_top(&dir)).unwrap();
    let robot = one_joint_robot("prismatic", element, Some(&dir));
    let checker = MeshChecker::new(&robot).unwrap();
    assert!(checker.shapes()[0].hull.is_some());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn missing_mesh_names_file_and_link() {
    let dir = std::env::temp_dir();
    let element = r#"<geometry><mesh filename="meshes/gfcs_no_such_mesh.obj"/></geometry>"#;
    let robot = one_joint_robot("prismatic", element, Some(&dir));
    match MeshChecker::new(&robot) {
        Err(FabricError::Mesh { path, message }) => {
            assert!(path.ends_with("gfcs_no_such_mesh.obj"), "{path}");
            assert!(message.contains("'link'"), "{message}");
        }
        other => panic!("expected a Mesh error, got {other:?}"),
    }
}

#[test]
fn trajectory_matches_states_whatever_the_threads() {
    let robot = one_joint_robot(
        "prismatic",
        r#"<geometry><box size="0.2 0.2 0.2"/></geometry>"#,
        None,
    );
    let checker = MeshChecker::new(&robot).unwrap();
    let scene = scene_with(vec![
        (cube_box(0.4), at(1.0, 0.0, 0.0)),
        (Shape::Sphere { radius: 0.1 }, at(-0.6, 0.1, 0.0)),
    ]);
    let qs: Vec<f64> = (0..101).map(|k| -0.8 + 1.6 * k as f64 / 100.0).collect();
    let one = checker.trajectory_clearance(&scene, &qs, Some(1)).unwrap();
    let two = checker.trajectory_clearance(&scene, &qs, Some(2)).unwrap();
    let pool = checker.trajectory_clearance(&scene, &qs, None).unwrap();
    assert_eq!(one, two);
    assert_eq!(one, pool);
    for (q, d) in qs.iter().zip(&one) {
        assert_eq!(*d, checker.clearance(&scene, &[*q]).unwrap());
    }
    assert!(one.iter().any(|d| d.is_infinite()) && one.iter().any(|d| *d < 0.0));
    // One row per collision shape (one shape here): the same values whatever the threads; under a
    // cutoff the values below it are kept and the others read at least the cutoff.
    for threads in [Some(1), Some(2)] {
        let rows = checker
            .trajectory_shape_clearances(&scene, &qs, threads, f64::INFINITY)
            .unwrap();
        assert_eq!(rows, one);
    }
    let near = checker
        .trajectory_shape_clearances(&scene, &qs, None, 0.05)
        .unwrap();
    for (d, n) in one.iter().zip(&near) {
        if *d < 0.05 {
            assert_eq!(d, n);
        } else {
            assert!(*n >= 0.05, "{d} read as {n}");
        }
    }
    // The trajectory minimum (two passes with a cutoff) equals the minimum of the states, for every
    // length (strides, a last state off the stride) and thread count.
    for n in [0, 1, 2, 9, 17, 101] {
        let part = &qs[..n];
        let all = checker.trajectory_clearance(&scene, part, None).unwrap();
        let expected = all.iter().copied().fold(f64::INFINITY, f64::min);
        for threads in [Some(1), Some(2)] {
            let got = checker
                .min_trajectory_clearance(&scene, part, threads, f64::INFINITY)
                .unwrap();
            assert_eq!(got, expected, "{n} states");
        }
    }
}

/// The MBM Panda with its collision meshes (panda.urdf) and SRDF.
fn mbm_mesh_panda(shared: &Path) -> Robot {
    let dir = shared.join("robots/mbm_panda");
    let opts = RobotOptions {
        ee_link: Some("panda_hand".into()),
        mesh_dir: Some(dir.clone()),
        ..RobotOptions::default()
    };
    let mut robot = Robot::from_urdf_file(&dir.join("panda.urdf"), &opts).expect("panda.urdf");
    let srdf = std::fs::read_to_string(dir.join("panda.srdf")).expect("panda.srdf");
    robot
        .set_self_collision_from_srdf(&srdf, "panda.srdf")
        .expect("SRDF");
    robot
}

#[test]
fn mbm_panda_meshes_free_start_and_table_contact() {
    let Some(shared) = shared_dir() else { return };
    let robot = mbm_mesh_panda(&shared);
    let checker = MeshChecker::new(&robot).unwrap();
    assert_eq!(checker.num_shapes(), 11);
    // Both fingers use finger.obj: loaded once, shared.
    let fingers: Vec<_> = checker
        .shapes()
        .iter()
        .filter(|s| s.label.ends_with("finger.obj"))
        .collect();
    assert_eq!(fingers.len(), 2);
    assert!(std::sync::Arc::ptr_eq(
        &fingers[0].shape.0,
        &fingers[1].shape.0
    ));
    assert!(fingers.iter().all(|f| f.hull.is_some()));
    let (scene, start, _goal) = mbm_problem(&shared, &robot, "table_pick", 1);
    let free = checker.clearance(&scene, &start).unwrap();
    assert!(
        free > 0.05,
        "start of table_pick/0001 should be free: {free}"
    );
    assert!(checker.self_clearance(&start).unwrap() > 0.0);
    // Only the table top, then the arm turned toward the table and bent down through it.
    let mut table = scene.clone();
    for id in scene.ids() {
        if table.get(id).map(|o| o.name.as_str()) != Some("table_top") {
            table.remove(id).unwrap();
        }
    }
    assert_eq!(table.len(), 1);
    let above = [1.17, 0.3, 0.0, -1.5, 0.0, 1.6, 0.785];
    let into = [1.17, 0.7, 0.0, -1.5, 0.0, 1.6, 0.785];
    assert!(checker.clearance(&table, &above).unwrap() > 0.05);
    let d = checker.clearance(&table, &into).unwrap();
    assert!(d <= 0.0, "arm pushed into the table: {d}");
    // Bending from `above` to `into` in 20 steps: positive clearance up to the first contact.
    let qs: Vec<f64> = (0..=20)
        .flat_map(|k| {
            let mut q = above;
            q[1] = 0.3 + 0.4 * k as f64 / 20.0;
            q
        })
        .collect();
    let path = checker.trajectory_clearance(&table, &qs, None).unwrap();
    let first = path
        .iter()
        .position(|d| *d <= 0.0)
        .expect("contact along the path");
    assert!(path[..first].iter().all(|d| *d > 0.0));
    // Trajectory minima equal the minima of the per-state values, on the free prefix and the whole.
    for states in [first, path.len()] {
        let part = &qs[..states * 7];
        let min = |v: Vec<f64>| v.into_iter().fold(f64::INFINITY, f64::min);
        let expected = min(checker.trajectory_clearance(&table, part, None).unwrap());
        let got = checker.min_trajectory_clearance(&table, part, None, f64::INFINITY);
        assert_eq!(got.unwrap(), expected);
        let expected = min(checker.trajectory_self_clearance(part, None).unwrap());
        let got = checker.min_trajectory_self_clearance(part, Some(1), f64::INFINITY);
        assert_eq!(got.unwrap(), expected);
        // With a cutoff: exact at or below it, +inf when nothing comes that near.
        for cutoff in [expected - 1e-3, expected, expected + 1e-3] {
            let got = checker
                .min_trajectory_self_clearance(part, Some(2), cutoff)
                .unwrap();
            if expected <= cutoff {
                assert_eq!(got, expected, "cutoff {cutoff} states {states}");
            } else {
                assert!(got > cutoff, "{got} at cutoff {cutoff}");
            }
        }
        let obstacles = min(checker.trajectory_clearance(&table, part, None).unwrap());
        for cutoff in [obstacles - 1e-3, obstacles + 1e-3] {
            let got = checker
                .min_trajectory_clearance(&table, part, None, cutoff)
                .unwrap();
            if obstacles <= cutoff {
                assert_eq!(got, obstacles);
            } else {
                assert!(got > cutoff, "{got} at cutoff {cutoff}");
            }
        }
    }
}

#[test]
fn mbm_panda_branch_and_bound_equals_brute_force() {
    let Some(shared) = shared_dir() else { return };
    let robot = mbm_mesh_panda(&shared);
    let checker = MeshChecker::new(&robot)
        .unwrap()
        .with_max_distance(f64::INFINITY)
        .unwrap();
    let (scene, _, _) = mbm_problem(&shared, &robot, "bookshelf_small", 1);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut contacts = 0;
    for _ in 0..40 {
        let q: Vec<f64> = robot
            .lower()
            .iter()
            .zip(robot.upper())
            .map(|(lo, up)| rng.gen_range(*lo..*up))
            .collect();
        let poses = checker.shape_poses(&q).unwrap();
        let brute = checker
            .shapes()
            .iter()
            .zip(&poses)
            .filter_map(|(s, p)| scene.shape_distance(&*s.shape, p, f64::INFINITY))
            .fold(f64::INFINITY, f64::min);
        let fast = checker.clearance(&scene, &q).unwrap();
        // Equal, except that an obstacle enclosed by a solid link mesh can only lower the value.
        assert!(fast <= brute + 1e-12, "{fast} > brute force {brute}");
        if brute > 0.0 {
            assert!(
                (fast - brute).abs() < 1e-12,
                "{fast} vs brute force {brute}"
            );
        } else {
            contacts += 1;
            assert!(fast <= 0.0);
        }
        let brute_self = checker
            .self_pairs()
            .iter()
            .map(|&(i, j)| {
                let (a, b) = (&checker.shapes()[i], &checker.shapes()[j]);
                match parry3d_f64::query::distance(&poses[i], &*a.shape, &poses[j], &*b.shape)
                    .unwrap()
                {
                    d if d > 0.0 => d,
                    _ => 0.0,
                }
            })
            .fold(f64::INFINITY, f64::min);
        let fast_self = checker.self_clearance(&q).unwrap();
        if brute_self > 0.0 {
            assert!(
                (fast_self - brute_self).abs() < 1e-12,
                "{fast_self} vs {brute_self}"
            );
        } else {
            assert!(fast_self <= 0.0);
        }
    }
    eprintln!("{contacts} of 40 random states in contact with the bookshelf scene");
}

#[test]
fn shape_poses_follow_forward_kinematics() {
    let robot = one_joint_robot(
        "revolute",
        r#"<origin xyz="0.3 0 0" rpy="0 0 0.5"/><geometry><sphere radius="0.1"/></geometry>"#,
        None,
    );
    let checker = MeshChecker::new(&robot).unwrap();
    let pose = checker.shape_poses(&[0.4]).unwrap()[0];
    let expect = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.4),
    ) * Isometry3::from_parts(
        Translation3::new(0.3, 0.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
    );
    assert!((pose.to_homogeneous() - expect.to_homogeneous()).norm() < 1e-12);
}

#[test]
fn self_clearance_closed_form() {
    // base (0.2 m cube) -- j1 (z) -- arm (no geometry) -- j2 (z, at x = 0.42) -- hand: a 0.05 m ball at
    // x = 0.3 in the hand frame. Hand and base are two joints apart: checked. For θ1 = 0 the ball centre
    // is c = (0.42 + 0.3 cos θ2, 0.3 sin θ2, 0), always outside the cube, so the clearance is
    // sdf_box(c) - 0.05, negative (penetration) near θ2 = π.
    let xml = r#"<robot name="folding">
      <link name="base"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
      <link name="arm"/>
      <link name="hand"><collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.05"/></geometry></collision></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
        <limit lower="-3.2" upper="3.2" velocity="1" effort="1"/></joint>
      <joint name="j2" type="revolute"><parent link="arm"/><child link="hand"/><origin xyz="0.42 0 0"/>
        <axis xyz="0 0 1"/><limit lower="-3.2" upper="3.2" velocity="1" effort="1"/></joint>
    </robot>"#;
    let robot = Robot::from_urdf_str(xml, "<test>", &RobotOptions::default()).unwrap();
    let checker = MeshChecker::new(&robot)
        .unwrap()
        .with_max_distance(f64::INFINITY)
        .unwrap();
    assert_eq!(checker.self_pairs().len(), 1);
    let h = Vector3::repeat(0.1);
    let mut qs = Vec::new();
    for k in 0..=32 {
        let t2 = -3.1 + 6.2 * k as f64 / 32.0;
        let c = Vector3::new(0.42 + 0.3 * t2.cos(), 0.3 * t2.sin(), 0.0);
        let d = checker.self_clearance(&[0.0, t2]).unwrap();
        let expect = box_sdf(&c, &h) - 0.05;
        assert!((d - expect).abs() < 1e-7, "θ2={t2}: {d} vs {expect}");
        qs.extend([0.0, t2]);
    }
    // θ2 = π: centre at x = 0.12, the ball reaches x = 0.07: penetration 0.03.
    let d = checker
        .self_clearance(&[0.0, std::f64::consts::PI])
        .unwrap();
    assert!((d + 0.03).abs() < 1e-7, "{d}");
    let along = checker.trajectory_self_clearance(&qs, Some(2)).unwrap();
    // the one pair's row is the self-clearance, penetration depths included
    let pairs = checker
        .trajectory_pair_clearances(&qs, Some(2), f64::INFINITY, true)
        .unwrap();
    assert_eq!(pairs, along);
    // without depths: the same distances apart, and contact (≤ 0, not deeper than the depth) where they touch
    let flat = checker
        .trajectory_pair_clearances(&qs, Some(2), f64::INFINITY, false)
        .unwrap();
    for (f, d) in flat.iter().zip(&along) {
        if *d > 0.0 {
            assert_eq!(f, d);
        } else {
            assert!(*f <= 0.0 && f >= d, "{f} vs depth {d}");
        }
    }
    for (k, d) in along.iter().enumerate() {
        assert_eq!(*d, checker.self_clearance(&qs[2 * k..2 * k + 2]).unwrap());
    }
    assert!(along.iter().any(|d| *d < 0.0) && along.iter().any(|d| *d > 0.1));
    // the pair is reported by self_contacts exactly when nearer than `within`, with its distance
    for k in 0..=32 {
        let t2 = -3.1 + 6.2 * k as f64 / 32.0;
        let d = checker.self_clearance(&[0.0, t2]).unwrap();
        for within in [0.0, 0.05, 0.2] {
            let contacts = checker.self_contacts(&[0.0, t2], within, true).unwrap();
            if d <= within {
                assert_eq!(contacts.len(), 1, "θ2={t2}, within {within}");
                let (i, j, got) = contacts[0];
                assert_eq!((i.min(j), i.max(j)), (0, 1));
                assert!((got - d).abs() < 1e-9, "θ2={t2}: {got} vs {d}");
            } else {
                assert!(
                    contacts.is_empty(),
                    "θ2={t2}, within {within}: {contacts:?}"
                );
            }
        }
    }
    for bad in [-0.001, f64::NAN, f64::INFINITY] {
        assert!(
            checker.self_contacts(&[0.0, 0.0], bad, true).is_err(),
            "{bad}"
        );
    }
}

/// Two arms on locked revolute joints about z at the base, each a 0.2 m cube 0.5 m out along x from its
/// joint, joint `a` at y = +0.15 and `b` at y = −0.15, and an active slider `s` carrying a third cube far
/// away. Held at 0 the two cubes face each other across 0.3 − 0.2 = 0.1 m; the locked positions `held`
/// turn them. A cube `c` on a locked joint at the centre of `a`'s overlaps it: adjacent links, held.
fn held_arms(held_a: f64, held_b: f64, srdf: Option<&str>) -> Robot {
    let cube = r#"<collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>"#;
    let xml = format!(
        r#"<robot name="held">
          <link name="base"/>
          <link name="a"><collision><origin xyz="0.5 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
          <link name="b"><collision><origin xyz="0.5 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
          <link name="s">{cube}</link>
          <link name="c"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
          <joint name="jc" type="revolute"><parent link="a"/><child link="c"/><origin xyz="0.5 0 0"/>
            <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
          <joint name="ja" type="revolute"><parent link="base"/><child link="a"/><origin xyz="0 0.15 0"/>
            <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
          <joint name="jb" type="revolute"><parent link="base"/><child link="b"/><origin xyz="0 -0.15 0"/>
            <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
          <joint name="js" type="prismatic"><parent link="base"/><child link="s"/><origin xyz="0 0 5"/>
            <axis xyz="1 0 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
        </robot>"#
    );
    let opts = RobotOptions {
        active_joints: Some(vec!["js".to_string()]),
        locked_positions: vec![("ja".to_string(), held_a), ("jb".to_string(), held_b)],
        ..RobotOptions::default()
    };
    let mut robot = Robot::from_urdf_str(&xml, "<test>", &opts).expect("test URDF");
    if let Some(s) = srdf {
        robot
            .set_self_collision_from_srdf(s, "<test>")
            .expect("test SRDF");
    }
    robot
}

#[test]
fn held_contacts_are_the_locked_links_that_touch_whatever_the_motion() {
    // held at 0: 0.1 m apart, no contact, but measured within 0.2 m (closed form: the faces' gap)
    let apart = MeshChecker::new(&held_arms(0.0, 0.0, None)).unwrap();
    assert!(
        apart.self_pairs().is_empty(),
        "the slider's cube is adjacent to the base and far from a, b"
    );
    let srdf_c = r#"<robot name="held"><disable_collisions link1="a" link2="c" reason="Adjacent"/>
      <disable_collisions link1="b" link2="c" reason="Never"/></robot>"#;
    let apart = MeshChecker::new(&held_arms(0.0, 0.0, Some(srdf_c))).unwrap();
    assert_eq!(
        apart.held_pairs().len(),
        1,
        "a and b only: c is disabled against both"
    );
    assert!(apart.held_contacts(&[0.0], 0.0, true).unwrap().is_empty());
    let near = apart.held_contacts(&[0.7], 0.2, true).unwrap();
    assert_eq!(near.len(), 1);
    assert!((near[0].2 - 0.1).abs() < TOL, "{near:?}");
    // MoveIt checks adjacent links the SRDF leaves enabled: `c` overlaps `a`, whatever the slider does
    let adjacent = MeshChecker::new(&held_arms(0.0, 0.0, None)).unwrap();
    let c = adjacent.held_contacts(&[0.3], 0.0, true).unwrap();
    let names = adjacent.robot().link_names();
    let pair = |k: usize| {
        let (i, j, _) = c[k];
        [
            names[adjacent.shapes()[i].link].as_str(),
            names[adjacent.shapes()[j].link].as_str(),
        ]
    };
    assert_eq!(c.len(), 1);
    assert_eq!(pair(0), ["a", "c"]);
    // a turned towards b by 0.3 rad: its cube crosses the gap (the slider changes nothing)
    let touching = MeshChecker::new(&held_arms(-0.3, 0.0, Some(srdf_c))).unwrap();
    for s in [-1.0, 0.0, 1.0] {
        let c = touching.held_contacts(&[s], 0.0, true).unwrap();
        assert_eq!(c.len(), 1, "at s = {s}");
        assert!(c[0].2 <= 0.0);
        let names = touching.robot().link_names();
        let links = [
            touching.shapes()[c[0].0].link,
            touching.shapes()[c[0].1].link,
        ];
        assert_eq!(
            [names[links[0]].as_str(), names[links[1]].as_str()],
            ["a", "b"]
        );
    }
    // the SRDF disables the pair: MoveIt does not check it, nor does the checker
    let srdf = r#"<robot name="held"><disable_collisions link1="b" link2="a" reason="Never"/>
      <disable_collisions link1="a" link2="c" reason="Adjacent"/>
      <disable_collisions link1="b" link2="c" reason="Never"/></robot>"#;
    let disabled = MeshChecker::new(&held_arms(-0.3, 0.0, Some(srdf))).unwrap();
    assert!(disabled
        .held_contacts(&[0.0], 0.0, true)
        .unwrap()
        .is_empty());
    // the two locked arms are one rigid body with the base: the fabric and the trajectory checks never
    // see the pair, so the endpoints' check is the only one that can
    let robot = held_arms(-0.3, 0.0, None);
    assert_eq!(robot.rigid_bodies()[1], robot.rigid_bodies()[2]);
}
