"""Rollout options of GFCS eq. 1-8 and the fabric a problem is planned with.

* :class:`RolloutSettings`: how a command sequence is integrated and scored (step, time per command,
  tolerances, cost terms, the command switch). Finishing the recorded trajectory is apart:
  :class:`gfcs.planning.finish.FinishOptions`.
* :func:`make_fabric`: a ``gfcs.Fabric`` for a problem.
* :func:`fabric_goal`: the configuration the fabric is commanded for a goal near a joint limit.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import Any, Dict, Optional

import numpy as np

from gfcs.planning._check import non_negative

__all__ = ["RolloutSettings", "make_fabric", "fabric_goal"]


@dataclass
class RolloutSettings:
    """Rollout parameters of GFCS eq. 1-8. The defaults are the ``default`` preset's; the ``paper`` preset
    (:mod:`gfcs.planning.presets`) sets ``tol`` 0.01, ``collision_penalty`` 0, ``blend_time`` 0,
    ``stall_window`` 0 and ``limit_hold_off`` None.

    Attributes:
        dt: integration step [s] (Euler at 100 Hz in the paper).
        t_max: time budget per command [s] (7 s in the paper).
        tol: ε of eq. 3 for the final goal [rad]. 0.02: a reached trajectory ends with a quintic blend onto
            the goal (:mod:`gfcs.blend`), so what is returned ends exactly at the goal whatever ε, and the
            looser ε spares the slow last approach of goals that barrier potentials of nearby objects hold
            off (grasps); success is judged at ``metrics.DEFAULT_SUCCESS_TOL`` (0.01 rad) on the finished
            trajectory.
        waypoint_tol: ε for the intermediate commands [rad] (looser: a command only steers the motion).
        penalty: p of eq. 4/8 added when the goal is not reached [s].
        collision_penalty: added when the sphere model collides (min clearance < −``collision_tol``) [s].
            An extension of eq. 4 (whose cost has no collision term): success requires a collision-free
            motion, so colliding candidates rank behind collision-free ones.
        collision_tol: sphere overlap [m], ≥ 0, that does not count as a collision in the cost. An attempt
            with a clearance floor below 0 (the goal-contact attempt) raises it to the overlap the floor
            accepts.
        distance_penalty: added per rad of the closest approach to the goal when the goal is not reached
            [s/rad] (an extension of eq. 4, default 0): it ranks failed candidates by how near they came.
        blend_time: at each handover the command moves to the next one along a smoothstep over this time
            [s] instead of jumping (an extension of eq. 7; 0 is the paper's switch): the jump of the command
            is a jump of the acceleration that dominates the jerk of a trajectory.
        integrator: ``"euler"`` (semi-implicit Euler, the paper's) or ``"rk4"``.
        stall_window, stall_progress: a rollout stops as "stalled" (t* = t_max, not reached) when its
            distance to the command has not shrunk by ``stall_progress`` [rad] over ``stall_window`` [s]
            (0 = off): it saves the steps of candidates stuck at a local minimum.
        limit_hold_off: a goal joint nearer a limit than the fabric's joint-limit margin plus this [rad] is
            commanded that far off the limit instead (:func:`fabric_goal`), and the goal blend covers the
            rest: the limit barrier holds the fabric off a goal at its limit. None: every goal is commanded
            as it is (the paper's command; a goal within the barrier's margin of a limit is then not reached).

    The defaults equal the core's (``RolloutOptions`` / ``SequenceOptions`` in ``fabric-core``) except
    ``collision_penalty`` (0 in the core) and ``tol`` (0.01 in the core, whose rollouts have no blend).
    """

    dt: float = 0.01
    t_max: float = 7.0
    tol: float = 0.02
    waypoint_tol: float = 0.3
    penalty: float = 100.0
    collision_penalty: float = 100.0
    collision_tol: float = 0.0
    distance_penalty: float = 0.0
    blend_time: float = 0.5
    integrator: str = "euler"
    stall_window: float = 0.5
    stall_progress: float = 0.005
    limit_hold_off: Optional[float] = 0.015

    def as_kwargs(self) -> Dict[str, Any]:
        """Keyword arguments for ``gfcs.Fabric.rollout_sequence`` / ``evaluate`` (every field but
        ``limit_hold_off``, which decides what the fabric is commanded)."""
        kwargs = dataclasses.asdict(self)
        del kwargs["limit_hold_off"]
        return kwargs


def make_fabric(problem: Any, fabric_config: Any = None, scene: Any = None) -> Any:
    """A ``gfcs.Fabric`` for ``problem`` (or for ``problem.robot`` in another ``scene``).

    Args:
        problem: a :class:`gfcs.problems.Problem`.
        fabric_config: None (defaults), a ``gfcs.FabricConfig``, a dict, or a path to a TOML/YAML/JSON file.
        scene: replaces ``problem.scene`` when given.
    """
    import gfcs

    config = str(fabric_config) if isinstance(fabric_config, os.PathLike) else fabric_config
    return gfcs.Fabric(problem.robot, problem.scene if scene is None else scene, config)


def fabric_goal(fabric: Any, goal: Any, hold_off: Optional[float]) -> np.ndarray:
    """The configuration (dof,) [rad] the fabric is commanded for ``goal`` (dof,): each joint at least
    ``joint_limits.margin`` + ``hold_off`` [rad, ≥ 0] from its limits (``goal`` itself when every joint is
    that far already, when the fabric's limit barrier is off, or when ``hold_off`` is None). The barrier holds the fabric off any
    configuration nearer its limit than that, so a rollout could not reach such a goal; the goal blend
    (:func:`gfcs.planning.finish.finish_rollout`) then covers the rest. A joint whose range is narrower than
    twice that room keeps its goal."""
    goal = np.asarray(goal, dtype=np.float64)
    if hold_off is None:
        return goal
    hold_off = non_negative("limit_hold_off", hold_off, " [rad]")
    limits = fabric.config.to_dict()["joint_limits"]
    if not limits["enabled"]:
        return goal
    room = float(limits["margin"]) + hold_off
    robot = fabric.robot
    lower = np.asarray(robot.lower, dtype=np.float64) + room
    upper = np.asarray(robot.upper, dtype=np.float64) - room
    return np.where(lower <= upper, np.minimum(np.maximum(goal, lower), upper), goal)
