//! The [`Scene`]: a set of obstacles with a broadphase (parry's dynamic [`Bvh`] over world AABBs) for
//! point distance queries and shape distance queries.
//!
//! Obstacles are stored densely; each has a stable slot which is its BVH leaf index, so adding, moving
//! and removing one obstacle touches only its own leaf (O(log n)); nothing is rebuilt, meshes and point
//! clouds keep their own BVHs in their obstacle frame. Unbounded obstacles (half-spaces) are kept out of
//! the BVH and always tested. Small scenes are scanned linearly by `query` ([`LINEAR_SCAN_MAX`]).

use std::collections::HashMap;
use std::fmt;

use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::partitioning::{Bvh, BvhNode, BvhWorkspace, TraversalAction};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Capsule, Cuboid, Cylinder, HalfSpace};

use super::distance::{distance_world, eval_world, DistanceSample, NearObstacle, SurfaceDistance};
use super::shape::{aabb_signed_distance, box_within, check_pose, fmax, Obstacle, Shape};
use crate::error::{FabricError, Result};

/// Identifier of an obstacle in a [`Scene`]; never reused within one scene.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, PartialOrd, Ord)]
pub struct ObstacleId(pub u64);

/// [`Scene::query`] scans scenes of at most this many obstacles linearly over a dense array of their
/// boxes instead of walking the BVH: for MotionBenchMaker-sized scenes (7-13 obstacles) the scan is
/// 25-35 % faster than the tree walk (`benches/distance.rs`). Larger scenes use the BVH, so the cost
/// grows with the number of obstacles near the query point. ([`Scene::signed_distance`] always uses
/// the best-first BVH search, which measured faster than a scan even for small scenes; also than a
/// scan visiting the boxes in increasing order of their bound, despite its ~25 % fewer instructions.)
pub const LINEAR_SCAN_MAX: usize = 16;

/// `slot_to_entry` value of an unused slot.
const FREE: u32 = u32::MAX;

#[derive(Clone, Debug)]
struct Entry {
    id: ObstacleId,
    /// Stable slot = BVH leaf index.
    slot: u32,
    obstacle: Obstacle,
    /// Rotation matrix of `obstacle.pose` (obstacle frame to world), cached for queries.
    rot: Matrix3<f64>,
    /// World AABB; `None` for unbounded shapes.
    aabb: Option<Aabb>,
}

impl Entry {
    fn new(id: ObstacleId, slot: u32, obstacle: Obstacle) -> Entry {
        let rot = obstacle.pose.rotation.to_rotation_matrix().into_inner();
        let aabb = obstacle.shape.aabb(&obstacle.pose);
        Entry {
            id,
            slot,
            obstacle,
            rot,
            aabb,
        }
    }

    fn refresh(&mut self) {
        self.rot = self
            .obstacle
            .pose
            .rotation
            .to_rotation_matrix()
            .into_inner();
        self.aabb = self.obstacle.shape.aabb(&self.obstacle.pose);
    }

    /// Signed distance only, when `<= max_distance`.
    #[inline]
    fn distance(&self, p: &Vector3<f64>, max_distance: f64) -> Option<f64> {
        distance_world(
            &self.obstacle.shape,
            &self.rot,
            &self.obstacle.pose.translation.vector,
            p,
            max_distance,
        )
    }

    /// The sample at `p` (world) when its signed distance is `<= max_distance` (m).
    fn sample(&self, p: &Vector3<f64>, max_distance: f64) -> Option<DistanceSample> {
        self.surface(p, max_distance).map(|s| self.tagged(s))
    }

    /// [`Entry::sample`] appended to `out`, built in place (pushing the returned 136-byte sample cost a
    /// `memcpy` call per sample).
    #[inline(always)]
    fn push_sample(&self, p: &Vector3<f64>, max_distance: f64, out: &mut Vec<DistanceSample>) {
        if let Some(s) = self.surface(p, max_distance) {
            out.push(self.tagged(s));
        }
    }

    /// Signed distance and derivatives at `p` (world), when `<= max_distance` (m).
    #[inline(always)]
    fn surface(&self, p: &Vector3<f64>, max_distance: f64) -> Option<SurfaceDistance> {
        eval_world(
            &self.obstacle.shape,
            &self.rot,
            &self.obstacle.pose.translation.vector,
            p,
            max_distance,
        )
    }

    /// `s` with this obstacle's id and velocity.
    #[inline(always)]
    fn tagged(&self, s: SurfaceDistance) -> DistanceSample {
        DistanceSample {
            obstacle: self.id,
            distance: s.distance,
            gradient: s.gradient,
            hessian: s.hessian,
            velocity: self.obstacle.velocity,
        }
    }
}

/// Obstacles plus broadphase. Read-only during evaluation (`Send + Sync`); `Clone` copies everything
/// (meshes and point clouds are shared through `Arc`).
#[derive(Clone, Default)]
pub struct Scene {
    /// Dense storage (insertion order, with swap-removal).
    entries: Vec<Entry>,
    /// Boxes of the entries for the linear scan (valid when `entries.len() <= LINEAR_SCAN_MAX`).
    linear: LinearBoxes,
    /// Slot (stable BVH leaf index) to position in `entries`, [`FREE`] when unused.
    slot_to_entry: Vec<u32>,
    free: Vec<u32>,
    /// Obstacle id to slot.
    index: HashMap<ObstacleId, u32>,
    /// Slots of unbounded obstacles (half-spaces), not in the BVH.
    unbounded: Vec<u32>,
    /// Number of obstacles in the BVH (bounded shapes).
    bounded: usize,
    next_id: u64,
    bvh: Bvh,
    bvh_workspace: BvhWorkspace,
}

impl fmt::Debug for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list()
            .entries(self.iter().map(|(id, o)| (id, &o.name, &o.shape)))
            .finish()
    }
}

impl Scene {
    /// An empty scene.
    pub fn new() -> Scene {
        Scene::default()
    }

    /// Add an obstacle after validating it ([`Obstacle::validate`]: sizes > 0, finite unit pose,
    /// finite velocity). O(log n).
    pub fn add(&mut self, obstacle: Obstacle) -> Result<ObstacleId> {
        obstacle.validate()?;
        let too_many = || FabricError::Value {
            what: "scene".into(),
            message: "too many obstacles".into(),
        };
        let position = u32::try_from(self.entries.len())
            .ok()
            .filter(|&n| n < FREE)
            .ok_or_else(too_many)?;
        let slot = match self.free.pop() {
            Some(s) => s,
            None => {
                let s = u32::try_from(self.slot_to_entry.len()).map_err(|_| too_many())?;
                self.slot_to_entry.push(FREE);
                s
            }
        };
        let id = ObstacleId(self.next_id);
        self.next_id += 1;
        let entry = Entry::new(id, slot, obstacle);
        match entry.aabb {
            Some(aabb) => {
                self.bvh.insert(aabb, slot);
                self.bounded += 1;
            }
            None => self.unbounded.push(slot),
        }
        self.entries.push(entry);
        self.slot_to_entry[slot as usize] = position;
        self.index.insert(id, slot);
        self.linear.sync(&self.entries);
        Ok(id)
    }

    /// Remove an obstacle and return it. `Err(Value)` for an unknown id. O(log n).
    pub fn remove(&mut self, id: ObstacleId) -> Result<Obstacle> {
        let slot = self.slot(id)?;
        let position = self.position(slot).ok_or_else(|| unknown(id))?;
        let entry = self.entries.swap_remove(position);
        self.linear.sync(&self.entries);
        if let Some(moved) = self.entries.get(position) {
            self.slot_to_entry[moved.slot as usize] = position as u32;
        }
        self.slot_to_entry[slot as usize] = FREE;
        self.index.remove(&id);
        if entry.aabb.is_some() {
            self.bvh.remove(slot);
            self.bounded -= 1;
        } else {
            self.unbounded.retain(|&s| s != slot);
        }
        self.free.push(slot);
        Ok(entry.obstacle)
    }

    /// Move an obstacle to `pose` (finite, unit quaternion). O(log n): only its BVH leaf and the
    /// ancestors that no longer contain it are enlarged.
    pub fn set_pose(&mut self, id: ObstacleId, pose: Isometry3<f64>) -> Result<()> {
        let slot = self.slot(id)?;
        let position = self.position(slot).ok_or_else(|| unknown(id))?;
        let entry = &mut self.entries[position];
        check_pose(&format!("obstacle '{}'", entry.obstacle.name), &pose)?;
        entry.obstacle.pose = pose;
        entry.refresh();
        if let Some(aabb) = entry.aabb {
            self.bvh.insert(aabb, slot);
        }
        self.linear.sync(&self.entries);
        Ok(())
    }

    /// Set the linear velocity (m/s, world) of an obstacle; it must be finite.
    pub fn set_velocity(&mut self, id: ObstacleId, v: Vector3<f64>) -> Result<()> {
        let slot = self.slot(id)?;
        let entry = self.entry_mut(slot).ok_or_else(|| unknown(id))?;
        if !v.iter().all(|c| c.is_finite()) {
            return Err(FabricError::NonFinite {
                what: format!("obstacle '{}': velocity", entry.obstacle.name),
            });
        }
        entry.obstacle.velocity = v;
        Ok(())
    }

    /// The obstacle with this id, if any.
    pub fn get(&self, id: ObstacleId) -> Option<&Obstacle> {
        let slot = *self.index.get(&id)?;
        self.entry(slot).map(|e| &e.obstacle)
    }

    /// The id of the first obstacle (lowest id) named `name`.
    pub fn find(&self, name: &str) -> Option<ObstacleId> {
        self.entries
            .iter()
            .filter(|e| e.obstacle.name == name)
            .map(|e| e.id)
            .min()
    }

    /// Ids of all obstacles, increasing (= insertion order).
    pub fn ids(&self) -> Vec<ObstacleId> {
        let mut ids: Vec<ObstacleId> = self.entries.iter().map(|e| e.id).collect();
        ids.sort_unstable();
        ids
    }

    /// All obstacles with their ids, in increasing id order.
    pub fn iter(&self) -> impl Iterator<Item = (ObstacleId, &Obstacle)> + '_ {
        let mut all: Vec<&Entry> = self.entries.iter().collect();
        all.sort_unstable_by_key(|e| e.id);
        all.into_iter().map(|e| (e.id, &e.obstacle))
    }

    /// Number of obstacles.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether the scene has no obstacle.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Move every obstacle by `velocity · dt` (dt in s, may be negative). Leaves of moved obstacles are
    /// updated and the BVH refitted once (O(n), no rebuild). A non-finite `dt` leaves the scene unchanged.
    pub fn advance(&mut self, dt: f64) {
        if !dt.is_finite() {
            return;
        }
        let mut moved = false;
        for entry in &mut self.entries {
            if entry.obstacle.velocity == Vector3::zeros() {
                continue;
            }
            entry.obstacle.pose.translation.vector += entry.obstacle.velocity * dt;
            entry.refresh();
            if let Some(aabb) = entry.aabb {
                self.bvh.insert_or_update_partially(aabb, entry.slot, 0.0);
                moved = true;
            }
        }
        if moved {
            self.bvh.refit(&mut self.bvh_workspace);
        }
        self.linear.sync(&self.entries);
    }

    /// Append to `out` a sample for every obstacle whose signed distance to `p` (world, m) is
    /// `<= max_distance` (m; may be negative; `f64::INFINITY` for all). The BVH prunes every subtree
    /// whose box is farther than `max_distance` (the signed box distance is a lower bound of the signed
    /// distance of anything inside it), so no obstacle within range is missed and the cost grows with the
    /// number of obstacles near `p` (scenes of at most [`LINEAR_SCAN_MAX`] bounded obstacles are
    /// scanned linearly instead). Order: deterministic for a given history of edits (storage order for
    /// small scenes; unbounded obstacles then BVH order for large ones). Derivatives are computed only
    /// for obstacles in range. A non-finite `p` or a NaN `max_distance` appends nothing.
    pub fn query(&self, p: &Vector3<f64>, max_distance: f64, out: &mut Vec<DistanceSample>) {
        self.visit_candidates(p, max_distance, |_, e| e.push_sample(p, max_distance, out));
    }

    /// The broadphase of [`Scene::query`] without derivatives: appends to `out` the storage position
    /// and signed distance (m) of every obstacle within `max_distance` of `p` (world), in the same
    /// order as `query`. Positions are valid until the scene is next modified; pass them to
    /// [`Scene::sample_near`]. (Used by the fabric: one query per robot link, then exact samples per
    /// collision sphere, without hashing obstacle ids.)
    pub fn query_near(&self, p: &Vector3<f64>, max_distance: f64, out: &mut Vec<NearObstacle>) {
        self.visit_candidates(p, max_distance, |entry, e| {
            if let Some(distance) = e.distance(p, max_distance) {
                out.push(NearObstacle { entry, distance });
            }
        });
    }

    /// The sample of [`Scene::query`] for the obstacle at storage position `near.entry` (from
    /// [`Scene::query_near`] on this unmodified scene) at `p` (world), when its signed distance is
    /// `<= max_distance` (m); `None` otherwise or for a position out of range.
    pub fn sample_near(
        &self,
        near: &NearObstacle,
        p: &Vector3<f64>,
        max_distance: f64,
    ) -> Option<DistanceSample> {
        self.entries
            .get(near.entry as usize)?
            .sample(p, max_distance)
    }

    /// Call `visit(position, entry)` for every obstacle whose box bound (a lower bound of its signed
    /// distance) allows a signed distance to `p` of at most `max_distance`; the caller does the exact
    /// test, once. See [`Scene::query`] for the order and the pruning.
    fn visit_candidates(
        &self,
        p: &Vector3<f64>,
        max_distance: f64,
        mut visit: impl FnMut(u32, &Entry),
    ) {
        if !p.iter().all(|c| c.is_finite()) || max_distance.is_nan() {
            return;
        }
        let n = self.entries.len();
        if n <= LINEAR_SCAN_MAX {
            self.linear
                .visit_within(n, p, max_distance, |i| visit(i as u32, &self.entries[i]));
            return;
        }
        let pt = Point3::from(*p);
        for &slot in &self.unbounded {
            if let Some(i) = self.position(slot) {
                visit(i as u32, &self.entries[i]);
            }
        }
        self.bvh.traverse(|node: &BvhNode| {
            if !box_within(&node.mins(), &node.maxs(), &pt, max_distance) {
                return TraversalAction::Prune;
            }
            if let Some(i) = node.leaf_data().and_then(|slot| self.position(slot)) {
                visit(i as u32, &self.entries[i]);
            }
            TraversalAction::Continue
        });
    }

    /// The obstacle of minimum signed distance to `p` (world) with its sample; `None` for an empty scene
    /// or a non-finite `p`. Best-first BVH search pruned by signed box distances (a lower bound of the
    /// signed distance of anything inside a box), on distances only; the gradient and Hessian are
    /// computed for the winner alone. Ties keep the first obstacle found (deterministic).
    pub fn signed_distance(&self, p: &Vector3<f64>) -> Option<DistanceSample> {
        if !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        let mut best_d = f64::INFINITY;
        let mut winner: Option<&Entry> = None;
        for &slot in &self.unbounded {
            let Some(e) = self.entry(slot) else { continue };
            if let Some(d) = e.distance(p, best_d) {
                if d < best_d {
                    (best_d, winner) = (d, Some(e));
                }
            }
        }
        let pt = Point3::from(*p);
        let found = self.bvh.find_best(
            best_d,
            |node: &BvhNode, _| aabb_signed_distance(&node.mins(), &node.maxs(), &pt),
            |slot, best_so_far| self.entry(slot)?.distance(p, best_so_far),
        );
        if let Some(e) = found.and_then(|(slot, _)| self.entry(slot)) {
            winner = Some(e);
        }
        winner.and_then(|e| e.sample(p, f64::INFINITY))
    }

    /// Minimum distance (m) between a parry shape placed at `pose` (world) and all obstacles, when it is
    /// `<= max` (m); `None` when every obstacle is farther or the scene is empty. Negative values are
    /// penetration depths (from `parry::query::contact`) when parry supports the pair; for pairs where it
    /// does not (e.g. mesh against mesh) an intersection gives 0. If parry supports no distance at all
    /// for a pair, the distance between the two AABBs is used (a lower bound, so never optimistic).
    /// Point clouds use the shape's point projection for each point near the shape.
    pub fn shape_distance(
        &self,
        shape: &dyn parry3d_f64::shape::Shape,
        pose: &Isometry3<f64>,
        max: f64,
    ) -> Option<f64> {
        if self.is_empty() {
            return None;
        }
        self.boxed_shape_distance(shape, pose, &shape.compute_aabb(pose), max)
    }

    /// [`Scene::shape_distance`] with a world box `shape_aabb` of the placed shape given by the caller (any
    /// box containing it: it only selects and bounds the obstacles), for callers that keep one per pose.
    pub fn boxed_shape_distance(
        &self,
        shape: &dyn parry3d_f64::shape::Shape,
        pose: &Isometry3<f64>,
        shape_aabb: &Aabb,
        max: f64,
    ) -> Option<f64> {
        if self.is_empty() || max.is_nan() || check_pose("shape_distance", pose).is_err() {
            return None;
        }
        let region = shape_aabb.loosened(max.max(0.0));
        let mut best: Option<f64> = None;
        let mut consider = |entry: &Entry| {
            if let Some(d) = pair_distance(entry, shape, pose, shape_aabb, max) {
                if d <= max && !matches!(best, Some(b) if b <= d) {
                    best = Some(d);
                }
            }
        };
        for &slot in &self.unbounded {
            if let Some(e) = self.entry(slot) {
                consider(e);
            }
        }
        for slot in self.bvh.intersect_aabb(&region) {
            if let Some(e) = self.entry(slot) {
                consider(e);
            }
        }
        best
    }

    /// World AABB of an obstacle (`None` for unknown ids and half-spaces).
    pub fn aabb(&self, id: ObstacleId) -> Option<Aabb> {
        let slot = *self.index.get(&id)?;
        self.entry(slot)?.aabb
    }

    fn position(&self, slot: u32) -> Option<usize> {
        let i = *self.slot_to_entry.get(slot as usize)?;
        (i != FREE).then_some(i as usize)
    }

    fn entry(&self, slot: u32) -> Option<&Entry> {
        self.entries.get(self.position(slot)?)
    }

    fn entry_mut(&mut self, slot: u32) -> Option<&mut Entry> {
        let i = self.position(slot)?;
        self.entries.get_mut(i)
    }

    fn slot(&self, id: ObstacleId) -> Result<u32> {
        self.index.get(&id).copied().ok_or_else(|| unknown(id))
    }
}

/// Boxes per chunk of [`LinearBoxes`]: the box test works on whole chunks (vectorised), so a scene
/// of n obstacles tests `n` rounded up to a multiple of this many boxes.
const LANES: usize = 4;

/// The boxes of up to [`LINEAR_SCAN_MAX`] entries as a structure of arrays in chunks of [`LANES`], so
/// that a point is tested against all of them in one vectorisable loop. Unused lanes hold empty boxes,
/// unbounded obstacles all of space.
#[derive(Clone, Debug)]
struct LinearBoxes {
    /// `lo[chunk][axis][lane]`: lower corners (m, world).
    lo: [[[f64; LANES]; 3]; LINEAR_SCAN_MAX / LANES],
    /// Upper corners, laid out as `lo`.
    hi: [[[f64; LANES]; 3]; LINEAR_SCAN_MAX / LANES],
}

impl Default for LinearBoxes {
    fn default() -> Self {
        LinearBoxes {
            lo: [[[f64::INFINITY; LANES]; 3]; LINEAR_SCAN_MAX / LANES],
            hi: [[[f64::NEG_INFINITY; LANES]; 3]; LINEAR_SCAN_MAX / LANES],
        }
    }
}

impl LinearBoxes {
    /// Rebuild from the entries (a no-op beyond [`LINEAR_SCAN_MAX`] entries, when the BVH is used).
    fn sync(&mut self, entries: &[Entry]) {
        if entries.len() > LINEAR_SCAN_MAX {
            return;
        }
        *self = LinearBoxes::default();
        for (i, e) in entries.iter().enumerate() {
            let (lo, hi) = match &e.aabb {
                Some(a) => (a.mins, a.maxs),
                None => (
                    Point3::from(Vector3::repeat(f64::NEG_INFINITY)),
                    Point3::from(Vector3::repeat(f64::INFINITY)),
                ),
            };
            for k in 0..3 {
                self.lo[i / LANES][k][i % LANES] = lo[k];
                self.hi[i / LANES][k][i % LANES] = hi[k];
            }
        }
    }

    /// Call `visit(i)`, in increasing `i < n` (`n <= LINEAR_SCAN_MAX`; entry `i` is lane `i % LANES` of
    /// chunk `i / LANES`), for every box that may hold a point at signed distance `<= max` (m, not NaN)
    /// from `p` (world, finite). The Euclidean distance from `p` to a box (0 inside) is a lower bound
    /// of the distance of anything in it, so a box is skipped when it is farther than `max >= 0`, or
    /// for `max < 0` when it does not contain `p`: its squared distance exceeds `max(max, 0)²`.
    #[inline(always)]
    fn visit_within(&self, n: usize, p: &Vector3<f64>, max: f64, mut visit: impl FnMut(usize)) {
        let reach = fmax(max, 0.0);
        let reach2 = reach * reach;
        let d2 = self.distances2(p, n);
        for (i, &d2) in d2.as_flattened()[..n].iter().enumerate() {
            if d2 <= reach2 {
                visit(i);
            }
        }
    }

    /// Squared Euclidean distance (0 inside) from `p` to the boxes of the first `n` lanes (whole
    /// chunks; the lanes of the other chunks are +∞). Branch-free and without square roots, vectorised
    /// over the lanes of a chunk. (Returned as an array on purpose: tested lane by lane in the same
    /// loop, the vectoriser paired axes instead of lanes and took ~40 % more instructions.)
    #[inline(always)]
    fn distances2(&self, p: &Vector3<f64>, n: usize) -> [[f64; LANES]; LINEAR_SCAN_MAX / LANES] {
        let mut out = [[f64::INFINITY; LANES]; LINEAR_SCAN_MAX / LANES];
        let chunks = out.iter_mut().zip(&self.lo).zip(&self.hi);
        for ((out, lo), hi) in chunks.take(n.div_ceil(LANES)) {
            let mut d2 = [0.0; LANES];
            for k in 0..3 {
                for (l, d2) in d2.iter_mut().enumerate() {
                    let o = fmax(fmax(lo[k][l] - p[k], p[k] - hi[k][l]), 0.0);
                    *d2 += o * o;
                }
            }
            *out = d2;
        }
        out
    }
}

fn unknown(id: ObstacleId) -> FabricError {
    FabricError::Value {
        what: "obstacle id".into(),
        message: format!("no obstacle with id {}", id.0),
    }
}

/// Rotation taking parry's cylinder axis (y) onto our cylinder axis (z): +90° about x.
fn y_to_z() -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2)
}

/// Distance between the query shape and one obstacle (see [`Scene::shape_distance`]).
fn pair_distance(
    entry: &Entry,
    shape: &dyn parry3d_f64::shape::Shape,
    pose: &Isometry3<f64>,
    shape_aabb: &Aabb,
    max: f64,
) -> Option<f64> {
    let opose = &entry.obstacle.pose;
    let parry_pair = |g: &dyn parry3d_f64::shape::Shape, gpose: &Isometry3<f64>| -> f64 {
        match query::distance(pose, shape, gpose, g) {
            Ok(d) if d > 0.0 => d,
            Ok(_) => match query::contact(pose, shape, gpose, g, 0.0) {
                Ok(Some(c)) => c.dist.min(0.0),
                _ => 0.0,
            },
            Err(_) => {
                let other = g.compute_aabb(gpose);
                let gap = Vector3::from_fn(|i, _| {
                    (other.mins[i] - shape_aabb.maxs[i])
                        .max(shape_aabb.mins[i] - other.maxs[i])
                        .max(0.0)
                });
                gap.norm()
            }
        }
    };
    Some(match &entry.obstacle.shape {
        Shape::Sphere { radius } => parry_pair(&Ball::new(*radius), opose),
        Shape::Cuboid { half_extents } => parry_pair(&Cuboid::new(*half_extents), opose),
        Shape::Cylinder {
            half_height,
            radius,
        } => {
            let gpose = opose * Isometry3::from_parts(Translation3::identity(), y_to_z());
            parry_pair(&Cylinder::new(*half_height, *radius), &gpose)
        }
        Shape::Capsule {
            half_height,
            radius,
        } => parry_pair(&Capsule::new_z(*half_height, *radius), opose),
        Shape::HalfSpace => parry_pair(&HalfSpace::new(Vector3::z_axis()), opose),
        Shape::TriMesh(m) => parry_pair(m.as_ref(), opose),
        Shape::PointCloud(pc) => {
            // Points near the shape, in the cloud frame; signed distance of each to the shape.
            let local_pose = opose.inv_mul(pose);
            let region = shape
                .compute_aabb(&local_pose)
                .loosened(max.max(0.0) + pc.radius());
            let mut best: Option<f64> = None;
            for i in pc.points_in(&region) {
                let Some(pt) = pc.points().get(i) else {
                    continue;
                };
                // `contains_point` is the reliable inside test (meshes use their pseudo-normals).
                let r = (pt - shape.project_point(&local_pose, pt, false).point).norm();
                let d = if shape.contains_point(&local_pose, pt) {
                    -r
                } else {
                    r
                } - pc.radius();
                if !matches!(best, Some(b) if b <= d) {
                    best = Some(d);
                }
            }
            return best;
        }
    })
}
