//! A continuous collision verdict along a joint path: every configuration on the straight segments
//! between consecutive states, not only the states, keeps its collision geometry farther than a
//! margin from the scene and from itself (conservative advancement).
//!
//! Checkers sample a path: MoveIt and MotionBenchMaker's validators interpolate it at a fixed joint
//! resolution (0.01 rad), a planner's own check visits its states. Neither sees a contact between
//! two samples. [`MeshChecker::sweep`] closes the gap with a motion bound: when q moves along the
//! segment from q_a to q_b, no point of a collision shape moves farther than
//! `B = Σ_j c_j |Δq_j|` ([`MotionBounds`]), so a distance that is d_a at q_a and d_b at q_b stays
//! above `(d_a + d_b − B) / 2` on the whole segment (it changes by at most the distance moved). A
//! segment with `d_a + d_b − B > 2 · margin` is certified; any other segment is cut in two at its
//! midpoint, whose distance is measured, and each half is checked again (the bound halves with
//! the segment). The verdict holds for the straight-line interpolation at *every* resolution.
//!
//! The motion bound of a shape: a revolute joint turning by Δθ moves a point at distance r from its
//! axis by at most r |Δθ|, and a prismatic joint by |Δθ|; r is bounded, whatever the configuration,
//! by the lengths of the kinematic chain from the joint to the shape plus the radius of the shape's
//! bounding sphere (prismatic joints in between at their largest travel). For a pair of shapes only
//! the joints that move one and not the other count (joints moving both move them rigidly
//! together). Units: metres and radians; Δq in the robot's joint order.

use std::time::Instant;

use rayon::prelude::*;

use super::{CollisionShape, MeshChecker, MeshWorkspace};
use crate::error::{FabricError, Result};
use crate::robot::model::Motion;
use crate::robot::Robot;
use crate::rollout::batch::with_threads;
use crate::scene::{Obstacle, Scene};

/// Halvings of one segment at most: a segment still uncertified after this many is a failure
/// (`B` is then 2⁻¹⁴ of the segment's, and the distances at its ends within the margin of it).
const MAX_DEPTH: u32 = 14;

/// Range (m) beyond the margin to which an anchor state's distances are measured: larger anchors
/// cover more of the path per measurement, at a higher cost per measurement.
const ANCHOR_RANGE: f64 = 0.01;

/// Extra cutoff (m) of each distance query beyond what certification needs, so that a state at
/// exactly the needed distance still certifies after round-off.
const CUTOFF_SLACK: f64 = 1e-6;

/// Per-shape and per-pair motion bounds: lists of (coordinate, coefficient) with the displacement
/// bound `Σ coefficient · |Δq[coordinate]|` (m for Δq in rad or m).
#[derive(Clone, Debug)]
pub struct MotionBounds {
    shapes: Vec<Vec<(usize, f64)>>,
    pairs: Vec<Vec<(usize, f64)>>,
}

/// (link whose joint it is, coordinate, coefficient) of every driven joint between a shape and the
/// base.
fn shape_chain(robot: &Robot, shape: &CollisionShape) -> Vec<(usize, usize, f64)> {
    let (center, radius) = bounding_sphere(shape);
    // Bound on the distance from the current frame's origin to any point of the shape.
    let mut reach = center + radius;
    let mut out = Vec::new();
    let mut link = shape.link;
    while let Some(Some(joint)) = robot.joints.get(link) {
        let post = joint.post.map_or(0.0, |p| p.translation.vector.norm());
        // From the joint's axis point (the joint frame's origin) to the shape.
        let from_axis = reach + post;
        let mut travel = 0.0;
        if let Some(c) = joint.coord {
            let scale = joint.scale.abs();
            match joint.motion {
                Motion::Revolute(_) => out.push((link, c, scale * from_axis)),
                Motion::Prismatic(_) => {
                    out.push((link, c, scale));
                    let (lo, hi) = (robot.lower[c], robot.upper[c]);
                    travel = scale * lo.abs().max(hi.abs()) + joint.offset.abs();
                }
                Motion::Fixed => {}
            }
        }
        reach = from_axis + joint.pre.translation.vector.norm() + travel;
        link = joint.parent;
    }
    out
}

/// (distance from the link frame's origin to the centre, radius) of a sphere enclosing `shape`, m.
fn bounding_sphere(shape: &CollisionShape) -> (f64, f64) {
    let sphere = shape.shape.compute_bounding_sphere(&shape.origin);
    (sphere.center.coords.norm(), sphere.radius)
}

impl MotionBounds {
    /// The bounds of every shape of `checker` against the scene and of every self-collision pair.
    fn new(checker: &MeshChecker) -> MotionBounds {
        let chains: Vec<Vec<(usize, usize, f64)>> = checker
            .shapes
            .iter()
            .map(|s| shape_chain(&checker.robot, s))
            .collect();
        let terms = |chain: &[(usize, usize, f64)], other: &[(usize, usize, f64)]| {
            chain
                .iter()
                .filter(|(link, _, _)| other.iter().all(|o| o.0 != *link))
                .map(|&(_, c, k)| (c, k))
                .collect::<Vec<_>>()
        };
        let shapes = chains.iter().map(|c| terms(c, &[])).collect();
        let pairs = checker
            .self_pairs
            .iter()
            .map(|&(i, j)| {
                let mut t = terms(&chains[i], &chains[j]);
                t.extend(terms(&chains[j], &chains[i]));
                t
            })
            .collect();
        MotionBounds { shapes, pairs }
    }

    fn largest(lists: &[Vec<(usize, f64)>], dq: &[f64]) -> f64 {
        lists
            .iter()
            .map(|l| l.iter().map(|&(c, k)| k * dq[c].abs()).sum::<f64>())
            .fold(0.0, f64::max)
    }

    /// Largest displacement (m) of any shape for the joint step `dq`.
    pub fn obstacle_bound(&self, dq: &[f64]) -> f64 {
        Self::largest(&self.shapes, dq)
    }

    /// Largest relative displacement (m) of any self-collision pair for the joint step `dq`.
    pub fn self_bound(&self, dq: &[f64]) -> f64 {
        Self::largest(&self.pairs, dq)
    }
}

/// Result of [`MeshChecker::sweep`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sweep {
    /// Smallest distance (m) to the scene measured at a state or a midpoint; exact when it is at most
    /// the margin plus the needed range, `f64::INFINITY` when nothing came that near.
    pub clearance: f64,
    /// Smallest self-distance (m), as `clearance`.
    pub self_clearance: f64,
    /// Every configuration on the path is certified farther than the margin from both.
    pub ok: bool,
    /// The verdict is final: false when the deadline came first (then `ok` is false).
    pub complete: bool,
    /// Configurations measured (states and midpoints).
    pub measured: usize,
}

/// Distances at one configuration: (scene, self), each a lower bound of the true one (exact below
/// its cutoff).
type Pair = (f64, f64);

/// What one segment's check found.
#[derive(Clone, Copy)]
struct Found {
    least: Pair,
    ok: bool,
    complete: bool,
    measured: usize,
}

impl Found {
    /// Nothing measured, nothing refused: the identity of [`Found::join`].
    const NONE: Found = Found {
        least: (f64::INFINITY, f64::INFINITY),
        ok: true,
        complete: true,
        measured: 0,
    };

    fn join(self, other: Found) -> Found {
        Found {
            least: (
                self.least.0.min(other.least.0),
                self.least.1.min(other.least.1),
            ),
            ok: self.ok && other.ok,
            complete: self.complete && other.complete,
            measured: self.measured + other.measured,
        }
    }
}

/// Shared inputs of one sweep.
struct Context<'a> {
    checker: &'a MeshChecker,
    bounds: MotionBounds,
    scene: &'a Scene,
    obstacles: Vec<&'a Obstacle>,
    margin: f64,
    deadline: Option<Instant>,
    /// The path: T × dof row-major.
    qs: &'a [f64],
    dof: usize,
}

impl Context<'_> {
    fn row(&self, k: usize) -> &[f64] {
        &self.qs[k * self.dof..(k + 1) * self.dof]
    }

    fn step(&self, from: usize, to: usize) -> Vec<f64> {
        self.row(to)
            .iter()
            .zip(self.row(from))
            .map(|(b, a)| b - a)
            .collect()
    }

    /// Certify the path through states `first..=last`. A measured state (an anchor) with distances
    /// a certifies every later state whose motion bound from it stays below a − margin, and the
    /// straight segments between them (the bound grows monotonically along a straight segment). The
    /// first state beyond that becomes the next anchor, and the segment reaching it is certified
    /// from both ends ([`Context::segment`]), with the lower bound a − bound at its near end.
    fn cover(&self, first: usize, last: usize, ws: &mut MeshWorkspace) -> Result<Found> {
        let mut found = Found::NONE;
        let range = (ANCHOR_RANGE, ANCHOR_RANGE);
        let mut anchor = first;
        let (mut a, raw) = self.measure(self.row(first), range, ws)?;
        found = found.join(self.at_state(raw, a));
        let mut k = first + 1;
        while found.ok && k <= last {
            let reach = self.bounds_of(&self.step(anchor, k));
            if a.0 - reach.0 > self.margin && a.1 - reach.1 > self.margin {
                k += 1;
                continue;
            }
            if self.late() {
                found.ok = false;
                found.complete = false;
                break;
            }
            let near = if k - 1 == anchor {
                a
            } else {
                let r = self.bounds_of(&self.step(anchor, k - 1));
                (a.0 - r.0, a.1 - r.1)
            };
            let (b, raw) = self.measure(self.row(k), range, ws)?;
            found = found.join(self.at_state(raw, b));
            if found.ok {
                let seg =
                    self.segment(self.row(k - 1), self.row(k), (near, b), (true, true), 0, ws)?;
                found = found.join(seg);
            }
            (anchor, a) = (k, b);
            k += 1;
        }
        Ok(found)
    }

    /// What a measured state contributes: its distances, and whether both exceed the margin.
    fn at_state(&self, raw: Pair, certified: Pair) -> Found {
        Found {
            least: raw,
            ok: certified.0 > self.margin && certified.1 > self.margin,
            complete: true,
            measured: 1,
        }
    }

    fn late(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() > d)
    }

    /// Both distances at q, each measured up to `margin + need + slack` (m; `need` NaN: not
    /// measured, +∞): (lower bounds clipped at that cutoff, for certificates; the values as measured,
    /// +∞ beyond the cutoff, for the report).
    fn measure(&self, q: &[f64], need: Pair, ws: &mut MeshWorkspace) -> Result<(Pair, Pair)> {
        let max = self.checker.max_distance;
        let cut = |n: f64| (self.margin + n + CUTOFF_SLACK).min(max);
        let scene = if need.0.is_nan() {
            (f64::INFINITY, f64::INFINITY)
        } else {
            let c = cut(need.0);
            let d = self
                .checker
                .clearance_in(self.scene, &self.obstacles, q, c, ws)?;
            (d.min(c), d)
        };
        let own = if need.1.is_nan() {
            (f64::INFINITY, f64::INFINITY)
        } else {
            let c = cut(need.1);
            let d = self
                .checker
                .self_clearance_in(q, c, c == f64::INFINITY, ws)?;
            (d.min(c), d)
        };
        Ok(((scene.0, own.0), (scene.1, own.1)))
    }

    /// Both motion bounds (scene, self) of the joint step `dq`.
    fn bounds_of(&self, dq: &[f64]) -> Pair {
        (self.bounds.obstacle_bound(dq), self.bounds.self_bound(dq))
    }

    /// Whether the segment with end distances `a`, `b` and bound `bound` stays beyond the margin.
    fn certified(&self, a: f64, b: f64, bound: f64) -> bool {
        a > self.margin && b > self.margin && a + b - bound > 2.0 * self.margin
    }

    /// Check the segment qa → qb (ends measured: `da`, `db`), halving it while it is not certified.
    /// `open`: which of (scene, self) still need certifying.
    fn segment(
        &self,
        qa: &[f64],
        qb: &[f64],
        (da, db): (Pair, Pair),
        open: (bool, bool),
        depth: u32,
        ws: &mut MeshWorkspace,
    ) -> Result<Found> {
        let dq: Vec<f64> = qa.iter().zip(qb).map(|(a, b)| b - a).collect();
        let bound = self.bounds_of(&dq);
        let scene_open = open.0 && !self.certified(da.0, db.0, bound.0);
        let self_open = open.1 && !self.certified(da.1, db.1, bound.1);
        if !scene_open && !self_open {
            return Ok(Found::NONE);
        }
        if self.late() {
            return Ok(Found {
                ok: false,
                complete: false,
                ..Found::NONE
            });
        }
        if depth >= MAX_DEPTH {
            return Ok(Found {
                ok: false,
                ..Found::NONE
            });
        }
        let qm: Vec<f64> = qa.iter().zip(qb).map(|(a, b)| 0.5 * (a + b)).collect();
        // Each half's bound is half the segment's (the bound is linear in |Δq|); the midpoint must
        // cover half of that for either half to certify.
        let need = |open: bool, bound: f64| if open { bound / 4.0 } else { f64::NAN };
        let (dm, raw) = self.measure(
            &qm,
            (need(scene_open, bound.0), need(self_open, bound.1)),
            ws,
        )?;
        let here = Found {
            least: raw,
            ok: !(scene_open && dm.0 <= self.margin || self_open && dm.1 <= self.margin),
            complete: true,
            measured: 1,
        };
        if !here.ok {
            return Ok(here);
        }
        let open = (scene_open, self_open);
        let left = self.segment(qa, &qm, (da, dm), open, depth + 1, ws)?;
        if !left.ok {
            return Ok(here.join(left));
        }
        let right = self.segment(&qm, qb, (dm, db), open, depth + 1, ws)?;
        Ok(here.join(left).join(right))
    }
}

impl MeshChecker {
    /// The motion bounds of this checker's shapes and self-collision pairs.
    pub fn motion_bounds(&self) -> MotionBounds {
        MotionBounds::new(self)
    }

    /// Continuous verdict on the path through the states `qs` (T × dof row-major, joint order of
    /// [`MeshChecker::robot`]), straight in joint space between consecutive states: whether every
    /// configuration on it keeps the collision geometry more than `margin` (m, ≥ 0) from `scene`
    /// and from itself (see the module documentation). The states are split into runs checked in
    /// parallel (rayon, on `threads` threads or the current pool), each from anchor to anchor
    /// ([`Context::cover`]); the verdict does not depend on the split. With a `deadline` the sweep
    /// ends at it with `complete = false`. T = 0: ok; T = 1: the state alone.
    ///
    /// Errors: `Shape` (length not a multiple of dof), `NonFinite`, `Value` (negative or NaN
    /// margin, `threads` = 0, a pair parry cannot measure).
    pub fn sweep(
        &self,
        scene: &Scene,
        qs: &[f64],
        margin: f64,
        threads: Option<usize>,
        deadline: Option<Instant>,
    ) -> Result<Sweep> {
        if margin.is_nan() || margin < 0.0 {
            return Err(FabricError::Value {
                what: "margin".to_string(),
                message: format!("must be >= 0 m, got {margin}"),
            });
        }
        let n = self.states(qs)?;
        let dof = self.robot.dof();
        let cx = Context {
            checker: self,
            bounds: self.motion_bounds(),
            scene,
            obstacles: scene.iter().map(|(_, o)| o).collect(),
            margin,
            deadline,
            qs,
            dof,
        };
        // Runs of states covered in parallel; neighbouring runs share their boundary state.
        let runs = (2 * rayon::current_num_threads().max(1)).min(n.max(1));
        let cuts: Vec<usize> = (0..=runs).map(|r| r * n.saturating_sub(1) / runs).collect();
        let found = if n == 0 {
            Found::NONE
        } else {
            with_threads(threads, || {
                cuts.par_windows(2)
                    .map_init(|| self.workspace(), |ws, w| cx.cover(w[0], w[1], ws))
                    .try_reduce(|| Found::NONE, |a, b| Ok(a.join(b)))
            })??
        };
        Ok(Sweep {
            clearance: found.least.0,
            self_clearance: found.least.1,
            ok: found.ok && found.complete,
            complete: found.complete,
            measured: found.measured,
        })
    }
}
