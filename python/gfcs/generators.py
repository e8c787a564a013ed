"""Procedural, seeded motion problems in the style of MotionBenchMaker (GFCS Sec. V, Fig. 2).

``generate(cls, n, seed)`` builds ``n`` problems of one class: a randomised scene of boxes and cylinders
(tables, shelves, an open box, a cage, cans and blocks), a start and a goal configuration found by
inverse kinematics to sampled end-effector targets. Every start and goal is inside the joint limits
(with a small inset) and collision-free under the robot's sphere model: for every collision sphere,
signed distance − radius ≥ ``margin`` against the scene, and ≥ :data:`SELF_MARGIN` between self-collision pairs.
For a robot with collision meshes on record (:func:`gfcs.problems.mesh_checker_for`, e.g. the MotionBenchMaker
Panda of :func:`gfcs.problems.mbm_panda`, whose spheres do not cover its meshes) the problems carry that
mesh checker, and their starts and goals keep the meshes more than :data:`gfcs.metrics.DEFAULT_MESH_MARGIN`
from the obstacles and from each other too, so that every generated problem can succeed.

Frames: the robot base is the world origin, z up. Each structure (shelf, table, ...) has a local frame
whose x axis points away from the robot (depth), y is lateral and z up; its front face is at local x = 0.
The structure sits at azimuth φ around the base with yaw ψ = φ + δ (|δ| ≤ 5°).

Classes (:data:`gfcs.problems.CLASSES`):

* ``bookshelf_small`` (single shelf): two 1.2 × 1.0 m boards 0.30 m apart, two sides, three cans; the
  front face 0.5-0.7 m from the base, the bottom board at z ∈ [−0.08, 0.67] m (the ranges of the
  MotionBenchMaker files). Goal: the gripper inside the shelf, pointing into it.
* ``bookshelf_tall``: 4-5 levels, 0.35-0.45 m deep. ``bookshelf_thin``: 3-4 thin levels, 0.22-0.28 m
  deep. Goal: inside a compartment, pointing into it.
* ``box``: an open-top box on a table; goal: inside the box, pointing down.
* ``cage``: a cage of bars on a table (bars on three sides, a single cross bar in front, a roof); goal:
  inside the cage, entering from the front.
* ``table_pick``: a table with blocks and cans; goal: above an object, pointing down (pre-grasp).
* ``table_under_pick``: a higher table; start: the gripper under the table; goal: as ``table_pick``.

Starts are the Panda "ready" configuration (the MotionBenchMaker start) except for ``table_under_pick``.
The layouts are the Panda's, drawn about its shoulder; for another robot every length is scaled by
:func:`workspace_scale` (its reach over the Panda's) and the layout is moved onto its shoulder
(:func:`arm_mount`), so that a smaller arm gets smaller structures nearer it and a mobile manipulator's
scenes stand in front of its arm, not its base.
Problem ``i`` of ``generate(cls, n, seed)`` depends only on (cls, seed, i), so a longer list extends a
shorter one. Generated problems keep their primitives in ``problem.meta["primitives"]`` and can be written
as MotionBenchMaker files with :func:`write_problems` (read back by :func:`gfcs.problems.load_mbm_dir`).
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from gfcs import metrics as _metrics
from gfcs.errors import GenerationError, InvalidValueError
from gfcs.pose_goal import quaternion_xyzw
from gfcs.profile import perturbed_poses
from gfcs.problems import CLASSES, Problem, canonical_class, mesh_checker_for

__all__ = [
    "Primitive",
    "Target",
    "READY",
    "PANDA_TCP",
    "PANDA_MOUNT",
    "PANDA_REACH",
    "generate",
    "workspace_scale",
    "arm_mount",
    "build_scene",
    "inverse_kinematics",
    "is_collision_free",
    "scene_yaml",
    "request_yaml",
    "write_problems",
]

#: The Panda "ready" configuration [rad] (the start state of the MotionBenchMaker Panda problems).
READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
#: Tool centre point of the Panda hand in the ``panda_hand`` frame [m] (between the finger pads).
PANDA_TCP = np.array([0.0, 0.0, 0.1034])

_CLASS_INDEX = {c: i for i, c in enumerate(CLASSES)}


@dataclass(frozen=True)
class Primitive:
    """One obstacle primitive in MoveIt conventions.

    Attributes:
        name: object id.
        kind: ``"box"`` (dims = full edge lengths (3,)), ``"cylinder"`` (dims = (height, radius), axis =
            local z) or ``"sphere"`` (dims = (radius,)) [m].
        position: (3,) centre in the world frame [m].
        quaternion: (4,) orientation [x, y, z, w].
    """

    name: str
    kind: str
    dims: Tuple[float, ...]
    position: Tuple[float, float, float]
    quaternion: Tuple[float, float, float, float]


@dataclass(frozen=True)
class Target:
    """An end-effector target for inverse kinematics.

    Attributes:
        position: (3,) world position of the tool centre point [m].
        approach: (3,) unit world direction the gripper should point along (hand z axis), or None.
        cone_deg: accepted angle between the hand z axis and ``approach`` [deg].
    """

    position: np.ndarray
    approach: Optional[np.ndarray] = None
    cone_deg: float = 25.0


class _Frame:
    """A structure frame: origin (3,) and yaw ψ about world z; places primitives given in local coords."""

    def __init__(self, origin: np.ndarray, yaw: float):
        self.origin = np.asarray(origin, dtype=np.float64)
        self.yaw = float(yaw)
        c, s = math.cos(yaw), math.sin(yaw)
        self.rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        self.quat = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
        self.items: List[Primitive] = []

    def point(self, local: Sequence[float]) -> np.ndarray:
        return self.origin + self.rot @ np.asarray(local, dtype=np.float64)

    def direction(self, local: Sequence[float]) -> np.ndarray:
        d = self.rot @ np.asarray(local, dtype=np.float64)
        return d / np.linalg.norm(d)

    def box(self, name: str, size: Sequence[float], center: Sequence[float]) -> None:
        self.items.append(Primitive(name, "box", tuple(float(v) for v in size),
                                    tuple(self.point(center).tolist()), self.quat))

    def cylinder(self, name: str, height: float, radius: float, center: Sequence[float]) -> None:
        self.items.append(Primitive(name, "cylinder", (float(height), float(radius)),
                                    tuple(self.point(center).tolist()), self.quat))


def _place_frame(rng: np.random.Generator, front: Tuple[float, float], z: Tuple[float, float],
                 azimuth: Tuple[float, float] = (-math.pi / 2, math.pi / 2)) -> _Frame:
    phi = rng.uniform(*azimuth)
    d = rng.uniform(*front)
    yaw = phi + rng.uniform(-math.radians(5), math.radians(5))
    return _Frame(np.array([d * math.cos(phi), d * math.sin(phi), rng.uniform(*z)]), yaw)


@dataclass
class _Layout:
    """A randomised scene with its target samplers (start None: the ready configuration)."""

    primitives: List[Primitive]
    goal: Callable[[np.random.Generator], Target]
    start: Optional[Callable[[np.random.Generator], Target]] = None


# ------------------------------------------------------------------------------------ scene layouts
def _shelf(rng: np.random.Generator, f: _Frame, depth: float, width: float, thickness: float,
           levels: int, spacing: float, can: Tuple[float, float], cans_per_level: Tuple[int, int]
           ) -> List[float]:
    """Boards (centres at local z = k·spacing), two sides and cans; returns the board-top heights."""
    tops = []
    for k in range(levels):
        zc = k * spacing
        f.box(f"shelf_{k}", (depth, width, thickness), (depth / 2, 0.0, zc))
        tops.append(zc + thickness / 2)
    height = (levels - 1) * spacing + thickness
    for side, y in (("left", -width / 2), ("right", width / 2)):
        f.box(f"side_{side}", (depth, 0.04, height), (depth / 2, y, (levels - 1) * spacing / 2))
    can_h, can_r = can
    for k in range(levels - 1):
        for j in range(int(rng.integers(cans_per_level[0], cans_per_level[1] + 1))):
            x = rng.uniform(0.1, depth - 0.06)
            y = rng.uniform(-width / 2 + 0.08, width / 2 - 0.08)
            f.cylinder(f"can_{k}_{j}", can_h, can_r, (x, y, tops[k] + can_h / 2))
    return tops


def _compartment_goal(f: _Frame, depth: float, width: float, tops: List[float], spacing: float,
                      thickness: float) -> Callable[[np.random.Generator], Target]:
    """Targets inside a reachable compartment (centre height in [−0.05, 0.85] m), pointing into it."""
    reachable = [k for k in range(len(tops) - 1)
                 if -0.05 <= f.point((0, 0, tops[k] + (spacing - thickness) / 2))[2] <= 0.85]
    levels = reachable or list(range(len(tops) - 1))

    def sample(rng: np.random.Generator) -> Target:
        k = levels[int(rng.integers(len(levels)))]
        gap = spacing - thickness
        x = rng.uniform(0.03, max(0.04, min(depth - 0.12, 0.3)))
        y = rng.uniform(-width / 2 + 0.18, width / 2 - 0.18)
        z = tops[k] + rng.uniform(min(0.07, gap / 2), max(min(0.07, gap / 2), min(0.15, gap - 0.09)))
        return Target(f.point((x, y, z)), f.direction((1.0, 0.0, 0.0)), 25.0)

    return sample


def _bookshelf_small(rng: np.random.Generator) -> _Layout:
    f = _place_frame(rng, front=(0.5, 0.7), z=(-0.08, 0.67))
    depth, width, spacing, t = 1.2, 1.0, 0.30, 0.04
    tops = [t / 2, spacing + t / 2]
    f.box("shelf_bottom", (depth, width, t), (depth / 2, 0.0, 0.0))
    f.box("shelf_top", (depth, width, t), (depth / 2, 0.0, spacing))
    for side, y in (("left", -width / 2), ("right", width / 2)):
        f.box(f"side_{side}", (depth, 0.04, spacing + t), (depth / 2, y, spacing / 2))
    for j, x in enumerate((0.5, 0.3, 0.1)):
        f.cylinder(f"Can{j + 1}", 0.14, 0.03, (x, rng.uniform(-0.45, 0.45), 0.08))
    return _Layout(f.items, _compartment_goal(f, depth, width, tops, spacing, t))


def _bookshelf_tall(rng: np.random.Generator) -> _Layout:
    f = _place_frame(rng, front=(0.55, 0.75), z=(-0.45, -0.25))
    depth, width = rng.uniform(0.35, 0.45), rng.uniform(0.8, 1.0)
    spacing, levels, t = rng.uniform(0.30, 0.36), int(rng.integers(4, 6)), 0.03
    tops = _shelf(rng, f, depth, width, t, levels, spacing, (0.14, 0.03), (0, 2))
    return _Layout(f.items, _compartment_goal(f, depth, width, tops, spacing, t))


def _bookshelf_thin(rng: np.random.Generator) -> _Layout:
    f = _place_frame(rng, front=(0.5, 0.7), z=(-0.3, 0.0))
    depth, width = rng.uniform(0.22, 0.28), rng.uniform(0.6, 0.8)
    spacing, levels, t = rng.uniform(0.28, 0.34), int(rng.integers(3, 5)), 0.02
    tops = _shelf(rng, f, depth, width, t, levels, spacing, (0.10, 0.025), (0, 2))
    return _Layout(f.items, _compartment_goal(f, depth, width, tops, spacing, t))


def _table(f: _Frame, depth: float, width: float, thickness: float = 0.04, legs: float = 0.7) -> None:
    """A table whose top surface is at local z = 0, front edge at local x = 0."""
    f.box("table_top", (depth, width, thickness), (depth / 2, 0.0, -thickness / 2))
    for i, (x, y) in enumerate(((0.03, -width / 2 + 0.03), (0.03, width / 2 - 0.03),
                                (depth - 0.03, -width / 2 + 0.03), (depth - 0.03, width / 2 - 0.03))):
        f.box(f"table_leg_{i}", (0.04, 0.04, legs), (x, y, -thickness - legs / 2))


def _table_objects(rng: np.random.Generator, f: _Frame, depth: float, width: float, count: int,
                   reach: float) -> List[Tuple[np.ndarray, float]]:
    """Blocks and cans on the table; returns (local top-centre, height) of each."""
    placed: List[Tuple[np.ndarray, float]] = []
    for j in range(200):
        if len(placed) == count:
            break
        x = rng.uniform(0.1, min(depth - 0.1, reach))
        y = rng.uniform(-width / 2 + 0.1, width / 2 - 0.1)
        if any(np.hypot(x - p[0][0], y - p[0][1]) < 0.15 for p in placed):
            continue
        h = rng.uniform(0.1, 0.2)
        if rng.uniform() < 0.5:
            f.cylinder(f"can_{len(placed)}", h, rng.uniform(0.03, 0.04), (x, y, h / 2))
        else:
            f.box(f"block_{len(placed)}", (rng.uniform(0.04, 0.08), rng.uniform(0.04, 0.08), h), (x, y, h / 2))
        placed.append((np.array([x, y, h]), h))
    return placed


def _pick_goal(f: _Frame, objects: List[Tuple[np.ndarray, float]]) -> Callable[[np.random.Generator], Target]:
    def sample(rng: np.random.Generator) -> Target:
        top, _ = objects[int(rng.integers(len(objects)))]
        return Target(f.point(top + np.array([0.0, 0.0, rng.uniform(0.03, 0.06)])), np.array([0.0, 0.0, -1.0]), 20.0)

    return sample


def _table_pick(rng: np.random.Generator) -> _Layout:
    f = _place_frame(rng, front=(0.3, 0.45), z=(-0.15, 0.15))
    depth, width = rng.uniform(0.6, 0.8), rng.uniform(1.0, 1.4)
    _table(f, depth, width)
    objects = _table_objects(rng, f, depth, width, int(rng.integers(3, 6)), 0.4)
    return _Layout(f.items, _pick_goal(f, objects))


def _table_under_pick(rng: np.random.Generator) -> _Layout:
    f = _place_frame(rng, front=(0.3, 0.4), z=(0.3, 0.45), azimuth=(-math.pi / 3, math.pi / 3))
    depth, width = rng.uniform(0.6, 0.8), rng.uniform(1.2, 1.5)
    _table(f, depth, width)
    objects = _table_objects(rng, f, depth, width, int(rng.integers(2, 5)), 0.35)

    def start(rng: np.random.Generator) -> Target:
        local = (rng.uniform(0.1, 0.3), rng.uniform(-0.3, 0.3), -rng.uniform(0.22, 0.32))
        return Target(f.point(local), f.direction((1.0, 0.0, 0.0)), 45.0)

    return _Layout(f.items, _pick_goal(f, objects), start)


def _box(rng: np.random.Generator) -> _Layout:
    f = _place_frame(rng, front=(0.3, 0.4), z=(-0.1, 0.15))
    depth, width = rng.uniform(0.6, 0.8), rng.uniform(1.0, 1.4)
    _table(f, depth, width)
    lx, ly, h, w = rng.uniform(0.35, 0.45), rng.uniform(0.35, 0.45), rng.uniform(0.18, 0.28), 0.02
    cx, cy = rng.uniform(0.05, 0.2) + lx / 2, rng.uniform(-0.15, 0.15)
    f.box("box_floor", (lx, ly, w), (cx, cy, w / 2))
    f.box("box_front", (w, ly, h), (cx - lx / 2 + w / 2, cy, h / 2))
    f.box("box_back", (w, ly, h), (cx + lx / 2 - w / 2, cy, h / 2))
    f.box("box_left", (lx, w, h), (cx, cy - ly / 2 + w / 2, h / 2))
    f.box("box_right", (lx, w, h), (cx, cy + ly / 2 - w / 2, h / 2))

    def goal(rng: np.random.Generator) -> Target:
        local = (cx + rng.uniform(-1, 1) * (lx / 2 - 0.13), cy + rng.uniform(-1, 1) * (ly / 2 - 0.13),
                 w + rng.uniform(0.06, 0.1))
        return Target(f.point(local), np.array([0.0, 0.0, -1.0]), 20.0)

    return _Layout(f.items, goal)


def _cage(rng: np.random.Generator) -> _Layout:
    f = _place_frame(rng, front=(0.3, 0.4), z=(-0.1, 0.15))
    depth, width = rng.uniform(0.6, 0.8), rng.uniform(1.0, 1.4)
    _table(f, depth, width)
    sx, sy, h, r = rng.uniform(0.45, 0.55), rng.uniform(0.45, 0.55), rng.uniform(0.35, 0.45), 0.012
    x0, cy = rng.uniform(0.05, 0.12), rng.uniform(-0.1, 0.1)
    f.box("cage_roof", (sx, sy, 0.02), (x0 + sx / 2, cy, h + 0.01))
    for i, (x, y) in enumerate(((x0, cy - sy / 2), (x0, cy + sy / 2), (x0 + sx, cy - sy / 2), (x0 + sx, cy + sy / 2))):
        f.cylinder(f"cage_post_{i}", h, 0.015, (x, y, h / 2))
    bars = 0
    for k in range(1, int(sy / 0.12)):
        f.cylinder(f"cage_bar_{bars}", h, r, (x0 + sx, cy - sy / 2 + k * sy / int(sy / 0.12), h / 2))
        bars += 1
    for side in (-1, 1):
        for k in range(1, int(sx / 0.12)):
            f.cylinder(f"cage_bar_{bars}", h, r, (x0 + k * sx / int(sx / 0.12), cy + side * sy / 2, h / 2))
            bars += 1
    f.box("cage_front_bar", (0.02, sy, 0.02), (x0, cy, h * rng.uniform(0.6, 0.75)))

    def goal(rng: np.random.Generator) -> Target:
        local = (x0 + sx * rng.uniform(0.35, 0.6), cy + rng.uniform(-0.08, 0.08), rng.uniform(0.07, 0.12))
        return Target(f.point(local), f.direction((1.0, 0.0, 0.0)), 30.0)

    return _Layout(f.items, goal)


_LAYOUTS: Dict[str, Callable[[np.random.Generator], _Layout]] = {
    "table_under_pick": _table_under_pick,
    "box": _box,
    "bookshelf_tall": _bookshelf_tall,
    "cage": _cage,
    "bookshelf_thin": _bookshelf_thin,
    "bookshelf_small": _bookshelf_small,
    "table_pick": _table_pick,
}


# ------------------------------------------------------------------------------------------- scenes
def build_scene(primitives: Sequence[Primitive]) -> Any:
    """A ``gfcs.Scene`` holding ``primitives`` (MoveIt conventions: full box sizes, cylinder axis z)."""
    import gfcs

    scene = gfcs.Scene()
    for p in primitives:
        pose = (list(p.position), list(p.quaternion))
        if p.kind == "box":
            scene.add_box(list(p.dims), pose=pose, name=p.name)
        elif p.kind == "cylinder":
            scene.add_cylinder(p.dims[0], p.dims[1], pose=pose, name=p.name)
        elif p.kind == "sphere":
            scene.add_sphere(list(p.position), p.dims[0], name=p.name)
        else:
            raise InvalidValueError(f"primitive '{p.name}': unknown kind '{p.kind}' (box, cylinder, sphere)")
    return scene


def scene_yaml(primitives: Sequence[Primitive], name: str = "") -> str:
    """MoveIt PlanningScene YAML (the MotionBenchMaker ``sceneNNNN.yaml`` layout) of ``primitives``."""
    import yaml

    objects = [
        {
            "id": p.name,
            "primitives": [{"type": p.kind, "dimensions": [float(v) for v in p.dims]}],
            "primitive_poses": [{"position": [float(v) for v in p.position],
                                 "orientation": [float(v) for v in p.quaternion]}],
        }
        for p in primitives
    ]
    doc = {"name": name, "robot_model_name": "panda", "world": {"collision_objects": objects}}
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def _start_state(joint_names: Sequence[str], q0: Sequence[float], locked: Optional[Dict[str, float]]
                 ) -> Dict[str, Any]:
    """A request's ``start_state``: the active joints at ``q0``, then the locked ones where the robot holds
    them (e.g. the shipped Panda's fingers at 0.04 m), as MotionBenchMaker lists its fingers."""
    names = list(joint_names) + list(locked or {})
    positions = [float(v) for v in q0] + [float(v) for v in (locked or {}).values()]
    return {"joint_state": {"name": names, "position": positions}}


def request_yaml(joint_names: Sequence[str], q0: Sequence[float], goal: Sequence[float],
                 group: str, locked: Optional[Dict[str, float]] = None) -> str:
    """MoveIt MotionPlanRequest YAML (``requestNNNN.yaml`` layout): start joint state (with ``locked``
    {joint: position} of the joints the robot holds, e.g. ``robot.locked_positions``), joint goal."""
    import yaml

    doc = {
        "start_state": _start_state(joint_names, q0, locked),
        "goal_constraints": [{"joint_constraints": [
            {"joint_name": j, "position": float(v)} for j, v in zip(joint_names, goal)]}],
        "group_name": group,
    }
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def pose_request_yaml(robot: Any, q0: Sequence[float], goal: Sequence[float], link: Any = None,
                      offset: Sequence[float] = PANDA_TCP, position_tolerance: float = 1e-3,
                      angle_tolerance: float = 0.01, group: str = "") -> str:
    """MoveIt MotionPlanRequest YAML with a pose goal: the pose that ``goal`` (dof,) [rad] gives ``link``
    (default the end-effector link), as a position constraint on the point ``offset`` (3,) [m] of the link
    (a sphere of radius ``position_tolerance`` [m] around it) and an orientation constraint with
    ``angle_tolerance`` [rad] about each axis (XYZ Euler angles), in the robot's root frame; the start
    state lists the robot's locked joints too."""
    import yaml

    index = robot.link_index(robot.ee_link if link is None else link)
    name = robot.link_names[index]
    pose = np.asarray(robot.link_poses(np.asarray(goal, dtype=np.float64)), dtype=np.float64)[index]
    point = pose[:3, :3] @ np.asarray(offset, dtype=np.float64) + pose[:3, 3]
    header = {"frame_id": robot.link_names[0]}
    group = group or robot.name
    doc = {
        "start_state": _start_state(robot.joint_names, q0, robot.locked_positions),
        "goal_constraints": [{
            "joint_constraints": [],
            "position_constraints": [{
                "header": header, "link_name": name,
                "target_point_offset": dict(zip("xyz", (float(v) for v in offset))),
                "constraint_region": {
                    "primitives": [{"type": "sphere", "dimensions": [float(position_tolerance)]}],
                    "primitive_poses": [{"position": [float(v) for v in point], "orientation": [0.0, 0.0, 0.0, 1.0]}],
                },
                "weight": 1.0,
            }],
            "orientation_constraints": [{
                "header": header, "link_name": name,
                "orientation": [float(v) for v in quaternion_xyzw(pose[:3, :3])],
                **{f"absolute_{a}_axis_tolerance": float(angle_tolerance) for a in "xyz"},
                "parameterization": 0, "weight": 1.0,
            }],
        }],
        "group_name": group,
    }
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def write_problems(problems: Sequence[Problem], directory: Any, pose_goals: bool = False,
                   group: Optional[str] = None) -> List[Path]:
    """Write generated problems as MotionBenchMaker files: ``<directory>/<cls>/sceneNNNN.yaml`` and
    ``requestNNNN.yaml`` (NNNN = 0001, 0002, ... per class, in list order). ``pose_goals``: the requests
    hold the pose of the hand's TCP at the goal (:func:`pose_request_yaml`) instead of the joint goal.
    ``group``: the requests' ``group_name`` (the robot's planning group in its SRDF, e.g.
    :func:`gfcs.srdf_groups.group_of`); a problem's own ``meta["group"]`` comes first; without either, the
    robot's name.

    Returns:
        The class folders written. Raises ValueError for a problem without ``meta["primitives"]``.
    """
    root = Path(directory)
    counts: Dict[str, int] = {}
    folders: List[Path] = []
    for p in problems:
        prims = p.meta.get("primitives")
        if prims is None:
            raise InvalidValueError(f"problem '{p.name}' has no meta['primitives'] (not generated?)")
        cls = p.cls or "generated"
        counts[cls] = counts.get(cls, 0) + 1
        folder = root / cls
        if folder not in folders:
            folder.mkdir(parents=True, exist_ok=True)
            folders.append(folder)
        number = f"{counts[cls]:04d}"
        prim_objs = [Primitive(**d) if isinstance(d, dict) else d for d in prims]
        (folder / f"scene{number}.yaml").write_text(scene_yaml(prim_objs, p.name))
        name = p.meta.get("group") or group or p.robot.name
        request = (pose_request_yaml(p.robot, p.q0, p.goal, group=name) if pose_goals
                   else request_yaml(p.robot.joint_names, p.q0, p.goal, group=name, locked=p.robot.locked_positions))
        (folder / f"request{number}.yaml").write_text(request)
    return folders


# ------------------------------------------------------------------------------- inverse kinematics
#: Self-collision clearance [m] required of generated starts and goals: the default fabric's
#: ``self_collision.margin``, which its barrier keeps between sphere pairs (a goal closer than that
#: would sit inside the barrier and be hard to reach).
SELF_MARGIN = 0.002


def is_collision_free(robot: Any, scene: Any, q: Any, margin: float = 0.01,
                      self_margin: float = SELF_MARGIN) -> bool:
    """Sphere-model check: every sphere ≥ ``margin`` from the obstacles, self pairs ≥ ``self_margin`` apart.

    Args:
        q: (dof,) configuration.
        margin: required obstacle clearance [m].
        self_margin: required clearance between self-collision sphere pairs [m].
    """
    qa = np.asarray(q, dtype=np.float64)[None, :]
    return bool(_metrics.obstacle_clearance(robot, scene, qa)[0] >= margin
                and _metrics.self_clearance(robot, qa)[0] >= self_margin)


def inverse_kinematics(
    robot: Any,
    target: Target,
    rng: np.random.Generator,
    *,
    link: Any = None,
    point: Sequence[float] = PANDA_TCP,
    axis: Sequence[float] = (0.0, 0.0, 1.0),
    q_seed: Optional[np.ndarray] = None,
    restarts: int = 20,
    iterations: int = 150,
    position_tol: float = 2e-3,
    inset: float = 0.05,
    accept: Optional[Callable[[np.ndarray], bool]] = None,
) -> Optional[np.ndarray]:
    """Damped-least-squares IK with random restarts for a point (and optionally an axis) of a link.

    Minimises ‖x_t − x(q)‖ for the point ``point`` fixed on ``link`` (default: the end-effector link),
    and, when ``target.approach`` is set, ‖a_t − R(q)·axis‖ with weight 0.5: Δq = Jᵀ(JJᵀ + λ²I)⁻¹e,
    λ = 0.05, step norm ≤ 0.3 rad, q kept in [lower + inset, upper − inset]. The first attempt starts from
    ``q_seed`` (when given), the others uniformly inside the limits.

    Args:
        robot: a :class:`gfcs.Robot` (each descent is its ``point_ik``).
        target: position [m] and optional approach direction with its cone.
        rng: generator for the restarts.
        link: link name or index (default ``robot.ee_link``).
        point: (3,) point in the link frame [m] (default: the Panda TCP).
        axis: (3,) link-frame axis aligned with ``target.approach``.
        accept: extra test of a converged solution (e.g. collision-free); rejected solutions restart.

    Returns:
        (dof,) configuration, or None when no restart converged and passed ``accept``.
    """
    idx = robot.link_index(link if link is not None else robot.ee_link) if not isinstance(link, int) else link
    lo = np.asarray(robot.lower, dtype=np.float64) + inset
    up = np.asarray(robot.upper, dtype=np.float64) - inset
    for attempt in range(int(restarts)):
        q = np.clip(q_seed if (attempt == 0 and q_seed is not None) else rng.uniform(lo, up), lo, up)
        # one descent in the core (Robot.point_ik): 0.27 ms against 14.6 ms for the former numpy loop
        q, converged = robot.point_ik(q, target.position, link=idx, point=point, axis=axis,
                                      approach=target.approach, cone_deg=target.cone_deg, lower=lo, upper=up,
                                      iterations=int(iterations), tolerance=position_tol, damping=0.05**2,
                                      axis_weight=0.5, max_step=0.3)
        if converged and (accept is None or accept(q)):
            return q
    return None


# ---------------------------------------------------------------------------------------- generator
def _is_panda(robot: Any) -> bool:
    """A 7-joint Panda (joints named ``panda_joint*``): the robot the layouts, READY and PANDA_TCP fit."""
    return robot.dof == READY.shape[0] and all(j.startswith("panda_joint") for j in robot.joint_names)


def _self_free(robot: Any, checker: Any = None, samples: int = 512) -> Iterator[np.ndarray]:
    """Configurations free of self-contact (the sphere pairs at least :data:`SELF_MARGIN` apart and, with a
    mesh ``checker``, the meshes too), nearest the middle of the joint ranges first (in range-normalised joint
    space): the middle itself, then ``samples`` seeded ones uniform in the limits. Lazy: the meshes are
    checked only for the configurations taken."""
    lo, up = np.asarray(robot.lower, dtype=np.float64), np.asarray(robot.upper, dtype=np.float64)
    mid = (lo + up) / 2
    candidates = np.vstack([mid, np.random.default_rng(0).uniform(lo, up, (int(samples), mid.size))])
    span = np.where(up > lo, up - lo, 1.0)
    candidates = candidates[np.argsort(np.linalg.norm((candidates - mid) / span, axis=1), kind="stable")]
    clear = _metrics.self_clearance(robot, candidates) >= SELF_MARGIN
    empty = None if checker is None else build_scene([])
    for q in candidates[clear]:
        if checker is None or _metrics.mesh_verdict(checker, empty, q[None, :])[2]:
            yield q


def _ready(robot: Any, checker: Any = None, samples: int = 512) -> np.ndarray:
    """The start of the layouts' problems: the Panda ready configuration for a 7-joint Panda; else the first of
    :func:`_self_free` (the middle of the joint ranges when it is free of self-contact, else the free
    configuration nearest it: an arm whose mid-range folds it into its torso); the middle when none is."""
    lo, up = np.asarray(robot.lower, dtype=np.float64), np.asarray(robot.upper, dtype=np.float64)
    if _is_panda(robot):
        return np.clip(READY, lo, up)
    return next(_self_free(robot, checker, samples), (lo + up) / 2)


#: How many of :func:`_self_free`'s configurations a layout without a start of its own may start from when
#: :func:`_ready` touches its structures.
START_ALTERNATIVES = 16


def _layout_start(robot: Any, ready: np.ndarray, free: Callable[[np.ndarray], bool],
                  alternatives: List[np.ndarray]) -> Optional[np.ndarray]:
    """The start of a layout that draws none (a table to pick from): ``ready`` when ``free`` in its scene;
    else, for a robot other than the Panda (whose ready configuration the layouts are drawn around), the first
    of ``alternatives`` (:func:`_self_free`'s, nearest the middle of the ranges first) that is: an arm whose
    ready configuration reaches forward into the structures (a humanoid's, hanging at its side) starts clear of
    them. None when none is."""
    if free(ready):
        return ready
    if _is_panda(robot):
        return None
    return next((q for q in alternatives if free(q)), None)


def arm_mount(robot: Any, q: Optional[np.ndarray] = None) -> np.ndarray:
    """(3,) world position [m] of the arm's shoulder, about which the layouts are placed: the origin of the
    first link turned by the first joint that turns the end effector (a revolute joint's child link; a
    prismatic torso before it only lifts the arm), at ``q`` (default :func:`_ready`). The shipped Panda's is
    (0, 0, 0.333); a mobile manipulator's sits on its torso, off its base."""
    poses, moved_poses = perturbed_poses(robot, _ready(robot) if q is None else q)
    ee = int(robot.link_index(robot.ee_link))
    first = None  # (links moved, first link moved) of the joint turning the end effector that moves the most
    for moved_pose in moved_poses:
        if np.max(np.abs(moved_pose[ee, :3, :3] - poses[ee, :3, :3])) < 1e-9:
            continue  # does not turn the end effector (a prismatic joint, or another branch)
        moved = np.flatnonzero(np.any(np.abs(moved_pose - poses) > 1e-12, axis=(1, 2)))
        if first is None or moved.size > first[0]:
            first = (moved.size, int(moved[0]))
    if first is None:
        return poses[int(robot.link_index(robot.base_link)), :3, 3].copy()
    return poses[first[1], :3, 3].copy()


def _reach(robot: Any, mount: np.ndarray, samples: int = 512, seed: int = 0) -> float:
    """The 95th percentile [m] of the end-effector link origin's distance from ``mount`` (3,) [m] (the arm's
    shoulder, :func:`arm_mount`) over seeded configurations uniform in the joint limits."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(np.asarray(robot.lower), np.asarray(robot.upper), (samples, int(robot.dof)))
    offsets = np.asarray(robot.ee_position(q)) - np.asarray(mount, dtype=np.float64)
    return float(np.percentile(np.linalg.norm(offsets, axis=1), 95))


def workspace_scale(robot: Any, mount: Optional[np.ndarray] = None) -> float:
    """How large ``robot``'s workspace is against the Panda's, for which the layouts are drawn: its
    :func:`_reach` from its shoulder ``mount`` (default :func:`arm_mount`) over the shipped Panda's (1 for a
    Panda). A smaller arm (a Unitree Z1, a Kinova) gets smaller shelves, tables and cages, nearer its
    shoulder."""
    import gfcs

    if _is_panda(robot):
        return 1.0
    mount = arm_mount(robot) if mount is None else mount
    panda = gfcs.Robot.panda()
    return _reach(robot, mount) / _reach(panda, arm_mount(panda))


def _placed(layout: _Layout, scale: float, mount: np.ndarray) -> _Layout:
    """``layout`` (drawn about the Panda's shoulder :data:`PANDA_MOUNT`) scaled by ``scale`` about that shoulder
    and moved onto ``mount`` (3,) [m]: primitive positions and sizes and target positions (orientations,
    approach directions and cones unchanged). The identity for a Panda."""
    shift = np.asarray(mount, dtype=np.float64) - scale * np.asarray(PANDA_MOUNT)
    if scale == 1.0 and not np.any(shift):
        return layout

    def place(x: Any) -> np.ndarray:
        return np.asarray(x, dtype=np.float64) * scale + shift

    def place_target(sample: Optional[Callable[[np.random.Generator], Target]]) -> Any:
        if sample is None:
            return None

        def draw(rng: np.random.Generator) -> Target:
            t = sample(rng)
            return dataclasses.replace(t, position=place(t.position))
        return draw

    prims = [dataclasses.replace(p, dims=tuple(d * scale for d in p.dims),
                                 position=tuple(float(x) for x in place(p.position))) for p in layout.primitives]
    return _Layout(prims, place_target(layout.goal), place_target(layout.start))


def _reachable_target(sample: Callable[[np.random.Generator], Target], rng: np.random.Generator,
                      reach: Optional[Tuple[Sequence[float], float]], tries: int = 50) -> Optional[Target]:
    """A target within ``reach`` = (centre (3,), radius) (any target when None); None after ``tries``."""
    for _ in range(tries):
        t = sample(rng)
        if reach is None or np.linalg.norm(t.position - np.asarray(reach[0])) <= reach[1]:
            return t
    return None


def tcp_along_approach(robot: Any) -> Dict[str, Tuple[float, float, float]]:
    """The hand's IK ``point`` and ``axis`` (:func:`inverse_kinematics`) for the layouts' targets: the robot's
    approach axis (its profile's, or derived from its gripper: :func:`gfcs.profile.profile_for`), and on it the
    point as deep inside the gripper's far end (:func:`gfcs.profile.gripper_reach`) as :data:`PANDA_TCP` lies
    inside the shipped Panda's. :data:`PANDA_TCP` on the z axis for a Panda (and for a hand without spheres);
    a hand whose approach is another axis (a wrist frame pointing back up the forearm) reaches targets with
    its fingers, and a longer gripper with its own tips, not the arm's flange."""
    from gfcs.profile import gripper_reach, profile_for

    depth = float(np.linalg.norm(PANDA_TCP))
    if _is_panda(robot):
        return {"point": tuple(float(x) for x in PANDA_TCP), "axis": (0.0, 0.0, 1.0)}
    axis = np.asarray(profile_for(robot).approach_axis, dtype=np.float64)
    reach = gripper_reach(robot, axis)
    if reach is not None:
        depth = max(0.0, reach - _panda_tcp_inset())
    return {"point": tuple(float(x) for x in depth * axis), "axis": tuple(float(x) for x in axis)}


@functools.lru_cache(maxsize=1)
def _panda_tcp_inset() -> float:
    """How far [m] :data:`PANDA_TCP` lies inside the shipped Panda's gripper's far end along its approach."""
    import gfcs
    from gfcs.profile import gripper_reach

    return float(gripper_reach(gfcs.Robot.panda(), (0.0, 0.0, 1.0))) - float(np.linalg.norm(PANDA_TCP))


#: The shipped Panda's :func:`arm_mount` [m]: the layouts are drawn about it.
PANDA_MOUNT = (0.0, 0.0, 0.333)
#: Workspace sphere of the Panda used to discard unreachable targets before IK: centre at the shoulder
#: (joint 2 axis, 0.333 m above the base) [m], radius [m] (the stretched arm reaches about 0.99 m).
PANDA_REACH = (PANDA_MOUNT, 0.9)


def generate(
    cls: str,
    n: int,
    seed: int = 0,
    robot: Any = None,
    margin: float = 0.01,
    min_distance: float = 0.5,
    max_scenes: int = 30,
    reach: Optional[Tuple[Sequence[float], float]] = PANDA_REACH,
    scale: Optional[float] = None,
    mesh_checker: Any = None,
) -> List[Problem]:
    """``n`` seeded problems of class ``cls`` (see the module docstring for the classes).

    Args:
        cls: a class of :data:`gfcs.problems.CLASSES` or an alias (``"table_under"``, ``"single_shelf"``).
        n: number of problems (≥ 0).
        seed: problem i depends only on (cls, seed, i).
        robot: default :meth:`gfcs.Robot.panda`. The layouts are drawn about a Panda's shoulder; for
            another robot they are scaled by ``scale`` and moved onto its shoulder (:func:`arm_mount`);
            targets are for the point of the end-effector link :data:`PANDA_TCP`'s distance along the
            robot's approach axis, approached along that axis (:func:`tcp_along_approach`; the z axis, the
            flange normal of ROS descriptions, for most).
        margin: obstacle clearance required of start and goal [m] (sphere model).
        min_distance: minimum ‖goal − start‖ [rad].
        max_scenes: scene re-draws allowed per problem before giving up.
        reach: (centre (3,), radius) [m]: targets outside this sphere are redrawn before IK (None: keep
            all); the default fits the Panda (radius scaled by ``scale``, centred on the shoulder).
        scale: factor [> 0] on every layout length (structures, their distances, targets, the default
            reach); None: :func:`workspace_scale` (1 for a Panda).
        mesh_checker: the :class:`gfcs.MeshChecker` of ``robot``'s collision meshes, which starts and goals
            clear and the problems carry; None: :func:`gfcs.problems.mesh_checker_for` (the MotionBenchMaker
            and shipped Pandas' own, none for other robots).

    Raises:
        ValueError: unknown class, negative n.
        RuntimeError: no valid problem after ``max_scenes`` scenes (names the class, seed and index).
        gfcs.CollisionError: two links that the joints outside the robot's active joints hold still touch
            (:func:`gfcs.planning.endpoints.check_held_links`): every state would be in collision.
    """
    import gfcs

    name = canonical_class(cls)
    if int(n) < 0:
        raise InvalidValueError(f"n must be ≥ 0, got {n}")
    robot = gfcs.Robot.panda() if robot is None else robot
    checker = mesh_checker_for(robot) if mesh_checker is None else mesh_checker
    if isinstance(checker, gfcs.MeshChecker):  # links the group cannot move apart put every problem in collision
        from gfcs.planning.endpoints import check_held_links

        check_held_links(checker, np.zeros(robot.dof), f"generate('{name}')")
    ready = _ready(robot, checker)
    layout_fn = _LAYOUTS[name]
    mount = PANDA_MOUNT if _is_panda(robot) else tuple(float(c) for c in arm_mount(robot, ready))
    scale = workspace_scale(robot, np.asarray(mount)) if scale is None else float(scale)
    if not (math.isfinite(scale) and scale > 0):
        raise InvalidValueError(f"scale must be a finite number > 0, got {scale}")
    if reach is PANDA_REACH and (scale != 1.0 or mount != PANDA_MOUNT):
        reach = (mount, PANDA_REACH[1] * scale)
    hand = tcp_along_approach(robot)
    problems = []
    alternatives: Optional[List[np.ndarray]] = None  # starts beside `ready`, computed when first needed
    for i in range(int(n)):
        rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(_CLASS_INDEX[name], i)))
        problem = None
        for _ in range(int(max_scenes)):
            layout = _placed(layout_fn(rng), scale, np.asarray(mount))
            scene = build_scene(layout.primitives)
            def free(q: np.ndarray, scene: Any = scene) -> bool:
                return is_collision_free(robot, scene, q, margin) and (
                    checker is None or _metrics.mesh_verdict(checker, scene, q)[2])
            if layout.start is None:
                if alternatives is None:
                    alternatives = list(itertools.islice(_self_free(robot, checker), START_ALTERNATIVES))
                q0 = _layout_start(robot, ready, free, alternatives)
            else:
                q0 = None
                for _ in range(5):
                    target = _reachable_target(layout.start, rng, reach)
                    q0 = None if target is None else inverse_kinematics(robot, target, rng, q_seed=ready,
                                                                        accept=free, **hand)
                    if q0 is not None:
                        break
            if q0 is None:
                continue
            for _ in range(8):
                target = _reachable_target(layout.goal, rng, reach)
                if target is None:
                    break
                goal = inverse_kinematics(
                    robot, target, rng, q_seed=ready,
                    accept=lambda q: free(q) and np.linalg.norm(q - q0) >= min_distance, **hand,
                )
                if goal is not None:
                    problem = Problem(
                        name=f"{name}/gen{int(seed)}_{i:04d}", robot=robot, scene=scene, q0=q0, goal=goal,
                        cls=name, mesh_checker=checker,
                        meta={"generator": name, "seed": int(seed), "index": i,
                              "primitives": [dataclasses.asdict(p) for p in layout.primitives]},
                    )
                    break
            if problem is not None:
                break
        if problem is None:
            raise GenerationError(f"generate('{name}', seed={seed}): no valid start/goal for problem {i} "
                                  f"after {max_scenes} scenes")
        problems.append(problem)
    return problems


# ------------------------------------------------------------------------------------ two-arm robot
#: Arm prefixes and base offsets [m] (along y) of :func:`two_arm_panda`.
TWO_ARM_MOUNTS = (("left_", 0.35), ("right_", -0.35))
#: The planning group of both arms in :func:`two_arm_panda`'s SRDF (subgroups ``left_arm``, ``right_arm``).
TWO_ARM_GROUP = "both_arms"


def _prefixed(element: Any, prefix: str) -> Any:
    """A copy of a URDF ``<link>`` or ``<joint>`` element with ``prefix`` on every link and joint name."""
    import copy

    el = copy.deepcopy(element)
    el.set("name", prefix + el.get("name"))
    for child in el:
        if child.tag in ("parent", "child"):
            child.set("link", prefix + child.get("link"))
        elif child.tag == "mimic":
            child.set("joint", prefix + child.get("joint"))
    return el


def two_arm_panda() -> Tuple[str, str, List[Tuple[str, List[float], float]]]:
    """A two-arm robot built from the shipped Panda, for planning groups that span two arms.

    Two copies of :func:`gfcs.panda_urdf` (links and joints prefixed ``left_`` / ``right_``, see
    :data:`TWO_ARM_MOUNTS`) on fixed joints from one ``base`` link, at y = ±0.35 m; the shipped Panda's
    collision spheres on both arms; an SRDF with the groups ``left_arm`` and ``right_arm`` (chains from
    each arm's ``panda_link0`` to its ``panda_hand``) and :data:`TWO_ARM_GROUP` (the two as subgroups), the
    shipped Panda's disabled collision pairs for each arm, and the base's adjacent pairs.

    Returns:
        (URDF text, SRDF text, spheres: [(link, centre (3,) m in the link frame, radius m)]) for
        :meth:`gfcs.Robot.from_urdf` or :func:`gfcs.srdf_groups.robot_for_group`.
    """
    import xml.etree.ElementTree as ET

    import gfcs

    panda = ET.fromstring(gfcs.panda_urdf())
    urdf = ET.Element("robot", name="two_arm_panda")
    ET.SubElement(urdf, "link", name="base")
    srdf = ET.Element("robot", name="two_arm_panda")
    shipped_pairs = ET.fromstring(gfcs.panda_srdf()).findall("disable_collisions")
    for prefix, y in TWO_ARM_MOUNTS:
        mount = ET.SubElement(urdf, "joint", name=f"{prefix}mount_joint", type="fixed")
        ET.SubElement(mount, "parent", link="base")
        ET.SubElement(mount, "child", link=f"{prefix}panda_link0")
        ET.SubElement(mount, "origin", xyz=f"0 {y} 0", rpy="0 0 0")
        for element in panda:
            if element.tag in ("link", "joint"):
                urdf.append(_prefixed(element, prefix))
        group = ET.SubElement(srdf, "group", name=f"{prefix}arm")
        ET.SubElement(group, "chain", base_link=f"{prefix}panda_link0", tip_link=f"{prefix}panda_hand")
    both = ET.SubElement(srdf, "group", name=TWO_ARM_GROUP)
    for prefix, _ in TWO_ARM_MOUNTS:
        ET.SubElement(both, "group", name=f"{prefix}arm")
    for prefix, _ in TWO_ARM_MOUNTS:
        ET.SubElement(srdf, "disable_collisions", link1="base", link2=f"{prefix}panda_link0", reason="Adjacent")
        for pair in shipped_pairs:
            ET.SubElement(srdf, "disable_collisions", link1=prefix + pair.get("link1"),
                          link2=prefix + pair.get("link2"), reason=pair.get("reason", "Never"))
    shipped = gfcs.Robot.panda()
    spheres = [(prefix + link, [float(v) for v in centre], float(radius))
               for prefix, _ in TWO_ARM_MOUNTS
               for link, centre, radius in zip(shipped.sphere_links, shipped.sphere_centers_local,
                                               shipped.sphere_radii)]
    return ET.tostring(urdf, encoding="unicode"), ET.tostring(srdf, encoding="unicode"), spheres


def two_arm_robot() -> Tuple[Any, List[str]]:
    """The :func:`two_arm_panda` robot planning for :data:`TWO_ARM_GROUP` (14 joints; end effector
    ``left_panda_hand``) with its fingers held as the shipped Panda holds them (0.04 m), and the group's
    tips (both hands), from :func:`gfcs.srdf_groups.robot_for_group`."""
    import gfcs
    from gfcs.srdf_groups import robot_for_group

    urdf, srdf, spheres = two_arm_panda()
    robot, tips = robot_for_group(urdf, srdf, TWO_ARM_GROUP, spheres=spheres)
    fingers = gfcs.Robot.panda().locked_positions
    held = {prefix + joint: value for prefix, _ in TWO_ARM_MOUNTS for joint, value in fingers.items()}
    return robot.with_locked_positions(held), tips


#: The obstacle of :func:`two_arm_problems`: a wall between the two arms, in front of the base.
TWO_ARM_DIVIDER = Primitive("divider", "box", (0.3, 0.1, 0.6), (0.55, 0.0, 0.3), (0.0, 0.0, 0.0, 1.0))


def two_arm_problems(n: int, seed: int = 0, spread: float = 0.6, margin: float = 0.02,
                     min_distance: float = 0.8, tries: int = 500) -> List[Problem]:
    """``n`` seeded joint-goal problems of the :func:`two_arm_robot` (both arms, 14 joints) around
    :data:`TWO_ARM_DIVIDER`: each arm starts and ends within ``spread`` rad of the Panda ready pose (per
    joint, uniform, inside the joint limits), and every start and goal keeps the spheres ``margin`` m from
    the divider and :data:`SELF_MARGIN` apart, across the arms too (:func:`is_collision_free`, the robot's
    ``self_clearance``). Problem ``i`` depends only on (seed, i). ``meta["ee_links"]`` holds both hands,
    whose paths the metrics report; ``meta["group"]`` the group.

    Raises:
        ValueError: n < 0. RuntimeError: no valid start/goal pair within ``tries`` draws (names seed, index).
    """
    if int(n) < 0:
        raise InvalidValueError(f"n must be ≥ 0, got {n}")
    robot, tips = two_arm_robot()
    scene = build_scene([TWO_ARM_DIVIDER])
    lo = np.asarray(robot.lower, dtype=np.float64) + 0.05
    up = np.asarray(robot.upper, dtype=np.float64) - 0.05
    centre = np.clip(np.concatenate([READY, READY]), lo, up)
    out = []
    for i in range(int(n)):
        rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(len(CLASSES), i)))

        def draw() -> Optional[np.ndarray]:
            for _ in range(int(tries)):
                q = np.clip(centre + rng.uniform(-spread, spread, size=centre.shape), lo, up)
                if is_collision_free(robot, scene, q, margin):
                    return q
            return None

        q0 = draw()
        goal = None
        for _ in range(int(tries) if q0 is not None else 0):
            goal = draw()
            if goal is not None and np.linalg.norm(goal - q0) >= min_distance:
                break
            goal = None
        if q0 is None or goal is None:
            raise GenerationError(f"two_arm_problems(seed={seed}): no valid start/goal for problem {i} in "
                                  f"{tries} draws")
        out.append(Problem(
            name=f"two_arm/gen{int(seed)}_{i:04d}", robot=robot, scene=scene, q0=q0, goal=goal, cls="two_arm",
            meta={"generator": "two_arm", "seed": int(seed), "index": i, "group": TWO_ARM_GROUP,
                  "ee_links": list(tips), "primitives": [dataclasses.asdict(TWO_ARM_DIVIDER)]}))
    return out
