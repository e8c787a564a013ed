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

/// Run `fill(robot, ws, out_row)` after forward kinematics of each configuration, in parallel.
fn for_each_config<T: Send + Clone>(
    robot: &Robot,
    qs: &[f64],
    per_row: usize,
    zero: T,
    fill: impl Fn(&KinematicsWorkspace, &mut [T]) + Sync,
) -> Result<Vec<T>> {
    let n = rows(robot, qs)?;
    let mut out = vec![zero; n * per_row];
    if per_row == 0 {
        return Ok(out);
    }
    out.par_chunks_mut(per_row)
        .zip(qs.par_chunks(robot.dof()))
        .try_for_each_init(
            || KinematicsWorkspace::new(robot),
            |ws, (row, q)| {
                robot.update_positions(q, ws)?;
                fill(ws, row);
                Ok(())
            },
        )?;
    Ok(out)
}

/// World poses of every link for N configurations: `qs` is N × dof row-major (rad or m); the result is
/// N × L row-major (L = number of links, in [`Robot::link_names`] order). Errors: `Shape`, `NonFinite`.
pub fn link_poses(robot: &Robot, qs: &[f64]) -> Result<Vec<Isometry3<f64>>> {
    let l = robot.link_names().len();
    for_each_config(robot, qs, l, Isometry3::identity(), |ws, row| {
        for (k, pose) in row.iter_mut().enumerate() {
            *pose = *robot.link_pose(ws, k);
        }
    })
}

/// World centres (m) of every collision sphere for N configurations: `qs` is N × dof row-major; the
/// result is N × S row-major (S = number of spheres). Errors: `Shape`, `NonFinite`.
pub fn sphere_centers(robot: &Robot, qs: &[f64]) -> Result<Vec<Vector3<f64>>> {
    let s = robot.spheres().len();
    for_each_config(robot, qs, s, Vector3::zeros(), |ws, row| {
        for (i, c) in row.iter_mut().enumerate() {
            *c = robot.sphere_center(ws, i);
        }
    })
}
