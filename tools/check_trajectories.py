#!/usr/bin/env python3
"""Check returned trajectories the way an outside validator would, without gfcs.

Everything here is independent of the package: the robot is read with yourdfpy and its collision meshes
with trimesh, distances come from FCL (python-fcl), the scene and the request are parsed from the MoveIt
YAML files with PyYAML, and the kinematics are recomputed from the URDF joints (checked against
yourdfpy's own forward kinematics on the first state of every trajectory). No code of ``gfcs`` is imported.

For every result file (the JSON of ``gfcs solve --json`` or of ``gfcs bench --results-dir``) and every
state of its trajectory:

* start: the first state against the request's start state [rad];
* goal (``goal_kind``): for a joint goal (``joint``), ``goal_error`` = ‖q_T − q_g‖ [rad], reached when
  ≤ ``--goal-tol``; for a pose goal (``pose``: ``goal_constraints[0]`` holds one ``position_constraints``
  entry, at most one ``orientation_constraints`` entry on the same link, no joint constraints), the final
  state's link pose against MoveIt's constraints, in the world frame of the FK (``header.frame_id`` "",
  absent, ``world``, ``/world`` or the URDF root; another frame, more than one constraint of a kind, mesh
  regions, or joint and pose constraints together are an error for that result):

  - ``goal_position_error`` [m]: how far the point p = T_link(q_T) · ``target_point_offset`` lies outside
    the nearest primitive of the ``constraint_region`` (box: full sizes; sphere: radius; cylinder: height,
    radius about the local z), 0 inside one; the constraint holds when ≤ 1e-6 m;
  - ``goal_orientation_error`` [rad]: max over x, y, z of |component| − ``absolute_<axis>_axis_tolerance``,
    clipped below at 0, where the components (``goal_orientation_components``) are those of
    D = R*ᵀ R (R*: the target rotation, R: the link's) as XYZ Euler angles, D = Rx(a) Ry(b) Rz(c), of the
    two representations the one of smaller norm (``parameterization`` 0 or absent), or as its rotation
    vector, angle in [0, π] (``parameterization`` 1); the constraint holds when ≤ 1e-6 rad; 0 (and
    components null) without an orientation constraint;

  ``goal_reached`` is the verdict of either kind; ``goal_error`` is null for pose goals, the pose fields
  null for joint goals;
* joint limits: the smallest distance to the URDF position limits [rad] (< 0: outside), and the largest
  ratio of the finite-difference joint speed to the URDF velocity limit;
* obstacles: the smallest FCL distance between a link's collision geometry and an obstacle [m]
  (≤ 0: contact);
* self-collision: the smallest FCL distance between two links' collision geometry [m], over the link
  pairs not disabled by the SRDF nor allowed by the scene's collision matrix, nor joined through fixed
  joints only (one rigid body: its pieces touch where a part is split into several links; ``--rigid-pairs``
  checks those too);
* end-effector and joint-space path lengths [m, rad], recomputed.

A state in contact is a collision (FCL reports 0 or less for touching or overlapping shapes). The verdict
``valid`` is: start matches (a start at most 1 mrad outside a bound matches the bound, as MoveIt moves it
there), goal reached (continuous joints modulo 2π), position limits kept (continuous joints have none), every
finite-difference speed within the URDF velocity limit, no contact with obstacles nor between links.

Output: one JSON line per result (``--json``, or stdout) and a summary on stderr; exit status 1 when a
result that claims ``success`` is not valid here, else 2 when a result could not be checked (its line has
an ``error``), else 0.

Example (every result of a benchmark run)::

    gfcs bench --problems ../shared/mbm --robot mbm --method gf gfcs --results-dir runs/
    python tools/check_trajectories.py --problems ../shared/mbm \\
        --urdf ../shared/robots/mbm_panda/panda.urdf --srdf ../shared/robots/mbm_panda/panda.srdf runs/
"""

from __future__ import annotations

import argparse
import functools
import itertools
import json
import math
import multiprocessing
import os
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple

import fcl
import numpy as np
import trimesh
import yaml
import yourdfpy


# ------------------------------------------------------------------------------------------ geometry
def quat_xyzw_to_matrix(q: Sequence[float]) -> np.ndarray:
    """Rotation matrix of a quaternion given as (x, y, z, w) (the MoveIt YAML order), normalised."""
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def components(value: Any, keys: str, where: str, default: Optional[Sequence[float]] = None) -> np.ndarray:
    """A MoveIt vector or quaternion given as a mapping (keys ``keys``, e.g. "xyzw"; a missing key takes
    its ``default``) or as a list, as floats; ``value`` None gives ``default`` (an error without one)."""
    if value is None and default is not None:
        return np.asarray(default, dtype=np.float64)
    if isinstance(value, dict):
        missing = [k for k in keys if k not in value]
        if missing and default is None:
            raise ValueError(f"{where}: no {', '.join(missing)}")
        value = [value[k] if k in value else d for k, d in zip(keys, default or [None] * len(keys))]
    if not isinstance(value, (list, tuple)) or len(value) != len(keys):
        raise ValueError(f"{where}: expected a mapping {{{', '.join(keys)}}} or a list of {len(keys)}, got {value!r}")
    out = np.asarray([float(v) for v in value], dtype=np.float64)
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{where}: not finite: {value!r}")
    return out


def quaternion_matrix(value: Any, where: str, default: Optional[Sequence[float]] = None) -> np.ndarray:
    """Rotation matrix of a MoveIt quaternion (x, y, z, w), as a mapping or a list; zero: an error."""
    q = components(value, "xyzw", where, default)
    if np.linalg.norm(q) < 1e-9:
        raise ValueError(f"{where}: zero quaternion")
    return quat_xyzw_to_matrix(q)


def pose_matrix(pose: Optional[Dict[str, Any]], where: str = "pose") -> np.ndarray:
    """4x4 transform of a MoveIt pose ``{position: [x, y, z], orientation: [x, y, z, w]}`` (lists or
    mappings; identity: None)."""
    T = np.eye(4)
    if pose:
        T[:3, :3] = quaternion_matrix(pose.get("orientation"), f"{where}.orientation", (0, 0, 0, 1))
        T[:3, 3] = components(pose.get("position"), "xyz", f"{where}.position", (0, 0, 0))
    return T


def fcl_object(geometry: Any, T: np.ndarray) -> fcl.CollisionObject:
    return fcl.CollisionObject(geometry, fcl.Transform(T[:3, :3], T[:3, 3]))


def primitive_geometry(kind: str, dims: Sequence[float], where: str) -> Any:
    """FCL geometry of a MoveIt SolidPrimitive (box: x y z; cylinder: height radius; sphere: radius)."""
    d = [float(v) for v in dims]
    if kind == "box" and len(d) == 3:
        return box_geometry(d)
    if kind == "cylinder" and len(d) == 2:
        return fcl.Cylinder(d[1], d[0])  # FCL: (radius, length along z)
    if kind == "sphere" and len(d) == 1:
        return fcl.Sphere(d[0])
    raise ValueError(f"{where}: unsupported primitive {kind!r} with dimensions {d}")


def box_geometry(size: Sequence[float]) -> fcl.BVHModel:
    """A box as a 12-triangle mesh: FCL 0.7's box primitive gives distances to boxes and to meshes up to
    60 mm too large (GJK on its box; 0.409 instead of 0.35 m between two cubes), its meshes exact ones."""
    return mesh_geometry(trimesh.creation.box(extents=[float(v) for v in size]))


def mesh_geometry(mesh: trimesh.Trimesh) -> fcl.BVHModel:
    model = fcl.BVHModel()
    model.beginModel(len(mesh.vertices), len(mesh.faces))
    model.addSubModel(np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int32))
    model.endModel()
    return model


# --------------------------------------------------------------------------------------------- scene
@dataclass
class Obstacle:
    """One primitive of a scene object: MoveIt kind and dimensions, world pose T (4x4), FCL object."""
    name: str
    kind: str
    dims: List[float]
    T: np.ndarray
    object: fcl.CollisionObject


@dataclass
class Part:
    """One URDF ``<collision>`` element: its link, origin in the link frame (4x4), FCL geometry, and a
    sphere (centre in the element's frame, radius) containing it, whose distances bound its own."""
    link: str
    origin: np.ndarray
    geometry: Any
    center: np.ndarray
    radius: float


def load_scene(path: Path) -> List[Obstacle]:
    """The obstacles of a MoveIt PlanningScene YAML, posed in the world frame."""
    doc = yaml.safe_load(path.read_text())
    objects = []
    for k, obj in enumerate(((doc or {}).get("world") or {}).get("collision_objects") or []):
        name = str(obj.get("id", k))
        T_obj = pose_matrix(obj.get("pose"))
        prims, poses = obj.get("primitives") or [], obj.get("primitive_poses") or []
        if len(prims) != len(poses):
            raise ValueError(f"{path}: object {name!r} has {len(prims)} primitives and {len(poses)} poses")
        if obj.get("meshes"):
            raise ValueError(f"{path}: object {name!r} has meshes (only primitives are read)")
        for prim, pose in zip(prims, poses):
            geom = primitive_geometry(prim["type"], prim["dimensions"], f"{path}: object {name!r}")
            T = T_obj @ pose_matrix(pose)
            objects.append(Obstacle(name, prim["type"], [float(v) for v in prim["dimensions"]], T, fcl_object(geom, T)))
    return objects


@dataclass
class Region:
    """One primitive of a position constraint's region: MoveIt kind, dimensions, world pose T (4x4)."""
    kind: str
    dims: List[float]
    T: np.ndarray


@dataclass
class PoseGoal:
    """A MoveIt pose goal on ``link``: the point ``offset`` (link frame) must lie in one of ``regions``;
    with a ``rotation`` (target R*, 3x3), D = R*ᵀ R must be within ``tolerance`` per component, as XYZ
    Euler angles or (``rotation_vector``) as a rotation vector."""
    link: str
    offset: np.ndarray
    regions: List[Region]
    rotation: Optional[np.ndarray] = None
    tolerance: Optional[np.ndarray] = None
    rotation_vector: bool = False


PRIMITIVE_KINDS = {1: "box", 2: "sphere", 3: "cylinder"}  # shape_msgs/SolidPrimitive
PRIMITIVE_DIMS = {"box": 3, "sphere": 1, "cylinder": 2}
GOAL_SLACK = 1e-6  # m for positions, rad for orientations
START_BOUNDS_TOLERANCE = 1e-3  # rad or m: a request's start this far outside a bound counts as on it


def load_request(path: Path, root: Optional[str] = None) -> Tuple[Dict[str, float], Any]:
    """(start joint positions by joint name, goal) from a MoveIt MotionPlanRequest YAML: the goal of
    ``goal_constraints[0]`` is a joint goal (joint name -> position) or a :class:`PoseGoal` whose frames
    must be the world (or ``root``, the URDF root link)."""
    doc = yaml.safe_load(path.read_text())
    js = doc["start_state"]["joint_state"]
    start = dict(zip(js["name"], map(float, js["position"])))
    where = f"{path}: goal_constraints[0]"
    c = (doc.get("goal_constraints") or [None])[0]
    if not isinstance(c, dict):
        raise ValueError(f"{where}: missing")
    joints = c.get("joint_constraints") or []
    positions, orientations = c.get("position_constraints") or [], c.get("orientation_constraints") or []
    if joints and (positions or orientations):
        raise ValueError(f"{where}: joint constraints together with position or orientation constraints "
                         "are not supported")
    if joints:
        return start, {j["joint_name"]: float(j["position"]) for j in joints}
    if not positions:
        raise ValueError(f"{where}: no joint constraints and no position constraint"
                         + (" (an orientation constraint needs one)" if orientations else ""))
    return start, parse_pose_goal(positions, orientations, where, root)


def parse_pose_goal(positions: List[Any], orientations: List[Any], where: str, root: Optional[str]) -> PoseGoal:
    """The :class:`PoseGoal` of one position constraint and at most one orientation constraint."""
    for items, what in ((positions, "position"), (orientations, "orientation")):
        if len(items) > 1:
            raise ValueError(f"{where}.{what}_constraints: one {what} constraint is supported, got {len(items)}")
    pc, w = positions[0], f"{where}.position_constraints[0]"
    link = constraint_link(pc, w)
    check_frame(pc, w, root)
    offset = components(pc.get("target_point_offset"), "xyz", f"{w}.target_point_offset", (0, 0, 0))
    goal = PoseGoal(link, offset, parse_region(pc.get("constraint_region"), f"{w}.constraint_region"))
    if orientations:
        oc, w = orientations[0], f"{where}.orientation_constraints[0]"
        if constraint_link(oc, w) != link:
            raise ValueError(f"{w}.link_name: {oc['link_name']!r} is not the position constraint's {link!r}")
        check_frame(oc, w, root)
        goal.rotation = quaternion_matrix(oc.get("orientation"), f"{w}.orientation")
        goal.tolerance = np.array([tolerance(oc, f"absolute_{a}_axis_tolerance", w) for a in "xyz"])
        kind = oc.get("parameterization", 0)
        if kind not in (0, 1) or isinstance(kind, bool):
            raise ValueError(f"{w}.parameterization: expected 0 (XYZ Euler angles) or 1 (rotation vector), "
                             f"got {kind!r}")
        goal.rotation_vector = kind == 1
    return goal


def constraint_link(c: Any, where: str) -> str:
    if not isinstance(c, dict) or not isinstance(c.get("link_name"), str) or not c["link_name"]:
        raise ValueError(f"{where}.link_name: missing")
    return c["link_name"]


def check_frame(c: Dict[str, Any], where: str, root: Optional[str]) -> None:
    """A constraint's ``header.frame_id`` must name the world frame of the FK."""
    frame = (c.get("header") or {}).get("frame_id") or ""
    if frame not in ("", "world", "/world") and frame != root:
        raise ValueError(f"{where}.header.frame_id: frame {frame!r} is not supported (only the world frame: "
                         f"'', 'world', '/world' or the URDF root {root!r})")


def tolerance(c: Dict[str, Any], key: str, where: str) -> float:
    if key not in c:
        raise ValueError(f"{where}.{key}: missing")
    value = float(c[key])
    if not value >= 0:
        raise ValueError(f"{where}.{key}: must be ≥ 0, got {value}")
    return value


def parse_region(region: Any, where: str) -> List[Region]:
    """The primitives of a ``constraint_region`` in the world frame (meshes are not supported)."""
    region = region or {}
    if region.get("meshes"):
        raise ValueError(f"{where}.meshes: mesh regions are not supported (only box, sphere, cylinder)")
    prims, poses = region.get("primitives") or [], region.get("primitive_poses") or []
    if not prims:
        raise ValueError(f"{where}.primitives: missing or empty")
    if len(prims) != len(poses):
        raise ValueError(f"{where}: {len(prims)} primitives and {len(poses)} primitive_poses")
    out = []
    for k, (prim, pose) in enumerate(zip(prims, poses)):
        w = f"{where}.primitives[{k}]"
        kind = primitive_kind(prim.get("type"), f"{w}.type")
        dims = [float(v) for v in prim.get("dimensions") or []]
        if len(dims) != PRIMITIVE_DIMS[kind] or min(dims) < 0:
            raise ValueError(f"{w}.dimensions: {kind} needs {PRIMITIVE_DIMS[kind]} sizes ≥ 0, got {dims}")
        out.append(Region(kind, dims, pose_matrix(pose, f"{where}.primitive_poses[{k}]")))
    return out


def primitive_kind(value: Any, where: str) -> str:
    """"box", "sphere" or "cylinder" of a SolidPrimitive type (a name, any case, or 1, 2, 3)."""
    if isinstance(value, str) and value.lower() in PRIMITIVE_DIMS:
        return value.lower()
    if isinstance(value, int) and not isinstance(value, bool) and value in PRIMITIVE_KINDS:
        return PRIMITIVE_KINDS[value]
    raise ValueError(f"{where}: unsupported primitive type {value!r} (box/1, sphere/2, cylinder/3)")


def allowed_pairs(scene_path: Path) -> set:
    """Link pairs the scene's allowed collision matrix allows (MoveIt ACM, ``true`` = allowed)."""
    doc = yaml.safe_load(scene_path.read_text()) or {}
    acm = doc.get("allowed_collision_matrix") or {}
    names, values = acm.get("entry_names") or [], acm.get("entry_values") or []
    return {frozenset((names[i], names[j])) for i, row in enumerate(values) for j, v in enumerate(row)
            if v and i != j}


# --------------------------------------------------------------------------------------------- robot
def rigid_link_pairs(joints: Iterable[Any]) -> set:
    """Pairs of distinct links joined through fixed joints only (one rigid body), as frozensets: such links
    never move relative to each other, and a part modelled as several links (a pedestal or a finger split
    into two meshes) touches itself wherever the pieces meet."""
    parent = {}  # union-find over the fixed joints

    def root(link: str) -> str:
        while parent.get(link, link) != link:
            link = parent[link]
        return link

    fixed = [j for j in joints if j.type == "fixed"]
    for j in fixed:
        parent[root(j.child)] = root(j.parent)
    bodies: Dict[str, List[str]] = {}
    for link in {j.child for j in fixed} | {j.parent for j in fixed}:
        bodies.setdefault(root(link), []).append(link)
    return {frozenset(pair) for links in bodies.values() for pair in itertools.combinations(sorted(links), 2)}


def ros_package(name: str, root: Path, depth: int = 4) -> Optional[Path]:
    """The folder of the package.xml whose <name> is ``name``, below ``root`` or a ROS_PACKAGE_PATH root (at most
    ``depth`` folders down, hidden ones skipped), as ROS finds a package whatever its folder is called."""
    roots = [root] + [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    for top in roots:
        found = _ros_packages(top, depth).get(name)
        if found is not None:
            return found
    return None


@functools.lru_cache(maxsize=None)
def _ros_packages(top: Path, depth: int) -> Dict[str, Path]:
    """{package name: folder} of the package.xml files below ``top`` (walked once per root: every mesh of a
    robot asks)."""
    found: Dict[str, Path] = {}
    for here, dirs, files in os.walk(top, followlinks=True):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        if "package.xml" in files:
            name = ET.parse(os.path.join(here, "package.xml")).getroot().findtext("name")
            if name is not None:
                found.setdefault(name.strip(), Path(here))
        if len(Path(here).relative_to(top).parts) >= depth:
            dirs[:] = []
    return found


class RobotModel:
    """The URDF read by yourdfpy: joint chain, limits and collision geometry as FCL objects per link."""

    def __init__(self, urdf: Path, srdf: Optional[Path], ee_link: str, mesh_dir: Optional[Path] = None,
                 rigid_pairs: bool = False):
        self.path = urdf
        root = mesh_dir or urdf.parent
        self.urdf = yourdfpy.URDF.load(str(urdf), load_meshes=False, build_scene_graph=True,
                                       build_collision_scene_graph=False, load_collision_meshes=False)
        robot = self.urdf.robot
        self.base = self.urdf.base_link
        self.joints = {j.child: j for j in robot.joints}  # child link -> joint
        self.actuated = [j.name for j in robot.joints if j.type in ("revolute", "continuous", "prismatic")
                         and j.mimic is None]
        self.ee_link = ee_link
        self.links = {l.name for l in robot.links}
        if ee_link not in self.links:
            raise ValueError(f"{urdf}: no link {ee_link!r} (--ee-link); its links: {', '.join(sorted(self.links))}")
        self.parts = [self._part(link.name, c, root) for link in robot.links for c in link.collisions]
        disabled = set()
        if srdf is not None:
            for e in ET.parse(srdf).getroot().iter("disable_collisions"):
                disabled.add(frozenset((e.get("link1"), e.get("link2"))))
        if not rigid_pairs:
            disabled |= rigid_link_pairs(robot.joints)
        self.disabled = disabled

    def parts_links(self) -> List[str]:
        return sorted({p.link for p in self.parts})

    def _part(self, link: str, c: Any, root: Path) -> Part:
        origin = c.origin if c.origin is not None else np.eye(4)
        g = c.geometry
        if g.mesh is not None:
            name = g.mesh.filename
            for prefix in ("package://", "file://"):
                if name.startswith(prefix):
                    name = name[len(prefix):]
            path = Path(name) if Path(name).is_absolute() else root / name
            if not path.exists():  # package://<package>/meshes/...: drop the package name
                path = root / Path(name).relative_to(Path(name).parts[0])
            if not path.exists() and g.mesh.filename.startswith("package://"):  # the package by its package.xml
                package = ros_package(Path(name).parts[0], root)
                if package is not None:
                    path = package / Path(name).relative_to(Path(name).parts[0])
            mesh = trimesh.load(str(path), force="mesh")
            if g.mesh.scale is not None:
                mesh.apply_scale(np.broadcast_to(np.asarray(g.mesh.scale, dtype=np.float64), (3,)))
            v = np.asarray(mesh.vertices, dtype=np.float64)
            center = (v.min(axis=0) + v.max(axis=0)) / 2
            return Part(link, origin, mesh_geometry(mesh), center, float(np.linalg.norm(v - center, axis=1).max()))
        if g.box is not None:
            size = np.asarray(g.box.size, dtype=np.float64)
            return Part(link, origin, box_geometry(size), np.zeros(3), float(np.linalg.norm(size) / 2))
        if g.cylinder is not None:
            r, h = float(g.cylinder.radius), float(g.cylinder.length)
            return Part(link, origin, fcl.Cylinder(r, h), np.zeros(3), math.hypot(r, h / 2))
        if g.sphere is not None:
            return Part(link, origin, fcl.Sphere(float(g.sphere.radius)), np.zeros(3), float(g.sphere.radius))
        raise ValueError(f"{self.path}: link {link!r} has an unsupported collision geometry")

    def chain(self, link: str) -> List[Any]:
        """Joints from the base to ``link``, base first."""
        out = []
        while link in self.joints:
            j = self.joints[link]
            out.append(j)
            link = j.parent
        return out[::-1]

    def fk(self, cfg: Dict[str, np.ndarray], links: Iterable[str], n: int) -> Dict[str, np.ndarray]:
        """World poses (n, 4, 4) of ``links`` for n configurations (``cfg``: joint name -> (n,) values;
        joints not given stay at 0), from the URDF joints: T = T_parent · origin · motion(q)."""
        cache: Dict[str, np.ndarray] = {self.base: np.broadcast_to(np.eye(4), (n, 4, 4))}

        def pose(link: str) -> np.ndarray:
            if link in cache:
                return cache[link]
            j = self.joints[link]
            T = pose(j.parent) @ (j.origin if j.origin is not None else np.eye(4))
            if j.type in ("revolute", "continuous", "prismatic"):
                q = np.asarray(cfg.get(j.mimic.joint if j.mimic else j.name, np.zeros(n)), dtype=np.float64)
                if j.mimic is not None:
                    q = q * j.mimic.multiplier + j.mimic.offset
                M = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
                axis = np.asarray(j.axis, dtype=np.float64) / np.linalg.norm(j.axis)
                if j.type == "prismatic":
                    M[:, :3, 3] = q[:, None] * axis
                else:  # Rodrigues
                    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
                    s, c = np.sin(q)[:, None, None], np.cos(q)[:, None, None]
                    M[:, :3, :3] = np.eye(3) + s * K + (1 - c) * (K @ K)
                T = T @ M
            cache[link] = T
            return T

        return {link: pose(link) for link in links}

    def limits(self, names: Sequence[str]) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lower, upper, velocity) URDF limits of the joints ``names``."""
        by_name = {j.name: j for j in self.urdf.robot.joints}
        lo, up, vel = [], [], []
        for n in names:
            lim = by_name[n].limit
            unbounded = by_name[n].type == "continuous"  # no position limits, whatever <limit> says
            lo.append(-math.inf if unbounded or lim is None or lim.lower is None else float(lim.lower))
            up.append(math.inf if unbounded or lim is None or lim.upper is None else float(lim.upper))
            vel.append(math.inf if lim is None or lim.velocity is None else float(lim.velocity))
        return np.array(lo), np.array(up), np.array(vel)


# --------------------------------------------------------------------------------------------- check
def fcl_distance(a: fcl.CollisionObject, b: fcl.CollisionObject) -> float:
    """FCL distance between two objects [m], 0 when they touch or overlap (FCL reports −1 then)."""
    return max(float(fcl.distance(a, b, fcl.DistanceRequest(), fcl.DistanceResult())), 0.0)


def obstacle_sdf(kind: str, dims: Sequence[float], T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Closed-form signed distance [m] from points p (..., 3) to a box, cylinder or sphere posed by T."""
    x = (p - T[:3, 3]) @ T[:3, :3]  # obstacle frame
    d = [float(v) for v in dims]
    if kind == "box":
        e = np.abs(x) - np.asarray(d) / 2
        return np.linalg.norm(np.maximum(e, 0), axis=-1) + np.minimum(e.max(axis=-1), 0)
    if kind == "cylinder":
        e = np.stack([np.linalg.norm(x[..., :2], axis=-1) - d[1], np.abs(x[..., 2]) - d[0] / 2], axis=-1)
        return np.linalg.norm(np.maximum(e, 0), axis=-1) + np.minimum(e.max(axis=-1), 0)
    return np.linalg.norm(x, axis=-1) - d[0]


def xyz_euler(D: np.ndarray) -> np.ndarray:
    """Angles (a, b, c) with D = Rx(a) · Ry(b) · Rz(c) (Eigen's ``eulerAngles(0, 1, 2)`` convention), of
    the two representations the one of smaller norm, each angle in [−π, π)."""
    cos_b = math.hypot(D[1, 2], D[2, 2])
    b = math.atan2(D[0, 2], cos_b)
    if cos_b > 1e-12:
        a, c = math.atan2(-D[1, 2], D[2, 2]), math.atan2(-D[0, 1], D[0, 0])
    else:  # gimbal lock: only a ± c is defined, take a = 0
        a, c = 0.0, math.atan2(D[1, 0], D[1, 1])
    first = np.array([a, b, c])
    second = (first + np.array([math.pi, math.pi - 2 * b, math.pi]) + math.pi) % (2 * math.pi) - math.pi
    return first if np.linalg.norm(first) <= np.linalg.norm(second) else second


def rotation_vector(D: np.ndarray) -> np.ndarray:
    """Axis · angle of the rotation D, angle in [0, π] (through its quaternion, Shepperd's method)."""
    trace = float(np.trace(D))
    k = int(np.argmax([D[0, 0], D[1, 1], D[2, 2], trace]))
    q = np.empty(4)  # x, y, z, w
    if k == 3:
        q[3] = math.sqrt(1 + trace) / 2
        q[:3] = np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]]) / (4 * q[3])
    else:  # the largest of x, y, z is q[k]
        i, j, l = k, (k + 1) % 3, (k + 2) % 3
        s = 2 * math.sqrt(max(1 + D[i, i] - D[j, j] - D[l, l], 0.0))  # 4 q[i]
        q[i], q[j], q[l], q[3] = s / 4, (D[j, i] + D[i, j]) / s, (D[l, i] + D[i, l]) / s, (D[l, j] - D[j, l]) / s
    q = q / np.linalg.norm(q) * (1 if q[3] >= 0 else -1)
    v, w = q[:3], q[3]
    sine = float(np.linalg.norm(v))  # sin(angle / 2)
    if sine < 1e-12:
        return 2 * v
    return v / sine * 2 * math.atan2(sine, w)


def region_distance(regions: Sequence[Region], p: np.ndarray) -> float:
    """How far the point p (3,) lies outside the nearest region primitive [m]; 0 inside one."""
    return max(min(float(obstacle_sdf(r.kind, r.dims, r.T, p)) for r in regions), 0.0)


def pose_goal_errors(goal: PoseGoal, T: np.ndarray) -> Dict[str, Any]:
    """The goal fields of a pose goal for the link's world pose T (4x4): errors and verdict."""
    position = region_distance(goal.regions, T[:3, :3] @ goal.offset + T[:3, 3])
    if goal.rotation is None:
        angles, orientation = None, 0.0
    else:
        D = goal.rotation.T @ T[:3, :3]
        angles = rotation_vector(D) if goal.rotation_vector else xyz_euler(D)
        orientation = max(float((np.abs(angles) - goal.tolerance).max()), 0.0)
    return {
        "goal_kind": "pose",
        "goal_error": None,
        "goal_link": goal.link,
        "goal_position_error": position,
        "goal_orientation_error": orientation,
        "goal_orientation_components": None if angles is None else [float(v) for v in angles],
        "goal_reached": bool(position <= GOAL_SLACK and orientation <= GOAL_SLACK),
    }


def smallest(bounds: np.ndarray, exact: Any) -> Tuple[float, Tuple[int, ...]]:
    """The minimum of ``exact(*index)`` over every index of ``bounds``, an array of lower bounds of it:
    indices are visited in increasing bound and the search stops at the first bound ≥ the smallest exact
    value found (branch and bound; the result is the exact minimum). Returns (min, its index)."""
    best, where = math.inf, ()
    flat = bounds.ravel()
    for i in np.argsort(flat, kind="stable"):
        if flat[i] >= best:
            break
        idx = np.unravel_index(i, bounds.shape)
        d = exact(*idx)
        if d < best:
            best, where = d, tuple(int(v) for v in idx)
    return best, where


def is_valid(row: Dict[str, Any], speed: bool = True) -> bool:
    """The verdict on one checked trajectory (a row of :func:`check_result`): it starts at the start, reaches
    the goal, keeps the joint limits, the meshes clear the obstacles and each other, and (``speed``) no joint
    exceeds its URDF velocity limit. ``speed=False`` judges the path alone (a planner that does not time its
    motions to the robot's limits)."""
    fast = speed and row["speed_ratio"] > 1.0 + 1e-6
    return bool(row["start_error"] <= 1e-6 and row["goal_reached"] and row["limit_margin"] >= 0 and not fast
                and row["clearance"] > 0 and row["self_clearance"] > 0)


def check_result(result: Dict[str, Any], model: RobotModel, scene_path: Path, request_path: Path,
                 goal_tol: float) -> Dict[str, Any]:
    """The independent verdict on one result (keys in the module docstring)."""
    traj = result["trajectory"]
    q = np.asarray(traj["q"], dtype=np.float64)
    t = np.asarray(traj["t"], dtype=np.float64)
    names = list(traj.get("joint_names") or result.get("joint_names") or model.actuated)
    if q.ndim != 2 or q.shape[1] != len(names) or q.shape[0] != t.shape[0] or q.shape[0] == 0:
        raise ValueError(f"trajectory: q {q.shape} and t {t.shape} do not match {len(names)} joints")
    start, goal = load_request(request_path, model.base)
    q_start = np.array([start[n] for n in names])
    pose_goal = isinstance(goal, PoseGoal)
    if pose_goal and goal.link not in model.links:
        raise ValueError(f"{request_path}: goal link {goal.link!r} is not a link of {model.path}")
    lo, up, vel = model.limits(names)
    n = q.shape[0]
    # joints the trajectory does not move stay where the request's start state holds them, as MoveIt keeps
    # them (0 where it names none)
    held = {name: start.get(name, 0.0) for name in model.actuated if name not in names}
    cfg = {**{name: np.full(n, v) for name, v in held.items()}, **{name: q[:, k] for k, name in enumerate(names)}}
    links = set(model.parts_links()) | {model.ee_link} | ({goal.link} if pose_goal else set())
    poses = model.fk(cfg, links, n)

    # the recomputed kinematics against yourdfpy's own: first state, and a pose goal's link at the last
    fk_error = fk_difference(model, names, q[0], {l: poses[l][0] for l in links}, held)
    if pose_goal:
        fk_error = max(fk_error, fk_difference(model, names, q[-1], {goal.link: poses[goal.link][-1]}, held))
        goal_fields = pose_goal_errors(goal, poses[goal.link][-1])
    else:
        diff = q[-1] - np.array([goal[n] for n in names])
        continuous = ~np.isfinite(lo)  # a continuous joint's goal is an orientation: compare modulo 2π
        diff[continuous] = (diff[continuous] + math.pi) % (2 * math.pi) - math.pi
        error = float(np.linalg.norm(diff))
        goal_fields = {"goal_kind": "joint", "goal_error": error, "goal_link": None, "goal_position_error": None,
                       "goal_orientation_error": None, "goal_orientation_components": None,
                       "goal_reached": bool(error <= goal_tol)}

    parts = model.parts
    world = [poses[p.link] @ p.origin for p in parts]  # (n, 4, 4) per part
    centers = np.stack([W[:, :3, :3] @ p.center + W[:, :3, 3] for W, p in zip(world, parts)], axis=1)
    radii = np.array([p.radius for p in parts])
    obj = [fcl_object(p.geometry, np.eye(4)) for p in parts]

    def place(k: int, i: int) -> fcl.CollisionObject:
        obj[i].setTransform(fcl.Transform(world[i][k, :3, :3], world[i][k, :3, 3]))
        return obj[i]

    obstacles = load_scene(scene_path)
    if obstacles:
        bounds = np.stack([obstacle_sdf(o.kind, o.dims, o.T, centers) for o in obstacles], axis=-1) - radii[:, None]
        clear, (k_obs, i_obs, j_obs) = smallest(bounds, lambda k, i, j: fcl_distance(place(k, i), obstacles[j].object))
        obstacle_hit = f"{parts[i_obs].link} / {obstacles[j_obs].name}"
    else:
        clear, k_obs, obstacle_hit = math.inf, -1, None
    allowed = allowed_pairs(scene_path) | model.disabled
    pairs = [(a, b) for a, b in itertools.combinations(range(len(parts)), 2)
             if parts[a].link != parts[b].link and frozenset((parts[a].link, parts[b].link)) not in allowed]
    if pairs:
        ia, ib = np.array(pairs).T
        bounds = np.linalg.norm(centers[:, ia] - centers[:, ib], axis=-1) - radii[ia] - radii[ib]
        self_clear, (k_self, m) = smallest(bounds, lambda k, m: fcl_distance(place(k, pairs[m][0]), place(k, pairs[m][1])))
        self_hit = [parts[ia[m]].link, parts[ib[m]].link]
    else:
        self_clear, self_hit = math.inf, None
    link_pairs = {frozenset((parts[a].link, parts[b].link)) for a, b in pairs}
    dq = np.diff(q, axis=0)
    dt = np.diff(t)
    speed_ratio = float(np.max(np.abs(dq / dt[:, None]) / vel)) if n > 1 else 0.0
    # MoveIt moves a start state that lies just outside its bounds (rounding, e.g. π against 3.14159) onto
    # them before planning; such a start matches the bound
    snapped = np.where((q_start < lo) & (lo - q_start <= START_BOUNDS_TOLERANCE), lo,
                       np.where((q_start > up) & (q_start - up <= START_BOUNDS_TOLERANCE), up, q_start))
    ee = poses[model.ee_link][:, :3, 3]
    out = {
        "problem": result.get("problem"),
        "method": result.get("method"),
        "claimed_success": bool(result.get("success")),
        "n_states": int(n),
        "start_error": float(min(np.abs(q[0] - q_start).max(), np.abs(q[0] - snapped).max())),
        **goal_fields,
        "limit_margin": float(min((q - lo).min(), (up - q).min())),
        "speed_ratio": speed_ratio,
        "clearance": clear,
        "closest_state": int(k_obs),
        "closest_obstacle": obstacle_hit,
        "self_clearance": self_clear,
        "closest_links": self_hit,
        "self_pairs": len(link_pairs),
        "ee_length": float(np.linalg.norm(np.diff(ee, axis=0), axis=1).sum()),
        "cspace_length": float(np.linalg.norm(dq, axis=1).sum()),
        "fk_error": fk_error,
    }
    out["valid"] = is_valid(out)
    reported = result.get("metrics") or {}
    for key in ("ee_length", "cspace_length"):
        if isinstance(reported.get(key), (int, float)):
            out[f"{key}_reported"] = float(reported[key])
    if isinstance(reported.get("mesh_clearance"), (int, float)):
        out["clearance_reported"] = float(reported["mesh_clearance"])
    return out


def fk_difference(model: RobotModel, names: Sequence[str], q: np.ndarray, poses: Dict[str, np.ndarray],
                  held: Dict[str, float]) -> float:
    """Largest difference between the recomputed link ``poses`` (4x4) of the configuration q of the joints
    ``names``, the others at ``held`` (joint -> value), and yourdfpy's."""
    model.urdf.update_cfg({**held, **{name: float(v) for name, v in zip(names, q)}})
    return max(float(np.abs(model.urdf.get_transform(l, model.base) - T).max()) for l, T in poses.items())


def problem_files(problems: Path, name: str) -> Tuple[Path, Path]:
    """Scene and request files of a MotionBenchMaker problem named ``<class>/<NNNN>``."""
    cls, number = name.rsplit("/", 1)
    folder = problems / cls if (problems / cls).is_dir() else problems
    scene, request = folder / f"scene{number}.yaml", folder / f"request{number}.yaml"
    if not scene.exists() or not request.exists():
        raise FileNotFoundError(f"problem {name!r}: no {scene} / {request}")
    return scene, request


_MODEL: Optional[RobotModel] = None
_ARGS: Optional[argparse.Namespace] = None


def _init(args: argparse.Namespace) -> None:
    """Load the robot model (a forked worker inherits the parent's)."""
    global _MODEL, _ARGS
    _ARGS = args
    if _MODEL is None:
        _MODEL = RobotModel(Path(args.urdf), Path(args.srdf) if args.srdf else None, args.ee_link,
                            Path(args.mesh_dir) if args.mesh_dir else None, rigid_pairs=args.rigid_pairs)


def _check_file(path: str) -> Dict[str, Any]:
    assert _MODEL is not None and _ARGS is not None
    try:
        result = json.loads(Path(path).read_text())
        if "trajectory" not in result:
            raise ValueError("no trajectory (written with --no-trajectory?)")
        scene, request = problem_files(Path(_ARGS.problems), str(result["problem"]))
        return {"file": path, **check_result(result, _MODEL, scene, request, _ARGS.goal_tol)}
    except Exception as e:  # reported per file; the run goes on
        return {"file": path, "error": f"{type(e).__name__}: {e}"}


def result_files(paths: Sequence[str]) -> List[str]:
    files: List[str] = []
    for p in map(Path, paths):
        files.extend(sorted(map(str, p.glob("*.json"))) if p.is_dir() else [str(p)])
    return files


def summary(rows: Sequence[Dict[str, Any]]) -> str:
    ok = [r for r in rows if "error" not in r]
    claimed = [r for r in ok if r["claimed_success"]]
    bad = [r for r in claimed if not r["valid"]]
    lines = [f"{len(rows)} results, {len(rows) - len(ok)} unreadable, {len(claimed)} claim success, "
             f"{len(claimed) - len(bad)} of them valid here, {len(bad)} not"]
    if claimed:
        joint = [r for r in claimed if r["goal_kind"] == "joint"]
        pose = [r for r in claimed if r["goal_kind"] == "pose"]
        goals = []
        if joint:
            goals.append("max goal error %.2e rad" % max(r["goal_error"] for r in joint))
        if pose:
            goals.append("max pose goal error %.2e m, %.2e rad beyond the tolerances"
                         % (max(r["goal_position_error"] for r in pose), max(r["goal_orientation_error"] for r in pose)))
        lines.append("claimed successes: min obstacle clearance %.2f mm, min self clearance %.2f mm, %s, min limit "
                     "margin %.4f rad, max speed/limit %.3f, max FK difference %.1e"
                     % (1e3 * min(r["clearance"] for r in claimed), 1e3 * min(r["self_clearance"] for r in claimed),
                        ", ".join(goals), min(r["limit_margin"] for r in claimed),
                        max(r["speed_ratio"] for r in claimed), max(r["fk_error"] for r in claimed)))
        diffs = [(abs(r["ee_length"] - r["ee_length_reported"]), abs(r["clearance"] - r["clearance_reported"]))
                 for r in claimed if "ee_length_reported" in r and "clearance_reported" in r
                 and math.isfinite(r["clearance_reported"])]
        if diffs:
            lines.append("against the reported metrics: max |EE length difference| %.2e m, max |clearance "
                         "difference| %.2e m" % (max(d[0] for d in diffs), max(d[1] for d in diffs)))
    lines += [f"NOT VALID: {r['file']}: {_why(r)}" for r in bad]
    lines += [f"ERROR: {r['file']}: {r['error']}" for r in rows if "error" in r]
    return "\n".join(lines)


def _why(r: Dict[str, Any]) -> str:
    goal = ("goal_error",) if r["goal_kind"] == "joint" else ("goal_position_error", "goal_orientation_error")
    return ", ".join(f"{k}={r[k]:.4g}" for k in ("start_error", *goal, "limit_margin", "clearance", "self_clearance"))


def main(argv: Optional[Sequence[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("results", nargs="+", help="result JSON files, or folders of them")
    p.add_argument("--problems", required=True, help="MotionBenchMaker folder (<class>/sceneNNNN.yaml, requestNNNN.yaml)")
    p.add_argument("--urdf", required=True, help="URDF whose collision geometry is checked")
    p.add_argument("--srdf", help="SRDF whose disabled collisions are not checked")
    p.add_argument("--rigid-pairs", action="store_true",
                   help="also check pairs of links joined by fixed joints only (one rigid body), as MoveIt does "
                        "unless the SRDF disables them")
    p.add_argument("--mesh-dir", help="folder resolving package:// mesh paths (default: the URDF's folder)")
    p.add_argument("--ee-link", default="panda_hand", help="end-effector link (default panda_hand)")
    p.add_argument("--goal-tol", type=float, default=0.01, help="joint goal tolerance, rad (default 0.01)")
    p.add_argument("--jobs", type=int, default=None, help="worker processes (default: all cores)")
    p.add_argument("--json", help="write one JSON line per result here (default: stdout)")
    args = p.parse_args(argv)
    files = result_files(args.results)
    if not files:
        p.error("no result files found")
    global _MODEL
    _MODEL = None  # this run's robot, loaded here first: a worker whose initializer fails is replaced forever
    try:
        _init(args)
    except (OSError, ValueError, ET.ParseError) as e:
        p.error(str(e))
    with multiprocessing.Pool(args.jobs, initializer=_init, initargs=(args,)) as pool:
        rows = pool.map(_check_file, files, chunksize=1)
    text = "\n".join(json.dumps(r) for r in rows) + "\n"
    if args.json:
        Path(args.json).write_text(text)
    else:
        sys.stdout.write(text)
    print(summary(rows), file=sys.stderr)
    if any(r.get("claimed_success") and not r.get("valid") for r in rows):
        return 1
    return 2 if any("error" in r for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
