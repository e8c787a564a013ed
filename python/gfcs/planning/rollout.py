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

from gfcs import _core
from gfcs.planning._check import non_negative

__all__ = ["RolloutSettings", "CORE_DEFAULTS", "make_fabric", "fabric_goal"]


#: The core's default of every rollout option (``gfcs._core.rollout_option_defaults()``): the one set of
#: defaults; the presets (:mod:`gfcs.planning.presets`) state where they differ.
CORE_DEFAULTS: Dict[str, Any] = _core.rollout_option_defaults()


@dataclass
class RolloutSettings:
    """Rollout parameters of GFCS eq. 1-8: the keyword options of ``gfcs.Fabric.rollout_sequence`` /
    ``evaluate`` (the same names, tested) and ``limit_hold_off``. Every default is the core's
    (:data:`CORE_DEFAULTS`); the ``default`` preset (:mod:`gfcs.planning.presets`) changes ``tol``,
    ``capture_tol``, ``collision_penalty`` and ``limit_hold_off``, the ``paper`` preset ``blend_time`` and
    ``stall_window``.
    Start from a preset's settings to change one option: ``dataclasses.replace(get_preset("default").settings,
    t_max=3.0)``.

    Attributes:
        dt: integration step [s] (Euler at 100 Hz in the paper).
        t_max: time budget per command [s] (7 s in the paper).
        tol: ε of eq. 3 for the final goal [rad].
        waypoint_tol: ε for the intermediate commands [rad] (looser: a command only steers the motion).
        penalty: p of eq. 4/8 added when the goal is not reached [s].
        collision_penalty: added when the sphere model collides (min clearance < −``collision_tol``) [s].
            An extension of eq. 4 (whose cost has no collision term).
        collision_tol: sphere overlap [m], ≥ 0, that does not count as a collision in the cost. An attempt
            with a clearance floor below 0 (the goal-contact attempt) raises it to the overlap the floor
            accepts.
        distance_penalty: added per rad of the closest approach to the goal when the goal is not reached
            [s/rad] (an extension of eq. 4): it ranks failed candidates by how near they came.
        blend_time: at each handover the command moves to the next one along a smoothstep over this time
            [s] instead of jumping (an extension of eq. 7; 0 is the paper's switch): the jump of the command
            is a jump of the acceleration that dominates the jerk of a trajectory.
        integrator: ``"euler"`` (semi-implicit Euler, the paper's) or ``"rk4"``.
        stall_window, stall_progress: a rollout stops as "stalled" (t* = t_max, not reached) when its
            distance to the command has not shrunk by ``stall_progress`` [rad] over ``stall_window`` [s]
            (0 = off): it saves the steps of candidates stuck at a local minimum.
        capture_tol: goal capture [rad] (0 = off, the paper's rule): a rollout that stalls within this
            distance of the goal has come to rest where the barriers of nearby obstacles hold it off the goal
            (a hand 7-10 mm from a shelf's boards rests 0.02-0.05 rad off it); it counts as reached, t* the
            time it stalled, and the goal blend (checked with the rest of the motion) covers the rest.
            Needs stall detection.
        limit_hold_off: a goal joint nearer a limit than the fabric's joint-limit margin plus this [rad] is
            commanded that far off the limit instead (:func:`fabric_goal`), and the goal blend covers the
            rest: the limit barrier holds the fabric off a goal at its limit. None: every goal is commanded
            as it is (the paper's command; a goal within the barrier's margin of a limit is then not reached).
    """

    dt: float = CORE_DEFAULTS["dt"]
    t_max: float = CORE_DEFAULTS["t_max"]
    tol: float = CORE_DEFAULTS["tol"]
    waypoint_tol: float = CORE_DEFAULTS["waypoint_tol"]
    penalty: float = CORE_DEFAULTS["penalty"]
    collision_penalty: float = CORE_DEFAULTS["collision_penalty"]
    collision_tol: float = CORE_DEFAULTS["collision_tol"]
    distance_penalty: float = CORE_DEFAULTS["distance_penalty"]
    blend_time: float = CORE_DEFAULTS["blend_time"]
    integrator: str = CORE_DEFAULTS["integrator"]
    stall_window: float = CORE_DEFAULTS["stall_window"]
    stall_progress: float = CORE_DEFAULTS["stall_progress"]
    capture_tol: float = CORE_DEFAULTS["capture_tol"]
    limit_hold_off: Optional[float] = None

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
