//! `Scene::surface_points`: every sample lies on an obstacle surface, and every surface point has a
//! sample within the requested spacing.

mod scene_support;

use std::sync::Arc;

use fabric_core::scene::meshio::build_mesh;
use fabric_core::scene::sampling::HALF_SPACE_PATCH;
use fabric_core::scene::{point_distance, Obstacle, PointCloud, Scene, Shape};
use nalgebra::{Isometry3, Point3, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use scene_support::{fine_cube, random_pose, rng, vec_in};

/// A random point on the surface of `shape` (local frame), drawn independently of the sampler.
fn random_surface_point(shape: &Shape, r: &mut ChaCha8Rng) -> Vector3<f64> {
    let tau = std::f64::consts::TAU;
    match shape {
        Shape::Sphere { radius } => vec_in(r, -1.0, 1.0).normalize() * *radius,
        Shape::Cuboid { half_extents } => {
            let mut p = Vector3::from_fn(|i, _| r.gen_range(-half_extents[i]..half_extents[i]));
            let k = r.gen_range(0..3);
            p[k] = if r.gen_bool(0.5) {
                half_extents[k]
            } else {
                -half_extents[k]
            };
            p
        }
        Shape::Cylinder {
            half_height,
            radius,
        } => {
            let t = r.gen_range(0.0..tau);
            if r.gen_bool(0.5) {
                Vector3::new(
                    radius * t.cos(),
                    radius * t.sin(),
                    r.gen_range(-half_height..*half_height),
                )
            } else {
                let rho = radius * r.gen_range(0.0f64..1.0).sqrt();
                let z = if r.gen_bool(0.5) {
                    *half_height
                } else {
                    -half_height
                };
                Vector3::new(rho * t.cos(), rho * t.sin(), z)
            }
        }
        Shape::Capsule {
            half_height,
            radius,
        } => {
            let u = vec_in(r, -1.0, 1.0).normalize() * *radius;
            let z = if *half_height > 0.0 {
                r.gen_range(-half_height..*half_height)
            } else {
                0.0
            };
            if r.gen_bool(0.5) {
                Vector3::new(u.x, u.y, 0.0).normalize() * *radius + Vector3::new(0.0, 0.0, z)
            } else {
                u + Vector3::new(0.0, 0.0, half_height * u.z.signum())
            }
        }
        Shape::HalfSpace => Vector3::new(
            r.gen_range(-HALF_SPACE_PATCH..HALF_SPACE_PATCH),
            r.gen_range(-HALF_SPACE_PATCH..HALF_SPACE_PATCH),
            0.0,
        ),
        Shape::TriMesh(m) => {
            let t = m.triangle(r.gen_range(0..m.indices().len() as u32));
            let (mut a, mut b) = (r.gen_range(0.0..1.0), r.gen_range(0.0..1.0));
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            t.a.coords + (t.b - t.a) * a + (t.c - t.a) * b
        }
        Shape::PointCloud(pc) => pc.points()[r.gen_range(0..pc.points().len())].coords,
    }
}

#[test]
fn samples_lie_on_and_cover_every_surface() {
    let mut r = rng(11);
    let (v, t) = fine_cube(0.15, 2);
    let cloud: Vec<Vector3<f64>> = (0..300).map(|_| vec_in(&mut r, -0.2, 0.2)).collect();
    let shapes = vec![
        Shape::Sphere { radius: 0.2 },
        Shape::Cuboid {
            half_extents: Vector3::new(0.1, 0.25, 0.05),
        },
        Shape::Cylinder {
            half_height: 0.2,
            radius: 0.08,
        },
        Shape::Capsule {
            half_height: 0.1,
            radius: 0.07,
        },
        Shape::Capsule {
            half_height: 0.0,
            radius: 0.07,
        },
        Shape::HalfSpace,
        Shape::TriMesh(Arc::new(build_mesh(v, t, "cube").unwrap())),
        Shape::PointCloud(Arc::new(PointCloud::new(cloud, 0.0).unwrap())),
    ];
    for spacing in [0.05, 0.02] {
        for shape in &shapes {
            let pose = random_pose(&mut r, 1.0);
            let mut scene = Scene::new();
            scene.add(Obstacle::new("o", shape.clone(), pose)).unwrap();
            let samples = scene.surface_points(spacing);
            assert!(!samples.is_empty());
            for s in &samples {
                let d = point_distance(shape, &pose, s, f64::INFINITY)
                    .unwrap()
                    .distance;
                assert!(d.abs() < 1e-9, "{shape:?}: sample {s:?} at distance {d}");
            }
            // Coverage: random surface points have a sample within `spacing` (point clouds are thinned
            // to one point per voxel of side `spacing`: within the voxel diagonal).
            let reach = if matches!(shape, Shape::PointCloud(_)) {
                spacing * 3f64.sqrt()
            } else {
                spacing
            };
            for _ in 0..300 {
                let q = pose * Point3::from(random_surface_point(shape, &mut r));
                let nearest = samples
                    .iter()
                    .map(|s| (s - q.coords).norm())
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    nearest <= reach,
                    "{shape:?} spacing {spacing}: gap {nearest} at {q:?}"
                );
            }
        }
    }
}

#[test]
fn box_samples_are_not_duplicated_and_scale_with_spacing() {
    let mut scene = Scene::new();
    scene
        .add(Obstacle::new(
            "b",
            Shape::cuboid_from_size(Vector3::new(0.2, 0.2, 0.2)),
            Isometry3::identity(),
        ))
        .unwrap();
    let s = scene.surface_points(0.1);
    // 3×3 nodes per face on a 0.2 m cube: 26 distinct grid points (the 3×3×3 grid minus its centre).
    assert_eq!(s.len(), 26);
    for (i, a) in s.iter().enumerate() {
        for b in &s[i + 1..] {
            assert!((a - b).norm() > 1e-9, "duplicate sample {a:?}");
        }
    }
    assert!(scene.surface_points(0.05).len() > 3 * s.len());
    assert!(scene.surface_points(0.0).is_empty());
    assert!(scene.surface_points(-1.0).is_empty());
    assert!(scene.surface_points(f64::NAN).is_empty());
    assert!(Scene::new().surface_points(0.1).is_empty());
}
