//! Point-to-obstacle signed distances, gradients and Hessians against closed forms, brute force over
//! dense surface samples and finite differences.

mod scene_support;

use std::sync::Arc;

use fabric_core::scene::meshio::{build_mesh, parse_obj};
use fabric_core::scene::{point_distance, PointCloud, Shape, SurfaceDistance};
use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use rand::Rng;
use scene_support::{fd_gradient, fd_hessian, fine_cube, random_pose, rng, vec_in, UNIT_CUBE_OBJ};

fn eval(shape: &Shape, pose: &Isometry3<f64>, p: &Vector3<f64>) -> SurfaceDistance {
    point_distance(shape, pose, p, f64::INFINITY).expect("distance with no limit")
}

fn unit_cube_mesh() -> Shape {
    let (v, t) = parse_obj(UNIT_CUBE_OBJ, "cube.obj").unwrap();
    Shape::TriMesh(Arc::new(build_mesh(v, t, "cube.obj").unwrap()))
}

fn fine_cube_mesh() -> Shape {
    let (v, t) = fine_cube(0.5, 3);
    Shape::TriMesh(Arc::new(build_mesh(v, t, "fine cube").unwrap()))
}

/// Minimum distance from `p` to a set of points.
fn brute_min(samples: &[Vector3<f64>], p: &Vector3<f64>) -> f64 {
    samples
        .iter()
        .map(|s| (s - p).norm())
        .fold(f64::INFINITY, f64::min)
}

/// Grid of step <= `step` on the box surface (local frame).
fn box_surface(h: &Vector3<f64>, step: f64) -> Vec<Vector3<f64>> {
    let mut out = Vec::new();
    for k in 0..3 {
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        let na = (2.0 * h[a] / step).ceil() as usize;
        let nb = (2.0 * h[b] / step).ceil() as usize;
        for s in [-1.0, 1.0] {
            for i in 0..=na {
                for j in 0..=nb {
                    let mut p = Vector3::zeros();
                    p[k] = s * h[k];
                    p[a] = -h[a] + 2.0 * h[a] * i as f64 / na as f64;
                    p[b] = -h[b] + 2.0 * h[b] * j as f64 / nb as f64;
                    out.push(p);
                }
            }
        }
    }
    out
}

/// Samples of step <= `step` on the cylinder surface (axis z, local frame).
fn cylinder_surface(hh: f64, r: f64, step: f64) -> Vec<Vector3<f64>> {
    let mut out = Vec::new();
    let na = (2.0 * std::f64::consts::PI * r / step).ceil() as usize;
    let nz = (2.0 * hh / step).ceil() as usize;
    for i in 0..na {
        let t = 2.0 * std::f64::consts::PI * i as f64 / na as f64;
        for j in 0..=nz {
            out.push(Vector3::new(
                r * t.cos(),
                r * t.sin(),
                -hh + 2.0 * hh * j as f64 / nz as f64,
            ));
        }
    }
    let nr = (r / step).ceil() as usize;
    for s in [-1.0, 1.0] {
        for k in 0..=nr {
            let rho = r * k as f64 / nr as f64;
            let m = ((2.0 * std::f64::consts::PI * rho / step).ceil() as usize).max(1);
            for i in 0..m {
                let t = 2.0 * std::f64::consts::PI * i as f64 / m as f64;
                out.push(Vector3::new(rho * t.cos(), rho * t.sin(), s * hh));
            }
        }
    }
    out
}

#[test]
fn sphere_is_exact() {
    let mut r = rng(1);
    for _ in 0..20 {
        let pose = random_pose(&mut r, 1.0);
        let radius = r.gen_range(0.05..0.5);
        let shape = Shape::Sphere { radius };
        for _ in 0..20 {
            let p = pose.translation.vector + vec_in(&mut r, -1.0, 1.0);
            let v = p - pose.translation.vector;
            if v.norm() < 1e-3 {
                continue;
            }
            let s = eval(&shape, &pose, &p);
            let u = v.normalize();
            assert!((s.distance - (v.norm() - radius)).abs() < 1e-12);
            assert!((s.gradient - u).norm() < 1e-12);
            let h = (Matrix3::identity() - u * u.transpose()) / v.norm();
            assert!((s.hessian - h).norm() < 1e-9 * (1.0 + h.norm()));
        }
    }
}

/// A sphere's distance, gradient and Hessian do not depend on its rotation: the same bits with a random
/// rotation as without; at its centre (no direction) the gradient is the rotated local +z.
#[test]
fn sphere_ignores_its_rotation() {
    let mut r = rng(7);
    for _ in 0..20 {
        let rotated = random_pose(&mut r, 1.0);
        let plain = Isometry3::from_parts(rotated.translation, Default::default());
        let shape = Shape::Sphere {
            radius: r.gen_range(0.05..0.5),
        };
        for _ in 0..20 {
            let p = rotated.translation.vector + vec_in(&mut r, -1.0, 1.0);
            assert_eq!(eval(&shape, &rotated, &p), eval(&shape, &plain, &p));
        }
        let centre = eval(&shape, &rotated, &rotated.translation.vector);
        let axis = rotated
            .rotation
            .to_rotation_matrix()
            .matrix()
            .column(2)
            .into_owned();
        assert_eq!(centre.gradient, axis);
        assert_eq!(centre.hessian, Matrix3::zeros());
    }
}

#[test]
fn box_matches_brute_force_surface_samples() {
    let mut r = rng(2);
    let he = Vector3::new(0.1, 0.15, 0.2);
    let samples = box_surface(&he, 1e-3);
    let shape = Shape::Cuboid { half_extents: he };
    for _ in 0..4 {
        let pose = random_pose(&mut r, 0.5);
        for _ in 0..25 {
            let local = vec_in(&mut r, -0.35, 0.35);
            let p = pose * Point3::from(local);
            let s = eval(&shape, &pose, &p.coords);
            let inside = (0..3).all(|i| local[i].abs() < he[i]);
            let reference = brute_min(&samples, &local);
            let expected = if inside { -reference } else { reference };
            assert!(
                (s.distance - expected).abs() <= 1e-3,
                "{} vs {expected}",
                s.distance
            );
            assert_eq!(s.distance < 0.0, inside);
            assert!((s.gradient.norm() - 1.0).abs() < 1e-12);
        }
    }
}

#[test]
fn cylinder_matches_brute_force_surface_samples() {
    let mut r = rng(3);
    let (hh, radius) = (0.12, 0.07);
    let samples = cylinder_surface(hh, radius, 1e-3);
    let shape = Shape::Cylinder {
        half_height: hh,
        radius,
    };
    for _ in 0..4 {
        let pose = random_pose(&mut r, 0.5);
        for _ in 0..25 {
            let local = vec_in(&mut r, -0.25, 0.25);
            let p = pose * Point3::from(local);
            let s = eval(&shape, &pose, &p.coords);
            let inside = local.xy().norm() < radius && local.z.abs() < hh;
            let reference = brute_min(&samples, &local);
            let expected = if inside { -reference } else { reference };
            assert!(
                (s.distance - expected).abs() <= 1e-3,
                "{} vs {expected} at {local:?}",
                s.distance
            );
            assert!((s.gradient.norm() - 1.0).abs() < 1e-12);
        }
    }
}

#[test]
fn capsule_matches_segment_brute_force() {
    let mut r = rng(4);
    let (hh, radius) = (0.2, 0.05);
    let segment: Vec<Vector3<f64>> = (0..=4000)
        .map(|i| Vector3::new(0.0, 0.0, -hh + 2.0 * hh * i as f64 / 4000.0))
        .collect();
    let shape = Shape::Capsule {
        half_height: hh,
        radius,
    };
    for _ in 0..5 {
        let pose = random_pose(&mut r, 0.5);
        for _ in 0..40 {
            let local = vec_in(&mut r, -0.3, 0.3);
            let p = pose * Point3::from(local);
            let s = eval(&shape, &pose, &p.coords);
            let expected = brute_min(&segment, &local) - radius;
            assert!(
                (s.distance - expected).abs() <= 1e-4,
                "{} vs {expected}",
                s.distance
            );
        }
    }
}

#[test]
fn half_space_is_exact() {
    let mut r = rng(5);
    for _ in 0..50 {
        let pose = random_pose(&mut r, 1.0);
        let n = pose.rotation * Vector3::z();
        let p = vec_in(&mut r, -2.0, 2.0);
        let s = eval(&Shape::HalfSpace, &pose, &p);
        assert!((s.distance - n.dot(&(p - pose.translation.vector))).abs() < 1e-12);
        assert!((s.gradient - n).norm() < 1e-12);
        assert_eq!(s.hessian, Matrix3::zeros());
    }
}

/// Local-frame test point of `shape` at least `m` away from every set where the distance or its
/// Hessian is not smooth (Voronoi-region boundaries, medial surfaces, curvature centres).
fn regular(shape: &Shape, q: &Vector3<f64>, m: f64) -> bool {
    match shape {
        Shape::Sphere { .. } => q.norm() > m,
        Shape::Cuboid { half_extents } => box_regular(half_extents, q, m),
        Shape::TriMesh(_) => box_regular(&Vector3::repeat(0.5), q, m),
        Shape::Cylinder {
            half_height,
            radius,
        } => {
            let (rho, a, b) = (
                q.xy().norm(),
                q.xy().norm() - radius,
                q.z.abs() - half_height,
            );
            rho > m && a.abs() > m && b.abs() > m && (a - b).abs() > m
        }
        Shape::Capsule {
            half_height,
            radius,
        } => {
            let c = Vector3::new(0.0, 0.0, q.z.clamp(-half_height, *half_height));
            (q.z.abs() - half_height).abs() > m
                && (q - c).norm() > m
                && ((q - c).norm() - radius).abs() > m
        }
        Shape::HalfSpace => true,
        Shape::PointCloud(pc) => {
            let mut d: Vec<f64> = pc.points().iter().map(|s| (s.coords - q).norm()).collect();
            d.sort_by(|a, b| a.total_cmp(b));
            d[0] > m && d[1] - d[0] > m
        }
    }
}

fn box_regular(h: &Vector3<f64>, q: &Vector3<f64>, m: f64) -> bool {
    let e = q.abs() - h;
    if e.iter().all(|&v| v < 0.0) {
        let mut s: Vec<f64> = e.iter().copied().collect();
        s.sort_by(|a, b| b.total_cmp(a));
        s[0] - s[1] > m
    } else {
        e.iter().all(|v| v.abs() > m)
    }
}

#[test]
fn derivatives_match_finite_differences() {
    let mut r = rng(6);
    let cloud_points: Vec<Vector3<f64>> = (0..40).map(|_| vec_in(&mut r, -0.3, 0.3)).collect();
    let shapes = vec![
        Shape::Sphere { radius: 0.2 },
        Shape::Cuboid {
            half_extents: Vector3::new(0.1, 0.2, 0.3),
        },
        Shape::Cylinder {
            half_height: 0.25,
            radius: 0.15,
        },
        Shape::Cylinder {
            half_height: 0.5,
            radius: 0.1,
        },
        Shape::Capsule {
            half_height: 0.2,
            radius: 0.1,
        },
        Shape::HalfSpace,
        unit_cube_mesh(),
        fine_cube_mesh(),
        Shape::PointCloud(Arc::new(PointCloud::new(cloud_points, 0.02).unwrap())),
    ];
    for shape in &shapes {
        let mut checked = 0;
        let mut curved = 0;
        let pose = random_pose(&mut r, 0.5);
        while checked < 60 {
            let q = vec_in(&mut r, -0.8, 0.8);
            if !regular(shape, &q, 0.02) {
                continue;
            }
            let p = (pose * Point3::from(q)).coords;
            let f = |x: &Vector3<f64>| eval(shape, &pose, x).distance;
            let s = eval(shape, &pose, &p);
            let g = fd_gradient(&f, &p, 1e-6);
            assert!(
                (s.gradient - g).norm() < 1e-6,
                "{shape:?} at {q:?}: gradient {:?} vs fd {g:?}",
                s.gradient
            );
            let h = fd_hessian(&f, &p, 1e-4);
            let tol = 1e-3 * (1.0 + s.hessian.norm());
            assert!(
                (s.hessian - h).norm() < tol,
                "{shape:?} at {q:?} (d = {}): hessian {} vs fd {h}",
                s.distance,
                s.hessian
            );
            assert!((s.hessian - s.hessian.transpose()).norm() < 1e-12);
            if s.hessian.norm() > 0.0 {
                curved += 1;
            }
            checked += 1;
        }
        // Every shape but the half-space has curved regions in this range.
        assert_eq!(curved > 0, !matches!(shape, Shape::HalfSpace), "{shape:?}");
    }
}

#[test]
fn inside_distances_are_minus_nearest_face() {
    let pose = Isometry3::identity();
    let b = Shape::Cuboid {
        half_extents: Vector3::new(0.1, 0.2, 0.3),
    };
    let s = eval(&b, &pose, &Vector3::new(0.02, -0.15, 0.0));
    assert!((s.distance + 0.05).abs() < 1e-15);
    assert_eq!(s.gradient, Vector3::new(0.0, -1.0, 0.0));
    assert_eq!(s.hessian, Matrix3::zeros());
    let c = Shape::Cylinder {
        half_height: 0.3,
        radius: 0.1,
    };
    let s = eval(&c, &pose, &Vector3::new(0.0, 0.0, 0.25));
    assert!((s.distance + 0.05).abs() < 1e-15);
    assert_eq!(s.gradient, Vector3::z());
    let s = eval(&c, &pose, &Vector3::new(0.06, 0.0, 0.0));
    assert!((s.distance + 0.04).abs() < 1e-15);
    assert_eq!(s.gradient, Vector3::x());
}

#[test]
fn singular_points_are_finite_deterministic_and_unit() {
    let pose = Isometry3::identity();
    let cases: Vec<(Shape, Vector3<f64>)> = vec![
        (Shape::Sphere { radius: 0.2 }, Vector3::zeros()),
        (Shape::Sphere { radius: 0.2 }, Vector3::new(0.2, 0.0, 0.0)),
        (
            Shape::Cuboid {
                half_extents: Vector3::repeat(0.1),
            },
            Vector3::zeros(),
        ),
        (
            Shape::Cuboid {
                half_extents: Vector3::repeat(0.1),
            },
            Vector3::new(0.1, 0.0, 0.0),
        ),
        (
            Shape::Cuboid {
                half_extents: Vector3::repeat(0.1),
            },
            Vector3::new(0.1, 0.1, 0.0),
        ),
        (
            Shape::Cuboid {
                half_extents: Vector3::repeat(0.1),
            },
            Vector3::new(0.1, 0.1, 0.1),
        ),
        (
            Shape::Cylinder {
                half_height: 0.5,
                radius: 0.1,
            },
            Vector3::zeros(),
        ),
        (
            Shape::Cylinder {
                half_height: 0.1,
                radius: 0.1,
            },
            Vector3::new(0.1, 0.0, 0.1),
        ),
        (
            Shape::Capsule {
                half_height: 0.2,
                radius: 0.1,
            },
            Vector3::new(0.0, 0.0, 0.1),
        ),
        (
            Shape::Capsule {
                half_height: 0.2,
                radius: 0.1,
            },
            Vector3::new(0.0, 0.0, 0.2),
        ),
        (
            Shape::Capsule {
                half_height: 0.0,
                radius: 0.1,
            },
            Vector3::zeros(),
        ),
        (unit_cube_mesh(), Vector3::new(0.5, 0.1, 0.2)),
        (unit_cube_mesh(), Vector3::new(0.5, 0.5, 0.5)),
        (unit_cube_mesh(), Vector3::zeros()),
        (
            Shape::PointCloud(Arc::new(
                PointCloud::new(vec![Vector3::new(0.1, 0.2, 0.3)], 0.0).unwrap(),
            )),
            Vector3::new(0.1, 0.2, 0.3),
        ),
    ];
    for (shape, p) in &cases {
        let a = eval(shape, &pose, p);
        let b = eval(shape, &pose, p);
        assert_eq!(a, b, "{shape:?}");
        assert!(
            a.distance.is_finite() && a.hessian.iter().all(|v| v.is_finite()),
            "{shape:?} {a:?}"
        );
        assert!((a.gradient.norm() - 1.0).abs() < 1e-12, "{shape:?} {a:?}");
    }
    // Documented tie rules: box centre -> +x face; cylinder centre of a tall cylinder -> side along +x.
    let s = eval(&cases[2].0, &pose, &Vector3::zeros());
    assert_eq!(s.gradient, Vector3::x());
    assert!((s.distance + 0.1).abs() < 1e-15);
    let s = eval(&cases[6].0, &pose, &Vector3::zeros());
    assert_eq!(s.gradient, Vector3::x());
    assert!((s.distance + 0.1).abs() < 1e-15);
    // Sphere centre: fallback +z, distance -radius.
    let s = eval(&cases[0].0, &pose, &Vector3::zeros());
    assert_eq!((s.distance, s.gradient), (-0.2, Vector3::z()));
}

#[test]
fn cube_meshes_match_the_cuboid() {
    let mut r = rng(7);
    let cuboid = Shape::Cuboid {
        half_extents: Vector3::repeat(0.5),
    };
    for mesh in [unit_cube_mesh(), fine_cube_mesh()] {
        assert!(mesh.is_solid());
        for _ in 0..3 {
            let pose = random_pose(&mut r, 1.0);
            let mut n = 0;
            while n < 100 {
                let q = vec_in(&mut r, -1.2, 1.2);
                if !box_regular(&Vector3::repeat(0.5), &q, 1e-6) {
                    continue;
                }
                n += 1;
                let p = (pose * Point3::from(q)).coords;
                let a = eval(&mesh, &pose, &p);
                let b = eval(&cuboid, &pose, &p);
                assert!(
                    (a.distance - b.distance).abs() < 1e-9,
                    "{q:?}: {} vs {}",
                    a.distance,
                    b.distance
                );
                assert!((a.gradient - b.gradient).norm() < 1e-9, "{q:?}");
                assert!(
                    (a.hessian - b.hessian).norm() < 1e-6 * (1.0 + b.hessian.norm()),
                    "{q:?}"
                );
            }
        }
    }
}

#[test]
fn open_mesh_is_unsigned() {
    let v = vec![
        Point3::new(-1.0, -1.0, 0.0),
        Point3::new(1.0, -1.0, 0.0),
        Point3::new(1.0, 1.0, 0.0),
        Point3::new(-1.0, 1.0, 0.0),
    ];
    let mesh = build_mesh(v, vec![[0, 1, 2], [0, 2, 3]], "square").unwrap();
    let shape = Shape::TriMesh(Arc::new(mesh));
    assert!(!shape.is_solid());
    let pose = Isometry3::identity();
    for z in [0.3, -0.3] {
        let s = eval(&shape, &pose, &Vector3::new(0.2, 0.1, z));
        assert!((s.distance - 0.3).abs() < 1e-12);
        assert!((s.gradient - Vector3::new(0.0, 0.0, z.signum())).norm() < 1e-12);
        assert_eq!(s.hessian, Matrix3::zeros());
    }
    // Beyond the border edge: distance to the edge line, edge Hessian.
    let s = eval(&shape, &pose, &Vector3::new(1.3, 0.0, 0.4));
    assert!((s.distance - 0.5).abs() < 1e-12);
    let u = Vector3::new(0.3, 0.0, 0.4) / 0.5;
    let h =
        (Matrix3::identity() - u * u.transpose() - Vector3::y() * Vector3::y().transpose()) / 0.5;
    assert!((s.hessian - h).norm() < 1e-9);
}

#[test]
fn point_cloud_matches_brute_force() {
    let mut r = rng(8);
    let pts: Vec<Vector3<f64>> = (0..500).map(|_| vec_in(&mut r, -0.5, 0.5)).collect();
    let radius = 0.01;
    let shape = Shape::PointCloud(Arc::new(PointCloud::new(pts.clone(), radius).unwrap()));
    let pose = random_pose(&mut r, 0.5);
    for _ in 0..200 {
        let q = vec_in(&mut r, -0.8, 0.8);
        let p = (pose * Point3::from(q)).coords;
        let s = eval(&shape, &pose, &p);
        let (i, d) = pts
            .iter()
            .enumerate()
            .map(|(i, s)| (i, (s - q).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert!((s.distance - (d - radius)).abs() < 1e-12);
        let u = pose.rotation * (q - pts[i]) / d;
        assert!((s.gradient - u).norm() < 1e-9);
        let h = (Matrix3::identity() - u * u.transpose()) / d;
        assert!((s.hessian - h).norm() < 1e-9 * (1.0 + h.norm()));
    }
}

#[test]
fn limits_filter_far_obstacles() {
    let pose = Isometry3::identity();
    let p = Vector3::new(1.0, 0.0, 0.0);
    for shape in [Shape::Sphere { radius: 0.5 }, unit_cube_mesh()] {
        assert!(point_distance(&shape, &pose, &p, 0.49).is_none());
        assert!(
            point_distance(&shape, &pose, &p, 0.5).is_some(),
            "{shape:?}"
        );
    }
    // A point deep inside a solid mesh is found for a negative limit.
    let s = point_distance(&unit_cube_mesh(), &pose, &Vector3::zeros(), -0.4).unwrap();
    assert!((s.distance + 0.5).abs() < 1e-12);
    assert!(point_distance(&unit_cube_mesh(), &pose, &Vector3::zeros(), -0.6).is_none());
}
