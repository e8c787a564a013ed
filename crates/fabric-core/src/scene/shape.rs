//! Obstacle shapes, point clouds and obstacles.
//!
//! Every shape is described in its own *obstacle frame*; an [`Obstacle`] places it in the world (= robot
//! base frame) with a rigid pose. Units are metres. Conventions shared by all shapes:
//!
//! * [`Shape::Cylinder`] and [`Shape::Capsule`] have their axis along the local `z` axis and are centred
//!   at the local origin (extent `z ∈ [-half_height, half_height]`, plus the caps of a capsule).
//! * [`Shape::HalfSpace`] is the solid `z ≤ 0` of its frame: the boundary is the plane `z = 0` and the
//!   free side is `+z` (the signed distance of a point is its local `z`).
//! * [`Shape::TriMesh`] is signed (solid) when the parry mesh carries pseudo-normals
//!   (`TriMeshFlags::ORIENTED`, set by [`crate::scene::meshio::build_mesh`] for closed, consistently
//!   oriented meshes) and unsigned (a thin surface) otherwise.
//! * [`Shape::PointCloud`] is a set of points in the obstacle frame, each thickened by
//!   [`PointCloud::radius`] (0 allowed).

use std::fmt;
use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhNode};
use parry3d_f64::shape::TriMesh;

use crate::error::{FabricError, Result};

/// Geometry of one obstacle, in its own frame (metres). See the module documentation for axes and signs.
#[derive(Clone)]
pub enum Shape {
    /// Ball of `radius` centred at the local origin.
    Sphere {
        /// Radius (m), > 0.
        radius: f64,
    },
    /// Box centred at the local origin, faces normal to the local axes.
    Cuboid {
        /// Half sizes along local x, y, z (m), each > 0. MoveIt gives FULL sizes: halve them.
        half_extents: Vector3<f64>,
    },
    /// Solid cylinder, axis = local z, centred at the origin.
    Cylinder {
        /// Half of the height along z (m), > 0.
        half_height: f64,
        /// Radius (m), > 0.
        radius: f64,
    },
    /// Capsule: the points within `radius` of the segment from `(0,0,-half_height)` to `(0,0,half_height)`.
    Capsule {
        /// Half length of the core segment (m), >= 0 (0 gives a sphere).
        half_height: f64,
        /// Radius (m), > 0.
        radius: f64,
    },
    /// Solid half-space `z <= 0` of the obstacle frame; the free side is `+z`.
    HalfSpace,
    /// Triangle mesh (vertices in the obstacle frame). Signed when it has pseudo-normals, see module doc.
    TriMesh(Arc<TriMesh>),
    /// Point cloud (points in the obstacle frame).
    PointCloud(Arc<PointCloud>),
}

impl fmt::Debug for Shape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Shape::Sphere { radius } => write!(f, "Sphere {{ radius: {radius} }}"),
            Shape::Cuboid { half_extents } => write!(
                f,
                "Cuboid {{ half_extents: [{}, {}, {}] }}",
                half_extents.x, half_extents.y, half_extents.z
            ),
            Shape::Cylinder {
                half_height,
                radius,
            } => {
                write!(
                    f,
                    "Cylinder {{ half_height: {half_height}, radius: {radius} }}"
                )
            }
            Shape::Capsule {
                half_height,
                radius,
            } => {
                write!(
                    f,
                    "Capsule {{ half_height: {half_height}, radius: {radius} }}"
                )
            }
            Shape::HalfSpace => write!(f, "HalfSpace"),
            Shape::TriMesh(m) => write!(
                f,
                "TriMesh {{ vertices: {}, triangles: {}, solid: {} }}",
                m.vertices().len(),
                m.indices().len(),
                m.pseudo_normals_if_oriented().is_some()
            ),
            Shape::PointCloud(pc) => write!(
                f,
                "PointCloud {{ points: {}, radius: {} }}",
                pc.points.len(),
                pc.radius
            ),
        }
    }
}

impl Shape {
    /// A box from its FULL sizes `size = [sx, sy, sz]` (m), as MoveIt and MotionBenchMaker give them.
    pub fn cuboid_from_size(size: Vector3<f64>) -> Shape {
        Shape::Cuboid {
            half_extents: size * 0.5,
        }
    }

    /// Short lower-case name of the shape kind (`"sphere"`, `"box"`, `"cylinder"`, `"capsule"`,
    /// `"half_space"`, `"mesh"`, `"point_cloud"`), used in error messages.
    pub fn kind(&self) -> &'static str {
        match self {
            Shape::Sphere { .. } => "sphere",
            Shape::Cuboid { .. } => "box",
            Shape::Cylinder { .. } => "cylinder",
            Shape::Capsule { .. } => "capsule",
            Shape::HalfSpace => "half_space",
            Shape::TriMesh(_) => "mesh",
            Shape::PointCloud(_) => "point_cloud",
        }
    }

    /// Whether a triangle mesh is treated as solid (signed distance). Primitives and half-spaces are
    /// always solid; point clouds never are (their distance is `|p - nearest point| - radius`).
    pub fn is_solid(&self) -> bool {
        match self {
            Shape::TriMesh(m) => m.pseudo_normals_if_oriented().is_some(),
            Shape::PointCloud(_) => false,
            _ => true,
        }
    }

    /// Check sizes: radii and half extents finite and > 0 (capsule half height >= 0), mesh vertices
    /// finite. `what` names the obstacle in the error.
    pub fn validate(&self, what: &str) -> Result<()> {
        let positive = |name: &str, v: f64| -> Result<()> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(FabricError::Value {
                    what: format!("{what}: {} {name}", self.kind()),
                    message: format!("must be finite and > 0, got {v}"),
                })
            }
        };
        match self {
            Shape::Sphere { radius } => positive("radius", *radius),
            Shape::Cuboid { half_extents } => {
                positive("half_extents.x", half_extents.x)?;
                positive("half_extents.y", half_extents.y)?;
                positive("half_extents.z", half_extents.z)
            }
            Shape::Cylinder {
                half_height,
                radius,
            } => {
                positive("half_height", *half_height)?;
                positive("radius", *radius)
            }
            Shape::Capsule {
                half_height,
                radius,
            } => {
                if !(half_height.is_finite() && *half_height >= 0.0) {
                    return Err(FabricError::Value {
                        what: format!("{what}: capsule half_height"),
                        message: format!("must be finite and >= 0, got {half_height}"),
                    });
                }
                positive("radius", *radius)
            }
            Shape::HalfSpace => Ok(()),
            Shape::TriMesh(m) => {
                if m.indices().is_empty() {
                    return Err(FabricError::Value {
                        what: format!("{what}: mesh"),
                        message: "has no triangles".into(),
                    });
                }
                if m.vertices()
                    .iter()
                    .any(|v| !v.coords.iter().all(|c| c.is_finite()))
                {
                    return Err(FabricError::NonFinite {
                        what: format!("{what}: mesh vertices"),
                    });
                }
                let n = m.vertices().len();
                if m.indices().iter().flatten().any(|&i| i as usize >= n) {
                    return Err(FabricError::Value {
                        what: format!("{what}: mesh"),
                        message: format!("triangle vertex index out of range ({n} vertices)"),
                    });
                }
                Ok(())
            }
            // Validated by `PointCloud::new`, the only constructor.
            Shape::PointCloud(_) => Ok(()),
        }
    }

    /// Axis-aligned bounding box in the obstacle frame; `None` for the unbounded half-space.
    /// Point-cloud boxes include the point radius.
    pub fn local_aabb(&self) -> Option<Aabb> {
        let sym = |h: Vector3<f64>| Some(Aabb::new(Point3::from(-h), Point3::from(h)));
        match self {
            Shape::Sphere { radius } => sym(Vector3::repeat(*radius)),
            Shape::Cuboid { half_extents } => sym(*half_extents),
            Shape::Cylinder {
                half_height,
                radius,
            } => sym(Vector3::new(*radius, *radius, *half_height)),
            Shape::Capsule {
                half_height,
                radius,
            } => sym(Vector3::new(*radius, *radius, half_height + radius)),
            Shape::HalfSpace => None,
            Shape::TriMesh(m) => Some(m.local_aabb()),
            Shape::PointCloud(pc) => Some(pc.local_aabb()),
        }
    }

    /// World axis-aligned bounding box for the obstacle at `pose`; `None` for the half-space. Tight for
    /// spheres, boxes, cylinders and capsules; for meshes and point clouds it is the box of the
    /// transformed vertices / transformed local box.
    pub fn aabb(&self, pose: &Isometry3<f64>) -> Option<Aabb> {
        let r = pose.rotation.to_rotation_matrix();
        let r = r.matrix();
        let c = Point3::from(pose.translation.vector);
        let around = |h: Vector3<f64>| Some(Aabb::new(c - h, c + h));
        match self {
            Shape::Sphere { radius } => around(Vector3::repeat(*radius)),
            Shape::Cuboid { half_extents } => around(r.abs() * half_extents),
            Shape::Cylinder {
                half_height,
                radius,
            } => {
                // Disc of radius ρ normal to a (= third column): extent ρ·sqrt(1 - a_i²) per axis.
                let a = r.column(2);
                let h = Vector3::from_fn(|i, _| {
                    half_height * a[i].abs() + radius * (1.0 - a[i] * a[i]).max(0.0).sqrt()
                });
                around(h)
            }
            Shape::Capsule {
                half_height,
                radius,
            } => {
                let a = r.column(2);
                around(Vector3::from_fn(|i, _| half_height * a[i].abs() + radius))
            }
            Shape::HalfSpace => None,
            Shape::TriMesh(m) => Some(m.aabb(pose)),
            Shape::PointCloud(pc) => Some(pc.local_aabb().transform_by(pose)),
        }
    }
}

/// A point cloud obstacle: points in the obstacle frame (m), each thickened by `radius` (m, >= 0), with
/// its own BVH over the points for nearest-point queries in O(log n).
#[derive(Clone)]
pub struct PointCloud {
    points: Vec<Point3<f64>>,
    radius: f64,
    bvh: Bvh,
    aabb: Aabb,
}

impl fmt::Debug for PointCloud {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "PointCloud {{ points: {}, radius: {} }}",
            self.points.len(),
            self.radius
        )
    }
}

impl PointCloud {
    /// Build a cloud from `points` (obstacle frame, m; at least one, all finite) and a thickness
    /// `radius` (m, finite, >= 0). The distance to the cloud is `min_i |p - s_i| - radius`.
    pub fn new(points: Vec<Vector3<f64>>, radius: f64) -> Result<PointCloud> {
        if points.is_empty() {
            return Err(FabricError::Value {
                what: "point cloud".into(),
                message: "needs at least one point".into(),
            });
        }
        if u32::try_from(points.len()).is_err() {
            return Err(FabricError::Value {
                what: "point cloud".into(),
                message: format!("too many points ({})", points.len()),
            });
        }
        if !points.iter().all(|p| p.iter().all(|c| c.is_finite())) {
            return Err(FabricError::NonFinite {
                what: "point cloud points".into(),
            });
        }
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(FabricError::Value {
                what: "point cloud radius".into(),
                message: format!("must be finite and >= 0, got {radius}"),
            });
        }
        let points: Vec<Point3<f64>> = points.into_iter().map(Point3::from).collect();
        let bvh = Bvh::from_iter(
            BvhBuildStrategy::Binned,
            points
                .iter()
                .enumerate()
                .map(|(i, p)| (i, Aabb::new(*p, *p))),
        );
        let mut aabb = Aabb::new(points[0], points[0]);
        for p in &points {
            aabb.mins = aabb.mins.inf(p);
            aabb.maxs = aabb.maxs.sup(p);
        }
        Ok(PointCloud {
            points,
            radius,
            bvh,
            aabb,
        })
    }

    /// The points, obstacle frame (m).
    pub fn points(&self) -> &[Point3<f64>] {
        &self.points
    }

    /// Thickness added around every point (m).
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// Box of the points enlarged by the radius, obstacle frame.
    pub fn local_aabb(&self) -> Aabb {
        let r = Vector3::repeat(self.radius);
        Aabb::new(self.aabb.mins - r, self.aabb.maxs + r)
    }

    /// Index of and distance to the point nearest to `p` (obstacle frame), among points whose distance
    /// to `p` (centre distance, radius not subtracted) is below `max_distance`; `None` when there is
    /// none. Ties go to the first one found by the BVH traversal (deterministic).
    pub fn nearest(&self, p: &Point3<f64>, max_distance: f64) -> Option<(usize, f64)> {
        if max_distance.is_nan() || max_distance <= 0.0 {
            return None;
        }
        let pts = &self.points;
        self.bvh
            .find_best(
                max_distance,
                |node: &BvhNode, _| aabb_distance(&node.mins(), &node.maxs(), p),
                |leaf, _| pts.get(leaf as usize).map(|s| (s - p).norm()),
            )
            .map(|(leaf, d)| (leaf as usize, d))
    }

    /// Indices of the points inside `aabb` (obstacle frame).
    pub fn points_in(&self, aabb: &Aabb) -> impl Iterator<Item = usize> + '_ {
        let aabb = *aabb;
        self.bvh
            .leaves(move |node: &BvhNode| boxes_overlap(&node.mins(), &node.maxs(), &aabb))
            .map(|i| i as usize)
    }
}

/// Euclidean distance from `p` to the box `[mins, maxs]` (0 inside).
pub(crate) fn aabb_distance(mins: &Point3<f64>, maxs: &Point3<f64>, p: &Point3<f64>) -> f64 {
    let e = Vector3::from_fn(|i, _| (mins[i] - p[i]).max(p[i] - maxs[i]).max(0.0));
    e.norm()
}

/// Signed distance from `p` to the box `[mins, maxs]`: Euclidean outside, minus the distance to the
/// nearest face inside. For any solid S inside the box, `aabb_signed_distance <= d_S(p)`, so it is a
/// valid lower bound for pruning signed-distance searches.
pub(crate) fn aabb_signed_distance(mins: &Point3<f64>, maxs: &Point3<f64>, p: &Point3<f64>) -> f64 {
    // Scalar code with plain comparisons (`fmax` compiles to one instruction; `f64::max` handles NaN
    // and costs several): this runs for every box visited. Inputs are finite (checked by the callers).
    let ex = fmax(mins.x - p.x, p.x - maxs.x);
    let ey = fmax(mins.y - p.y, p.y - maxs.y);
    let ez = fmax(mins.z - p.z, p.z - maxs.z);
    if ex <= 0.0 && ey <= 0.0 && ez <= 0.0 {
        return fmax(fmax(ex, ey), ez);
    }
    let (ox, oy, oz) = (fmax(ex, 0.0), fmax(ey, 0.0), fmax(ez, 0.0));
    (ox * ox + oy * oy + oz * oz).sqrt()
}

/// `max(a, b)` for non-NaN inputs, as a single comparison.
#[inline(always)]
pub(crate) fn fmax(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

/// Whether anything inside the box `[mins, maxs]` may be within signed distance `max` of `p`
/// (squared outside distance when `max >= 0`, signed box distance otherwise).
#[inline]
pub(crate) fn box_within(
    mins: &Point3<f64>,
    maxs: &Point3<f64>,
    p: &Point3<f64>,
    max: f64,
) -> bool {
    if max >= 0.0 {
        let ox = fmax(fmax(mins.x - p.x, p.x - maxs.x), 0.0);
        let oy = fmax(fmax(mins.y - p.y, p.y - maxs.y), 0.0);
        let oz = fmax(fmax(mins.z - p.z, p.z - maxs.z), 0.0);
        ox * ox + oy * oy + oz * oz <= max * max
    } else {
        aabb_signed_distance(mins, maxs, p) <= max
    }
}

fn boxes_overlap(mins: &Point3<f64>, maxs: &Point3<f64>, b: &Aabb) -> bool {
    (0..3).all(|i| mins[i] <= b.maxs[i] && maxs[i] >= b.mins[i])
}

/// One obstacle: a shape placed in the world (= robot base frame) by `pose`, moving with a constant
/// linear `velocity` (m/s, world frame) that [`crate::scene::Scene::advance`] integrates.
#[derive(Clone, Debug)]
pub struct Obstacle {
    /// Free-form name (for MoveIt scenes: the collision object id, see [`crate::scene::moveit`]).
    pub name: String,
    /// Geometry in the obstacle frame.
    pub shape: Shape,
    /// Pose of the obstacle frame in the world: `p_world = pose * p_local`.
    pub pose: Isometry3<f64>,
    /// Linear velocity of the obstacle (m/s, world frame).
    pub velocity: Vector3<f64>,
}

impl Obstacle {
    /// An obstacle at rest.
    pub fn new(name: impl Into<String>, shape: Shape, pose: Isometry3<f64>) -> Obstacle {
        Obstacle {
            name: name.into(),
            shape,
            pose,
            velocity: Vector3::zeros(),
        }
    }

    /// The same obstacle with linear velocity `v` (m/s, world frame).
    pub fn with_velocity(mut self, v: Vector3<f64>) -> Obstacle {
        self.velocity = v;
        self
    }

    /// Check the shape sizes ([`Shape::validate`]), the pose (finite, unit quaternion within 1e-6)
    /// and the velocity (finite).
    pub fn validate(&self) -> Result<()> {
        let what = format!("obstacle '{}'", self.name);
        self.shape.validate(&what)?;
        check_pose(&what, &self.pose)?;
        if !self.velocity.iter().all(|v| v.is_finite()) {
            return Err(FabricError::NonFinite {
                what: format!("{what}: velocity"),
            });
        }
        Ok(())
    }
}

/// `Ok` when the pose is finite and its quaternion has unit norm within 1e-6.
pub(crate) fn check_pose(what: &str, pose: &Isometry3<f64>) -> Result<()> {
    let q = pose.rotation.coords;
    if !(pose
        .translation
        .vector
        .iter()
        .chain(q.iter())
        .all(|v| v.is_finite()))
    {
        return Err(FabricError::NonFinite {
            what: format!("{what}: pose"),
        });
    }
    if (q.norm() - 1.0).abs() > 1e-6 {
        return Err(FabricError::Value {
            what: format!("{what}: pose"),
            message: format!("rotation quaternion has norm {}, expected 1", q.norm()),
        });
    }
    Ok(())
}
