"""Joint-space semantics of MoveIt requests: continuous joints and values on a bound.

* Continuous joints (URDF ``type="continuous"``) have no position limits. The core reports their range as
  [−2π, 2π] (``Robot.lower`` / ``upper``), a box for sampling commands, not a limit: a start or goal of
  such a joint may hold any angle, the goal error wraps (:func:`joint_difference`), and a goal is commanded
  as the equivalent angle nearest the start (:func:`unwrap_goal`), so that the arm turns the short way.
* Values on a bound: a MoveIt request stores angles rounded differently from the URDF's bounds (a start
  at π = 3.14159265… against a bound of 3.14159). MoveIt moves such a start state onto its bounds when it
  lies outside by little (the ``FixStartStateBounds`` adapter) and samples goals within both the goal
  constraint and the bounds. :func:`snap_to_bounds` does the same for values outside by at most
  ``BOUNDS_TOLERANCE``.
"""

from __future__ import annotations

import math
from typing import Any, List, Optional, Tuple

import numpy as np

__all__ = ["continuous_mask", "joint_difference", "unwrap_goal", "snap_to_bounds", "velocity_scales",
           "BOUNDS_TOLERANCE"]

#: Largest distance [rad or m] outside a joint's bounds at which :func:`snap_to_bounds` moves a value onto
#: the bound; farther out, a value is an error.
BOUNDS_TOLERANCE = 1e-3


def continuous_mask(robot: Any) -> np.ndarray:
    """(dof,) bool: the active joints that are URDF ``continuous`` joints (``Robot.continuous``). A revolute
    joint limited to [−2π, 2π] (the xArm's, many UR descriptions') is bounded: its goal is not wrapped. An
    object without ``continuous`` (a stand-in robot) counts the joints whose range is the core's [−2π, 2π]
    for continuous joints."""
    flags = getattr(robot, "continuous", None)
    if flags is not None:
        return np.asarray(flags, dtype=bool)
    lower = np.asarray(robot.lower, dtype=np.float64)
    upper = np.asarray(robot.upper, dtype=np.float64)
    return (lower == -math.tau) & (upper == math.tau)


def joint_difference(a: Any, b: Any, continuous: Any) -> np.ndarray:
    """a − b for joint vectors (..., dof), each continuous joint's component wrapped into [−π, π)."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    wrapped = (d + math.pi) % math.tau - math.pi
    return np.where(np.asarray(continuous, dtype=bool), wrapped, d)


def unwrap_goal(q0: Any, goal: Any, continuous: Any) -> np.ndarray:
    """``goal`` with each continuous joint moved by whole turns to the angle nearest ``q0`` (the same
    orientation of the joint, reached the short way); other joints unchanged."""
    q0, goal = np.asarray(q0, dtype=np.float64), np.asarray(goal, dtype=np.float64)
    return np.where(np.asarray(continuous, dtype=bool), q0 + joint_difference(goal, q0, continuous), goal)


def snap_to_bounds(robot: Any, q: Any, tol: float = BOUNDS_TOLERANCE) -> Tuple[np.ndarray, List[str]]:
    """``q`` (dof,) with every value outside its joint's bounds by at most ``tol`` moved onto the bound
    (continuous joints untouched), and a description of each move ("joint = value -> bound").

    Values farther outside are left as they are (the problem's own check then names them)."""
    q = np.array(q, dtype=np.float64)
    lower = np.asarray(robot.lower, dtype=np.float64)
    upper = np.asarray(robot.upper, dtype=np.float64)
    bounded = ~continuous_mask(robot)
    moved: List[str] = []
    for j, name in enumerate(robot.joint_names):
        if not bounded[j]:
            continue
        for bound, outside in ((lower[j], q[j] < lower[j]), (upper[j], q[j] > upper[j])):
            if outside and abs(q[j] - bound) <= tol:
                moved.append(f"{name} = {float(q[j])!r} -> {float(bound)!r}")
                q[j] = bound
    return q, moved


def velocity_scales(robot: Any) -> Optional[np.ndarray]:
    """(dof,) scales s_i = v_ref / v_i of the joint attractor (``Fabric.with_joint_scales``) from the URDF
    velocity limits v_i [rad/s or m/s], v_ref their median: the attractor then measures each joint's error
    in time at its speed limit, and a joint much slower than the others (a lift at 0.1 m/s beside arm joints
    at 2 rad/s) weighs accordingly in the fabric's metric. None when a limit is missing, zero or not finite
    (no time scale to derive)."""
    v = np.asarray(robot.velocity_limits, dtype=np.float64)
    if v.size == 0 or not np.all(np.isfinite(v)) or not np.all(v > 0):
        return None
    return float(np.median(v)) / v
