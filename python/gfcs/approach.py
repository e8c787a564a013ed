"""Approach configurations: the goal's end-effector pose backed off along its approach axis, by inverse
kinematics.

A grasp goal (MotionBenchMaker's shelves, boxes, cages, tables) sits in narrow free space that the arm can
enter only along the gripper's approach direction. The configuration whose end effector has the goal's
orientation but stands ``distance`` metres back along that axis (a pre-grasp) lies at the mouth of that
corridor, and makes a good intermediate command for GFCS (:class:`gfcs.optimize.ApproachSampler`).

Inverse kinematics: damped least squares on the stacked task e = [p* − p; w (x* − x); w (z* − z)] (EE
position and two EE axes, world frame; w = ``AXIS_WEIGHT`` m per unit of axis error), started at the goal
configuration and continued from one distance to the next, each step clipped into the joint limits.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

__all__ = ["approach_configurations", "AXIS_WEIGHT"]

#: Weight (m) of an EE-axis error relative to a position error of 1 m.
AXIS_WEIGHT = 0.3
_DAMPING = 1e-3
_TOL = 1e-5


def approach_configurations(
    robot: Any,
    q_goal: Any,
    distances: Sequence[float],
    axis: Sequence[float] = (0.0, 0.0, 1.0),
    iterations: int = 30,
) -> np.ndarray:
    """Configurations whose end effector keeps the goal's orientation and backs off along ``axis``.

    Args:
        robot: a ``gfcs.Robot`` (its ``ee_link`` is the end effector).
        q_goal: (dof,) goal configuration, rad (or m for prismatic joints).
        distances: back-off distances d ≥ 0 (m), solved in the given order, each starting from the
            previous solution (sort them ascending for the shortest continuation).
        axis: approach direction in the end-effector frame (unit vector after normalisation; default its z
            axis, the Panda gripper's). The target position is p_goal − d · R_goal · axis.
        iterations: damped least-squares steps per distance (fewer when the task error falls below 1e-5).

    Returns:
        (len(distances), dof) configurations inside the joint limits. Where the target cannot be reached
        (limits, singularities) the row is the closest configuration the iteration found.

    Raises:
        ValueError: ``q_goal`` of the wrong shape or not finite, a negative or non-finite distance, a zero
            or non-finite axis.
    """
    lo = np.asarray(robot.lower, dtype=np.float64)
    up = np.asarray(robot.upper, dtype=np.float64)
    q = np.asarray(q_goal, dtype=np.float64).copy()
    if q.shape != lo.shape or not np.all(np.isfinite(q)):
        raise ValueError(f"q_goal: expected {lo.shape[0]} finite values, got shape {q.shape}")
    d = np.asarray(distances, dtype=np.float64).reshape(-1)
    if not (np.all(np.isfinite(d)) and np.all(d >= 0)):
        raise ValueError(f"distances must be finite and >= 0, got {d.tolist()}")
    a = np.asarray(axis, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
        raise ValueError(f"axis: expected a non-zero 3-vector, got {np.asarray(axis).tolist()}")
    a = a / np.linalg.norm(a)
    ee = robot.link_index(robot.ee_link)
    goal_pose = np.asarray(robot.link_poses(q))[ee]
    x_t, z_t = goal_pose[:3, 0], goal_pose[:3, 2]
    out = np.empty((d.shape[0], q.shape[0]))
    for row, dist in enumerate(d):
        p_t = goal_pose[:3, 3] - dist * (goal_pose[:3, :3] @ a)
        for _ in range(int(iterations)):
            pose = np.asarray(robot.link_poses(q))[ee]
            e = np.concatenate([p_t - pose[:3, 3], AXIS_WEIGHT * (x_t - pose[:3, 0]),
                                AXIS_WEIGHT * (z_t - pose[:3, 2])])
            if np.linalg.norm(e) < _TOL:
                break
            jac = np.vstack([robot.point_jacobian(q, ee, np.zeros(3)),
                             AXIS_WEIGHT * np.asarray(robot.axis_jacobian(q, ee, [1.0, 0.0, 0.0])),
                             AXIS_WEIGHT * np.asarray(robot.axis_jacobian(q, ee, [0.0, 0.0, 1.0]))])
            step = jac.T @ np.linalg.solve(jac @ jac.T + _DAMPING * np.eye(9), e)
            q = np.clip(q + step, lo, up)
        out[row] = q
    return out
