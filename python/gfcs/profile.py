"""Robot profiles: what the planner needs to know about a robot beyond its kinematics, as data.

A :class:`RobotProfile` holds

* ``acceleration_limits``: {joint name: limit [rad/s² or m/s²]}. URDF files carry none, so they come from a
  profile data file (``gfcs/data/profiles/*.json``, matched by joint names), from a MoveIt
  ``joint_limits.yaml`` (:func:`read_joint_limits_yaml`), or from the caller; joints without one are not
  limited in acceleration;
* ``velocity_limits``: {joint name: limit} that tighten the URDF's ``<limit velocity>`` (a MoveIt
  ``joint_limits.yaml`` may set lower ones; the URDF's always apply);
* ``approach_axis``: the gripper's approach direction in the end-effector frame, used by the warm start
  (:class:`gfcs.optimize.ApproachSampler`). From the data file when one matches, else derived from the
  robot's own collision spheres by :func:`derive_approach_axis`.

:func:`profile_for` resolves the profile of a robot: the first shipped data file whose joints the robot
has, else a derived one. A robot with no data file still gets limits from its URDF and a derived approach
axis.
"""

from __future__ import annotations

import dataclasses
import functools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

__all__ = ["RobotProfile", "profile_for", "load_profile", "derive_approach_axis", "gripper_reach", "read_joint_limits_yaml",
           "velocity_limits", "acceleration_limits", "PROFILE_DIR"]

PathLike = Union[str, Path]
#: Folder of the shipped profile data files.
PROFILE_DIR = Path(__file__).resolve().parent / "data" / "profiles"
#: A derived approach direction within this angle [rad] of an axis of the end-effector frame is that axis.
_SNAP_ANGLE = np.deg2rad(25.0)


@dataclass(frozen=True)
class RobotProfile:
    """Planner-facing facts about a robot (see the module docstring).

    Attributes:
        name: the profile's name (the data file's stem, or ``"derived"``).
        joints: joint names the profile is for (a data file applies to robots that have all of them).
        acceleration_limits: {joint: a > 0} [rad/s² or m/s²].
        velocity_limits: {joint: v > 0} [rad/s or m/s] that tighten the URDF's.
        approach_axis: (3,) unit approach direction in the end-effector frame, or None (derive it).
        source: where the profile came from (file path or ``"derived from the robot"``).
    """

    name: str
    joints: Tuple[str, ...] = ()
    acceleration_limits: Dict[str, float] = field(default_factory=dict)
    velocity_limits: Dict[str, float] = field(default_factory=dict)
    approach_axis: Optional[Tuple[float, float, float]] = None
    source: str = ""

    def merged(self, other: "RobotProfile") -> "RobotProfile":
        """This profile with ``other``'s limits on top (a value of ``other`` replaces this one's) and
        ``other``'s approach axis when it has one."""
        return RobotProfile(
            name=f"{self.name}+{other.name}", joints=tuple(dict.fromkeys(self.joints + other.joints)),
            acceleration_limits={**self.acceleration_limits, **other.acceleration_limits},
            velocity_limits={**self.velocity_limits, **other.velocity_limits},
            approach_axis=other.approach_axis if other.approach_axis is not None else self.approach_axis,
            source=f"{self.source}; {other.source}")


def _positive_table(table: Any, what: str, source: str) -> Dict[str, float]:
    """{name: positive finite float}; ValueError naming ``source`` and ``what`` otherwise."""
    from gfcs.errors import InvalidValueError

    if not isinstance(table, dict):
        raise InvalidValueError(f"{source}: '{what}' must map joint names to numbers, got {type(table).__name__}")
    out: Dict[str, float] = {}
    for name, value in table.items():
        try:
            x = float(value)
        except (TypeError, ValueError):
            x = float("nan")
        if not (np.isfinite(x) and x > 0):
            raise InvalidValueError(f"{source}: '{what}.{name}' must be a finite number > 0, got {value!r}")
        out[str(name)] = x
    return out


def load_profile(path: PathLike) -> RobotProfile:
    """A profile from a JSON file: ``{"joints": [...], "acceleration_limits": {joint: a},
    "velocity_limits": {joint: v}, "approach_axis": [x, y, z]}`` (every key optional but ``joints``)."""
    from gfcs.errors import InvalidValueError

    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise InvalidValueError(f"{p}: cannot read the robot profile: {e}") from e
    if not isinstance(data, dict) or not isinstance(data.get("joints"), list):
        raise InvalidValueError(f"{p}: a robot profile is an object with a 'joints' list")
    axis = data.get("approach_axis")
    if axis is not None:
        a = np.asarray(axis, dtype=np.float64)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
            raise InvalidValueError(f"{p}: 'approach_axis' must be 3 finite numbers, not all 0, got {axis!r}")
        axis = tuple(float(x) for x in a / np.linalg.norm(a))
    return RobotProfile(
        name=p.stem, joints=tuple(str(j) for j in data["joints"]),
        acceleration_limits=_positive_table(data.get("acceleration_limits", {}), "acceleration_limits", str(p)),
        velocity_limits=_positive_table(data.get("velocity_limits", {}), "velocity_limits", str(p)),
        approach_axis=axis, source=str(p))


def read_joint_limits_yaml(path: PathLike) -> RobotProfile:
    """The limits of a MoveIt ``joint_limits.yaml`` (``joint_limits: {joint: {has_velocity_limits,
    max_velocity, has_acceleration_limits, max_acceleration}}``) as a profile without approach axis."""
    import yaml

    from gfcs.errors import InvalidValueError

    p = Path(path)
    try:
        data = yaml.safe_load(p.read_text())
    except (OSError, yaml.YAMLError) as e:
        raise InvalidValueError(f"{p}: cannot read the joint limits: {e}") from e
    table = data.get("joint_limits") if isinstance(data, dict) else None
    if not isinstance(table, dict):
        raise InvalidValueError(f"{p}: expected a 'joint_limits' mapping (MoveIt joint_limits.yaml)")
    velocity: Dict[str, Any] = {}
    acceleration: Dict[str, Any] = {}
    for joint, entry in table.items():
        if not isinstance(entry, dict):
            raise InvalidValueError(f"{p}: joint_limits.{joint} must be a mapping")
        if entry.get("has_velocity_limits") and "max_velocity" in entry:
            velocity[joint] = entry["max_velocity"]
        if entry.get("has_acceleration_limits") and "max_acceleration" in entry:
            acceleration[joint] = entry["max_acceleration"]
    return RobotProfile(
        name=p.stem, joints=tuple(str(j) for j in table),
        velocity_limits=_positive_table(velocity, "joint_limits.*.max_velocity", str(p)),
        acceleration_limits=_positive_table(acceleration, "joint_limits.*.max_acceleration", str(p)),
        source=str(p))


@functools.lru_cache(maxsize=1)
def _shipped_profiles() -> Tuple[RobotProfile, ...]:
    """The package's profile data files, read once (they ship with the package and do not change)."""
    return tuple(load_profile(path) for path in sorted(PROFILE_DIR.glob("*.json")))


def _data_profile(robot: Any) -> RobotProfile:
    """The first shipped data file whose joints ``robot`` all has (active or locked), else an empty
    profile; no derived approach axis."""
    joints = set(robot.joint_names) | set(getattr(robot, "locked_positions", {}) or {})
    return next((p for p in _shipped_profiles() if p.joints and set(p.joints) <= joints),
                RobotProfile(name="derived", source="derived from the robot"))


def _rigid_with_ee(robot: Any, rng: np.random.Generator, samples: int = 3, link: Optional[str] = None) -> np.ndarray:
    """Boolean (links,) mask of the links rigidly attached to the end-effector link (``link``, default
    ``robot.ee_link``: the same pose relative to it at ``samples`` random configurations), that link
    included."""
    lo, up = np.asarray(robot.lower, dtype=np.float64), np.asarray(robot.upper, dtype=np.float64)
    ee = int(robot.link_index(robot.ee_link if link is None else link))
    rigid = np.ones(len(robot.link_names), dtype=bool)
    reference = None
    for _ in range(samples):
        poses = np.asarray(robot.link_poses(rng.uniform(lo, up)), dtype=np.float64)
        relative = np.linalg.inv(poses[ee])[None] @ poses
        if reference is None:
            reference = relative
        else:
            rigid &= np.all(np.abs(relative - reference) < 1e-9, axis=(1, 2))
    return rigid


def perturbed_poses(robot: Any, q: np.ndarray, delta: float = 1e-3) -> Tuple[np.ndarray, np.ndarray]:
    """World link poses at ``q`` (L, 4, 4) and with each coordinate in turn moved by ``delta`` [rad or m]
    (dof, L, 4, 4), in one batched forward kinematics: which links a joint moves, and how."""
    q = np.asarray(q, dtype=np.float64)
    batch = np.vstack([q, q + delta * np.eye(int(robot.dof))])
    poses = np.asarray(robot.link_poses(batch), dtype=np.float64).reshape(batch.shape[0], -1, 4, 4)
    return poses[0], poses[1:]


def _parent_links(robot: Any, q: np.ndarray, link: str) -> np.ndarray:
    """Boolean (links,) mask of the links of the body before the end effector's: those that the second
    nearest joint moving ``link`` moves and the nearest does not (a joint nearer the end effector moves
    fewer links); all False when one joint or none moves ``link``."""
    poses, moved_poses = perturbed_poses(robot, q)
    moved = np.any(np.abs(moved_poses - poses[None]) > 1e-12, axis=(2, 3))  # (dof, links)
    ee = int(robot.link_index(link))
    chain = sorted((m for m in moved if m[ee]), key=lambda m: int(m.sum()))
    if len(chain) < 2:
        return np.zeros(len(robot.link_names), dtype=bool)
    return chain[1] & ~chain[0]


@dataclass(frozen=True)
class _Hand:
    """The collision spheres at the middle of the joint ranges ``q`` (dof,), with the link poses ``poses``
    (L, 4, 4), the sphere centres ``centres`` (S, 3) in the world frame, their radii (S,) and links
    ``sphere_link`` (S,), ``rigid`` (L,): the links rigidly attached to the end-effector link, and ``on`` (S,):
    the spheres on them."""

    q: np.ndarray
    poses: np.ndarray
    centres: np.ndarray
    radii: np.ndarray
    sphere_link: np.ndarray
    rigid: np.ndarray
    on: np.ndarray


def _hand(robot: Any, link: str) -> Optional[_Hand]:
    """The spheres of the hand at the end-effector link ``link`` (:class:`_Hand`); None when no sphere is
    rigidly attached to it."""
    rigid = _rigid_with_ee(robot, np.random.default_rng(0), link=link)
    names = list(robot.link_names)
    sphere_link = np.array([names.index(name) for name in robot.sphere_links], dtype=np.int64)
    on = rigid[sphere_link] if sphere_link.size else np.zeros(0, dtype=bool)
    if not on.any():
        return None
    q = 0.5 * (np.asarray(robot.lower, dtype=np.float64) + np.asarray(robot.upper, dtype=np.float64))
    return _Hand(q, np.asarray(robot.link_poses(q), dtype=np.float64),
                 np.asarray(robot.sphere_centers(q), dtype=np.float64).reshape(-1, 3),
                 np.asarray(robot.sphere_radii, dtype=np.float64), sphere_link, rigid, on)


def gripper_reach(robot: Any, axis: Sequence[float], link: Optional[str] = None) -> Optional[float]:
    """How far [m] the gripper reaches along ``axis`` (3,) (a unit vector in the frame of the end-effector link
    ``link``, default ``robot.ee_link``): the largest c·axis + r over the collision spheres rigidly attached to
    that link (centre c in its frame, radius r), at the middle of the joint ranges; None when no sphere is
    attached there."""
    link = robot.ee_link if link is None else link
    hand = _hand(robot, link)
    if hand is None:
        return None
    ee = hand.poses[int(robot.link_index(link))]
    local = (hand.centres[hand.on] - ee[:3, 3]) @ ee[:3, :3]
    return float(np.max(local @ np.asarray(axis, dtype=np.float64) + hand.radii[hand.on]))


def derive_approach_axis(robot: Any, link: Optional[str] = None) -> Tuple[float, float, float]:
    """The gripper's approach direction in the frame of the end-effector link ``link`` (default
    ``robot.ee_link``; another for the second hand of a two-arm group), from the robot's collision spheres
    at the middle of the joint ranges: the direction from the origin of the last moving body (the child link
    of the last joint that moves the end effector) to the volume-weighted centroid of the spheres rigidly
    attached to the end effector (a gripper extends from the wrist along its approach direction). When that
    centroid lies behind the origin, on the side of the body before it (a bare flange whose frame sits on
    the flange face, the link's volume behind it), the direction from that body's sphere centroid to the end
    effector's is used instead: a tool extends away from the arm. Snapped to the nearest axis of the
    end-effector frame when within 25° of it. The z axis when the robot has no spheres there."""
    link = robot.ee_link if link is None else link
    hand = _hand(robot, link)
    if hand is None:
        return (0.0, 0.0, 1.0)
    poses, weights = hand.poses, hand.radii ** 3

    def centroid(on: np.ndarray) -> np.ndarray:
        return weights[on] @ hand.centres[on] / weights[on].sum()

    tool = centroid(hand.on)
    # the body's origin: among the rigidly attached links, the one nearest the base in the link order
    body_origin = poses[int(np.flatnonzero(hand.rigid)[0]), :3, 3]
    d = tool - body_origin
    on_parent = _parent_links(robot, hand.q, link)[hand.sphere_link]
    if on_parent.any():
        away = tool - centroid(on_parent)
        if float(d @ away) <= 0.0:
            d = away
    ee_rot = poses[int(robot.link_index(link)), :3, :3]
    d = ee_rot.T @ d
    if np.linalg.norm(d) < 1e-9:
        return (0.0, 0.0, 1.0)
    d = d / np.linalg.norm(d)
    k = int(np.argmax(np.abs(d)))
    if np.arccos(min(1.0, abs(d[k]))) <= _SNAP_ANGLE:
        sign = 1.0 if d[k] > 0 else -1.0
        d = np.zeros(3)
        d[k] = sign
    return (float(d[0]), float(d[1]), float(d[2]))


def profile_for(robot: Any, extra: Optional[RobotProfile] = None) -> RobotProfile:
    """The profile of ``robot``: the first shipped data file whose joints it all has (else an empty one),
    with ``extra`` (e.g. :func:`read_joint_limits_yaml`) on top, and the approach axis derived by
    :func:`derive_approach_axis` when neither gives one."""
    base = _data_profile(robot)
    if extra is not None:
        base = base.merged(extra)
    if base.approach_axis is None:
        base = dataclasses.replace(base, approach_axis=derive_approach_axis(robot))
    return base


def velocity_limits(robot: Any, profile: Optional[RobotProfile] = None) -> np.ndarray:
    """(dof,) velocity limits [rad/s or m/s] of the active joints: the URDF's, tightened by the profile's
    (inf for a continuous joint without one)."""
    v = np.asarray(robot.velocity_limits, dtype=np.float64).copy()
    table = {} if profile is None else profile.velocity_limits
    for j, name in enumerate(robot.joint_names):
        if name in table:
            v[j] = min(v[j], table[name])
    return v


def acceleration_limits(robot: Any, profile: Optional[RobotProfile] = None) -> Optional[np.ndarray]:
    """(dof,) acceleration limits [rad/s² or m/s²] of the active joints from the profile (default: the
    robot's data file, as :func:`profile_for` finds it, without deriving its approach axis), inf where it
    has none; None when it has none at all."""
    table = (_data_profile(robot) if profile is None else profile).acceleration_limits
    a = np.array([table.get(name, np.inf) for name in robot.joint_names], dtype=np.float64)
    return None if np.all(np.isinf(a)) else a
