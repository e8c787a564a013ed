"""Finishing a rolled-out trajectory before it is returned (:mod:`gfcs.blend` does the work).

The fabric's own trajectory starts with a jump of acceleration, converges to the goal only asymptotically
and ignores the robot's speed and acceleration limits. :func:`finish_rollout` therefore, as
:class:`FinishOptions` says: re-times the start from rest along the same path, appends a quintic blend
that ends exactly at the goal, at rest (when the goal was reached), and re-times the whole path within the
URDF velocity limits and the robot profile's acceleration limits, and moves the excursions past a position
bound that re-timing's interpolation leaves onto the bound (:func:`onto_bounds`). None of this changes the
cost of eq. 4, which is the fabric's own time. The ``paper`` preset turns every step off but the last.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple

import numpy as np

from gfcs import metrics as _metrics
from gfcs import profile as _profile
from gfcs.blend import append_goal_blend, limit_dynamics, retime_start
from gfcs.joints import continuous_mask
from gfcs.planning.rollout import RolloutSettings, fabric_goal
from gfcs.results import Trajectory

__all__ = ["FinishOptions", "finish_rollout", "onto_bounds", "retime_within_limits", "rollout_commands",
           "with_raw_ldj"]


@dataclass
class FinishOptions:
    """What :func:`finish_rollout` does to a recorded trajectory.

    Attributes:
        retime_start: leave rest smoothly: the first 0.3 s re-timed along the same path
            (:func:`gfcs.blend.retime_start`).
        goal_blend: a reached trajectory ends with a quintic blend exactly at the goal, at rest, within the
            joint limits (:func:`gfcs.blend.append_goal_blend`).
        limit_velocity: re-time the path within the URDF velocity limits (and the profile's tighter ones).
        limit_acceleration: re-time the path within the acceleration limits too.
        acceleration_limits: (dof,) limits [rad/s²], inf where none; None: the robot profile's
            (:func:`gfcs.profile.acceleration_limits`).
        velocity_limits: (dof,) limits [rad/s or m/s] that tighten the URDF's (e.g. a MoveIt
            ``joint_limits.yaml``, :func:`gfcs.profile.read_joint_limits_yaml`), inf where none; None: the
            URDF's (:func:`gfcs.profile.velocity_limits`).
    """

    retime_start: bool = True
    goal_blend: bool = True
    limit_velocity: bool = True
    limit_acceleration: bool = True
    acceleration_limits: Optional[Tuple[float, ...]] = None
    velocity_limits: Optional[Tuple[float, ...]] = None

    def to_dict(self) -> Dict[str, Any]:
        """The options as a JSON-ready dict (recorded in a result's settings)."""
        d = dataclasses.asdict(self)
        for key in ("acceleration_limits", "velocity_limits"):
            if d[key] is not None:
                d[key] = [float(a) for a in d[key]]
        return d


def finish_rollout(fabric: Any, seq: Any, goal: Any, dt: float, options: FinishOptions,
                   ) -> Tuple[Trajectory, float, bool, np.ndarray]:
    """The recorded ``gfcs.SequenceRollout`` ``seq`` of ``fabric`` (sampled every ``dt`` s) finished as
    ``options`` say: (trajectory, cost of eq. 4, goal reached, t_stars (n + 1,))."""
    t, q, qd, qdd = np.asarray(seq.t), np.asarray(seq.q), np.asarray(seq.qd), np.asarray(seq.qdd)
    robot = fabric.robot
    if options.retime_start:
        t, q, qd = retime_start(t, q, qd, qdd, dt)
    if seq.reached and options.goal_blend:
        t, q, qd = append_goal_blend(t, q, qd, qdd[-1], np.asarray(goal, dtype=np.float64), dt,
                                     np.asarray(robot.lower), np.asarray(robot.upper))
    t, q, qd = retime_within_limits(robot, t, q, qd, dt, options)
    return (Trajectory(t, q, qd, raw_q=np.asarray(seq.q)), float(seq.cost), bool(seq.reached),
            np.asarray(seq.t_stars, dtype=np.float64))


def retime_within_limits(robot: Any, t: np.ndarray, q: np.ndarray, qd: np.ndarray, dt: float,
                         options: FinishOptions) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, qd) re-timed along the same path within the velocity and acceleration limits ``options``
    keeps (:func:`gfcs.blend.limit_dynamics`; unchanged when it keeps none), then moved onto the position
    bounds where its interpolation crosses bounds the given path keeps (:func:`onto_bounds`): every returned
    trajectory, a repaired one too, passes here."""
    accel = None
    if options.limit_acceleration:
        accel = options.acceleration_limits
        accel = _profile.acceleration_limits(robot) if accel is None else accel
    velocity = _profile.velocity_limits(robot) if options.limit_velocity else None
    if velocity is not None and options.velocity_limits is not None:
        velocity = np.minimum(velocity, np.asarray(options.velocity_limits, dtype=np.float64))
    given = q
    if velocity is not None or accel is not None:
        t, q, qd = limit_dynamics(t, q, qd, dt, velocity=velocity, acceleration=accel)
    return t, onto_bounds(robot, q, given), qd


def onto_bounds(robot: Any, q: np.ndarray, given: Optional[np.ndarray] = None,
                tol: float = _metrics.DEFAULT_LIMIT_TOL) -> np.ndarray:
    """``q`` (T, dof) with values of bounded joints outside their position bounds moved onto the bound, its
    first row (the robot's state) kept: every such value of a joint that the path ``q`` was resampled from,
    ``given`` (T', dof), keeps within its bounds (to ``tol``), and elsewhere those outside by at most ``tol``
    [rad or m].

    A path that ends on a bound (a goal at a joint's limit) or runs along one (a repaired path held at a
    limit) is resampled by the re-timing's cubic Hermite curve, which crosses the bound between samples (by
    10⁻¹⁰ to 10⁻⁵ rad); a validator that compares each state with the bounds exactly counts that as a limit
    violation. Where the given path itself leaves a bound by more than ``tol``, the values farther outside
    are left as they are, for the limit check to reject. Continuous joints have no bounds and are not
    touched."""
    lower = np.asarray(robot.lower, dtype=np.float64)
    upper = np.asarray(robot.upper, dtype=np.float64)
    bounded = ~continuous_mask(robot)
    kept = np.zeros_like(bounded)
    if given is not None and len(given):
        kept = (np.min(given, axis=0) >= lower - tol) & (np.max(given, axis=0) <= upper + tol)
    rest = q[1:]
    low = bounded & (rest < lower) & ((rest >= lower - tol) | kept)
    high = bounded & (rest > upper) & ((rest <= upper + tol) | kept)
    if not (low.any() or high.any()):
        return q
    rest = np.where(low, lower, np.where(high, upper, rest))
    return np.vstack([q[:1], rest])


def with_raw_ldj(metrics: Dict[str, Any], robot: Any, trajectory: Trajectory, dt: float) -> Dict[str, Any]:
    """``metrics`` with the LDJ of the fabric's own rollout (:func:`gfcs.metrics.raw_ldj`) when the
    trajectory keeps it."""
    if trajectory.raw_q is not None and trajectory.raw_q.shape[0] > 0:
        metrics.update(_metrics.raw_ldj(robot, trajectory.raw_q, dt))
    return metrics


def rollout_commands(fabric: Any, q0: Any, qd0: Any, goal: Any, commands: Any, settings: RolloutSettings,
                     finish: Optional[FinishOptions] = None) -> Tuple[Trajectory, float, bool, np.ndarray]:
    """Roll out a command sequence q_g¹..q_gⁿ then the goal (GFCS eq. 5-7), record it and finish it
    (:func:`finish_rollout`, default :class:`FinishOptions`).

    Args:
        fabric: a ``gfcs.Fabric``.
        q0, qd0, goal: (dof,) start state and goal.
        commands: (n, dof) free commands (n may be 0: the GF baseline).
        settings: :class:`gfcs.planning.rollout.RolloutSettings`.
        finish: :class:`FinishOptions`.

    Returns:
        (trajectory, cost of eq. 4, goal reached, t_stars (n + 1,)). The fabric is commanded
        :func:`gfcs.planning.rollout.fabric_goal` for the goal (``settings.limit_hold_off``); the blend
        ends at ``goal``.
    """
    dof = int(np.asarray(goal).shape[0])
    cmds = np.asarray(commands, dtype=np.float64).reshape(-1, dof)
    seq = fabric.rollout_sequence(q0, qd0, cmds, fabric_goal(fabric, goal, settings.limit_hold_off),
                                  **settings.as_kwargs())
    return finish_rollout(fabric, seq, goal, settings.dt, finish or FinishOptions())
