//! Scene editing and the broadphase: `query` and `signed_distance` against brute force over every
//! obstacle on random scenes, before and after adds, moves, removals and `advance`; `shape_distance`.

mod scene_support;

use std::collections::BTreeMap;
use std::sync::Arc;

use fabric_core::scene::meshio::{build_mesh, parse_obj};
use fabric_core::scene::{
    point_distance, DistanceSample, Obstacle, ObstacleId, PointCloud, Scene, Shape, LINEAR_SCAN_MAX,
};
use fabric_core::FabricError;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::bounding_volume::BoundingVolume;
use parry3d_f64::shape::{Ball, Cuboid, Shape as _};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use scene_support::{random_pose, rng, vec_in, UNIT_CUBE_OBJ};

fn random_obstacle(
    r: &mut ChaCha8Rng,
    cube: &Arc<parry3d_f64::shape::TriMesh>,
    i: usize,
) -> Obstacle {
    let shape = match r.gen_range(0..6) {
        0 => Shape::Sphere {
            radius: r.gen_range(0.01..0.1),
        },
        1 => Shape::Cuboid {
            half_extents: vec_in(r, 0.01, 0.1),
        },
        2 => Shape::Cylinder {
            half_height: r.gen_range(0.01..0.1),
            radius: r.gen_range(0.01..0.1),
        },
        3 => Shape::Capsule {
            half_height: r.gen_range(0.0..0.1),
            radius: r.gen_range(0.01..0.1),
        },
        4 => Shape::TriMesh(Arc::new(
            cube.as_ref().clone().scaled(&vec_in(r, 0.02, 0.2)),
        )),
        _ => {
            let pts = (0..20).map(|_| vec_in(r, -0.05, 0.05)).collect();
            Shape::PointCloud(Arc::new(
                PointCloud::new(pts, r.gen_range(0.0..0.02)).unwrap(),
            ))
        }
    };
    Obstacle::new(format!("o{i}"), shape, random_pose(r, 1.0))
}

/// A scene holding only the half-space z ≤ −1 m ("floor").
fn scene_with_floor() -> Scene {
    let mut scene = Scene::new();
    scene
        .add(Obstacle::new(
            "floor",
            Shape::HalfSpace,
            Isometry3::translation(0.0, 0.0, -1.0),
        ))
        .unwrap();
    scene
}

fn cube_mesh() -> Arc<parry3d_f64::shape::TriMesh> {
    let (v, t) = parse_obj(UNIT_CUBE_OBJ, "cube.obj").unwrap();
    Arc::new(build_mesh(v, t, "cube.obj").unwrap())
}

/// Brute force: every obstacle's distance, without the broadphase.
fn brute(scene: &Scene, p: &Vector3<f64>) -> BTreeMap<ObstacleId, f64> {
    scene
        .iter()
        .map(|(id, o)| {
            (
                id,
                point_distance(&o.shape, &o.pose, p, f64::INFINITY)
                    .unwrap()
                    .distance,
            )
        })
        .collect()
}

/// `query` and `signed_distance` at random points against brute force; with `dense`, also require
/// that the points hit obstacles often enough for the test to mean something.
fn check_against_brute_force(scene: &Scene, r: &mut ChaCha8Rng, points: usize, dense: bool) {
    let mut out: Vec<DistanceSample> = Vec::new();
    let mut nonempty = 0;
    for _ in 0..points {
        let p = vec_in(r, -1.3, 1.3);
        let max = r.gen_range(-0.05..0.4);
        let all = brute(scene, &p);
        out.clear();
        scene.query(&p, max, &mut out);
        let got: BTreeMap<ObstacleId, f64> = out.iter().map(|s| (s.obstacle, s.distance)).collect();
        assert_eq!(got.len(), out.len(), "an obstacle was reported twice");
        let expected: BTreeMap<ObstacleId, f64> = all
            .iter()
            .filter(|(_, &d)| d <= max)
            .map(|(&i, &d)| (i, d))
            .collect();
        assert_eq!(
            got.keys().collect::<Vec<_>>(),
            expected.keys().collect::<Vec<_>>(),
            "at {p:?}, max {max}"
        );
        for (id, d) in &got {
            assert!((d - expected[id]).abs() < 1e-12);
        }
        nonempty += usize::from(!got.is_empty());
        let best = scene.signed_distance(&p).unwrap();
        let min = all.values().copied().fold(f64::INFINITY, f64::min);
        assert!(
            (best.distance - min).abs() < 1e-12,
            "signed_distance {} vs brute {min}",
            best.distance
        );
        assert_eq!(all[&best.obstacle], best.distance);
    }
    assert!(
        !dense || nonempty > points / 10,
        "test points too far from the obstacles ({nonempty})"
    );
}

#[test]
fn query_never_misses_on_random_scenes() {
    let cube = cube_mesh();
    for seed in 0..3 {
        let mut r = rng(100 + seed);
        let mut scene = Scene::new();
        let mut ids = Vec::new();
        for i in 0..200 {
            ids.push(scene.add(random_obstacle(&mut r, &cube, i)).unwrap());
        }
        let floor = Isometry3::translation(0.0, 0.0, -1.2);
        scene
            .add(Obstacle::new("floor", Shape::HalfSpace, floor))
            .unwrap();
        check_against_brute_force(&scene, &mut r, 150, true);

        // Remove 50, move 50, add 50: incremental updates only.
        for _ in 0..50 {
            let k = r.gen_range(0..ids.len());
            let id = ids.swap_remove(k);
            scene.remove(id).unwrap();
        }
        for _ in 0..50 {
            let id = ids[r.gen_range(0..ids.len())];
            scene.set_pose(id, random_pose(&mut r, 1.0)).unwrap();
        }
        for i in 0..50 {
            ids.push(scene.add(random_obstacle(&mut r, &cube, 1000 + i)).unwrap());
        }
        assert_eq!(scene.len(), 201);
        check_against_brute_force(&scene, &mut r, 150, true);

        // Velocities and several advance steps (BVH refit).
        for &id in &ids {
            scene.set_velocity(id, vec_in(&mut r, -0.5, 0.5)).unwrap();
        }
        for _ in 0..5 {
            scene.advance(0.1);
        }
        check_against_brute_force(&scene, &mut r, 150, true);
    }
}

#[test]
fn small_scenes_and_mode_switches_match_brute_force() {
    // Scenes at and around LINEAR_SCAN_MAX use the linear scan; growing and shrinking across it
    // switches between the scan and the BVH.
    let cube = cube_mesh();
    let mut r = rng(200);
    let mut scene = scene_with_floor();
    let mut ids = Vec::new();
    for i in 0..LINEAR_SCAN_MAX + 6 {
        ids.push(scene.add(random_obstacle(&mut r, &cube, i)).unwrap());
        check_against_brute_force(&scene, &mut r, 40, false);
    }
    while let Some(id) = ids.pop() {
        let k = r.gen_range(0..=ids.len());
        ids.push(id);
        let id = ids.swap_remove(k);
        scene.remove(id).unwrap();
        if let Some(&other) = ids.first() {
            scene.set_pose(other, random_pose(&mut r, 1.0)).unwrap();
            scene
                .set_velocity(other, vec_in(&mut r, -0.5, 0.5))
                .unwrap();
        }
        scene.advance(0.05);
        if !ids.is_empty() {
            check_against_brute_force(&scene, &mut r, 40, false);
        }
    }
    assert_eq!(scene.len(), 1);
}

/// In a scene small enough for the linear scan, built by adds only (storage order = id order), `query`
/// returns exactly (values and order) the `point_distance` samples of every obstacle within the limit,
/// for limits negative, positive and infinite: the vectorised box test drops nothing the exact test
/// keeps.
#[test]
fn linear_scan_query_equals_exact_samples_in_storage_order() {
    let cube = cube_mesh();
    let mut r = rng(300);
    let mut scene = scene_with_floor();
    for i in 1..LINEAR_SCAN_MAX {
        scene.add(random_obstacle(&mut r, &cube, i)).unwrap();
    }
    let mut out: Vec<DistanceSample> = Vec::new();
    let mut hits = 0;
    for t in 0..600 {
        let p = vec_in(&mut r, -1.3, 1.3);
        let max = match t % 10 {
            0 => f64::INFINITY,
            1 => r.gen_range(-0.1..0.0),
            _ => r.gen_range(0.0..0.4),
        };
        let expected: Vec<DistanceSample> = scene
            .iter()
            .filter_map(|(id, o)| {
                let s = point_distance(&o.shape, &o.pose, &p, max)?;
                Some(DistanceSample {
                    obstacle: id,
                    distance: s.distance,
                    gradient: s.gradient,
                    hessian: s.hessian,
                    velocity: o.velocity,
                })
            })
            .collect();
        out.clear();
        scene.query(&p, max, &mut out);
        assert_eq!(out, expected, "at {p:?}, max {max}");
        hits += expected.len();
    }
    assert!(hits > 600, "{hits} samples");
}

#[test]
fn add_get_move_remove() {
    let mut scene = Scene::new();
    assert!(scene.is_empty());
    assert!(scene.signed_distance(&Vector3::zeros()).is_none());
    let a = scene
        .add(Obstacle::new(
            "a",
            Shape::Sphere { radius: 0.1 },
            Isometry3::identity(),
        ))
        .unwrap();
    let b = scene
        .add(Obstacle::new(
            "b",
            Shape::cuboid_from_size(Vector3::new(0.2, 0.2, 0.2)),
            Isometry3::translation(1.0, 0.0, 0.0),
        ))
        .unwrap();
    assert_ne!(a, b);
    assert_eq!(scene.ids(), vec![a, b]);
    assert_eq!(scene.len(), 2);
    assert_eq!(scene.find("b"), Some(b));
    assert_eq!(scene.get(a).unwrap().name, "a");

    let p = Vector3::new(0.5, 0.0, 0.0);
    let mut out = Vec::new();
    scene.query(&p, 0.5, &mut out);
    assert_eq!(out.len(), 2);
    assert!((scene.signed_distance(&p).unwrap().distance - 0.4).abs() < 1e-12);

    scene
        .set_pose(a, Isometry3::translation(3.0, 0.0, 0.0))
        .unwrap();
    let s = scene.signed_distance(&p).unwrap();
    assert_eq!(s.obstacle, b);
    assert!((s.distance - 0.4).abs() < 1e-12);
    out.clear();
    scene.query(&p, 0.45, &mut out);
    assert_eq!(out.iter().map(|s| s.obstacle).collect::<Vec<_>>(), vec![b]);

    let removed = scene.remove(b).unwrap();
    assert_eq!(removed.name, "b");
    assert!(scene.get(b).is_none());
    assert!(matches!(scene.remove(b), Err(FabricError::Value { .. })));
    assert!(matches!(
        scene.set_pose(b, Isometry3::identity()),
        Err(FabricError::Value { .. })
    ));
    assert_eq!(scene.signed_distance(&p).unwrap().obstacle, a);
    // Ids are not reused after a removal.
    let c = scene
        .add(Obstacle::new("c", Shape::HalfSpace, Isometry3::identity()))
        .unwrap();
    assert!(c.0 > b.0);
    assert!(
        (scene
            .signed_distance(&Vector3::new(0.0, 0.0, 0.3))
            .unwrap()
            .distance
            - 0.3)
            .abs()
            < 1e-12
    );
    scene.remove(c).unwrap();
    assert!((scene.signed_distance(&p).unwrap().distance - 2.4).abs() < 1e-12);
}

#[test]
fn invalid_obstacles_are_rejected() {
    let mut scene = Scene::new();
    let id = Isometry3::identity();
    let bad = [
        Obstacle::new("s", Shape::Sphere { radius: -0.1 }, id),
        Obstacle::new(
            "b",
            Shape::Cuboid {
                half_extents: Vector3::new(0.1, 0.0, 0.1),
            },
            id,
        ),
        Obstacle::new(
            "c",
            Shape::Cylinder {
                half_height: 0.1,
                radius: f64::NAN,
            },
            id,
        ),
        Obstacle::new(
            "k",
            Shape::Capsule {
                half_height: -0.1,
                radius: 0.1,
            },
            id,
        ),
    ];
    for o in bad {
        assert!(matches!(scene.add(o), Err(FabricError::Value { .. })));
    }
    let nan_pose = Isometry3::translation(f64::NAN, 0.0, 0.0);
    assert!(matches!(
        scene.add(Obstacle::new("n", Shape::Sphere { radius: 0.1 }, nan_pose)),
        Err(FabricError::NonFinite { .. })
    ));
    let skew = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(2.0, 0.0, 0.0, 0.0)),
    );
    assert!(matches!(
        scene.add(Obstacle::new("q", Shape::Sphere { radius: 0.1 }, skew)),
        Err(FabricError::Value { .. })
    ));
    let moving = Obstacle::new("v", Shape::Sphere { radius: 0.1 }, id).with_velocity(Vector3::new(
        f64::INFINITY,
        0.0,
        0.0,
    ));
    assert!(matches!(
        scene.add(moving),
        Err(FabricError::NonFinite { .. })
    ));
    assert!(PointCloud::new(vec![], 0.0).is_err());
    assert!(PointCloud::new(vec![Vector3::zeros()], -1.0).is_err());
    assert!(scene.is_empty());
    // Non-finite query points give nothing rather than garbage.
    let a = scene
        .add(Obstacle::new("a", Shape::Sphere { radius: 0.1 }, id))
        .unwrap();
    let mut out = Vec::new();
    scene.query(&Vector3::new(f64::NAN, 0.0, 0.0), 1.0, &mut out);
    assert!(out.is_empty());
    assert!(scene
        .signed_distance(&Vector3::new(0.0, f64::INFINITY, 0.0))
        .is_none());
    assert!(matches!(
        scene.set_velocity(a, Vector3::new(0.0, f64::NAN, 0.0)),
        Err(FabricError::NonFinite { .. })
    ));
}

#[test]
fn advance_moves_obstacles_by_their_velocity() {
    let mut scene = Scene::new();
    let v = Vector3::new(0.2, -0.1, 0.05);
    let a = scene
        .add(
            Obstacle::new("a", Shape::Sphere { radius: 0.1 }, Isometry3::identity())
                .with_velocity(v),
        )
        .unwrap();
    let b = scene
        .add(Obstacle::new(
            "b",
            Shape::HalfSpace,
            Isometry3::translation(0.0, 0.0, -1.0),
        ))
        .unwrap();
    scene.set_velocity(b, Vector3::new(0.0, 0.0, 0.5)).unwrap();
    scene.advance(0.5);
    scene.advance(f64::NAN);
    assert!((scene.get(a).unwrap().pose.translation.vector - v * 0.5).norm() < 1e-15);
    assert!((scene.get(b).unwrap().pose.translation.vector.z + 0.75).abs() < 1e-15);
    let p = v * 0.5 + Vector3::new(0.3, 0.0, 0.0);
    let mut out = Vec::new();
    scene.query(&p, 0.25, &mut out);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].obstacle, a);
    assert!((out[0].distance - 0.2).abs() < 1e-12);
    assert_eq!(out[0].velocity, v);
    // Backwards in time returns to the start.
    scene.advance(-0.5);
    assert!(scene.get(a).unwrap().pose.translation.vector.norm() < 1e-15);
}

/// `boxed_shape_distance` with any box containing the placed shape (here the exact box, loosened by 0-0.3 m)
/// gives `shape_distance`'s value: the box only selects and bounds the obstacles.
#[test]
fn boxed_shape_distance_is_shape_distance() {
    let mut scene = Scene::new();
    let ball = Ball::new(0.1);
    let pose = Isometry3::translation(0.3, 0.0, 0.0);
    let exact = ball.compute_aabb(&pose);
    assert!(
        scene
            .boxed_shape_distance(&ball, &pose, &exact, 10.0)
            .is_none(),
        "empty scene"
    );
    let (v, t) = parse_obj(UNIT_CUBE_OBJ, "cube.obj").unwrap();
    let mesh = Arc::new(build_mesh(v, t, "cube.obj").unwrap());
    let cloud = PointCloud::new(vec![Vector3::zeros(), Vector3::new(0.0, 0.0, 0.1)], 0.01).unwrap();
    for (name, shape, at) in [
        (
            "s",
            Shape::Sphere { radius: 0.2 },
            Vector3::new(1.0, 0.0, 0.0),
        ),
        ("m", Shape::TriMesh(mesh), Vector3::new(-1.0, 0.5, 0.0)),
        (
            "pc",
            Shape::PointCloud(Arc::new(cloud)),
            Vector3::new(0.0, -1.0, 0.0),
        ),
        (
            "cyl",
            Shape::Cylinder {
                half_height: 0.5,
                radius: 0.1,
            },
            Vector3::new(0.0, 1.0, 0.0),
        ),
        ("floor", Shape::HalfSpace, Vector3::new(0.0, 0.0, -1.0)),
    ] {
        scene
            .add(Obstacle::new(
                name,
                shape,
                Isometry3::from_parts(at.into(), UnitQuaternion::identity()),
            ))
            .unwrap();
    }
    let cube = Cuboid::new(Vector3::new(0.1, 0.2, 0.05));
    let mut r = rng(11);
    let mut compared = 0;
    for _ in 0..300 {
        let pose = random_pose(&mut r, 1.5);
        for shape in [&ball as &dyn parry3d_f64::shape::Shape, &cube] {
            let exact = shape.compute_aabb(&pose);
            let loose = exact.loosened(r.gen_range(0.0..0.3));
            let want = scene.shape_distance(shape, &pose, 0.8);
            for aabb in [exact, loose] {
                let got = scene.boxed_shape_distance(shape, &pose, &aabb, 0.8);
                match (want, got) {
                    (Some(a), Some(b)) => assert!((a - b).abs() < 1e-12, "{a} vs {b}"),
                    (None, None) => {}
                    other => panic!("{other:?} at {pose:?}"),
                }
            }
            compared += usize::from(want.is_some());
        }
    }
    assert!(compared > 100, "only {compared} poses near an obstacle");
}

#[test]
fn shape_distance_to_obstacles() {
    let mut scene = Scene::new();
    assert!(scene
        .shape_distance(&Ball::new(0.1), &Isometry3::identity(), 10.0)
        .is_none());
    scene
        .add(Obstacle::new(
            "s",
            Shape::Sphere { radius: 0.2 },
            Isometry3::translation(1.0, 0.0, 0.0),
        ))
        .unwrap();
    scene
        .add(Obstacle::new(
            "floor",
            Shape::HalfSpace,
            Isometry3::translation(0.0, 0.0, -1.0),
        ))
        .unwrap();
    let (v, t) = parse_obj(UNIT_CUBE_OBJ, "cube.obj").unwrap();
    let mesh = Arc::new(build_mesh(v, t, "cube.obj").unwrap());
    scene
        .add(Obstacle::new(
            "m",
            Shape::TriMesh(mesh),
            Isometry3::translation(-3.0, 0.0, 0.0),
        ))
        .unwrap();
    scene
        .add(Obstacle::new(
            "cyl",
            Shape::Cylinder {
                half_height: 0.5,
                radius: 0.1,
            },
            Isometry3::translation(0.0, 3.0, 0.0),
        ))
        .unwrap();
    let cloud = PointCloud::new(vec![Vector3::zeros(), Vector3::new(0.0, 0.0, 0.1)], 0.01).unwrap();
    scene
        .add(Obstacle::new(
            "pc",
            Shape::PointCloud(Arc::new(cloud)),
            Isometry3::translation(0.0, -3.0, 0.0),
        ))
        .unwrap();

    let ball = Ball::new(0.1);
    // Near the sphere: |c1 - c2| - r1 - r2.
    let d = scene
        .shape_distance(&ball, &Isometry3::translation(0.5, 0.0, 0.0), 1.0)
        .unwrap();
    assert!((d - 0.2).abs() < 1e-9, "{d}");
    // Penetrating the sphere: negative depth.
    let d = scene
        .shape_distance(&ball, &Isometry3::translation(0.75, 0.0, 0.0), 1.0)
        .unwrap();
    assert!((d + 0.05).abs() < 1e-9, "{d}");
    // Nothing within `max`.
    assert!(scene
        .shape_distance(&ball, &Isometry3::translation(0.0, 0.0, 0.5), 0.1)
        .is_none());
    // The floor.
    let d = scene
        .shape_distance(&ball, &Isometry3::translation(0.0, 0.0, -0.7), 0.5)
        .unwrap();
    assert!((d - 0.2).abs() < 1e-9, "{d}");
    // The mesh cube (faces at x = -2.5) and a box shape against it.
    let d = scene
        .shape_distance(
            &Cuboid::new(Vector3::repeat(0.1)),
            &Isometry3::translation(-2.2, 0.0, 0.0),
            1.0,
        )
        .unwrap();
    assert!((d - 0.2).abs() < 1e-9, "{d}");
    let d = scene
        .shape_distance(&ball, &Isometry3::translation(-2.45, 0.0, 0.0), 1.0)
        .unwrap();
    assert!(d <= 0.0, "{d}");
    // The cylinder, axis along z (parry's is along y): side at y = 2.9.
    let d = scene
        .shape_distance(&ball, &Isometry3::translation(0.0, 2.6, 0.3), 1.0)
        .unwrap();
    assert!((d - 0.2).abs() < 1e-9, "{d}");
    let d = scene
        .shape_distance(&ball, &Isometry3::translation(0.0, 3.0, 0.7), 1.0)
        .unwrap();
    assert!((d - 0.1).abs() < 1e-9, "{d}");
    // The point cloud: nearest point (0, -3, 0.1), thickness 0.01; inside the ball -> negative.
    let d = scene
        .shape_distance(&ball, &Isometry3::translation(0.0, -3.0, 0.4), 1.0)
        .unwrap();
    assert!((d - (0.3 - 0.1 - 0.01)).abs() < 1e-9, "{d}");
    let d = scene
        .shape_distance(&ball, &Isometry3::translation(0.0, -3.0, 0.15), 1.0)
        .unwrap();
    assert!((d - (-(0.1 - 0.05) - 0.01)).abs() < 1e-9, "{d}");
    // Agrees with the point query for a tiny ball.
    let p = Vector3::new(0.9, 0.7, 0.2);
    let tiny = scene
        .shape_distance(
            &Ball::new(1e-9),
            &Isometry3::translation(p.x, p.y, p.z),
            5.0,
        )
        .unwrap();
    assert!((tiny - scene.signed_distance(&p).unwrap().distance).abs() < 1e-7);
}

#[test]
fn scene_is_shareable_across_threads() {
    fn assert_shareable<T: Send + Sync + Clone>() {}
    assert_shareable::<Scene>();
    assert_shareable::<Obstacle>();
    let mut scene = Scene::new();
    scene
        .add(Obstacle::new(
            "s",
            Shape::Sphere { radius: 0.1 },
            Isometry3::identity(),
        ))
        .unwrap();
    let copy = scene.clone();
    scene
        .set_pose(scene.ids()[0], Isometry3::translation(1.0, 0.0, 0.0))
        .unwrap();
    // The clone is independent.
    assert!((copy.signed_distance(&Vector3::zeros()).unwrap().distance + 0.1).abs() < 1e-15);
    assert!((scene.signed_distance(&Vector3::zeros()).unwrap().distance - 0.9).abs() < 1e-15);
}

/// `query_near` then `sample_near` at the same point and limit give exactly `query` (same obstacles,
/// same order, same samples) in small (linear scan) and large (BVH) scenes, after adds, moves and
/// removals (which reorder the dense storage).
#[test]
fn near_queries_and_samples_equal_query() {
    let mut r = rng(11);
    let cube = cube_mesh();
    for size in [6, LINEAR_SCAN_MAX + 24] {
        let mut scene = Scene::new();
        let mut ids = Vec::new();
        for i in 0..size {
            ids.push(scene.add(random_obstacle(&mut r, &cube, i)).unwrap());
        }
        let (mut near, mut expected, mut got) = (Vec::new(), Vec::new(), Vec::new());
        let mut hits = 0;
        for round in 0..40 {
            // edit: remove one, add one, move one
            let victim = ids.swap_remove(r.gen_range(0..ids.len()));
            scene.remove(victim).unwrap();
            ids.push(
                scene
                    .add(random_obstacle(&mut r, &cube, size + round))
                    .unwrap(),
            );
            let moved = ids[r.gen_range(0..ids.len())];
            let pose = random_obstacle(&mut r, &cube, 0).pose;
            scene.set_pose(moved, pose).unwrap();
            for _ in 0..60 {
                let p = Vector3::new(
                    r.gen_range(-1.2..1.2),
                    r.gen_range(-1.2..1.2),
                    r.gen_range(-1.2..1.2),
                );
                let max = r.gen_range(-0.05..0.5);
                expected.clear();
                scene.query(&p, max, &mut expected);
                near.clear();
                scene.query_near(&p, max, &mut near);
                got.clear();
                for n in &near {
                    if let Some(s) = scene.sample_near(n, &p, max) {
                        // the distance-only path may differ in the last bits (spheres: world
                        // frame)
                        assert!((n.distance - s.distance).abs() < 1e-12);
                        got.push(s);
                    }
                }
                assert_eq!(got, expected, "at {p:?}, max {max}");
                hits += expected.len();
            }
        }
        assert!(hits > 150, "{hits} hits in scenes of {size}");
    }
}
