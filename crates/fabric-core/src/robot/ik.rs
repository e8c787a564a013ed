//! Damped least-squares inverse kinematics of one link, for many targets in parallel (rayon, in the
//! current thread pool; results in input order whatever the thread count).
//!
//! Each target asks for the origin of the link at `position` (world = base frame, m) and, optionally,
//! for the link's x and z axes along `axes` (unit world directions). The task error is
//! e = [p* − p; w (x* − x); w (z* − z)] with w = [`IkOptions::axis_weight`] (m per unit of axis error),
//! and each step is Δq = Jᵀ (J Jᵀ + λ I)⁻¹ e (λ = [`IkOptions::damping`], m²), then q is clipped into the
//! joint limits. The iteration stops after [`IkOptions::iterations`] steps or when ‖e‖ <
//! [`IkOptions::tolerance`]; a target out of reach returns the closest configuration it found.

use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;

use super::kinematics::{KinematicsWorkspace, TaskPoint};
use super::model::Robot;
use crate::error::{check_finite, FabricError, Result};

/// One inverse-kinematics target of a link.
#[derive(Clone, Debug, PartialEq)]
pub struct IkTarget {
    /// Position (m, world frame) of the link origin.
    pub position: Vector3<f64>,
    /// World directions of the link's x and z axes (normalised here), or `None` for position only.
    pub axes: Option<[Vector3<f64>; 2]>,
}

/// Settings of [`inverse_kinematics`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkOptions {
    /// Maximum number of damped least-squares steps.
    pub iterations: usize,
    /// λ (> 0, m²): damping of J Jᵀ.
    pub damping: f64,
    /// Stop when ‖e‖ is below this (m, > 0).
    pub tolerance: f64,
    /// w (≥ 0, m): weight of an axis error relative to a position error of 1 m.
    pub axis_weight: f64,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            iterations: 30,
            damping: 1e-3,
            tolerance: 1e-5,
            axis_weight: 0.3,
        }
    }
}

impl IkOptions {
    fn check(&self) -> Result<()> {
        check_settings(self.damping, self.tolerance, self.axis_weight)
    }
}

/// `Err(Value)` naming the setting unless damping and tolerance are finite and > 0 and the axis weight
/// finite and ≥ 0 (the settings both IK functions share).
fn check_settings(damping: f64, tolerance: f64, axis_weight: f64) -> Result<()> {
    let bad = |what: &str, message: String| {
        Err(FabricError::Value {
            what: what.into(),
            message,
        })
    };
    if !(damping.is_finite() && damping > 0.0) {
        return bad("damping", format!("must be > 0, got {damping}"));
    }
    if !(tolerance.is_finite() && tolerance > 0.0) {
        return bad("tolerance", format!("must be > 0, got {tolerance}"));
    }
    if !(axis_weight.is_finite() && axis_weight >= 0.0) {
        return bad("axis_weight", format!("must be >= 0, got {axis_weight}"));
    }
    Ok(())
}

/// Clip `q` into [`lower`, `upper`] element-wise.
fn clip(q: &mut [f64], lower: &[f64], upper: &[f64]) {
    for ((v, l), u) in q.iter_mut().zip(lower).zip(upper) {
        *v = v.clamp(*l, *u);
    }
}

/// The damped least-squares step Δq = Jᵀ (J Jᵀ + λ I)⁻¹ e (λ = `damping` > 0, which makes J Jᵀ + λ I
/// symmetric positive definite); None if its Cholesky factorisation fails all the same.
fn damped_step(jac: &DMatrix<f64>, err: &DVector<f64>, damping: f64) -> Option<DVector<f64>> {
    let mut gram = jac * jac.transpose();
    for i in 0..gram.nrows() {
        gram[(i, i)] += damping;
    }
    let chol = gram.cholesky()?;
    Some(jac.transpose() * chol.solve(err))
}

/// Inverse kinematics of `link` for N targets: row i starts at `q_init` row i (N × dof, row-major, rad
/// or m; clipped into the limits first) and goes to `targets[i]`. Returns N × dof row-major
/// configurations inside the joint limits.
///
/// Errors: `Shape` (q_init not N × dof for N = targets.len()), `NonFinite` (q_init or a target),
/// `Value` (link index out of range, a zero axis, bad options).
pub fn inverse_kinematics(
    robot: &Robot,
    link: usize,
    q_init: &[f64],
    targets: &[IkTarget],
    options: &IkOptions,
) -> Result<Vec<f64>> {
    robot.check_link_index(link, "link")?;
    options.check()?;
    let dof = robot.dof();
    if q_init.len() != targets.len() * dof {
        return Err(FabricError::Shape {
            what: "q_init".into(),
            expected: format!("({}, {dof})", targets.len()),
            got: format!("{} values", q_init.len()),
        });
    }
    check_finite("q_init", q_init)?;
    let mut goals = Vec::with_capacity(targets.len());
    for t in targets {
        check_finite("target position", t.position.as_slice())?;
        let axes = match t.axes {
            None => None,
            Some([x, z]) => {
                check_finite("target axes", x.as_slice())?;
                check_finite("target axes", z.as_slice())?;
                if x.norm() == 0.0 || z.norm() == 0.0 {
                    return Err(FabricError::Value {
                        what: "target axes".into(),
                        message: "an axis is zero".into(),
                    });
                }
                Some([x.normalize(), z.normalize()])
            }
        };
        goals.push((t.position, axes));
    }
    let mut out = q_init.to_vec();
    out.par_chunks_mut(dof.max(1))
        .zip(goals.par_iter())
        .for_each_init(
            || (KinematicsWorkspace::new(robot), TaskPoint::new(dof)),
            |(ws, tp), (q, goal)| solve_one(robot, link, q, goal, options, ws, tp),
        );
    Ok(out)
}

/// The iteration of [`inverse_kinematics`] for one row, in place on `q` (checked: length dof, finite).
fn solve_one(
    robot: &Robot,
    link: usize,
    q: &mut [f64],
    (position, axes): &(Vector3<f64>, Option<[Vector3<f64>; 2]>),
    options: &IkOptions,
    ws: &mut KinematicsWorkspace,
    tp: &mut TaskPoint,
) {
    let (lo, up) = (robot.lower(), robot.upper());
    clip(q, lo, up);
    let dof = q.len();
    let rows = if axes.is_some() { 9 } else { 3 };
    let w = options.axis_weight;
    let mut jac = DMatrix::<f64>::zeros(rows, dof);
    let mut err = DVector::<f64>::zeros(rows);
    for _ in 0..options.iterations {
        robot.forward_positions(q, ws);
        robot.point(ws, link, &Vector3::zeros(), tp);
        err.rows_mut(0, 3).copy_from(&(position - tp.x));
        jac.rows_mut(0, 3).copy_from(&tp.jac);
        if let Some(targets) = axes {
            for (k, (local, target)) in [Vector3::x(), Vector3::z()].iter().zip(targets).enumerate()
            {
                robot.axis(ws, link, local, tp);
                err.rows_mut(3 + 3 * k, 3).copy_from(&((target - tp.x) * w));
                jac.rows_mut(3 + 3 * k, 3).copy_from(&(&tp.jac * w));
            }
        }
        if err.norm() < options.tolerance {
            return;
        }
        let Some(step) = damped_step(&jac, &err, options.damping) else {
            return;
        };
        for (v, s) in q.iter_mut().zip(step.iter()) {
            *v += s;
        }
        clip(q, lo, up);
    }
}

/// Settings of [`point_ik`] (defaults: those of the procedural problem generators).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointIkOptions {
    /// Maximum number of damped least-squares steps.
    pub iterations: usize,
    /// λ² (> 0, m²): damping of J Jᵀ.
    pub damping: f64,
    /// Converged when the point is within this of its target (m, > 0) and the axis inside its cone.
    pub tolerance: f64,
    /// w (≥ 0): weight of the axis rows (J and e) relative to the position rows.
    pub axis_weight: f64,
    /// Largest step norm ‖Δq‖ (rad, > 0): longer steps are scaled down to it.
    pub max_step: f64,
}

impl Default for PointIkOptions {
    fn default() -> Self {
        PointIkOptions {
            iterations: 150,
            damping: 0.05 * 0.05,
            tolerance: 2e-3,
            axis_weight: 0.5,
            max_step: 0.3,
        }
    }
}

/// Target of [`point_ik`]: a position for a point of the link and, optionally, a direction for one of
/// its axes, met when the axis lies within a cone around it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointTarget {
    /// Position (m, world frame) of the link point.
    pub position: Vector3<f64>,
    /// World direction for the link axis (normalised here) and the cosine of the cone's half angle.
    pub approach: Option<(Vector3<f64>, f64)>,
}

/// One damped least-squares descent, in place on `q` (dof), of the point `point` (link frame, m) of
/// `link` to `target.position` and, with an approach, of the link axis `axis` (link frame) toward the
/// approach direction a*: e = [x* − x; w (a* − R·axis)], Δq = Jᵀ (J Jᵀ + λ² I)⁻¹ e scaled to at most
/// `max_step`, q clipped into [`lower`, `upper`] (rad) before the first step and after each. Returns
/// whether it converged: ‖x* − x‖ < `tolerance` and a*·(R·axis) ≥ the cone's cosine, tested before
/// each step (so a start that already meets the target is returned unchanged, clipped).
///
/// Errors: `Shape` (q, lower or upper not of length dof), `NonFinite` (inputs), `Value` (link out of
/// range, zero axis or approach, lower > upper, bad options).
#[allow(clippy::too_many_arguments)]
pub fn point_ik(
    robot: &Robot,
    link: usize,
    point: &Vector3<f64>,
    axis: &Vector3<f64>,
    target: &PointTarget,
    q: &mut [f64],
    lower: &[f64],
    upper: &[f64],
    options: &PointIkOptions,
) -> Result<bool> {
    robot.check_link_index(link, "link")?;
    let dof = robot.dof();
    for (what, v) in [("q", &*q), ("lower", lower), ("upper", upper)] {
        if v.len() != dof {
            return Err(FabricError::Shape {
                what: what.into(),
                expected: format!("({dof},)"),
                got: format!("({},)", v.len()),
            });
        }
        check_finite(what, v)?;
    }
    check_finite("point", point.as_slice())?;
    check_finite("axis", axis.as_slice())?;
    check_finite("target position", target.position.as_slice())?;
    let value = |what: &str, message: String| FabricError::Value {
        what: what.into(),
        message,
    };
    if lower.iter().zip(upper).any(|(l, u)| l > u) {
        return Err(value(
            "lower",
            "a lower bound exceeds its upper bound".into(),
        ));
    }
    let o = options;
    check_settings(o.damping, o.tolerance, o.axis_weight)?;
    if !(o.max_step.is_finite() && o.max_step > 0.0) {
        return Err(value(
            "max_step",
            format!("must be > 0, got {}", o.max_step),
        ));
    }
    let approach = match target.approach {
        None => None,
        Some((a, cos_cone)) => {
            check_finite("approach", a.as_slice())?;
            check_finite("cone", &[cos_cone])?;
            if a.norm() == 0.0 || axis.norm() == 0.0 {
                return Err(value(
                    "approach",
                    "the approach direction or the axis is zero".into(),
                ));
            }
            Some((a.normalize(), cos_cone))
        }
    };
    clip(q, lower, upper);
    let rows = if approach.is_some() { 6 } else { 3 };
    let w = o.axis_weight;
    let (mut ws, mut tp) = (KinematicsWorkspace::new(robot), TaskPoint::new(dof));
    let mut jac = DMatrix::<f64>::zeros(rows, dof);
    let mut err = DVector::<f64>::zeros(rows);
    for _ in 0..o.iterations {
        robot.forward_positions(q, &mut ws);
        robot.point(&ws, link, point, &mut tp);
        let position_error = target.position - tp.x;
        err.rows_mut(0, 3).copy_from(&position_error);
        jac.rows_mut(0, 3).copy_from(&tp.jac);
        let mut inside = true;
        if let Some((a, cos_cone)) = approach {
            robot.axis(&ws, link, axis, &mut tp);
            inside = a.dot(&tp.x) >= cos_cone;
            err.rows_mut(3, 3).copy_from(&((a - tp.x) * w));
            jac.rows_mut(3, 3).copy_from(&(&tp.jac * w));
        }
        if position_error.norm() < o.tolerance && inside {
            return Ok(true);
        }
        let Some(mut step) = damped_step(&jac, &err, o.damping) else {
            return Ok(false);
        };
        let norm = step.norm();
        if norm > o.max_step {
            step *= o.max_step / norm;
        }
        for (v, s) in q.iter_mut().zip(step.iter()) {
            *v += s;
        }
        clip(q, lower, upper);
    }
    Ok(false)
}
