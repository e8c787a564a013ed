//! Signed distance from a point to one obstacle, with its gradient and Hessian.
//!
//! These are the distance task maps `x = d(p(q))` of the collision-avoidance components (GF Sec. VII-A,
//! "Distance Space Repulsion": the repulsion lives on `x = d(p)` for every robot sphere centre `p`);
//! the fabric pulls them back through `J_d = ∇dᵀ J_p` and needs the curvature `ṗᵀ ∇²d ṗ` for `J̇q̇`
//! (GF eq. 11-12, 16).
//!
//! Conventions: metres; `d > 0` outside, `d < 0` inside; `∇d = ∂d/∂p` (world frame, unit length);
//! `∇²d = ∂²d/∂p²` (world frame, symmetric). With `c` the closest surface point, `r = |p - c|`,
//! `u = (p - c)/r` and `s = ±1` the side:
//!
//! | nearest feature | `d` | `∇d` | `∇²d` |
//! |---|---|---|---|
//! | flat face (box face, cylinder cap, half-space, mesh face) | `s r` | face normal | `0` |
//! | straight edge with unit direction `e` (box edge, capsule core, mesh edge) | `s r - ρ` | `s u` | `s (I - uuᵀ - eeᵀ)/r` |
//! | point (sphere centre, box corner, capsule end, mesh vertex, cloud point) | `s r - ρ` | `s u` | `s (I - uuᵀ)/r` |
//! | cylinder side (radius `R`, radial `e_r`, tangent `e_θ`, `ρ_xy` = distance to the axis) | `ρ_xy - R` | `e_r` | `e_θ e_θᵀ / ρ_xy` |
//! | cylinder rim (circle): `a = ρ_xy - R`, `b = |z| - h` | `√(a²+b²)` | `u` | `t tᵀ/d + (a/d) e_θ e_θᵀ/ρ_xy` |
//!
//! For meshes the feature is decided from all triangles touching the nearest point `c`: edges between
//! coplanar triangles and vertices inside flat regions count as faces, vertices on a straight crease as
//! edges, so the Hessian is exact for any triangulation.
//!
//! (`ρ` = sphere/capsule/cloud radius, `t` = unit vector normal to `u` in the (e_r, z) plane.) These are
//! exact, including inside spheres, capsules and cylinders (inside a box or a cylinder the nearest
//! feature is a face, so `d` = minus the distance to the nearest face; the Hessian is 0 on flat faces).
//!
//! Singularities (exact ties or `r <= 1e-12` m: a point on the surface, at a sphere/capsule centre, on
//! a cylinder axis, on the medial surface of a box): the result stays finite and deterministic and the
//! gradient stays unit. Ties between box faces pick the lowest axis index (x, then y, then z) and the
//! `+` side when the coordinate is 0; between a cylinder cap and side the cap wins; when `r <= 1e-12` the
//! gradient is a fixed fallback direction (sphere: `+z`; capsule core: `+x`; capsule end: `±z`; cylinder
//! axis: `e_r = +x`; mesh: the triangle normal) and the Hessian is set to 0.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use parry3d_f64::partitioning::BvhNode;
use parry3d_f64::query::{PointQuery, PointQueryWithLocation};
use parry3d_f64::shape::{Segment, TriMesh, TrianglePointLocation};

use super::shape::{fmax, PointCloud, Shape};
use super::ObstacleId;
use crate::linalg::rotate;

/// Below this distance (m) to a point/edge feature the Hessian `1/r` is replaced by 0 and the gradient by
/// a fixed fallback direction (see the module documentation).
pub const SINGULAR_EPS: f64 = 1e-12;

/// Signed distance from a point `p` (world) to one obstacle surface and its derivatives w.r.t. `p`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistanceSample {
    /// The obstacle.
    pub obstacle: ObstacleId,
    /// Signed distance (m): positive outside, negative inside.
    pub distance: f64,
    /// `∂d/∂p` (world frame, unit length).
    pub gradient: Vector3<f64>,
    /// `∂²d/∂p²` (world frame, 1/m, symmetric).
    pub hessian: Matrix3<f64>,
    /// Linear velocity of the obstacle (m/s, world): `ḋ = ∇dᵀ (ṗ - v)` for a moving obstacle.
    pub velocity: Vector3<f64>,
}

/// A broadphase hit of `Scene::query_near`: the obstacle at storage position `entry` of the scene lies
/// at signed distance `distance` (m) from the query point. The position is valid only until the scene
/// is next modified (use [`DistanceSample::obstacle`] ids for anything kept).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearObstacle {
    /// Position of the obstacle in the scene's dense storage.
    pub entry: u32,
    /// Signed distance (m) from the query point, positive outside.
    pub distance: f64,
}

/// Signed distance, gradient and Hessian of one shape at one point (world frame), without identity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceDistance {
    /// Signed distance (m), positive outside.
    pub distance: f64,
    /// `∂d/∂p` (world, unit).
    pub gradient: Vector3<f64>,
    /// `∂²d/∂p²` (world, 1/m).
    pub hessian: Matrix3<f64>,
}

/// Distance of world point `p` to `shape` placed at `pose`, when it is `<= max_distance`
/// (`f64::INFINITY` for no limit); `None` otherwise. See the module documentation for formulas.
pub fn point_distance(
    shape: &Shape,
    pose: &Isometry3<f64>,
    p: &Vector3<f64>,
    max_distance: f64,
) -> Option<SurfaceDistance> {
    let rot = pose.rotation.to_rotation_matrix().into_inner();
    eval_world(shape, &rot, &pose.translation.vector, p, max_distance)
}

/// [`point_distance`] with the rotation matrix `rot` (obstacle to world) precomputed. Each closed form
/// tests its distance against `max_distance` before computing derivatives, so obstacles that the
/// broadphase bound could not exclude cost little more than their distance. Inlined into the scene's
/// query loops (meshes and point clouds stay out of line).
#[inline(always)]
pub(crate) fn eval_world(
    shape: &Shape,
    rot: &Matrix3<f64>,
    trans: &Vector3<f64>,
    p: &Vector3<f64>,
    max_distance: f64,
) -> Option<SurfaceDistance> {
    // the obstacle-frame point, for every shape but the sphere (rotation-invariant: world frame)
    let local = || to_local(rot, trans, p);
    let f = Frame {
        rot,
        max: max_distance,
    };
    match shape {
        Shape::Sphere { radius } => sphere(rot, &(p - trans), *radius, max_distance),
        Shape::Cuboid { half_extents } => cuboid(&f, &local(), half_extents),
        Shape::Cylinder {
            half_height,
            radius,
        } => cylinder(&f, &local(), *half_height, *radius),
        Shape::Capsule {
            half_height,
            radius,
        } => capsule(&f, &local(), *half_height, *radius),
        Shape::HalfSpace => f.flat(local().z, column(rot, 2)),
        Shape::TriMesh(m) => trimesh(&f, m, &local()),
        Shape::PointCloud(pc) => point_cloud(&f, pc, &local()),
    }
}

/// `Rᵀ (p - t)`: world point to obstacle frame, written out (the generic nalgebra product is several
/// times slower here, and this runs for every obstacle near every query point).
#[inline(always)]
fn to_local(rot: &Matrix3<f64>, trans: &Vector3<f64>, p: &Vector3<f64>) -> Vector3<f64> {
    let (dx, dy, dz) = (p.x - trans.x, p.y - trans.y, p.z - trans.z);
    Vector3::new(
        rot.m11 * dx + rot.m21 * dy + rot.m31 * dz,
        rot.m12 * dx + rot.m22 * dy + rot.m32 * dz,
        rot.m13 * dx + rot.m23 * dy + rot.m33 * dz,
    )
}

/// Signed distance only (no derivatives), when it is `<= max_distance`: the cheap test used by the
/// broadphase before [`eval_world`]. Same value as `eval_world(..).distance`.
pub(crate) fn distance_world(
    shape: &Shape,
    rot: &Matrix3<f64>,
    trans: &Vector3<f64>,
    p: &Vector3<f64>,
    max_distance: f64,
) -> Option<f64> {
    let d = match shape {
        Shape::Sphere { radius } => (p - trans).norm() - radius,
        Shape::Cuboid { half_extents } => {
            let l = to_local(rot, trans, p);
            let (qx, qy, qz) = (
                l.x.abs() - half_extents.x,
                l.y.abs() - half_extents.y,
                l.z.abs() - half_extents.z,
            );
            if qx <= 0.0 && qy <= 0.0 && qz <= 0.0 {
                fmax(fmax(qx, qy), qz)
            } else {
                let (ox, oy, oz) = (fmax(qx, 0.0), fmax(qy, 0.0), fmax(qz, 0.0));
                (ox * ox + oy * oy + oz * oz).sqrt()
            }
        }
        Shape::Cylinder {
            half_height,
            radius,
        } => {
            let l = to_local(rot, trans, p);
            let a = (l.x * l.x + l.y * l.y).sqrt() - radius;
            let b = l.z.abs() - half_height;
            if a > 0.0 && b > 0.0 {
                (a * a + b * b).sqrt()
            } else {
                fmax(a, b)
            }
        }
        Shape::Capsule {
            half_height,
            radius,
        } => {
            let l = to_local(rot, trans, p);
            let z = l.z - l.z.clamp(-half_height, *half_height);
            (l.x * l.x + l.y * l.y + z * z).sqrt() - radius
        }
        Shape::HalfSpace => to_local(rot, trans, p).z,
        Shape::TriMesh(_) | Shape::PointCloud(_) => {
            return eval_world(shape, rot, trans, p, max_distance).map(|s| s.distance)
        }
    };
    (d <= max_distance).then_some(d)
}

/// Whether a distance fails the limit `max` (NaN included): every closed form returns `None` then,
/// before computing derivatives, so [`eval_world`] needs no test of its own.
#[inline(always)]
fn beyond(d: f64, max: f64) -> bool {
    d.is_nan() || d > max
}

/// Column `k` of `rot`: the world direction of the obstacle's local axis `k` (= `rotate(rot, e_k)`).
#[inline(always)]
fn column(rot: &Matrix3<f64>, k: usize) -> Vector3<f64> {
    rot.column(k).into_owned()
}

/// The Hessian `α I + Σ_k β_k w_k w_kᵀ` (world frame) from world vectors `w_k`. Every closed form of
/// this module has this shape, and `R (α I + β v vᵀ) Rᵀ = α I + β (Rv)(Rv)ᵀ`: the obstacle-frame
/// vectors are rotated, never the matrix.
#[inline(always)]
fn curvature(alpha: f64, terms: &[(f64, Vector3<f64>)]) -> Matrix3<f64> {
    // Upper triangle xx, xy, xz, yy, yz, zz.
    let mut h = [alpha, 0.0, 0.0, alpha, 0.0, alpha];
    for (b, w) in terms {
        let (bx, by, bz) = (b * w.x, b * w.y, b * w.z);
        h[0] += bx * w.x;
        h[1] += bx * w.y;
        h[2] += bx * w.z;
        h[3] += by * w.y;
        h[4] += by * w.z;
        h[5] += bz * w.z;
    }
    Matrix3::new(h[0], h[1], h[2], h[1], h[3], h[4], h[2], h[4], h[5])
}

/// The obstacle being evaluated: its rotation `rot` (obstacle to world) and the distance limit `max`
/// (m). Its closed forms take obstacle-frame vectors and return world-frame results, or `None` when
/// the distance is [`beyond`] the limit (tested before any derivative is computed).
struct Frame<'a> {
    rot: &'a Matrix3<f64>,
    max: f64,
}

impl Frame<'_> {
    /// Flat feature: distance `d`, world gradient `g`, Hessian 0.
    #[inline(always)]
    fn flat(&self, d: f64, g: Vector3<f64>) -> Option<SurfaceDistance> {
        (!beyond(d, self.max)).then_some(SurfaceDistance {
            distance: d,
            gradient: g,
            hessian: Matrix3::zeros(),
        })
    }

    /// `d = s|v| - offset` about a point feature (`v = p - c`, obstacle frame).
    #[inline(always)]
    fn about_point(
        &self,
        v: &Vector3<f64>,
        s: f64,
        offset: f64,
        fallback: Vector3<f64>,
    ) -> Option<SurfaceDistance> {
        self.radial(v, s, offset, fallback, None)
    }

    /// `d = s|v| - offset` about a straight line of world unit direction `e` (`v = p - c ⟂ e`,
    /// obstacle frame).
    #[inline(always)]
    fn about_line(
        &self,
        v: &Vector3<f64>,
        e: Vector3<f64>,
        s: f64,
        offset: f64,
        fallback: Vector3<f64>,
    ) -> Option<SurfaceDistance> {
        self.radial(v, s, offset, fallback, Some(e))
    }

    /// `d = s|v| - offset` (`s = ±1`) with `v` the offset from a point or (with `axis`, world frame)
    /// from a line: gradient `s·u`, `u = R v/|v|`, Hessian `(s/|v|)(I − uuᵀ)`, minus `eeᵀ` along the
    /// line. At `|v| ≤ SINGULAR_EPS`: flat, with the obstacle-frame `fallback` normal.
    #[inline(always)]
    fn radial(
        &self,
        v: &Vector3<f64>,
        s: f64,
        offset: f64,
        fallback: Vector3<f64>,
        axis: Option<Vector3<f64>>,
    ) -> Option<SurfaceDistance> {
        let r = v.norm();
        let d = s * r - offset;
        if beyond(d, self.max) {
            return None;
        }
        if r <= SINGULAR_EPS {
            return self.flat(d, rotate(self.rot, &fallback));
        }
        let inv = 1.0 / r;
        let u = rotate(self.rot, &(v * inv));
        let k = s * inv;
        let hessian = match axis {
            None => curvature(k, &[(-k, u)]),
            Some(e) => curvature(k, &[(-k, u), (-k, e)]),
        };
        Some(SurfaceDistance {
            distance: d,
            gradient: u * s,
            hessian,
        })
    }
}

/// Widen a search limit so that features at exactly `max` are not lost to strict comparisons.
fn widen(max: f64) -> f64 {
    max + 1e-9 * (1.0 + max.abs())
}

fn sign_of(v: f64) -> f64 {
    if v >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

/// Sphere of radius `radius` about the world offset `v = p − c`: d = |v| − radius, gradient v/|v|,
/// Hessian (I − uuᵀ)/|v|, all in the world frame (a sphere's distance does not depend on its rotation, so
/// no rotation is applied: the same bits as [`Frame::about_point`] on the obstacle-frame offset when the
/// rotation is the identity). At `|v| ≤ SINGULAR_EPS` (the centre): flat, along the obstacle's local z.
#[inline(always)]
fn sphere(rot: &Matrix3<f64>, v: &Vector3<f64>, radius: f64, max: f64) -> Option<SurfaceDistance> {
    let r = v.norm();
    let d = r - radius;
    if beyond(d, max) {
        return None;
    }
    if r <= SINGULAR_EPS {
        return Some(SurfaceDistance {
            distance: d,
            gradient: column(rot, 2),
            hessian: Matrix3::zeros(),
        });
    }
    let inv = 1.0 / r;
    let u = v * inv;
    Some(SurfaceDistance {
        distance: d,
        gradient: u,
        hessian: curvature(inv, &[(-inv, u)]),
    })
}

/// Box of half extents `h`: face (Hessian 0), edge or corner outside; nearest face inside. The face
/// normals and edge directions are the columns of the rotation.
fn cuboid(f: &Frame, p: &Vector3<f64>, h: &Vector3<f64>) -> Option<SurfaceDistance> {
    let q = p.abs() - h;
    let outside = q.iter().filter(|&&v| v > 0.0).count();
    match outside {
        0 | 1 => {
            // Inside, on the surface, or in a face region: the face of largest excess (first on ties).
            let mut i = 0;
            for k in 1..3 {
                if q[k] > q[i] {
                    i = k;
                }
            }
            f.flat(q[i], column(f.rot, i) * sign_of(p[i]))
        }
        2 => {
            let j = (0..3).find(|&k| q[k] <= 0.0).unwrap_or(0);
            let c = Vector3::from_fn(|k, _| p[k].clamp(-h[k], h[k]));
            f.about_line(&(p - c), column(f.rot, j), 1.0, 0.0, Vector3::z())
        }
        _ => {
            let c = Vector3::from_fn(|k, _| p[k].clamp(-h[k], h[k]));
            f.about_point(&(p - c), 1.0, 0.0, Vector3::z())
        }
    }
}

/// Cylinder of half height `hh` and radius `radius` along z: side, cap, rim (circle) or inside.
fn cylinder(f: &Frame, p: &Vector3<f64>, hh: f64, radius: f64) -> Option<SurfaceDistance> {
    let rho = (p.x * p.x + p.y * p.y).sqrt();
    let a = rho - radius;
    let b = p.z.abs() - hh;
    // Rim (a, b > 0) or side (outside, or inside nearer to the side than to a cap); else a cap.
    let rim = a > 0.0 && b > 0.0;
    if !(a > 0.0 || (b <= 0.0 && a > b)) {
        return f.flat(b, column(f.rot, 2) * sign_of(p.z));
    }
    let d = if rim { (a * a + b * b).sqrt() } else { a };
    if beyond(d, f.max) {
        return None;
    }
    let on_axis = rho <= SINGULAR_EPS;
    let inv_rho = if on_axis { 0.0 } else { 1.0 / rho };
    let (er, eth) = if on_axis {
        (Vector3::x(), Vector3::y())
    } else {
        (
            Vector3::new(p.x * inv_rho, p.y * inv_rho, 0.0),
            Vector3::new(-p.y * inv_rho, p.x * inv_rho, 0.0),
        )
    };
    let eth = rotate(f.rot, &eth);
    if rim {
        // Rim: distance to a circle. ∇²d = t tᵀ/d + (a/d) ∇²ρ with ∇²ρ = e_θ e_θᵀ/ρ.
        let (z, sz) = (Vector3::z(), sign_of(p.z));
        let inv_d = 1.0 / d;
        let g = (er * a + z * (b * sz)) * inv_d;
        let t = (er * (-b) + z * (a * sz)) * inv_d;
        Some(SurfaceDistance {
            distance: d,
            gradient: rotate(f.rot, &g),
            hessian: curvature(
                0.0,
                &[(inv_d, rotate(f.rot, &t)), (a * inv_d * inv_rho, eth)],
            ),
        })
    } else if on_axis {
        // Side (outside, or inside nearer to the side than to a cap), on the axis.
        f.flat(a, column(f.rot, 0))
    } else {
        // Side.
        Some(SurfaceDistance {
            distance: a,
            gradient: rotate(f.rot, &er),
            hessian: curvature(0.0, &[(inv_rho, eth)]),
        })
    }
}

/// Capsule: distance to the core segment minus the radius.
fn capsule(f: &Frame, p: &Vector3<f64>, hh: f64, radius: f64) -> Option<SurfaceDistance> {
    let zc = p.z.clamp(-hh, hh);
    let v = Vector3::new(p.x, p.y, p.z - zc);
    if p.z.abs() < hh {
        f.about_line(&v, column(f.rot, 2), 1.0, radius, Vector3::x())
    } else {
        f.about_point(&v, 1.0, radius, Vector3::z() * sign_of(p.z))
    }
}

/// Triangle mesh via parry's point projection with feature location; signed with pseudo-normals.
#[inline(never)]
fn trimesh(f: &Frame, m: &TriMesh, p: &Vector3<f64>) -> Option<SurfaceDistance> {
    let solid = m.pseudo_normals_if_oriented().is_some();
    let pt = Point3::from(*p);
    let limit = if solid && m.local_aabb().contains_local_point(&pt) {
        f64::INFINITY
    } else if f.max >= 0.0 {
        widen(f.max)
    } else {
        return None;
    };
    let (proj, (tri, loc)) =
        m.project_local_point_and_get_location_with_max_dist(&pt, false, limit)?;
    let s = if solid && proj.is_inside { -1.0 } else { 1.0 };
    let v = p - proj.point.coords;
    let normal = m
        .triangle(tri)
        .normal()
        .map(|n| n.into_inner())
        .unwrap_or_else(Vector3::z);
    let r = v.norm();
    if beyond(s * r, f.max) {
        return None;
    }
    if r <= SINGULAR_EPS {
        return f.flat(s * r, rotate(f.rot, &normal));
    }
    if matches!(
        loc,
        TrianglePointLocation::OnFace(..) | TrianglePointLocation::OnSolid
    ) {
        return f.flat(s * r, rotate(f.rot, &(v * (s / r))));
    }
    // Nearest point on an edge or a vertex: the Hessian depends on the directions along which the
    // nearest point slides (face region: 2, edge region: 1, vertex region: 0), found from every triangle
    // touching it, so that edges between coplanar triangles and vertices on straight creases are exact.
    let u = v / r;
    match sliding_directions(m, &proj.point, &u) {
        Slide::Plane => f.flat(s * r, rotate(f.rot, &(u * s))),
        Slide::Line(e) => f.about_line(&v, rotate(f.rot, &e), s, 0.0, normal),
        Slide::None => f.about_point(&v, s, 0.0, normal),
    }
}

/// Directions (orthogonal to `u`) along which the nearest point `c` of a mesh slides as `p` moves.
enum Slide {
    Plane,
    Line(Vector3<f64>),
    None,
}

/// Collect the sliding directions at `c` from the triangles touching it: a triangle whose normal is
/// parallel to `u` contributes its plane, any other contributes its edges through `c` orthogonal to `u`.
fn sliding_directions(m: &TriMesh, c: &Point3<f64>, u: &Vector3<f64>) -> Slide {
    const PARALLEL: f64 = 1e-7;
    let scale = 1.0 + c.coords.abs().max();
    let touch = 1e-9 * scale;
    let mut basis: Vec<Vector3<f64>> = Vec::with_capacity(2);
    let add = |w: Vector3<f64>, basis: &mut Vec<Vector3<f64>>| {
        let mut w = w - u * u.dot(&w);
        for b in basis.iter() {
            w -= b * b.dot(&w);
        }
        if let Some(w) = w.try_normalize(1e-6) {
            basis.push(w);
        }
    };
    let leaves = m.bvh().leaves(|node: &BvhNode| {
        (0..3).all(|i| node.mins()[i] - touch <= c[i] && c[i] <= node.maxs()[i] + touch)
    });
    for t in leaves {
        if basis.len() >= 2 {
            break;
        }
        let tri = m.triangle(t);
        if tri.distance_to_local_point(c, true) > touch {
            continue;
        }
        match tri.normal() {
            Some(n) if n.dot(u).abs() >= 1.0 - PARALLEL => {
                add(tri.b - tri.a, &mut basis);
                add(tri.c - tri.a, &mut basis);
            }
            _ => {
                for (a, b) in [(tri.a, tri.b), (tri.b, tri.c), (tri.c, tri.a)] {
                    let Some(e) = (b - a).try_normalize(0.0) else {
                        continue;
                    };
                    let through_c = Segment::new(a, b).distance_to_local_point(c, true) <= touch;
                    if through_c && e.dot(u).abs() < PARALLEL {
                        add(e, &mut basis);
                    }
                }
            }
        }
    }
    match basis.len() {
        0 => Slide::None,
        1 => Slide::Line(basis[0]),
        _ => Slide::Plane,
    }
}

/// Point cloud: nearest point (BVH) minus the cloud radius.
#[inline(never)]
fn point_cloud(f: &Frame, pc: &PointCloud, p: &Vector3<f64>) -> Option<SurfaceDistance> {
    let (i, _) = pc.nearest(&Point3::from(*p), widen(f.max + pc.radius()))?;
    let c = pc.points().get(i)?;
    f.about_point(&(p - c.coords), 1.0, pc.radius(), Vector3::z())
}
