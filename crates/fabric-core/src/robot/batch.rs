//! Batched forward kinematics over many configurations, in parallel with rayon (in the current rayon
//! thread pool: wrap a call in `ThreadPool::install` to choose the thread count). Results are in input
//! order whatever the thread count.

use nalgebra::{Isometry3, Vector3};
use rayon::prelude::*;

use super::kinematics::KinematicsWorkspace;
use super::model::Robot;
use crate::error::{check_finite, FabricError, Result};

/// Number of configurations in `qs` (N × dof, row-major). Errors with `Shape` when the length is not a
/// multiple of dof.
fn rows(robot: &Robot, qs: &[f64]) -> Result<usize> {
    let dof = robot.dof();
    if qs.len().checked_rem(dof) != Some(0) {
        return Err(FabricError::Shape {
            what: "qs".into(),
            expected: format!("(N*{dof},)"),
            got: format!("({},)", qs.len()),
        });
    }
    check_finite("qs", qs)?;
    Ok(qs.len() / dof)
}

/// Fewer configurations than this are computed on the calling thread: forward kinematics takes about a
/// microsecond per configuration, waking rayon's workers tens of microseconds (a Python loop calling
/// `Robot.link_poses` once per step spent most of its time in futex wake-ups).
const PARALLEL_MIN_CONFIGS: usize = 32;

/// `value(ws, k)` for entry k of each configuration's output row after its forward kinematics, in
/// parallel ([`PARALLEL_MIN_CONFIGS`] and more). The result is collected by rayon straight into its final buffer (no serial zero-filling
/// first, which would keep one thread busy touching every page); a worker recomputes the kinematics
/// only when it moves on to the next configuration.
fn for_each_config<T: Send>(
    robot: &Robot,
    qs: &[f64],
    per_row: usize,
    value: impl Fn(&KinematicsWorkspace, usize) -> T + Sync,
) -> Result<Vec<T>> {
    let n = rows(robot, qs)?;
    let dof = robot.dof();
    if n < PARALLEL_MIN_CONFIGS {
        // a few configurations: waking the pool's threads would cost more than the kinematics
        let mut ws = KinematicsWorkspace::new(robot);
        let mut out = Vec::with_capacity(n * per_row);
        for q in qs.chunks_exact(dof) {
            robot.forward_positions(q, &mut ws);
            out.extend((0..per_row).map(|k| value(&ws, k)));
        }
        return Ok(out);
    }
    Ok((0..n * per_row)
        .into_par_iter()
        .with_min_len(per_row.max(1))
        .map_init(
            || (KinematicsWorkspace::new(robot), usize::MAX),
            |(ws, current), k| {
                let row = k / per_row;
                if *current != row {
                    // `rows` checked the lengths and finiteness of every configuration.
                    robot.forward_positions(&qs[row * dof..(row + 1) * dof], ws);
                    *current = row;
                }
                value(ws, k % per_row)
            },
        )
        .collect())
}

/// World poses of every link for N configurations: `qs` is N × dof row-major (rad or m); the result is
/// N × L row-major (L = number of links, in [`Robot::link_names`] order). Errors: `Shape`, `NonFinite`.
pub fn link_poses(robot: &Robot, qs: &[f64]) -> Result<Vec<Isometry3<f64>>> {
    let l = robot.link_names().len();
    for_each_config(robot, qs, l, |ws, k| *robot.link_pose(ws, k))
}

/// World centres (m) of every collision sphere for N configurations: `qs` is N × dof row-major; the
/// result is N × S row-major (S = number of spheres). Errors: `Shape`, `NonFinite`.
pub fn sphere_centers(robot: &Robot, qs: &[f64]) -> Result<Vec<Vector3<f64>>> {
    let s = robot.spheres().len();
    for_each_config(robot, qs, s, |ws, i| robot.sphere_center(ws, i))
}

/// World position (m) of the origin of `link` for N configurations: `qs` is N × dof row-major; the
/// result has N rows. Errors: `Shape`, `NonFinite`, `Value` when `link` is not a link index.
pub fn link_origins(robot: &Robot, qs: &[f64], link: usize) -> Result<Vec<Vector3<f64>>> {
    robot.check_link_index(link, "link")?;
    for_each_config(robot, qs, 1, |ws, _| {
        robot.link_pose(ws, link).translation.vector
    })
}

/// Self-collision clearance (m) for N configurations: per configuration, the minimum over
/// [`Robot::self_collision_pairs`] of ‖c_a − c_b‖ − r_a − r_b (negative: the spheres overlap); +∞ when
/// the robot has no pairs. `qs` is N × dof row-major. Errors: `Shape`, `NonFinite`.
pub fn self_clearance(robot: &Robot, qs: &[f64]) -> Result<Vec<f64>> {
    let spheres = robot.spheres();
    let pairs = robot.self_collision_pairs();
    for_each_config(robot, qs, 1, |ws, _| {
        let centers: Vec<Vector3<f64>> = (0..spheres.len())
            .map(|i| robot.sphere_center(ws, i))
            .collect();
        pairs.iter().fold(f64::INFINITY, |best, &(a, b)| {
            let d = (centers[a] - centers[b]).norm() - spheres[a].radius - spheres[b].radius;
            best.min(d)
        })
    })
}
