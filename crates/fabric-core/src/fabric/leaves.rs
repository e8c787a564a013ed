//! Task maps of the 1-D distance leaves of the robot transform tree (GF VII-A2): the value x, its rate ẋ,
//! the row Jacobian J = ∂x/∂q (n,) and the curvature J̇q̇, from the kinematics of sphere centres
//! ([`TaskPoint`]: c, ċ = J_c q̇, J_c, J̇_c q̇).
//!
//! - Obstacle leaf, x = d(c) − r − margin with d the signed distance of the obstacle (gradient ∇d,
//!   Hessian H, velocity v_o):
//!   ```text
//!   ẋ = ∇dᵀ (ċ − v_o),  J = ∇dᵀ J_c,  J̇q̇ = ∇dᵀ J̇_c q̇ + (ċ − v_o)ᵀ H (ċ − v_o).
//!   ```
//!   For a static obstacle this is the exact chain rule of x(q) = d(c(q)); for a moving one (translating
//!   at constant v_o) it is d/dt of ẋ along the motion, so that ẍ = J q̈ + J̇q̇ still holds.
//! - Self-collision leaf, x = ‖c_a − c_b‖ − r_a − r_b − margin, with u = c_a − c_b, n̂ = u/‖u‖:
//!   ```text
//!   ẋ = n̂ᵀ u̇,  J = n̂ᵀ (J_a − J_b),  J̇q̇ = n̂ᵀ (J̇_a q̇ − J̇_b q̇) + (‖u̇‖² − (n̂ᵀu̇)²) / ‖u‖.
//!   ```
//!   Coincident centres (‖u‖ < 1e-12) use n̂ = +z and drop the curvature term.
//!
//! Both accept a minimum curvature radius ρ that bounds the curvature term of J̇q̇ (exact when ρ = 0).
//!
//! Signs of J̇q̇ are checked against finite differences of J(q + t q̇) q̇ in `tests/fabric_leaves.rs`.

use nalgebra::Vector3;

use crate::robot::TaskPoint;
use crate::scene::DistanceSample;

/// Value, rate and curvature of a 1-D leaf; its row Jacobian is written into a caller buffer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LeafState {
    /// x (m).
    pub x: f64,
    /// ẋ (m/s).
    pub xd: f64,
    /// J̇q̇ (m/s²).
    pub jdot_qdot: f64,
    /// Number of leading entries of the row Jacobian that may be non-zero (the rest are written as 0):
    /// the widest [`TaskPoint::width`] of the leaf's points.
    pub width: usize,
}

/// Obstacle leaf for a sphere of radius `radius` centred at the task point `c` and one distance `sample`
/// of its centre; writes J (n,) into `jac`. See the module docs for the formulas.
///
/// `min_curvature_radius` ρ (m, ≥ 0) bounds the curvature of the distance field used in J̇q̇: the Hessian
/// is scaled by min(1, 1/(ρ‖H‖_F)), i.e. surface features sharper than ρ are treated as if rounded to
/// radius ρ. With ρ = 0 the exact Hessian is used. (Near box edges the exact curvature 1/d of the
/// distance field makes J̇q̇ ~ ‖ċ‖²/d, too stiff for explicit integration at dt = 0.01 s.)
///
/// With `curvature` false, J̇q̇ is not computed and returned as 0: for a leaf whose metric is zero (a
/// barrier moving away, [`SwitchedEnergy1D`](super::energy::SwitchedEnergy1D)), where the root only
/// uses it multiplied by that zero metric (M J̇q̇ in ξ̃ and f̃); in a cluttered scene many leaves are
/// such. x and ẋ are [`obstacle_value`]'s.
pub fn obstacle_leaf(
    c: &TaskPoint,
    radius: f64,
    margin: f64,
    sample: &DistanceSample,
    min_curvature_radius: f64,
    curvature: bool,
    jac: &mut [f64],
) -> LeafState {
    let g = &sample.gradient;
    let (x, xd) = obstacle_value(c, radius, margin, sample);
    let (row, zero) = jac.split_at_mut(c.width.min(jac.len()));
    for (j, col) in row.iter_mut().zip(c.jac.as_slice().chunks_exact(3)) {
        *j = g.x * col[0] + g.y * col[1] + g.z * col[2];
    }
    zero.fill(0.0);
    let jdot_qdot = if curvature {
        let rel = c.xd - sample.velocity;
        // ‖H‖_F = 0 on flat features (faces): skip the square root
        let h_norm2 = sample.hessian.norm_squared();
        let h_norm = if h_norm2 > 0.0 { h_norm2.sqrt() } else { 0.0 };
        let scale = if min_curvature_radius * h_norm > 1.0 {
            1.0 / (min_curvature_radius * h_norm)
        } else {
            1.0
        };
        g.dot(&c.jdot_qdot) + scale * rel.dot(&(sample.hessian * rel))
    } else {
        0.0
    };
    LeafState {
        x,
        xd,
        jdot_qdot,
        width: row.len(),
    }
}

/// The value x = d(c) − r − margin (m) and rate ẋ = ∇dᵀ (ċ − v_o) (m/s) of an obstacle leaf: what a
/// barrier needs before the leaf's Jacobian ([`obstacle_leaf`] returns the same two numbers).
#[inline]
pub fn obstacle_value(
    c: &TaskPoint,
    radius: f64,
    margin: f64,
    sample: &DistanceSample,
) -> (f64, f64) {
    let rel = c.xd - sample.velocity;
    (sample.distance - radius - margin, sample.gradient.dot(&rel))
}

/// Self-collision leaf between spheres (c_a, r_a) and (c_b, r_b); writes J (n,) into `jac`. See the module
/// docs for the formulas. The curvature term divides by max(‖u‖, `min_curvature_radius`) (see
/// [`obstacle_leaf`]; inactive while the spheres do not overlap deeply when ρ ≤ r_a + r_b).
pub fn self_collision_leaf(
    a: &TaskPoint,
    ra: f64,
    b: &TaskPoint,
    rb: f64,
    margin: f64,
    min_curvature_radius: f64,
    jac: &mut [f64],
) -> LeafState {
    let u = a.x - b.x;
    let ud = a.xd - b.xd;
    let dist = u.norm();
    let (n, curv) = if dist > 1e-12 {
        let n = u / dist;
        let along = n.dot(&ud);
        (
            n,
            (ud.norm_squared() - along * along) / dist.max(min_curvature_radius),
        )
    } else {
        (Vector3::z(), 0.0)
    };
    let columns = a
        .jac
        .as_slice()
        .chunks_exact(3)
        .zip(b.jac.as_slice().chunks_exact(3));
    let (row, zero) = jac.split_at_mut(a.width.max(b.width).min(jac.len()));
    for (j, (ca, cb)) in row.iter_mut().zip(columns) {
        *j = n.x * (ca[0] - cb[0]) + n.y * (ca[1] - cb[1]) + n.z * (ca[2] - cb[2]);
    }
    zero.fill(0.0);
    LeafState {
        x: dist - ra - rb - margin,
        xd: n.dot(&ud),
        jdot_qdot: n.dot(&(a.jdot_qdot - b.jdot_qdot)) + curv,
        width: row.len(),
    }
}
