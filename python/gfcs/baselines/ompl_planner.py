"""Sampling-based baselines (GFCS Table I: RRTConnect, Bi-EST, BIT*) planned with OMPL on the project's own
collision model and judged exactly as GFCS is.

The set-up follows what MoveIt does with OMPL, so that the rows compare with MoveIt's:

* State space: the planned joints (the problem robot's active joints; the others are locked in the model,
  held at the request's start values) as a real vector space within the joint bounds. A continuous joint
  gets the bounds [−2π, 2π] widened to hold its start and goal (a box, no wrap-around: the goal is taken as
  the angle nearest the start, :func:`gfcs.joints.unwrap_goal`, and the simplifier removes detours).
* Validity (:class:`gfcs.baselines.validity.SphereValidity`): the planning model GFCS plans with first
  (:func:`gfcs.planning.models.models_for`: the thin spheres with their wider margin where the robot has
  them, else its own spheres; never the covering spheres GFCS may try first), every sphere at least the
  fabric's obstacle margin from the obstacles (2 mm by default, 6 mm on the thin spheres), no self-collision of
  sphere pairs.
* Motion checks at MoveIt's default resolution: ``longest_valid_segment_fraction`` 0.005 of the state
  space's maximum extent (13.04 rad for the Panda's 7 joints: a step of 0.065 rad), the states of a segment
  checked in at most two batched calls (a Python ``MotionValidator``).
* RRTConnect and BIT* are OMPL's (default parameters, as MoveIt's default planner configurations leave them).
  Bi-EST is OMPL's algorithm run in numpy (:mod:`gfcs.baselines.biest`): the PyPI wheels bind no class for
  it. RRTConnect and Bi-EST stop at their first path; BIT* improves its path until the planner time ends.
* Simplification as MoveIt's ``simplifySolution``: OMPL's ``PathSimplifier.simplify`` (vertex reduction,
  shortcutting, B-spline smoothing) in the planner time left, or ``simplifyMax`` when none is left.
* Time parameterisation (:func:`gfcs.baselines.timing.time_path`): the path at the velocity limits, from
  rest to rest, re-timed by :func:`gfcs.blend.limit_dynamics` within the acceleration limits where known,
  the limits being those GFCS's trajectories keep (:class:`gfcs.planning.finish.FinishOptions`), and
  moved onto the position bounds where re-timing crossed them by rounding
  (:func:`gfcs.planning.finish.onto_bounds`).

The returned :class:`gfcs.results.SolveResult` carries :func:`gfcs.metrics.trajectory_metrics` of that
trajectory on the planning model and the problem's mesh checker, the same success criterion, rows and JSON
as a GFCS solve. A problem the planner does not solve (no path within the time, start or goal invalid for
the planning model) gives a failed result whose ``settings["failure"]`` says why, not an exception.

Seeds: ``ompl.util.RNG.setSeed`` reseeds OMPL's seed generator before each plan, so every random generator
the plan creates (planner, samplers, simplifier) follows the seed, also after earlier plans in the process
(OMPL's complaint that sampling had already started is silenced with the rest of its log during a plan);
Bi-EST draws from a numpy generator. RRTConnect and Bi-EST give the same path for the same seed (tested);
BIT*'s path depends on how many batches fit in its time.
"""

from __future__ import annotations

import math
import time
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from gfcs import metrics as _metrics
from gfcs.baselines.biest import BiEST
from gfcs.baselines.timing import time_path
from gfcs.baselines.validity import MOVEIT_SEGMENT_FRACTION, SphereValidity
from gfcs.errors import InvalidValueError
from gfcs.joints import continuous_mask, unwrap_goal

__all__ = ["plan_ompl", "PLANNERS", "planner_label", "is_ompl_method", "DEFAULT_PLANNER_TIME"]

#: The planners, by method name: the label of their benchmark rows.
PLANNERS: Dict[str, str] = {"rrtconnect": "RRTConnect", "biest": "Bi-EST", "bitstar": "BIT*"}
#: Default planning time [s]: MoveIt's default allowed planning time, and the default time limit of a GFCS
#: solve from the command line.
DEFAULT_PLANNER_TIME = 5.0


def is_ompl_method(method: str) -> bool:
    """Whether ``method`` names one of :data:`PLANNERS`."""
    return method in PLANNERS


def planner_label(planner: str, planner_time: float, with_time: bool = False) -> str:
    """The row label of ``planner``: e.g. ``"RRTConnect"``, ``"BIT* (1.2 s)"``. BIT*, which uses all its
    time, always names it; the others when ``with_time`` (several planner times in one benchmark)."""
    name = PLANNERS[planner]
    return f"{name} ({planner_time:g} s)" if with_time or planner == "bitstar" else name


def _ompl() -> Tuple[Any, Any, Any]:
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError as e:
        raise ImportError("the sampling-based baselines need OMPL: pip install 'gfcs[baselines]' "
                          f"(ompl>=2.0): {e}") from e
    return ob, og, ou


def _check_arguments(problem: Any, planner: str, planner_time: Any, segment_fraction: Any) -> Tuple[float, float]:
    from gfcs.planning._check import positive

    if planner not in PLANNERS:
        raise InvalidValueError(f"planner must be one of {', '.join(PLANNERS)}, got {planner!r}")
    seconds = positive("planner_time", planner_time, " [s]")
    fraction = positive("segment_fraction", segment_fraction)
    if fraction > 1.0:
        raise InvalidValueError(f"segment_fraction must be in (0, 1], got {segment_fraction!r}")
    if np.any(np.asarray(problem.qd0, dtype=np.float64) != 0.0):
        raise InvalidValueError(f"problem {problem.name!r}: qd0: the sampling-based planners plan paths from "
                                "rest; this problem starts moving")
    return seconds, fraction


def _bounds(robot: Any, q0: np.ndarray, goal: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lower, upper, goal to plan for): the joint bounds, continuous joints' widened to hold q0 and the
    goal taken nearest q0."""
    continuous = continuous_mask(robot)
    goal = unwrap_goal(q0, goal, continuous)
    lower = np.asarray(robot.lower, dtype=np.float64).copy()
    upper = np.asarray(robot.upper, dtype=np.float64).copy()
    lower[continuous] = np.minimum(lower, np.minimum(q0, goal))[continuous]
    upper[continuous] = np.maximum(upper, np.maximum(q0, goal))[continuous]
    return lower, upper, goal


def _vector(state: Any, dof: int) -> np.ndarray:
    """The (dof,) joint vector of an OMPL real-vector state."""
    return np.array([state[j] for j in range(dof)], dtype=np.float64)


def _motion_validator(ob: Any, si: Any, validity: SphereValidity, dof: int) -> Any:
    """An OMPL ``MotionValidator`` that checks every state of a segment at the check resolution in one batched
    call. It holds ``validity`` and ``dof`` only: nothing that leads back to ``si``, which owns it (a cycle
    through C++ that Python's garbage collector cannot free)."""

    class _Segments(ob.MotionValidator):
        def checkMotion(self, s1: Any, s2: Any) -> bool:  # noqa: N802 (OMPL's name)
            return validity.segment_valid(_vector(s1, dof), _vector(s2, dof))

    return _Segments(si)


class _Space:
    """The OMPL state space, space information and motion validator of one plan."""

    def __init__(self, validity: SphereValidity, fraction: float) -> None:
        ob, og, _ = _ompl()
        dof = self.dof = validity.lower.shape[0]
        space = ob.RealVectorStateSpace(dof)
        bounds = ob.RealVectorBounds(dof)
        for j in range(dof):
            bounds.setLow(j, float(validity.lower[j]))
            bounds.setHigh(j, float(validity.upper[j]))
        space.setBounds(bounds)
        self.si = ob.SpaceInformation(space)
        self.si.setStateValidityCheckingResolution(fraction)
        self.si.setStateValidityChecker(lambda s: bool(validity.valid(_vector(s, dof))[0]))
        self.extent = float(self.si.getMaximumExtent())
        validity.step = fraction * self.extent
        self.si.setMotionValidator(_motion_validator(ob, self.si, validity, dof))
        self.si.setup()
        self.space, self.og = space, og

    def vector(self, state: Any) -> np.ndarray:
        return _vector(state, self.dof)

    def state(self, q: np.ndarray) -> Any:
        s = self.si.allocState()
        for j in range(self.dof):
            s[j] = float(q[j])
        return s

    def path(self, states: List[np.ndarray]) -> Any:
        path = self.og.PathGeometric(self.si)
        for q in states:
            path.append(self.state(q))
        return path

    def waypoints(self, path: Any) -> np.ndarray:
        return np.array([self.vector(path.getState(i)) for i in range(path.getStateCount())])


def _run_ompl(space: _Space, planner: str, start: np.ndarray, goal: np.ndarray, seconds: float
              ) -> Tuple[Optional[Any], str]:
    """(OMPL path or None, planner status) of OMPL's RRTConnect or BIT* within ``seconds``."""
    og = space.og
    setup = og.SimpleSetup(space.si)
    setup.setStartAndGoalStates(space.state(start), space.state(goal))
    setup.setPlanner((og.RRTConnect if planner == "rrtconnect" else og.BITstar)(space.si))
    status = setup.solve(seconds)
    if not setup.haveExactSolutionPath():
        return None, str(status)
    return og.PathGeometric(setup.getSolutionPath()), str(status)


def _run_biest(space: _Space, validity: SphereValidity, start: np.ndarray, goal: np.ndarray, seconds: float,
               seed: int) -> Tuple[Optional[Any], str]:
    """(OMPL path or None, status) of Bi-EST (:mod:`gfcs.baselines.biest`) within ``seconds``."""
    planner = BiEST(validity, space.extent)
    states = planner.solve(start, goal, np.random.default_rng(seed), time.perf_counter() + seconds)
    if states is None:
        return None, "Timeout"
    return space.path(states), "Exact solution"


def _simplify(space: _Space, path: Any, seconds_left: float) -> None:
    """MoveIt's simplification of ``path`` in place: OMPL's ``simplify`` within the time left (at least one
    round), ``simplifyMax`` when no time is left."""
    simplifier = space.og.PathSimplifier(space.si)
    if seconds_left > 1e-9:
        simplifier.simplify(path, seconds_left, True)
    else:
        simplifier.simplifyMax(path)


def _ompl_seed(seed: int) -> int:
    """A non-zero 32-bit seed for OMPL (which ignores 0) derived from ``seed``."""
    return int(np.random.SeedSequence(int(seed)).generate_state(1)[0]) or 1


def _limits(robot: Any, finish: Any) -> Tuple[Optional[np.ndarray], Optional[np.ndarray]]:
    """(velocity limits, acceleration limits), each None when not kept: those
    :func:`gfcs.planning.finish.finish_rollout` gives GFCS's trajectories under the same options."""
    from gfcs import profile as _profile

    velocity = _profile.velocity_limits(robot) if finish.limit_velocity else None
    if velocity is not None and finish.velocity_limits is not None:
        velocity = np.minimum(velocity, np.asarray(finish.velocity_limits, dtype=np.float64))
    accel = None
    if finish.limit_acceleration:
        accel = finish.acceleration_limits
        accel = _profile.acceleration_limits(robot) if accel is None else accel
    return velocity, (None if accel is None else np.asarray(accel, dtype=np.float64))


def _plan_path(space: _Space, validity: SphereValidity, planner: str, start: np.ndarray, goal: np.ndarray,
               seconds: float, seed: int, simplify: bool, record: Dict[str, Any]) -> Optional[np.ndarray]:
    """The simplified waypoints (K, dof) of a plan, or None; times and counts go to ``record``."""
    began = time.perf_counter()
    if planner == "biest":
        path, status = _run_biest(space, validity, start, goal, seconds, seed)
    else:
        path, status = _run_ompl(space, planner, start, goal, seconds)
    record["plan_time"] = time.perf_counter() - began
    record["status"] = status
    if path is None:
        record["failure"] = f"no path found within {seconds:g} s ({status})"
        return None
    record["raw_waypoints"] = int(path.getStateCount())
    record["raw_length"] = float(path.length())
    began = time.perf_counter()
    if simplify:
        _simplify(space, path, seconds - record["plan_time"])
    record["simplify_time"] = time.perf_counter() - began
    return space.waypoints(path)


def plan_ompl(
    problem: Any,
    planner: str = "rrtconnect",
    planner_time: float = DEFAULT_PLANNER_TIME,
    seed: int = 0,
    *,
    simplify: bool = True,
    segment_fraction: float = MOVEIT_SEGMENT_FRACTION,
    thin_spheres: bool = True,
    element_spheres: bool = True,
    fabric_config: Any = None,
    finish: Any = None,
    mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN,
    dt: float = 0.01,
) -> Any:
    """Plan ``problem`` with a sampling-based planner (see the module docstring) and judge the motion as
    :func:`gfcs.planning.solve` judges its own.

    Args:
        problem: a :class:`gfcs.problems.Problem` at rest at its start (``qd0`` = 0).
        planner: ``"rrtconnect"``, ``"biest"`` or ``"bitstar"`` (:data:`PLANNERS`).
        planner_time: planning time [s] (MoveIt's allowed planning time): the planner's, then the
            simplification's in what is left.
        seed: seed of the planner's random numbers.
        simplify: simplify the path (MoveIt does by default).
        segment_fraction: motion-check resolution as a fraction of the state space's maximum extent
            (MoveIt's ``longest_valid_segment_fraction``, default 0.005).
        thin_spheres: check on the thin sphere model first, as GFCS plans, where the robot has one and the
            problem a mesh checker (False: the robot's own spheres).
        element_spheres: check on the validator's collision spheres where its robot description has any, as
            GFCS plans (:func:`gfcs.planning.models.models_for`).
        fabric_config: the fabric configuration whose obstacle margin the spheres keep (None: defaults).
        finish: :class:`gfcs.planning.finish.FinishOptions` whose limits the trajectory keeps (None:
            defaults: URDF velocity limits, the profile's acceleration limits).
        mesh_margin: clearance [m] the collision meshes must keep for success (as for GFCS).
        dt: sample period of the trajectory [s].

    Returns:
        A :class:`gfcs.results.SolveResult` with ``method`` = ``planner``; ``cost`` the trajectory's
        duration [s] (inf without a path); ``solve_time`` planning plus simplification [s]; ``settings``
        the set-up, the planner status, ``failure`` (why no motion was planned, when none was) and the
        simplified ``waypoints``.

    Raises:
        gfcs.InvalidValueError: an unknown planner, a planner time or fraction out of range, a moving start.
        ImportError: OMPL is not installed (the ``baselines`` extra).
    """
    from gfcs.planning.models import models_for

    started = time.perf_counter()
    seconds, fraction = _check_arguments(problem, planner, planner_time, segment_fraction)
    finish, margin_base = _finish_and_margin(finish, fabric_config)
    _, _, ou = _ompl()
    models = models_for(problem, thin_spheres=bool(thin_spheres), element_spheres=bool(element_spheres))
    model = models.planning[0]
    q0 = np.asarray(problem.q0, dtype=np.float64)
    lower, upper, goal = _bounds(model.robot, q0, np.asarray(problem.goal, dtype=np.float64))
    validity = SphereValidity(model.robot, problem.scene, margin_base + model.margin_offset, lower, upper, 0.0)
    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(_ompl_seed(seed))
        space = _Space(validity, fraction)
        record: Dict[str, Any] = {"planner": PLANNERS[planner], "planner_time": seconds, "simplify": bool(simplify),
                                  "segment_fraction": fraction, "state_space_extent": space.extent,
                                  "check_step": validity.step, "sphere_model": model.name, **model.settings(),
                                  "obstacle_margin": validity.margin, "mesh_margin": float(mesh_margin),
                                  "plan_time": 0.0, "simplify_time": 0.0, **finish.to_dict()}
        invalid = validity.why_invalid(q0, "start") or validity.why_invalid(goal, "goal")
        if invalid:
            record.update(status="Invalid start or goal", failure=invalid)
            waypoints = None
        else:
            waypoints = _plan_path(space, validity, planner, q0, goal, seconds, seed, simplify, record)
    finally:
        ou.setLogLevel(level)
    record.update(states_checked=validity.counts["states"], segments_checked=validity.counts["segments"])
    return _result(problem, planner, seed, model, models, waypoints, record, finish, mesh_margin, dt, started)


def _finish_and_margin(finish: Any, fabric_config: Any) -> Tuple[Any, float]:
    """(finishing options, the fabric's obstacle margin [m])."""
    import os

    import gfcs
    from gfcs.planning.finish import FinishOptions

    config = str(fabric_config) if isinstance(fabric_config, os.PathLike) else fabric_config
    if not isinstance(config, gfcs.FabricConfig):
        config = (gfcs.FabricConfig.from_file(config) if isinstance(config, str)
                  else gfcs.FabricConfig(config))
    return (finish if finish is not None else FinishOptions()), float(config.to_dict()["obstacles"]["margin"])


def _result(problem: Any, planner: str, seed: int, model: Any, models: Any, waypoints: Optional[np.ndarray],
            record: Dict[str, Any], finish: Any, mesh_margin: float, dt: float, started: float) -> Any:
    """The :class:`gfcs.results.SolveResult` of a plan: the timed trajectory (the start alone without a path)
    and its metrics."""
    from gfcs.planning.finish import onto_bounds
    from gfcs.results import SolveResult, Trajectory

    robot = model.robot
    q0 = np.asarray(problem.q0, dtype=np.float64)
    if waypoints is None:
        traj = Trajectory(np.zeros(1), q0[None, :], np.zeros((1, q0.shape[0])))
    else:
        velocity, accel = _limits(robot, finish)
        traj = time_path(waypoints, np.full(q0.shape[0], np.inf) if velocity is None else velocity, accel, dt)
        traj = Trajectory(traj.t, onto_bounds(robot, traj.q), traj.qd)
        record["waypoints"] = waypoints.tolist()
    meta = getattr(problem, "meta", None) or {}
    met = _metrics.trajectory_metrics(robot, problem.scene, traj.t, traj.q, problem.goal,
                                      mesh_checker=models.validator, mesh_margin=mesh_margin,
                                      ee_links=meta.get("ee_links"))
    reached = waypoints is not None
    duration = float(traj.t[-1]) if reached else math.inf
    dof = q0.shape[0]
    return SolveResult(
        problem=str(problem.name), cls=str(getattr(problem, "cls", "")), method=planner, seed=int(seed), q0=q0,
        qd0=np.asarray(problem.qd0, dtype=np.float64), goal=np.asarray(problem.goal, dtype=np.float64),
        commands=np.zeros((0, dof)), cost=duration, reached=reached,
        t_stars=np.array([duration]) if reached else np.zeros(0), trajectory=traj, success=bool(met["success"]),
        metrics=met, n_evaluations=int(record["states_checked"]),
        solve_time=float(record["plan_time"] + record["simplify_time"]), settings=record,
        joint_names=list(robot.joint_names), pose_goal=meta.get("pose_goal"), time_limit=record["planner_time"],
        robot=robot, wall_time=time.perf_counter() - started)
