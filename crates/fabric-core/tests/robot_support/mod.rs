//! Helpers shared by the `robot_*` integration tests: the shared-data skip rule, random states, and
//! finite-difference references.
#![allow(dead_code)]

#[path = "../common/mod.rs"]
mod common;

use std::path::PathBuf;

use fabric_core::robot::{KinematicsWorkspace, Robot, RobotOptions, TaskPoint};
use nalgebra::{Matrix3xX, Point3, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// The shared-data skip rule (`tests/common`): `<repo>/../shared` (or `$GFCS_SHARED`), `None` (test
/// skipped, reason printed) when absent, unless `CI=true`: then the test fails.
#[allow(unused_imports)] // not every test crate that includes this module calls it
pub use common::shared_dir;

/// The MotionBenchMaker Panda directory, or `None` (skip rule of [`shared_dir`]).
pub fn mbm_panda_dir() -> Option<PathBuf> {
    shared_dir().map(|d| d.join("robots/mbm_panda"))
}

/// The spherized MBM Panda with default options, or `None` (skip rule).
pub fn mbm_spherized() -> Option<Robot> {
    let dir = mbm_panda_dir()?;
    Some(
        Robot::from_urdf_file(&dir.join("panda_spherized.urdf"), &RobotOptions::default())
            .expect("MBM Panda"),
    )
}

/// Uniform q inside the limits, and q̇ uniform in [-2, 2] per coordinate.
pub fn random_state(robot: &Robot, rng: &mut ChaCha8Rng) -> (Vec<f64>, Vec<f64>) {
    let q = robot
        .lower()
        .iter()
        .zip(robot.upper())
        .map(|(&l, &u)| rng.gen_range(l..u))
        .collect();
    let qd = (0..robot.dof()).map(|_| rng.gen_range(-2.0..2.0)).collect();
    (q, qd)
}

/// ‖a − b‖ / max(‖a‖, ‖b‖, 1e-3).
pub fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    let n = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    n(&d) / n(a).max(n(b)).max(1e-3)
}

/// A task map evaluated from forward kinematics only (link poses), independent of `point`/`axis`.
#[derive(Clone, Copy, Debug)]
pub enum Task {
    /// A point fixed on a link (link frame coordinates).
    Point(usize, Vector3<f64>),
    /// A direction fixed on a link (link frame).
    Axis(usize, Vector3<f64>),
}

impl Task {
    /// x(q) from the link pose after `update_positions`.
    pub fn eval(&self, robot: &Robot, ws: &mut KinematicsWorkspace, q: &[f64]) -> Vector3<f64> {
        robot.update_positions(q, ws).expect("fk");
        match *self {
            Task::Point(l, p) => (robot.link_pose(ws, l) * Point3::from(p)).coords,
            Task::Axis(l, u) => robot.link_pose(ws, l).rotation * u,
        }
    }

    /// Analytic kinematics at (q, q̇) from `point` / `axis`.
    pub fn analytic(
        &self,
        robot: &Robot,
        ws: &mut KinematicsWorkspace,
        q: &[f64],
        qd: &[f64],
    ) -> TaskPoint {
        robot.update(q, qd, ws).expect("update");
        let mut out = TaskPoint::new(robot.dof());
        match *self {
            Task::Point(l, p) => robot.point(ws, l, &p, &mut out),
            Task::Axis(l, u) => robot.axis(ws, l, &u, &mut out),
        }
        out
    }
}

fn shifted(q: &[f64], dir: &[f64], h: f64) -> Vec<f64> {
    q.iter().zip(dir).map(|(a, b)| a + h * b).collect()
}

/// Derivative at 0 of a smooth function of one variable: central differences with steps h and h/2
/// combined by Richardson extrapolation (error O(h⁴)).
fn richardson(mut f: impl FnMut(f64) -> Vector3<f64>, h: f64) -> Vector3<f64> {
    let mut central = |h: f64| (f(h) - f(-h)) / (2.0 * h);
    let (coarse, fine) = (central(h), central(h / 2.0));
    (4.0 * fine - coarse) / 3.0
}

/// Finite-difference step of the first-derivative references (with Richardson extrapolation, the
/// truncation error is about 1e-12 and the rounding error about 1e-13).
const H: f64 = 1e-3;

/// Jacobian ∂x/∂q of the forward kinematics by finite differences, column by column.
pub fn fd_jacobian(
    task: &Task,
    robot: &Robot,
    ws: &mut KinematicsWorkspace,
    q: &[f64],
) -> Matrix3xX<f64> {
    let mut jac = Matrix3xX::zeros(robot.dof());
    for c in 0..robot.dof() {
        let mut e = vec![0.0; robot.dof()];
        e[c] = 1.0;
        let d = richardson(|h| task.eval(robot, ws, &shifted(q, &e, h)), H);
        jac.set_column(c, &d);
    }
    jac
}

/// J̇q̇ as d/dt (J(q + t q̇) q̇) at t = 0, by finite differences of the analytic J.
pub fn fd_jdot_qdot(
    task: &Task,
    robot: &Robot,
    ws: &mut KinematicsWorkspace,
    q: &[f64],
    qd: &[f64],
) -> Vector3<f64> {
    let v = nalgebra::DVector::from_column_slice(qd);
    richardson(
        |h| task.analytic(robot, ws, &shifted(q, qd, h), qd).jac * &v,
        H,
    )
}

/// ẍ along q(t) = q + t q̇ (q̈ = 0) from the forward kinematics only: second central differences with
/// steps 2e-3 and 1e-3 combined by Richardson extrapolation (error O(h⁴), about 1e-9 m/s² here).
pub fn fd_second(
    task: &Task,
    robot: &Robot,
    ws: &mut KinematicsWorkspace,
    q: &[f64],
    qd: &[f64],
) -> Vector3<f64> {
    let x0 = task.eval(robot, ws, q);
    let mut second = |h: f64| {
        let xp = task.eval(robot, ws, &shifted(q, qd, h));
        let xm = task.eval(robot, ws, &shifted(q, qd, -h));
        (xp - 2.0 * x0 + xm) / (h * h)
    };
    let (coarse, fine) = (second(2e-3), second(1e-3));
    (4.0 * fine - coarse) / 3.0
}

/// ẋ along q̇ by finite differences of the forward kinematics.
pub fn fd_velocity(
    task: &Task,
    robot: &Robot,
    ws: &mut KinematicsWorkspace,
    q: &[f64],
    qd: &[f64],
) -> Vector3<f64> {
    richardson(|h| task.eval(robot, ws, &shifted(q, qd, h)), H)
}

/// Check x, ẋ, J and J̇q̇ of `task` at (q, q̇) against the finite-difference references; returns the
/// largest relative error over J, J̇q̇ (analytic-J reference) and ẋ, and the error against the FK-only
/// second difference separately.
pub fn check_task(task: &Task, robot: &Robot, q: &[f64], qd: &[f64]) -> (f64, f64) {
    let mut ws = KinematicsWorkspace::new(robot);
    let tp = task.analytic(robot, &mut ws, q, qd);
    let x = task.eval(robot, &mut ws, q);
    assert!((tp.x - x).norm() < 1e-12, "x mismatch {task:?}");
    let jq = &tp.jac * nalgebra::DVector::from_column_slice(qd);
    assert!(
        (tp.xd - jq).norm() <= 1e-12 * (1.0 + jq.norm()),
        "xd != J qd for {task:?}"
    );
    let j_fd = fd_jacobian(task, robot, &mut ws, q);
    let jd_fd = fd_jdot_qdot(task, robot, &mut ws, q, qd);
    let xd_fd = fd_velocity(task, robot, &mut ws, q, qd);
    let e = rel_err(tp.jac.as_slice(), j_fd.as_slice())
        .max(rel_err(tp.jdot_qdot.as_slice(), jd_fd.as_slice()))
        .max(rel_err(tp.xd.as_slice(), xd_fd.as_slice()));
    let e2 = rel_err(
        tp.jdot_qdot.as_slice(),
        fd_second(task, robot, &mut ws, q, qd).as_slice(),
    );
    (e, e2)
}
