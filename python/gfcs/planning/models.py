"""A problem's robot models, resolved once per solve: what the fabric plans with, what judges the motion,
and the robot's limits and profile.

* Planning models, in the order a solve tries them (:class:`PlanningModel`): for a robot with a thinner
  sphere model on record and a collision-mesh validator (the shipped Panda and Franka descriptions given
  its spheres, :func:`gfcs.problems.thin_sphere_model`), first the thin spheres with a wider obstacle
  margin, then the robot's own (covering) spheres; for a robot whose own spheres leave the validator's
  meshes centimetres uncovered (a sphere model made for another checker), first spheres fitted around those
  meshes (:func:`covering_model`), then its own; for any other robot, its own spheres.
* Element spheres: where the validator's robot description models a part by a collision sphere (a
  head, a sensor dome), every planning model carries that sphere exactly in place of its own spheres inside
  it (:func:`gfcs.coverage.with_element_spheres`; ``element_spheres=False``, the ``paper`` preset: the
  robot's spheres as given).
* The validator: the problem's mesh checker (collision meshes or polytopes), or None (spheres only).
* Limits and profile: the URDF's joint and velocity limits, the profile's acceleration limits and approach
  axis (:mod:`gfcs.profile`).

Everything that asks which model a result was planned on (the CLI's hints, the viewer, replay, the
reactivity experiment) goes through :func:`planned_robot`.
"""

from __future__ import annotations

import copy
import dataclasses
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from gfcs import coverage as _coverage
from gfcs import problems as _problems
from gfcs import profile as _profile
from gfcs.errors import InvalidValueError

__all__ = ["PlanningModel", "RobotModels", "models_for", "model_named", "planned_robot", "with_robot",
           "THIN_SPHERE_MARGIN"]

#: How much wider [m] than the fabric's obstacle margin the thin spheres are kept from obstacles: they miss
#: the Franka meshes by up to 8.3 mm, and at the plain margin a motion can bring a collision polytope into
#: an obstacle with every sphere clear; 4 mm more keeps the polytopes clear for most motions, and the
#: mesh-retry policy widens it further where they still touch (docs/tuning.md).
THIN_SPHERE_MARGIN = 0.004

#: How far [m] a robot's own spheres may leave the validator's meshes of a moving link uncovered before a solve
#: plans on spheres fitted around those meshes first (:func:`covering_model`). The MotionBenchMaker Fetch's
#: spheres miss its torso by 45 mm: there the covering spheres solve the shelf and cage problems its own
#: spheres cannot, in half the time; the UR5's (30 mm, its forearm) and the MBM Panda's (19 mm) solve more as
#: they are (docs/tuning.md).
COVERING_DEFICIT = 0.04


@dataclass(frozen=True)
class PlanningModel:
    """A collision-sphere model the fabric plans with.

    Attributes:
        name: ``"thin"`` (a thinner model than the robot's own, with :data:`THIN_SPHERE_MARGIN`) or
            ``"spheres"`` (the robot's own spheres).
        robot: the ``gfcs.Robot`` carrying those spheres.
        margin_offset: added to the fabric's obstacle margin when planning with it [m].
        element_spheres: the validator's collision spheres the model carries (link, centre m, radius m;
            :func:`gfcs.coverage.element_spheres`), () when none.
    """

    name: str
    robot: Any
    margin_offset: float = 0.0
    element_spheres: Tuple[Tuple[str, Tuple[float, ...], float], ...] = ()

    def settings(self) -> Dict[str, Any]:
        """What a result records of the model so that :func:`model_named` rebuilds it: ``sphere_model``
        ("thin" or "covering"; the covering model's ``spheres`` [{link, center, radius}] with it) and
        ``element_spheres`` ([{link, center, radius}], when it carries any)."""
        out: Dict[str, Any] = {"sphere_model": self.name} if self.name in ("thin", "covering") else {}
        if self.name == "covering":
            out["spheres"] = [{"link": link, "center": c, "radius": r}
                              for link, c, r in _problems._robot_spheres(self.robot)]
        if self.element_spheres:
            out["element_spheres"] = [{"link": link, "center": list(c), "radius": r}
                                      for link, c, r in self.element_spheres]
        return out


@dataclass(frozen=True)
class RobotModels:
    """What a solve knows about the problem's robot (see the module docstring).

    Attributes:
        robot: the problem's robot.
        planning: the planning models, in the order tried (at least one).
        validator: the mesh checker that judges motions, or None.
        profile: the robot's :class:`gfcs.profile.RobotProfile`.
    """

    robot: Any
    planning: Tuple[PlanningModel, ...]
    validator: Any
    profile: Any

    @property
    def velocity_limits(self) -> np.ndarray:
        """(dof,) velocity limits [rad/s or m/s] (the URDF's, tightened by the profile)."""
        return _profile.velocity_limits(self.robot, self.profile)

    @property
    def acceleration_limits(self) -> Optional[np.ndarray]:
        """(dof,) acceleration limits, inf where unknown; None when none is known."""
        return _profile.acceleration_limits(self.robot, self.profile)

    def model(self, name: str) -> PlanningModel:
        """The planning model called ``name`` (KeyError naming the known ones otherwise)."""
        for m in self.planning:
            if m.name == name:
                return m
        raise InvalidValueError(f"no planning model {name!r}; this robot has {[m.name for m in self.planning]}")


def models_for(problem: Any, thin_spheres: bool = True, element_spheres: bool = True,
               covering: bool = False) -> RobotModels:
    """The :class:`RobotModels` of ``problem`` (its robot and mesh checker). ``thin_spheres``: plan on a thin
    model first when the robot has one and the problem a validator to judge it (False: own spheres only,
    the ``paper`` preset). ``element_spheres``: every planning model carries the validator's collision
    spheres (module docstring; False: the ``paper`` preset). ``covering``: plan on the covering model
    (:func:`covering_model`) first when the robot's own spheres leave its meshes uncovered (the ``default``
    preset)."""
    robot = problem.robot
    validator = getattr(problem, "mesh_checker", None)
    exact: Tuple[Tuple[str, Tuple[float, ...], float], ...] = ()
    if element_spheres and validator is not None and hasattr(validator, "robot"):
        known = set(robot.link_names)
        exact = tuple((link, tuple(c), r) for link, c, r in _coverage.element_spheres(validator.robot)
                      if link in known)

    def model(name: str, spheres: Any, offset: float = 0.0) -> PlanningModel:
        carried = _coverage.with_element_spheres(spheres, exact)
        return PlanningModel(name, carried, offset, exact if carried is not spheres else ())

    own = model("spheres", robot)
    thin = _problems.thin_sphere_model(robot) if thin_spheres and validator is not None else None
    planning = (model("thin", thin, THIN_SPHERE_MARGIN), own) if thin is not None else (own,)
    # a robot with a thin model on record has its covering spheres already: its own
    fitted = covering_model(own.robot, validator) if covering and thin is None else None
    if fitted is not None:
        planning = (model("covering", fitted),) + planning
    return RobotModels(robot, planning, validator, _profile.profile_for(robot))


#: The covering models built in this process (:func:`covering_model`), by what they depend on; the most
#: recently used :data:`_COVERING_KEPT` are kept.
_COVERING: "OrderedDict[Tuple[Any, ...], Any]" = OrderedDict()
_COVERING_KEPT = 32


def covering_model(robot: Any, validator: Any) -> Optional[Any]:
    """``robot`` with spheres fitted around its validator's collision meshes (:func:`gfcs.sphere_fit.covering_model`)
    when its own spheres leave the meshes of a link its joints move uncovered by more than
    :data:`COVERING_DEFICIT` (:func:`gfcs.coverage.sphere_deficits`; a fixed base is left out: it never
    moves toward an obstacle), else None (no validator, or spheres near enough to the meshes: the shipped
    Panda's, a robot's fitted ones). Built once per process for a robot and validator."""
    if validator is None or not hasattr(validator, "robot"):
        return None
    key = (_problems.sphere_fingerprint(robot), tuple(robot.link_names), tuple(robot.joint_names),
           tuple(sorted(robot.locked_positions.items())), tuple(np.asarray(robot.lower).tolist()),
           tuple(np.asarray(robot.upper).tolist()), len(robot.self_collision_pairs),
           tuple(_coverage._key(e) for e in validator.robot.collision_geometry()))
    if key not in _COVERING:
        from gfcs import sphere_fit

        _COVERING[key] = sphere_fit.covering_model(robot, validator) if _uncovered(robot, validator, key) else None
        while len(_COVERING) > _COVERING_KEPT:
            _COVERING.popitem(last=False)
    _COVERING.move_to_end(key)
    return _COVERING[key]


def _uncovered(robot: Any, validator: Any, key: Tuple[Any, ...]) -> bool:
    """Whether ``robot``'s spheres leave a moving link's meshes more than :data:`COVERING_DEFICIT` uncovered;
    kept in the disk cache (:mod:`gfcs.cache`) under ``key`` and the mesh files' bytes: reading and sampling
    the meshes takes a second on a large robot, once per machine."""
    from gfcs import cache as _cache

    meshes = sorted({element[2] for element in key[-1] if element[2]})  # the mesh paths of the validator's geometry
    digest = _cache.digest("covering_deficit", COVERING_DEFICIT, repr(key), [(m, _cache.file_digest(m)) for m in meshes],
                           _cache.file_digest(__file__), _cache.file_digest(_coverage.__file__))
    hit = _cache.load("covering", digest)
    if isinstance(hit, bool):
        return hit
    deficit = _coverage.sphere_deficits(robot, validator.robot)
    moving = np.isin(np.asarray(robot.sphere_links, dtype=str), _moving_links(robot))
    uncovered = bool(np.any(deficit[moving] > COVERING_DEFICIT))
    _cache.store("covering", digest, uncovered)
    return uncovered


def with_robot(problem: Any, robot: Any) -> Any:
    """``problem`` with ``robot`` in place of its own (a copy; ``problem`` is unchanged)."""
    if robot is problem.robot:
        return problem
    if dataclasses.is_dataclass(problem):
        return dataclasses.replace(problem, robot=robot)
    other = copy.copy(problem)
    other.robot = robot
    return other


def model_named(robot: Any, settings: Optional[Dict[str, Any]]) -> Any:
    """``robot`` as the planning model a result's ``settings`` name (:meth:`PlanningModel.settings`)
    carries it: its thin model for ``sphere_model == "thin"`` (``robot`` itself when it has none, e.g. when
    it already is that model), the recorded spheres for ``"covering"`` (the self-collision pairs the solve
    left out of that model stay checked), with the ``element_spheres`` recorded there."""
    settings = settings or {}
    if settings.get("sphere_model") == "thin":
        robot = _problems.thin_sphere_model(robot) or robot
    elif settings.get("sphere_model") == "covering":
        robot = robot.with_spheres([(e["link"], e["center"], e["radius"]) for e in settings["spheres"]])
    recorded = settings.get("element_spheres") or []
    return _coverage.with_element_spheres(robot, [(e["link"], e["center"], e["radius"]) for e in recorded])


def planned_robot(result: Any, problem: Any) -> Any:
    """The robot ``result`` was planned on: its own ``robot`` (set by solve, e.g. the thin spheres), else,
    for a result loaded from JSON, ``problem.robot`` as the model the result names
    (``settings["sphere_model"]``)."""
    robot = getattr(result, "robot", None)
    if robot is not None:
        return robot
    return model_named(problem.robot, getattr(result, "settings", None))


def _moving_links(robot: Any, samples: int = 4) -> List[str]:
    """The links of ``robot`` whose pose (in the root frame) changes with its joints: seeded configurations
    within the limits, links whose poses differ between them by more than 1e-9."""
    lower, upper = np.asarray(robot.lower, dtype=np.float64), np.asarray(robot.upper, dtype=np.float64)
    finite = np.isfinite(lower) & np.isfinite(upper)
    q = np.random.default_rng(0).uniform(np.where(finite, lower, -np.pi), np.where(finite, upper, np.pi),
                                         (samples, int(robot.dof)))
    poses = np.asarray(robot.link_poses(q), dtype=np.float64).reshape(samples, len(robot.link_names), -1)
    varies = np.abs(poses - poses[:1]).max(axis=(0, 2)) > 1e-9
    return [name for name, v in zip(robot.link_names, varies) if v]
