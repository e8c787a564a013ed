//! Validation of joint configurations and trajectories against the robot's URDF collision geometry
//! (meshes and primitives), independently of the collision spheres that the fabric avoids obstacles with.
//!
//! The GFCS evaluation (GFCS Sec. V, Table I) counts a motion as a success when it reaches the goal
//! without collision; independent validators check every state against the robot's collision *meshes*.
//! The fabric's repulsion (GF Sec. VII-A) only sees collision spheres, so a trajectory whose spheres
//! clear every obstacle may still bring a mesh into contact: [`MeshChecker`] measures that exactly.
//!
//! * [`MeshChecker::new`] loads every URDF `<collision>` element of a [`Robot`] once (meshes scaled by
//!   their URDF `scale`; boxes, cylinders, capsules and spheres as parry shapes).
//! * [`MeshChecker::clearance`]: min over the shapes of the distance to the scene at q (m; ≤ 0 means
//!   contact or penetration), [`MeshChecker::trajectory_clearance`] for T states in parallel.
//! * [`MeshChecker::self_clearance`]: min over the self-collision shape pairs (links on different rigid
//!   bodies, not adjacent, not disabled by the SRDF: the rule of [`Robot::self_collision_pairs`] applied
//!   to links), [`MeshChecker::trajectory_self_clearance`].
//!
//! Frames: q in the order of [`Robot::joint_names`]; poses in the robot base frame (= the scene's world
//! frame). Distances are in metres, positive when separated. Queries are local: distances above
//! [`MeshChecker::max_distance`] (default [`DEFAULT_MAX_DISTANCE`]) are not computed and reported as
//! `f64::INFINITY`.

mod sweep;

pub use sweep::{MotionBounds, Sweep};

use std::collections::HashMap;
use std::fmt;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::Arc;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::query::{self, PointQuery};
use parry3d_f64::shape::{SharedShape, TriMesh};
use rayon::prelude::*;

use crate::error::{check_finite, FabricError, Result};
use crate::mesh_tree::{MeshTree, MeshTreeStack};
use crate::robot::{GeometryKind, KinematicsWorkspace, Robot};
use crate::rollout::batch::with_threads;
use crate::scene::meshio::{build_mesh, load_mesh};
use crate::scene::{Obstacle, Scene, Shape};

/// Default cutoff (m) of the clearance queries: obstacles farther than this from every collision shape
/// are not measured, and a state with nothing within it has clearance `f64::INFINITY`.
pub const DEFAULT_MAX_DISTANCE: f64 = 0.5;

/// Strides of the first two passes of [`MeshChecker::min_trajectory_clearance`] (the third takes the
/// remaining states). The first pass measures everything within `max_distance` and costs most per
/// state, so it visits few states; the later passes only measure near the minimum found so far.
const MIN_STRIDES: [usize; 2] = [32, 8];

/// One URDF `<collision>` element ready for distance queries.
#[derive(Clone)]
pub struct CollisionShape {
    /// Link index (see [`Robot::link_names`]).
    pub link: usize,
    /// Pose of the parry shape frame in the link frame: the URDF `<origin>`, followed for cylinders by a
    /// +90° rotation about x (parry's cylinder axis is y, URDF's is z).
    pub origin: Isometry3<f64>,
    /// The shape (mesh vertices in m after the URDF `scale`).
    pub shape: SharedShape,
    /// What the element is, for messages: `"mesh <path>"`, `"box"`, `"cylinder"`, `"capsule"`,
    /// `"sphere"`.
    pub label: String,
    /// Convex hull of a mesh's vertices (same frame as `shape`), `None` for primitives, flat meshes and
    /// convex meshes (a closed mesh that bounds the same solid as its hull is measured as that hull:
    /// `shape` is then the hull itself, [`convex_solid`]). The hull contains the mesh, so its distance to
    /// anything is a lower bound of the mesh's: queries measure hulls first and the exact mesh only where
    /// the bound can still change the minimum (branch and bound; the result is the exact mesh distance).
    pub hull: Option<SharedShape>,
    /// Box tree of a mesh's triangles, for mesh-mesh distances ([`MeshTree::distance`]) unless both meshes
    /// are convex; `None` for primitives.
    pub tree: Option<Arc<MeshTree>>,
    /// Box of `shape` in its own frame, computed once: a placed shape's box is this box transformed (as
    /// parry boxes a mesh; a convex polyhedron would visit every vertex at every pose).
    pub local_aabb: Aabb,
}

impl CollisionShape {
    /// The shape whose distances bound this shape's from below: the hull, or the shape itself.
    fn bound(&self) -> &dyn parry3d_f64::shape::Shape {
        match &self.hull {
            Some(h) => &**h,
            None => &*self.shape,
        }
    }

    /// The mesh, when this shape is a closed, outward-oriented (solid) triangle mesh.
    fn solid_mesh(&self) -> Option<&TriMesh> {
        self.shape
            .as_trimesh()
            .filter(|m| m.pseudo_normals_if_oriented().is_some())
    }
}

impl fmt::Debug for CollisionShape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CollisionShape")
            .field("link", &self.link)
            .field("label", &self.label)
            .field("origin", &self.origin)
            .finish()
    }
}

/// Per-thread scratch of a [`MeshChecker`]: forward kinematics and the world pose and box of each
/// collision shape. Create it once per thread with [`MeshChecker::workspace`]; it is reused without
/// allocation.
#[derive(Clone, Debug)]
pub struct MeshWorkspace {
    kinematics: KinematicsWorkspace,
    /// World pose of each collision shape, shape (S,).
    poses: Vec<Isometry3<f64>>,
    /// World AABB of each collision shape, shape (S,).
    boxes: Vec<Aabb>,
    /// (lower bound, shape or pair index) candidates of the exact pass (capacity S, or P pairs).
    order: Vec<(f64, usize)>,
    /// Scratch of the mesh-mesh distances.
    stack: MeshTreeStack,
}

/// Exact clearance of a robot's URDF collision geometry against a [`Scene`] and against itself.
///
/// Immutable and `Send + Sync`: share one checker across threads, each with its own
/// [`MeshWorkspace`]. It owns a clone of the robot it was built from.
#[derive(Clone)]
pub struct MeshChecker {
    robot: Robot,
    shapes: Vec<CollisionShape>,
    /// Shape index pairs `(i, j)`, `i < j`, checked for self-collision.
    self_pairs: Vec<(usize, usize)>,
    /// Shape index pairs `(i, j)`, `i < j`, that locked joints hold still relative to each other (see
    /// [`held_shape_pairs`]): constant over every motion, so checked at endpoints only.
    held_pairs: Vec<(usize, usize)>,
    /// Shape index pairs `(i, j)`, `i < j`, on adjacent rigid bodies that a loaded SRDF leaves enabled (see
    /// [`adjacent_shape_pairs`]): checked at endpoints only.
    adjacent_pairs: Vec<(usize, usize)>,
    max_distance: f64,
}

impl fmt::Debug for MeshChecker {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MeshChecker")
            .field("robot", &self.robot.name())
            .field("shapes", &self.shapes)
            .field("self_pairs", &self.self_pairs.len())
            .field("max_distance", &self.max_distance)
            .finish()
    }
}

/// `Mesh` error naming the file and the link.
fn mesh_error(path: &str, link: &str, message: impl fmt::Display) -> FabricError {
    FabricError::Mesh {
        path: path.to_string(),
        message: format!("collision mesh of link '{link}': {message}"),
    }
}

/// Load a collision mesh and apply its URDF per-axis `scale`. A non-unit scale rebuilds the mesh with
/// [`build_mesh`], so that its solidity and outward orientation are decided again (a mirroring scale
/// flips the triangles, which the signed volume test corrects).
fn load_scaled_mesh(path: &Path, scale: &Vector3<f64>, link: &str) -> Result<TriMesh> {
    let source = path.display().to_string();
    if scale.iter().any(|s| !s.is_finite() || *s == 0.0) {
        return Err(mesh_error(
            &source,
            link,
            format!(
                "scale [{}, {}, {}] must be finite and non-zero",
                scale.x, scale.y, scale.z
            ),
        ));
    }
    let mesh = load_mesh(path).map_err(|e| match e {
        FabricError::Mesh { message, .. } => mesh_error(&source, link, message),
        other => other,
    })?;
    if *scale == Vector3::repeat(1.0) {
        return Ok(mesh);
    }
    let vertices = mesh
        .vertices()
        .iter()
        .map(|v| Point3::from(v.coords.component_mul(scale)))
        .collect();
    build_mesh(vertices, mesh.indices().to_vec(), &source).map_err(|e| match e {
        FabricError::Mesh { message, .. } => mesh_error(&source, link, message),
        other => other,
    })
}

/// Shape index pairs `(i, j)`, `i < j`, whose links the SRDF does not disable
/// ([`Robot::disabled_collisions`]) and for which `keep(link i, link j)` holds.
fn enabled_shape_pairs(
    robot: &Robot,
    shapes: &[CollisionShape],
    keep: impl Fn(usize, usize) -> bool,
) -> Vec<(usize, usize)> {
    let disabled = robot.disabled_collisions();
    let mut pairs = Vec::new();
    for (i, a) in shapes.iter().enumerate() {
        for (j, b) in shapes.iter().enumerate().skip(i + 1) {
            let link_pair = (a.link.min(b.link), a.link.max(b.link));
            if keep(a.link, b.link) && !disabled.contains(&link_pair) {
                pairs.push((i, j));
            }
        }
    }
    pairs
}

/// Whether rigid bodies `a` and `b` are one movable joint apart: `adjacent` from [`adjacent_bodies`].
fn are_adjacent(adjacent: &[(usize, usize)], a: usize, b: usize) -> bool {
    adjacent.binary_search(&(a.min(b), a.max(b))).is_ok()
}

/// Shape index pairs checked for self-collision: shapes on links of different rigid bodies
/// ([`Robot::rigid_bodies`]) that are not adjacent (one movable joint between the bodies) and whose
/// links are not disabled by the SRDF ([`Robot::disabled_collisions`]).
fn self_shape_pairs(robot: &Robot, shapes: &[CollisionShape]) -> Vec<(usize, usize)> {
    let (bodies, adjacent) = (robot.rigid_bodies(), adjacent_bodies(robot));
    enabled_shape_pairs(robot, shapes, |a, b| {
        bodies[a] != bodies[b] && !are_adjacent(&adjacent, bodies[a], bodies[b])
    })
}

/// Pairs (smaller, larger) of rigid bodies ([`Robot::rigid_bodies`]) joined by one movable joint, sorted.
fn adjacent_bodies(robot: &Robot) -> Vec<(usize, usize)> {
    let bodies = robot.rigid_bodies();
    let mut adjacent: Vec<(usize, usize)> = (0..bodies.len())
        .filter_map(|child| {
            let parent = robot.link_parent(child)?;
            let (bp, bc) = (*bodies.get(parent)?, *bodies.get(child)?);
            (bp != bc).then(|| (bp.min(bc), bp.max(bc)))
        })
        .collect();
    adjacent.sort_unstable();
    adjacent
}

/// Shape index pairs on adjacent rigid bodies (one movable joint between them) whose links a loaded SRDF
/// does not disable; none without an SRDF. The planner never measures adjacent links (their meshes
/// usually meet at the joint); MoveIt checks every pair its SRDF leaves enabled, and MoveIt Setup Assistant
/// disables adjacent ones, but an SRDF written for another tool may not ([`MeshChecker::adjacent_contacts`]).
fn adjacent_shape_pairs(robot: &Robot, shapes: &[CollisionShape]) -> Vec<(usize, usize)> {
    if !robot.has_srdf() {
        return Vec::new();
    }
    let (bodies, adjacent) = (robot.rigid_bodies(), adjacent_bodies(robot));
    enabled_shape_pairs(robot, shapes, |a, b| {
        bodies[a] != bodies[b] && are_adjacent(&adjacent, bodies[a], bodies[b])
    })
}

/// Rigid-body label of each link when only fixed joints join links (locked joints count as moving):
/// the bodies of the whole robot, whatever its active joints.
fn fixed_bodies(robot: &Robot) -> Vec<usize> {
    let mut bodies: Vec<usize> = (0..robot.joints.len()).collect();
    for (child, joint) in robot.joints.iter().enumerate() {
        if let Some(j) = joint {
            if !j.movable {
                bodies[child] = bodies[j.parent];
            }
        }
    }
    bodies
}

/// Shape index pairs that the robot's locked joints hold still relative to each other: shapes on links of
/// one rigid body ([`Robot::rigid_bodies`]) that are on different bodies of the whole robot
/// ([`fixed_bodies`]) and whose links the SRDF does not disable. MoveIt checks such a pair like any other,
/// adjacent links included (MoveIt Setup Assistant disables those; an SRDF written for another tool may
/// not); no motion of the active joints changes its distance, so a pair in contact at the held joint values
/// puts every state in collision ([`MeshChecker::held_contacts`]).
fn held_shape_pairs(robot: &Robot, shapes: &[CollisionShape]) -> Vec<(usize, usize)> {
    let (rigid, bodies) = (robot.rigid_bodies(), fixed_bodies(robot));
    enabled_shape_pairs(robot, shapes, |a, b| {
        rigid[a] == rigid[b] && bodies[a] != bodies[b]
    })
}

/// Whether `inner` lies inside `outer` (closed boxes).
fn aabb_inside(inner: &Aabb, outer: &Aabb) -> bool {
    (0..3).all(|k| inner.mins[k] >= outer.mins[k] && inner.maxs[k] <= outer.maxs[k])
}

/// Euclidean gap between two boxes (0 when they overlap): a lower bound of the distance between
/// anything inside them.
fn aabb_gap(a: &Aabb, b: &Aabb) -> f64 {
    Vector3::from_fn(|k, _| (b.mins[k] - a.maxs[k]).max(a.mins[k] - b.maxs[k]).max(0.0)).norm()
}

/// A point inside (or on) an obstacle, when the obstacle is bounded and solid-or-surface: the centre of
/// a sphere, box, cylinder or capsule, the first vertex of a mesh. `None` for half-spaces and point clouds
/// (the scene's point-cloud query already tests each point against the shape).
fn obstacle_point(o: &Obstacle) -> Option<Point3<f64>> {
    match &o.shape {
        Shape::Sphere { .. }
        | Shape::Cuboid { .. }
        | Shape::Cylinder { .. }
        | Shape::Capsule { .. } => Some(Point3::from(o.pose.translation.vector)),
        Shape::TriMesh(m) => m.vertices().first().map(|v| o.pose * v),
        Shape::HalfSpace | Shape::PointCloud(_) => None,
    }
}

/// Clearance ≤ 0 when an obstacle lies wholly inside a solid link mesh, `None` otherwise.
///
/// Mesh distances in parry are surface-to-surface (a mesh is a set of triangles), so an obstacle
/// enclosed by a link mesh without touching its triangles would read as separated. An enclosed obstacle
/// has its box inside the mesh's box and its reference point ([`obstacle_point`]) inside the mesh; the
/// value returned is then `-(depth of that point below the mesh surface)`, a penetration whose magnitude
/// may underestimate the true one (the sign is what matters).
fn enclosed_clearance(
    mesh: &TriMesh,
    pose: &Isometry3<f64>,
    mesh_box: &Aabb,
    obstacles: &[&Obstacle],
) -> Option<f64> {
    let mut best: Option<f64> = None;
    for o in obstacles {
        let Some(obox) = o.shape.aabb(&o.pose) else {
            continue;
        };
        if !aabb_inside(&obox, mesh_box) {
            continue;
        }
        let Some(p) = obstacle_point(o) else { continue };
        if !mesh.contains_point(pose, &p) {
            continue;
        }
        let surface = mesh.project_point(pose, &p, false).point;
        let d = -(p - surface).norm();
        if !matches!(best, Some(b) if b <= d) {
            best = Some(d);
        }
    }
    best
}

/// [`enclosed_clearance`] of the obstacles enclosed by shape `s` placed at `pose` (box `aabb`), when it is a
/// solid mesh.
fn enclosed_by(
    s: &CollisionShape,
    pose: &Isometry3<f64>,
    aabb: &Aabb,
    obstacles: &[&Obstacle],
) -> Option<f64> {
    enclosed_clearance(s.solid_mesh()?, pose, aabb, obstacles)
}

/// Distance between two placed parry shapes: positive when separated, the (negative) penetration depth
/// from `parry::query::contact` when they intersect and parry supports the pair, 0 for an intersection it
/// cannot measure; `None` when parry has no distance for the pair.
fn pair_distance(
    pa: &Isometry3<f64>,
    a: &dyn parry3d_f64::shape::Shape,
    pb: &Isometry3<f64>,
    b: &dyn parry3d_f64::shape::Shape,
) -> Option<f64> {
    match query::distance(pa, a, pb, b) {
        Ok(d) if d > 0.0 => Some(d),
        Ok(_) => Some(match query::contact(pa, a, pb, b, 0.0) {
            Ok(Some(c)) => c.dist.min(0.0),
            _ => 0.0,
        }),
        Err(_) => None,
    }
}

/// A URDF box of full sizes `size` (m) centred on its frame, as the convex polyhedron of its eight
/// corners rather than a parry `Cuboid`: parry 0.25's dedicated cuboid-cuboid `distance` (a SAT-based
/// closest-points routine) overestimates the gap of separated boxes (dimforge/parry issue #431; e.g.
/// 0.714 m instead of 0.7 m for two axis-aligned cubes), while the polyhedron goes through the general
/// GJK / EPA support-map path, which is exact. Same solid, same frame.
fn box_shape(size: &Vector3<f64>) -> SharedShape {
    let h = size / 2.0;
    let corners: Vec<Point3<f64>> = (0..8)
        .map(|k| {
            let sign = |bit: usize| if k & bit == 0 { -1.0 } else { 1.0 };
            Point3::new(sign(1) * h.x, sign(2) * h.y, sign(4) * h.z)
        })
        .collect();
    SharedShape::convex_hull(&corners).unwrap_or_else(|| SharedShape::cuboid(h.x, h.y, h.z))
}

/// Slack (m) on hull lower bounds before they prune an exact query, for GJK round-off.
const BOUND_SLACK: f64 = 1e-9;

/// Convex hull of a mesh's vertices, `None` for a flat mesh (or if parry's hull fails on it).
fn mesh_hull(mesh: &TriMesh) -> Option<SharedShape> {
    let points = mesh.vertices();
    catch_unwind(AssertUnwindSafe(|| SharedShape::convex_hull(points)))
        .ok()
        .flatten()
}

/// How far (m) a hull vertex may lie in front of a mesh triangle's plane for that triangle to count as
/// lying on the hull's boundary ([`convex_solid`]): mesh files store coordinates in single precision
/// (~10⁻⁸ m on a link of 0.1 m), far below this, and the distances of the mesh and of its hull differ by
/// at most this much.
const CONVEX_TOL: f64 = 1e-6;

/// Triangles × hull vertices beyond which [`convex_solid`] does not test a mesh (it then counts as not
/// convex, and is measured exactly as a mesh): the test costs one dot product per pair.
const CONVEX_TEST_LIMIT: usize = 20_000_000;

/// Whether the closed, outward-oriented (solid) `mesh` bounds the same solid as its convex `hull`: every
/// triangle lies in a supporting plane of the hull (no hull vertex more than [`CONVEX_TOL`] in front of
/// it). The solid is then the intersection of those half-spaces, which contains the hull and is
/// contained in it (its vertices are the mesh's), so measuring the hull is measuring the mesh: one convex
/// query instead of the triangles of the mesh behind its hull bound (convex collision meshes, such as
/// the shipped Panda's polytopes, are common). Open or inward meshes, and meshes above
/// [`CONVEX_TEST_LIMIT`], are not.
fn convex_solid(mesh: &TriMesh, hull: &SharedShape) -> bool {
    let Some(poly) = hull.as_convex_polyhedron() else {
        return false;
    };
    let corners = poly.points();
    let (vertices, triangles) = (mesh.vertices(), mesh.indices());
    if mesh.pseudo_normals_if_oriented().is_none()
        || triangles.len().saturating_mul(corners.len()) > CONVEX_TEST_LIMIT
    {
        return false;
    }
    triangles.iter().all(|t| {
        let a = vertices[t[0] as usize];
        let n = (vertices[t[1] as usize] - a).cross(&(vertices[t[2] as usize] - a));
        let norm = n.norm();
        // a sliver without a plane of its own lies on the planes of its neighbours
        norm <= f64::EPSILON * (vertices[t[1] as usize] - a).norm_squared()
            || corners.iter().all(|c| n.dot(&(c - a)) <= CONVEX_TOL * norm)
    })
}

impl MeshChecker {
    /// Build a checker from the `<collision>` elements of `robot` ([`Robot::collision_geometry`]); the
    /// checker keeps a clone of the robot. Every mesh file is read once (elements sharing a file and a
    /// scale share the shape). The cutoff is [`DEFAULT_MAX_DISTANCE`].
    ///
    /// Errors: `Mesh` naming the file and the link when a mesh file is missing, unreadable, malformed or
    /// has a zero / non-finite scale; `Value` when the robot has no collision geometry at all (e.g. the
    /// shipped [`Robot::panda`], which carries spheres only).
    pub fn new(robot: &Robot) -> Result<MeshChecker> {
        let geometry = robot.collision_geometry();
        if geometry.is_empty() {
            return Err(FabricError::Value {
                what: format!("robot '{}'", robot.name()),
                message: "has no URDF <collision> geometry to check (load a URDF with collision meshes or primitives)"
                    .to_string(),
            });
        }
        // The distinct meshes by (file, scale bits): elements sharing both share the shapes (mesh, hull,
        // tree), `mesh_of` holds each element's index into them. They load in parallel (each independent of
        // the others); the error reported is the first missing file in element order, else the first mesh
        // that fails to load.
        type Loaded = (SharedShape, Option<SharedShape>, Option<Arc<MeshTree>>);
        let mut wanted: Vec<(&Path, &Vector3<f64>, String)> = Vec::new();
        let mut index: HashMap<(&Path, [u64; 3]), usize> = HashMap::new();
        let mut mesh_of = vec![usize::MAX; geometry.len()];
        for (e, g) in geometry.iter().enumerate() {
            if let GeometryKind::Mesh {
                path,
                scale,
                exists,
            } = &g.kind
            {
                let link_name = robot
                    .link_names()
                    .get(g.link)
                    .cloned()
                    .unwrap_or_else(|| format!("#{}", g.link));
                if !exists {
                    return Err(mesh_error(
                        &path.display().to_string(),
                        &link_name,
                        "file not found (mesh paths resolve against the robot's mesh_dir; a package:// path also in the \
                         folder of the package.xml naming its package, below mesh_dir or ROS_PACKAGE_PATH)",
                    ));
                }
                let key = (
                    path.as_path(),
                    [scale.x.to_bits(), scale.y.to_bits(), scale.z.to_bits()],
                );
                mesh_of[e] = *index.entry(key).or_insert_with(|| {
                    wanted.push((path.as_path(), scale, link_name));
                    wanted.len() - 1
                });
            }
        }
        let loads: Vec<Result<Loaded>> = wanted
            .par_iter()
            .map(|(path, scale, link_name)| {
                let mesh = load_scaled_mesh(path, scale, link_name)?;
                let hull = mesh_hull(&mesh);
                let tree = MeshTree::new(&mesh).map(Arc::new);
                if let Some(hull) = hull.as_ref().filter(|h| convex_solid(&mesh, h)) {
                    // a convex solid is its hull: measured exactly by it, with no lower bound to refine;
                    // the triangle tree stays for distances to non-convex meshes
                    return Ok((hull.clone(), None, tree));
                }
                Ok((SharedShape::new(mesh), hull, tree))
            })
            .collect();
        let loaded = loads.into_iter().collect::<Result<Vec<Loaded>>>()?;
        let mut shapes = Vec::with_capacity(geometry.len());
        for (e, g) in geometry.iter().enumerate() {
            let mut origin = g.origin;
            let (shape, hull, tree, label) = match &g.kind {
                GeometryKind::Mesh { path, .. } => {
                    let (shape, hull, tree) = loaded[mesh_of[e]].clone();
                    (shape, hull, tree, format!("mesh {}", path.display()))
                }
                GeometryKind::Box { size } => (box_shape(size), None, None, "box".to_string()),
                GeometryKind::Cylinder { radius, length } => {
                    origin *= Isometry3::from_parts(
                        Translation3::identity(),
                        UnitQuaternion::from_axis_angle(
                            &Vector3::x_axis(),
                            std::f64::consts::FRAC_PI_2,
                        ),
                    );
                    (
                        SharedShape::cylinder(length / 2.0, *radius),
                        None,
                        None,
                        "cylinder".to_string(),
                    )
                }
                GeometryKind::Capsule { radius, length } => (
                    SharedShape::capsule_z(length / 2.0, *radius),
                    None,
                    None,
                    "capsule".to_string(),
                ),
                GeometryKind::Sphere { radius } => {
                    (SharedShape::ball(*radius), None, None, "sphere".to_string())
                }
            };
            shapes.push(CollisionShape {
                link: g.link,
                origin,
                local_aabb: shape.compute_local_aabb(),
                shape,
                label,
                hull,
                tree,
            });
        }
        let self_pairs = self_shape_pairs(robot, &shapes);
        let held_pairs = held_shape_pairs(robot, &shapes);
        let adjacent_pairs = adjacent_shape_pairs(robot, &shapes);
        Ok(MeshChecker {
            robot: robot.clone(),
            shapes,
            self_pairs,
            held_pairs,
            adjacent_pairs,
            max_distance: DEFAULT_MAX_DISTANCE,
        })
    }

    /// The same checker with another cutoff `max` (m, ≥ 0; `f64::INFINITY` measures every distance).
    /// Errors: `Value` for a negative or NaN cutoff.
    pub fn with_max_distance(mut self, max: f64) -> Result<MeshChecker> {
        if max.is_nan() || max < 0.0 {
            return Err(FabricError::Value {
                what: "max_distance".to_string(),
                message: format!("must be >= 0 m, got {max}"),
            });
        }
        self.max_distance = max;
        Ok(self)
    }

    /// Cutoff (m): clearances above it are reported as `f64::INFINITY`.
    pub fn max_distance(&self) -> f64 {
        self.max_distance
    }

    /// The robot (a clone of the one given to [`MeshChecker::new`]); q follows its joint order.
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The collision shapes, in URDF order (one per `<collision>` element).
    pub fn shapes(&self) -> &[CollisionShape] {
        &self.shapes
    }

    /// Number of collision shapes S.
    pub fn num_shapes(&self) -> usize {
        self.shapes.len()
    }

    /// Shape index pairs `(i, j)`, `i < j`, checked by [`MeshChecker::self_clearance`].
    pub fn self_pairs(&self) -> &[(usize, usize)] {
        &self.self_pairs
    }

    /// Shape index pairs `(i, j)`, `i < j`, that locked joints hold still relative to each other
    /// ([`MeshChecker::held_contacts`]).
    pub fn held_pairs(&self) -> &[(usize, usize)] {
        &self.held_pairs
    }

    /// A fresh per-thread workspace.
    pub fn workspace(&self) -> MeshWorkspace {
        let s = self.shapes.len();
        MeshWorkspace {
            kinematics: KinematicsWorkspace::new(&self.robot),
            poses: vec![Isometry3::identity(); s],
            boxes: vec![Aabb::new_invalid(); s],
            order: Vec::with_capacity(s.max(self.self_pairs.len())),
            stack: MeshTreeStack::new(),
        }
    }

    /// Forward kinematics at q, then the world pose (link pose · origin) and box of every shape.
    fn place(&self, q: &[f64], ws: &mut MeshWorkspace) -> Result<()> {
        if ws.poses.len() != self.shapes.len() || ws.boxes.len() != self.shapes.len() {
            return Err(FabricError::Shape {
                what: "mesh workspace (shapes)".to_string(),
                expected: format!("({},)", self.shapes.len()),
                got: format!("({},)", ws.poses.len()),
            });
        }
        self.robot.update_positions(q, &mut ws.kinematics)?;
        for ((s, pose), aabb) in self.shapes.iter().zip(&mut ws.poses).zip(&mut ws.boxes) {
            *pose = self.robot.link_pose(&ws.kinematics, s.link) * s.origin;
            *aabb = s.local_aabb.transform_by(pose);
        }
        Ok(())
    }

    /// World poses of every collision shape at q (dof,): shape (S,), in [`MeshChecker::shapes`] order.
    /// Errors: `Shape`, `NonFinite` for a bad q.
    pub fn shape_poses(&self, q: &[f64]) -> Result<Vec<Isometry3<f64>>> {
        let mut ws = self.workspace();
        self.place(q, &mut ws)?;
        Ok(ws.poses)
    }

    /// Clearance at q with the obstacles gathered once by the caller.
    ///
    /// Branch and bound: pass 1 measures primitives exactly and meshes by their hulls (a lower bound);
    /// pass 2 measures the meshes exactly in increasing order of their bounds until the bound reaches
    /// the minimum found so far. Distances at or above `cutoff` (m) are not measured: the result is
    /// exact when below min(cutoff, max_distance), and otherwise some value at or above it, or +∞.
    fn clearance_in(
        &self,
        scene: &Scene,
        obstacles: &[&Obstacle],
        q: &[f64],
        cutoff: f64,
        ws: &mut MeshWorkspace,
    ) -> Result<f64> {
        self.place(q, ws)?;
        let max = self.max_distance.min(cutoff);
        let mut best = f64::INFINITY;
        ws.order.clear();
        for (i, (s, pose)) in self.shapes.iter().zip(&ws.poses).enumerate() {
            let slack = if s.hull.is_some() { BOUND_SLACK } else { 0.0 };
            let Some(d) =
                scene.boxed_shape_distance(s.bound(), pose, &ws.boxes[i], best.min(max) + slack)
            else {
                continue;
            };
            if s.hull.is_some() {
                ws.order.push((d, i));
            } else {
                best = best.min(d);
            }
        }
        ws.order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for &(bound, i) in &ws.order {
            if bound - BOUND_SLACK >= best.min(max) {
                break;
            }
            let (s, pose) = (&self.shapes[i], &ws.poses[i]);
            if let Some(d) =
                scene.boxed_shape_distance(&*s.shape, pose, &ws.boxes[i], best.min(max))
            {
                best = best.min(d);
            }
            // An obstacle enclosed by the mesh is inside its hull too: the bound is then <= 0.
            if bound <= 0.0 {
                if let Some(d) = enclosed_by(s, pose, &ws.boxes[i], obstacles) {
                    best = best.min(d);
                }
            }
        }
        Ok(best)
    }

    /// Clearance of each collision shape at q against the scene into `out` (S,): its distance as in
    /// [`MeshChecker::clearance_in`] (obstacles enclosed by a solid link mesh count as contact), exact
    /// below min(`cutoff`, max distance) and +∞ where no obstacle lies that near.
    fn shape_clearances_in(
        &self,
        scene: &Scene,
        obstacles: &[&Obstacle],
        q: &[f64],
        cutoff: f64,
        ws: &mut MeshWorkspace,
        out: &mut [f64],
    ) -> Result<()> {
        self.place(q, ws)?;
        let max = self.max_distance.min(cutoff);
        for (i, (s, pose)) in self.shapes.iter().zip(&ws.poses).enumerate() {
            out[i] = f64::INFINITY;
            let slack = if s.hull.is_some() { BOUND_SLACK } else { 0.0 };
            let Some(bound) =
                scene.boxed_shape_distance(s.bound(), pose, &ws.boxes[i], max + slack)
            else {
                continue;
            };
            if s.hull.is_none() {
                out[i] = bound;
                continue;
            }
            if let Some(d) = scene.boxed_shape_distance(&*s.shape, pose, &ws.boxes[i], max) {
                out[i] = d;
            }
            if bound <= 0.0 {
                if let Some(d) = enclosed_by(s, pose, &ws.boxes[i], obstacles) {
                    out[i] = out[i].min(d);
                }
            }
        }
        Ok(())
    }

    /// Distance of each self-collision pair ([`MeshChecker::self_pairs`]) at q into `out` (P,), exact up to
    /// `max` (m) and +∞ beyond (pairs whose box gap or hull distance exceeds it are not measured); two
    /// meshes in contact read parry's (negative) penetration depth with `depth`, 0 without (a contact
    /// verdict needs no depth, and the depth of two overlapping meshes costs far more than the contact).
    fn pair_distances_within(
        &self,
        q: &[f64],
        (max, depth): (f64, bool),
        ws: &mut MeshWorkspace,
        out: &mut [f64],
    ) -> Result<()> {
        self.distances_of_pairs_within(&self.self_pairs, q, (max, depth), ws, out)
    }

    /// [`MeshChecker::pair_distances_within`] for the shape pairs `pairs`.
    fn distances_of_pairs_within(
        &self,
        pairs: &[(usize, usize)],
        q: &[f64],
        (max, depth): (f64, bool),
        ws: &mut MeshWorkspace,
        out: &mut [f64],
    ) -> Result<()> {
        self.place(q, ws)?;
        for (k, &(i, j)) in pairs.iter().enumerate() {
            out[k] = f64::INFINITY;
            if aabb_gap(&ws.boxes[i], &ws.boxes[j]) - BOUND_SLACK > max {
                continue;
            }
            let (a, b) = (&self.shapes[i], &self.shapes[j]);
            if a.hull.is_some() || b.hull.is_some() {
                let bound = pair_distance(&ws.poses[i], a.bound(), &ws.poses[j], b.bound())
                    .unwrap_or(f64::NEG_INFINITY);
                if bound - BOUND_SLACK > max {
                    continue;
                }
            }
            let d = self.pair_exact((i, j), &ws.poses, &mut ws.stack, (max, depth))?;
            if d <= max {
                out[k] = d;
            }
        }
        Ok(())
    }

    /// Run `row(workspace, q, out)` on every state of `qs` (T × dof row-major) in parallel, each filling
    /// a row of `width` values: T × `width` row-major, in state order whatever the thread count.
    fn per_state_rows(
        &self,
        qs: &[f64],
        threads: Option<usize>,
        width: usize,
        row: impl Fn(&mut MeshWorkspace, &[f64], &mut [f64]) -> Result<()> + Sync + Send,
    ) -> Result<Vec<f64>> {
        let n = self.states(qs)?;
        let mut out = vec![f64::INFINITY; n * width];
        if n == 0 || width == 0 {
            return Ok(out);
        }
        let dof = self.robot.dof();
        with_threads(threads, || {
            qs.par_chunks(dof)
                .zip(out.par_chunks_mut(width))
                .try_for_each_init(|| self.workspace(), |ws, (q, o)| row(ws, q, o))
        })??;
        Ok(out)
    }

    /// The clearance of every collision shape ([`MeshChecker::shapes`]) to `scene` at every state of
    /// `qs` (T × dof row-major): T × S row-major (m), each exact below min(`cutoff`, max distance) and
    /// +∞ where no obstacle lies that near; the minimum of a row is [`MeshChecker::clearance`] (where
    /// below the cutoff). Which link touches what, per state, e.g. for the gradients of a path repair
    /// that must move two links off two obstacles at once. Parallel as
    /// [`MeshChecker::trajectory_clearance`].
    ///
    /// Errors: as [`MeshChecker::trajectory_clearance`].
    pub fn trajectory_shape_clearances(
        &self,
        scene: &Scene,
        qs: &[f64],
        threads: Option<usize>,
        cutoff: f64,
    ) -> Result<Vec<f64>> {
        let obstacles: Vec<&Obstacle> = scene.iter().map(|(_, o)| o).collect();
        self.per_state_rows(qs, threads, self.shapes.len(), |ws, q, out| {
            self.shape_clearances_in(scene, &obstacles, q, cutoff, ws, out)
        })
    }

    /// The distance of every self-collision pair ([`MeshChecker::self_pairs`]) at every state of `qs`:
    /// T × P row-major (m), exact below min(`cutoff`, max distance), +∞ beyond; in contact, negative
    /// penetration depths with `depth`, and without, 0 for two meshes that are not both convex (contact
    /// verdicts, e.g. a collision matrix; convex shapes read their depth, which costs little); the minimum
    /// of a row is [`MeshChecker::self_clearance`] (where below the cutoff).
    ///
    /// Errors: as [`MeshChecker::trajectory_self_clearance`].
    pub fn trajectory_pair_clearances(
        &self,
        qs: &[f64],
        threads: Option<usize>,
        cutoff: f64,
        depth: bool,
    ) -> Result<Vec<f64>> {
        let max = self.max_distance.min(cutoff);
        self.per_state_rows(qs, threads, self.self_pairs.len(), |ws, q, out| {
            self.pair_distances_within(q, (max, depth), ws, out)
        })
    }

    /// Clearance (m) of the collision geometry at q (dof, joint order of [`MeshChecker::robot`]) against
    /// `scene`: the minimum over the shapes of [`Scene::shape_distance`] (positive when separated,
    /// negative penetration depth or 0 when in contact), with obstacles wholly enclosed by a solid link
    /// mesh counted as contact. `f64::INFINITY` when no obstacle is within
    /// [`MeshChecker::max_distance`] of any shape (or the scene is empty).
    ///
    /// Positive values are exact distances. Negative values of a mesh are the penetration depths parry
    /// reports against its triangles, which underestimate the solid's once an obstacle crosses deeper
    /// than the nearest face: read them as "in contact", not as a depth.
    ///
    /// Errors: `Shape` (q of the wrong length), `NonFinite`.
    pub fn clearance(&self, scene: &Scene, q: &[f64]) -> Result<f64> {
        let obstacles: Vec<&Obstacle> = scene.iter().map(|(_, o)| o).collect();
        self.clearance_in(scene, &obstacles, q, f64::INFINITY, &mut self.workspace())
    }

    /// Number of states in `qs` (T × dof row-major), checked.
    fn states(&self, qs: &[f64]) -> Result<usize> {
        let dof = self.robot.dof();
        if qs.len().checked_rem(dof) != Some(0) {
            return Err(FabricError::Shape {
                what: "qs".to_string(),
                expected: format!("(T*{dof},)"),
                got: format!("({},)", qs.len()),
            });
        }
        check_finite("qs", qs)?;
        Ok(qs.len().checked_div(dof).unwrap_or(0))
    }

    /// Run `per_state(workspace, q)` on every state of `qs` (T × dof row-major) in parallel; results in
    /// state order whatever the thread count.
    fn per_state(
        &self,
        qs: &[f64],
        threads: Option<usize>,
        f: impl Fn(&mut MeshWorkspace, &[f64]) -> Result<f64> + Sync + Send,
    ) -> Result<Vec<f64>> {
        let n = self.states(qs)?;
        if n == 0 {
            return Ok(Vec::new());
        }
        let dof = self.robot.dof();
        with_threads(threads, || {
            qs.par_chunks(dof)
                .map_init(|| self.workspace(), |ws, q| f(ws, q))
                .collect::<Result<Vec<f64>>>()
        })?
    }

    /// [`MeshChecker::clearance`] of every state of a trajectory: `qs` is T × dof row-major (rad or m),
    /// the result has shape (T,). Evaluated in parallel with rayon: on a dedicated pool of `threads`
    /// threads, or on the current pool when `None`; the result does not depend on it.
    ///
    /// Errors: `Shape` (length not a multiple of dof), `NonFinite`, `Value` (`threads` = 0).
    pub fn trajectory_clearance(
        &self,
        scene: &Scene,
        qs: &[f64],
        threads: Option<usize>,
    ) -> Result<Vec<f64>> {
        self.trajectory_clearance_within(scene, qs, threads, f64::INFINITY)
    }

    /// [`MeshChecker::trajectory_clearance`] measured up to `cutoff` (m, > 0; +∞: all): each value is
    /// exact where it is below `cutoff` and otherwise some value at or above it, or +∞. Shape pairs
    /// whose bounds lie beyond `cutoff` are not measured, which spares most of the cost of states away
    /// from contact (e.g. the constraint values of a path repair, which only needs the near ones).
    ///
    /// Errors: as [`MeshChecker::trajectory_clearance`].
    pub fn trajectory_clearance_within(
        &self,
        scene: &Scene,
        qs: &[f64],
        threads: Option<usize>,
        cutoff: f64,
    ) -> Result<Vec<f64>> {
        let obstacles: Vec<&Obstacle> = scene.iter().map(|(_, o)| o).collect();
        self.per_state(qs, threads, |ws, q| {
            self.clearance_in(scene, &obstacles, q, cutoff, ws)
        })
    }

    /// Distance of the self-collision pair `(i, j)` at world `poses` (S,), exact when below `cutoff` (m) and
    /// otherwise some value at or above it; `Err(Value)` naming both elements when parry cannot
    /// measure it. Two meshes are measured by their trees ([`MeshTree::distance`]); when they touch,
    /// parry's penetration depth (negative) is asked for only with `depth`, and the contact is
    /// otherwise reported as 0.
    fn pair_exact(
        &self,
        (i, j): (usize, usize),
        poses: &[Isometry3<f64>],
        stack: &mut MeshTreeStack,
        (cutoff, depth): (f64, bool),
    ) -> Result<f64> {
        let (a, b) = (&self.shapes[i], &self.shapes[j]);
        // two meshes by their triangle trees, unless both are convex (one GJK query measures those)
        let trees = match (&a.tree, &b.tree) {
            (Some(ta), Some(tb)) if !(a.shape.is_convex() && b.shape.is_convex()) => Some((ta, tb)),
            _ => None,
        };
        if let Some((ta, tb)) = trees {
            let d = ta.distance(&poses[i], tb, &poses[j], cutoff, stack);
            if d > 0.0 || !depth {
                return Ok(d);
            }
        }
        pair_distance(&poses[i], &*a.shape, &poses[j], &*b.shape).ok_or_else(|| {
            let name = |s: &CollisionShape| {
                let link = self
                    .robot
                    .link_names()
                    .get(s.link)
                    .map_or("?", String::as_str);
                format!("{} of link '{link}'", s.label)
            };
            FabricError::Value {
                what: "self-collision pair".to_string(),
                message: format!("parry has no distance between {} and {}", name(a), name(b)),
            }
        })
    }

    /// Self-clearance at q with a workspace: branch and bound over the pairs as
    /// [`MeshChecker::clearance_in`], with box gaps and hull distances as lower bounds, and the same
    /// `cutoff`. Two meshes in contact read parry's (negative) penetration depth with `depth`, and 0
    /// without (a verdict needs no depth).
    fn self_clearance_in(
        &self,
        q: &[f64],
        cutoff: f64,
        depth: bool,
        ws: &mut MeshWorkspace,
    ) -> Result<f64> {
        self.place(q, ws)?;
        let max = self.max_distance.min(cutoff);
        let mut best = f64::INFINITY;
        ws.order.clear();
        for (k, &(i, j)) in self.self_pairs.iter().enumerate() {
            let cutoff = best.min(max);
            if aabb_gap(&ws.boxes[i], &ws.boxes[j]) - BOUND_SLACK > cutoff {
                continue;
            }
            let (a, b) = (&self.shapes[i], &self.shapes[j]);
            if a.hull.is_none() && b.hull.is_none() {
                let d = self.pair_exact((i, j), &ws.poses, &mut ws.stack, (cutoff, depth))?;
                if d <= cutoff {
                    best = d;
                }
                continue;
            }
            let bound = pair_distance(&ws.poses[i], a.bound(), &ws.poses[j], b.bound())
                .unwrap_or(f64::NEG_INFINITY);
            if bound - BOUND_SLACK <= cutoff {
                ws.order.push((bound, k));
            }
        }
        ws.order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        for &(bound, k) in &ws.order {
            if bound - BOUND_SLACK >= best.min(max) {
                break;
            }
            let (i, j) = self.self_pairs[k];
            let d = self.pair_exact((i, j), &ws.poses, &mut ws.stack, (best.min(max), depth))?;
            if d <= best.min(max) {
                best = d;
            }
        }
        Ok(best)
    }

    /// The self-collision shape pairs ([`MeshChecker::self_pairs`]) nearer than `within` (m, ≥ 0) at q
    /// (dof,): (shape i, shape j, distance m), nearest first; a pair in contact has distance ≤ 0 (with
    /// `depth`, parry's penetration depth where the shapes overlap; without, 0 for two meshes that are not
    /// both convex). For reports that name the links in contact, e.g. a start state MoveIt would refuse.
    ///
    /// Errors: `Shape`, `NonFinite` (q), `Value` for a negative or non-finite `within`, or when parry
    /// cannot measure a pair.
    pub fn self_contacts(
        &self,
        q: &[f64],
        within: f64,
        depth: bool,
    ) -> Result<Vec<(usize, usize, f64)>> {
        self.contacts_among(&self.self_pairs, q, (within, depth))
    }

    /// The shape pairs that locked joints hold still relative to each other (links on one rigid body of
    /// this robot, on two of the whole robot; see [`held_shape_pairs`]) nearer than `within` (m, ≥ 0) at
    /// q (dof,), as [`MeshChecker::self_contacts`]. Their distances depend on the locked joint values only:
    /// a pair in contact puts every state of every motion in collision, as MoveIt checks it.
    ///
    /// Errors: as [`MeshChecker::self_contacts`].
    pub fn held_contacts(
        &self,
        q: &[f64],
        within: f64,
        depth: bool,
    ) -> Result<Vec<(usize, usize, f64)>> {
        self.contacts_among(&self.held_pairs, q, (within, depth))
    }

    /// The shape pairs on adjacent rigid bodies (one movable joint between them) that a loaded SRDF leaves
    /// enabled (see [`adjacent_shape_pairs`]) nearer than `within` (m, ≥ 0) at q (dof,), as
    /// [`MeshChecker::self_contacts`]: the planner does not measure them, MoveIt does.
    ///
    /// Errors: as [`MeshChecker::self_contacts`].
    pub fn adjacent_contacts(
        &self,
        q: &[f64],
        within: f64,
        depth: bool,
    ) -> Result<Vec<(usize, usize, f64)>> {
        self.contacts_among(&self.adjacent_pairs, q, (within, depth))
    }

    /// The pairs of `pairs` nearer than `within` at q, nearest first.
    fn contacts_among(
        &self,
        pairs: &[(usize, usize)],
        q: &[f64],
        (within, depth): (f64, bool),
    ) -> Result<Vec<(usize, usize, f64)>> {
        if !(within.is_finite() && within >= 0.0) {
            return Err(FabricError::Value {
                what: "within".to_string(),
                message: format!("must be a finite distance >= 0 m, got {within}"),
            });
        }
        let mut distances = vec![f64::INFINITY; pairs.len()];
        self.distances_of_pairs_within(
            pairs,
            q,
            (within, depth),
            &mut self.workspace(),
            &mut distances,
        )?;
        let mut out: Vec<(usize, usize, f64)> = pairs
            .iter()
            .zip(distances)
            .filter(|&(_, d)| d <= within)
            .map(|(&(i, j), d)| (i, j, d))
            .collect();
        out.sort_by(|a, b| a.2.total_cmp(&b.2));
        Ok(out)
    }

    /// Self-clearance (m) at q (dof,): the minimum distance over [`MeshChecker::self_pairs`] (shapes on
    /// links of different, non-adjacent rigid bodies whose pair the SRDF does not disable); ≤ 0 means
    /// contact. `f64::INFINITY` when no pair is within [`MeshChecker::max_distance`] or there is no pair.
    ///
    /// Errors: `Shape`, `NonFinite`, `Value` when parry cannot measure a pair of shapes.
    pub fn self_clearance(&self, q: &[f64]) -> Result<f64> {
        self.self_clearance_in(q, f64::INFINITY, true, &mut self.workspace())
    }

    /// [`MeshChecker::self_clearance`] of every state of `qs` (T × dof row-major) -> (T,), in parallel
    /// as [`MeshChecker::trajectory_clearance`].
    pub fn trajectory_self_clearance(
        &self,
        qs: &[f64],
        threads: Option<usize>,
    ) -> Result<Vec<f64>> {
        self.trajectory_self_clearance_within(qs, threads, f64::INFINITY)
    }

    /// [`MeshChecker::trajectory_self_clearance`] measured up to `cutoff` as
    /// [`MeshChecker::trajectory_clearance_within`]; pairs in contact still read parry's (negative)
    /// penetration depth.
    pub fn trajectory_self_clearance_within(
        &self,
        qs: &[f64],
        threads: Option<usize>,
        cutoff: f64,
    ) -> Result<Vec<f64>> {
        self.per_state(qs, threads, |ws, q| {
            self.self_clearance_in(q, cutoff, true, ws)
        })
    }

    /// min over the states of a trajectory of `at(workspace, q, cutoff)`, exact where it is ≤ `cutoff`
    /// (+∞ when no state comes that near), in three parallel passes: every `MIN_STRIDES[0]`-th state and
    /// the last one with `cutoff`, then the other
    /// `MIN_STRIDES[1]`-th states, then the rest, each pass with the minimum of the passes before as its
    /// cutoff, so that states farther from contact than the closest one seen are culled by the
    /// broadphase. Each state's cutoff is fixed before its pass: deterministic whatever the thread count.
    fn trajectory_min(
        &self,
        qs: &[f64],
        threads: Option<usize>,
        cutoff: f64,
        at: impl Fn(&mut MeshWorkspace, &[f64], f64) -> Result<f64> + Sync + Send,
    ) -> Result<f64> {
        let n = self.states(qs)?;
        let dof = self.robot.dof();
        let level = |k: usize| {
            if k.is_multiple_of(MIN_STRIDES[0]) || k + 1 == n {
                0
            } else if k.is_multiple_of(MIN_STRIDES[1]) {
                1
            } else {
                2
            }
        };
        let pass = |of: usize, cutoff: f64| {
            with_threads(threads, || {
                (0..n)
                    .into_par_iter()
                    .filter(|&k| level(k) == of)
                    .map_init(
                        || self.workspace(),
                        |ws, k| at(ws, &qs[k * dof..(k + 1) * dof], cutoff),
                    )
                    .try_reduce(|| f64::INFINITY, |a, b| Ok(a.min(b)))
            })?
        };
        let mut best = pass(0, cutoff)?;
        for of in 1..3 {
            best = best.min(pass(of, best.min(cutoff))?);
        }
        Ok(best)
    }

    /// min over the states of `qs` (T × dof row-major) of [`MeshChecker::clearance`]: the same value as
    /// the minimum of [`MeshChecker::trajectory_clearance`] when that is ≤ `cutoff` (m; +∞: always), at a
    /// fraction of its cost (states farther from the scene than the closest of every eighth state are
    /// culled, and so is every shape pair whose bounds lie beyond `cutoff`); +∞ when no state comes
    /// within `cutoff`, and for T = 0. A verdict "clear by more than m" needs only `cutoff` > m, and
    /// then skips the exact mesh distances of every pair that is clearly farther.
    ///
    /// Errors: as [`MeshChecker::trajectory_clearance`].
    pub fn min_trajectory_clearance(
        &self,
        scene: &Scene,
        qs: &[f64],
        threads: Option<usize>,
        cutoff: f64,
    ) -> Result<f64> {
        let obstacles: Vec<&Obstacle> = scene.iter().map(|(_, o)| o).collect();
        self.trajectory_min(qs, threads, cutoff, |ws, q, cutoff| {
            self.clearance_in(scene, &obstacles, q, cutoff, ws)
        })
    }

    /// min over the states of `qs` of [`MeshChecker::self_clearance`], as
    /// [`MeshChecker::min_trajectory_clearance`] (exact where ≤ `cutoff`, +∞ when nothing is that near).
    pub fn min_trajectory_self_clearance(
        &self,
        qs: &[f64],
        threads: Option<usize>,
        cutoff: f64,
    ) -> Result<f64> {
        self.trajectory_min(qs, threads, cutoff, |ws, q, cutoff| {
            self.self_clearance_in(q, cutoff, cutoff == f64::INFINITY, ws)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn box_robot(extra: &str) -> Robot {
        let xml = format!(
            r#"<robot name="slider">
              <link name="base"/>
              <link name="cart"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
              <joint name="x" type="prismatic"><parent link="base"/><child link="cart"/>
                <axis xyz="1 0 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
              {extra}
            </robot>"#
        );
        Robot::from_urdf_str(&xml, "<string>", &Default::default()).unwrap()
    }

    #[test]
    fn aabb_helpers() {
        let a = Aabb::new(Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 1.0, 1.0));
        let b = Aabb::new(Point3::new(2.0, 0.0, 3.0), Point3::new(3.0, 1.0, 4.0));
        assert!((aabb_gap(&a, &b) - (1.0f64 + 4.0).sqrt()).abs() < 1e-15);
        assert_eq!(aabb_gap(&a, &a), 0.0);
        let inner = Aabb::new(Point3::new(0.2, 0.2, 0.2), Point3::new(0.8, 0.8, 1.0));
        assert!(aabb_inside(&inner, &a));
        assert!(!aabb_inside(&a, &inner));
    }

    #[test]
    fn cutoff_validation_and_empty_robot() {
        let c = MeshChecker::new(&box_robot("")).unwrap();
        assert_eq!(c.max_distance(), DEFAULT_MAX_DISTANCE);
        assert!(c.clone().with_max_distance(-1.0).is_err());
        assert!(c.clone().with_max_distance(f64::NAN).is_err());
        assert_eq!(
            c.with_max_distance(f64::INFINITY).unwrap().max_distance(),
            f64::INFINITY
        );
        let err = MeshChecker::new(&Robot::panda()).unwrap_err();
        assert!(matches!(err, FabricError::Value { .. }), "{err}");
    }

    #[test]
    fn threads_zero_and_bad_shapes_are_errors() {
        let c = MeshChecker::new(&box_robot("")).unwrap();
        let scene = Scene::new();
        assert!(matches!(
            c.trajectory_clearance(&scene, &[0.0, 0.1], Some(0)),
            Err(FabricError::Value { .. })
        ));
        assert!(matches!(
            c.clearance(&scene, &[0.0, 0.1]),
            Err(FabricError::Shape { .. })
        ));
        assert!(matches!(
            c.clearance(&scene, &[f64::NAN]),
            Err(FabricError::NonFinite { .. })
        ));
        assert_eq!(c.clearance(&scene, &[0.0]).unwrap(), f64::INFINITY);
        assert!(c
            .trajectory_clearance(&scene, &[], None)
            .unwrap()
            .is_empty());
    }

    #[test]
    fn adjacent_and_same_body_pairs_are_skipped() {
        // cart (box) -- fixed -- cart2 (sphere) share a body; arm on a revolute joint is adjacent to the
        // cart body; tip is fixed to arm. Only base-level pairs two joints apart would remain: none here.
        let extra = r#"
          <link name="cart2"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
          <joint name="f" type="fixed"><parent link="cart"/><child link="cart2"/></joint>
          <link name="arm"><collision><geometry><cylinder radius="0.02" length="0.3"/></geometry></collision></link>
          <joint name="r" type="revolute"><parent link="cart"/><child link="arm"/><axis xyz="0 0 1"/>
            <limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
          <link name="hand"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
          <joint name="r2" type="revolute"><parent link="arm"/><child link="hand"/><axis xyz="0 0 1"/>
            <origin xyz="0.5 0 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>"#;
        let robot = box_robot(extra);
        let c = MeshChecker::new(&robot).unwrap();
        let link = |n: &str| robot.link_index(n).unwrap();
        let pairs: Vec<(usize, usize)> = c
            .self_pairs()
            .iter()
            .map(|&(i, j)| {
                let (a, b) = (c.shapes()[i].link, c.shapes()[j].link);
                (a.min(b), a.max(b))
            })
            .collect();
        let mut pairs = pairs;
        pairs.sort_unstable();
        // hand (two joints from the cart body) against cart and cart2 only.
        assert_eq!(
            pairs,
            vec![(link("cart"), link("hand")), (link("cart2"), link("hand"))]
        );
    }
}
