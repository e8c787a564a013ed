"""Planning groups of an SRDF, resolved against a URDF's joint tree as MoveIt resolves them.

A MoveIt request plans for one group (``group_name``); the joints outside it stay where the request's start
state puts them. This module reads the SRDF's ``<group>`` elements, turns one group into the robot's
active joints and its end-effector (tip) links, and builds the :class:`gfcs.Robot` that plans for it.

Group members, as MoveIt reads them (``srdfdom`` and ``moveit::core::RobotModel``):

* ``<chain base_link= tip_link=>``: the joints on the path between the two links (the parent joints of the
  links from the tip up to the base, not the base's own parent joint; when the base is not an ancestor of
  the tip, the path through their deepest common ancestor). Its tip is ``tip_link``.
* ``<joint name=>``: that joint. ``<link name=>``: the link's parent joint.
* ``<group name=>``: every member of that (sub)group; its tips are the subgroup's tips.

The group's active joints are its movable members (revolute, continuous, prismatic) that do not mimic
another joint, in URDF tree order (depth first from the root, children in file order). Its tips are the
chain tips and the subgroups' tips in document order, then, for its joint and link lists, the deepest of
the links they name (child links of the joints, the links themselves: those with no other such link below
them); a tip above another tip of the group is not a tip.

Entries naming links or joints the URDF lacks are skipped with one :class:`gfcs.GfcsWarning` listing them
(MoveIt warns and skips them too); an unknown group, or a group with no movable joint, is an error.
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Set, Tuple, Union

from gfcs.errors import FormatError, GfcsWarning, InvalidValueError, IoError, LinkError

__all__ = [
    "MAX_XML_BYTES",
    "UrdfJoint",
    "UrdfTree",
    "SrdfGroup",
    "GroupResolution",
    "read_xml",
    "read_urdf_tree",
    "collision_links",
    "read_srdf_groups",
    "read_group_states",
    "resolve_group",
    "robot_for_group",
    "ee_links",
]

#: Largest URDF or SRDF read here [bytes]. Robot descriptions are tens of kB; the core refuses anything
#: above its own, larger limit before parsing, and this module parses the same files again with
#: ``xml.etree``, so it refuses sizes no real description has.
MAX_XML_BYTES = 8 << 20

#: Joint types that move (MoveIt's single-variable joints); ``fixed`` does not, and the core has no
#: ``floating``/``planar`` joints.
MOVABLE_TYPES = ("revolute", "continuous", "prismatic")

PathOrXml = Union[str, Path]


@dataclass(frozen=True)
class UrdfJoint:
    """One URDF ``<joint>``: its name, type, parent and child link names, the joint it mimics (or None), and
    whether its ``<limit>`` is one position (:func:`_zero_range`)."""

    name: str
    type: str
    parent: str
    child: str
    mimic: Optional[str] = None
    zero_range: bool = False

    @property
    def active(self) -> bool:
        """True for a joint a planner moves: movable type, not a mimic joint, and a range wider than one
        position (MoveIt moves no joint of zero range; the core holds it at its one position)."""
        return self.type in MOVABLE_TYPES and self.mimic is None and not self.zero_range


@dataclass(frozen=True)
class UrdfTree:
    """A URDF's joint tree.

    Attributes:
        source: the file (or ``"<string>"``) it was read from, for messages.
        root: the root link (the one link that is no joint's child).
        joints: every joint in tree order (depth first from the root, children in file order).
    """

    source: str
    root: str
    joints: Tuple[UrdfJoint, ...]

    @property
    def links(self) -> List[str]:
        """Every link, in tree order (the root first)."""
        return [self.root] + [j.child for j in self.joints]

    def joint(self, name: str) -> Optional[UrdfJoint]:
        """The joint called ``name``, or None."""
        return next((j for j in self.joints if j.name == name), None)

    def parent_joint(self, link: str) -> Optional[UrdfJoint]:
        """The joint whose child is ``link`` (None for the root or an unknown link)."""
        return next((j for j in self.joints if j.child == link), None)

    def ancestors(self, link: str) -> List[str]:
        """The links above ``link``, nearest first, up to the root."""
        out = []
        joint = self.parent_joint(link)
        while joint is not None:
            out.append(joint.parent)
            joint = self.parent_joint(joint.parent)
        return out


@dataclass(frozen=True)
class SrdfGroup:
    """One SRDF ``<group>``: its members in document order, each ``(kind, value)`` with kind ``"chain"``
    (value (base_link, tip_link)), ``"joint"``, ``"link"`` or ``"group"`` (value a name)."""

    name: str
    members: Tuple[Tuple[str, Any], ...]


@dataclass(frozen=True)
class GroupResolution:
    """A group resolved against a URDF.

    Attributes:
        group: the group's name.
        joints: its active joints (movable, not mimic), in URDF tree order.
        tips: its tip links (see the module docstring), the first being the robot's end effector.
        skipped: the ``"link X"`` / ``"joint X"`` entries of the SRDF that the URDF lacks (warned about).
    """

    group: str
    joints: Tuple[str, ...]
    tips: Tuple[str, ...]
    skipped: Tuple[str, ...] = ()


def read_xml(source: PathOrXml, what: str) -> Tuple[ET.Element, str]:
    """The root element of ``source`` (a path, or XML text starting with ``<``) and its name for messages.
    ``IoError`` for an unreadable or oversized file, ``FormatError`` for malformed XML, both naming it."""
    text_given = isinstance(source, str) and source.lstrip().startswith("<")
    name = f"<{what} string>" if text_given else str(source)
    if text_given:
        text = str(source)
        if len(text.encode("utf-8")) > MAX_XML_BYTES:
            raise IoError(f"{name}: more than {MAX_XML_BYTES} bytes, larger than any {what} description")
    else:
        path = Path(source)
        try:
            size = path.stat().st_size
            if size > MAX_XML_BYTES:
                raise IoError(f"{path}: {size} bytes exceed the limit of {MAX_XML_BYTES} bytes for a {what} file")
            text = path.read_text(encoding="utf-8")
        except OSError as e:
            raise IoError(f"{path}: cannot read {what} file: {e.strerror or e}") from e
        except UnicodeDecodeError as e:
            raise FormatError(f"{path}: {what} file is not UTF-8 text: {e}") from e
    try:
        return ET.fromstring(text), name
    except ET.ParseError as e:
        raise FormatError(f"{name}: malformed {what} XML: {e}") from e


def _zero_range(kind: Optional[str], limit: Optional[ET.Element]) -> bool:
    """A revolute or prismatic joint whose ``<limit>`` (with a velocity > 0, as the core requires) gives
    lower and upper (0 when absent) as one finite number."""
    if kind not in ("revolute", "prismatic") or limit is None:
        return False
    try:
        lower, upper, velocity = (float(limit.get(k, 0)) for k in ("lower", "upper", "velocity"))
    except ValueError:
        return False  # the core names the malformed limit
    return velocity > 0 and math.isfinite(lower) and lower == upper


def read_urdf_tree(urdf: PathOrXml) -> UrdfTree:
    """The joint tree of a URDF (path or XML text).

    Raises:
        gfcs.IoError: unreadable or oversized file. gfcs.FormatError: malformed XML, a joint without name,
            type, parent or child, or links that do not form one tree (the message names the file).
    """
    root_el, source = read_xml(urdf, "URDF")
    joints: List[UrdfJoint] = []
    for el in root_el.findall("joint"):
        parent, child, mimic = el.find("parent"), el.find("child"), el.find("mimic")
        fields = (el.get("name"), el.get("type"),
                  None if parent is None else parent.get("link"), None if child is None else child.get("link"))
        if not all(fields):
            raise FormatError(f"{source}: joint {fields[0] or '(unnamed)'} lacks a name, type, parent or child link")
        joints.append(UrdfJoint(*fields, mimic=None if mimic is None else mimic.get("joint"),  # type: ignore[arg-type]
                                zero_range=_zero_range(fields[1], el.find("limit"))))
    links = [el.get("name") for el in root_el.findall("link")]
    children = {j.child for j in joints}
    roots = [link for link in links if link not in children]
    if len(roots) != 1:
        raise FormatError(f"{source}: expected one root link, found {roots or 'none'}")
    below: Dict[str, List[UrdfJoint]] = {}
    for j in joints:
        below.setdefault(j.parent, []).append(j)
    ordered: List[UrdfJoint] = []
    stack = list(reversed(below.get(roots[0], [])))
    seen: Set[str] = {roots[0]}
    while stack:  # depth first; pushed reversed so that the first child in file order comes out first
        joint = stack.pop()
        if joint.child in seen:
            raise FormatError(f"{source}: link {joint.child} is reached twice (the joints form no tree)")
        seen.add(joint.child)
        ordered.append(joint)
        stack.extend(reversed(below.get(joint.child, [])))
    if len(ordered) != len(joints):
        raise FormatError(f"{source}: {len(joints) - len(ordered)} joint(s) are not below the root link {roots[0]}")
    return UrdfTree(source=source, root=roots[0], joints=tuple(ordered))


def collision_links(urdf: PathOrXml) -> List[str]:
    """The links of a URDF (path or XML text) that have ``<collision>`` geometry, in file order; errors as
    :func:`read_urdf_tree`'s."""
    root_el, _ = read_xml(urdf, "URDF")
    return [str(el.get("name")) for el in root_el.findall("link") if el.find("collision") is not None]


def read_srdf_groups(srdf: PathOrXml) -> Dict[str, SrdfGroup]:
    """The ``<group>`` elements of an SRDF (path or XML text), by name, in document order.

    Raises:
        gfcs.IoError / gfcs.FormatError: as :func:`read_urdf_tree`; also a group or member without its
            name attributes (the message names the file and the group).
    """
    root_el, source = read_xml(srdf, "SRDF")
    groups: Dict[str, SrdfGroup] = {}
    for el in root_el.findall("group"):
        name = el.get("name")
        if not name:
            raise FormatError(f"{source}: a <group> has no name")
        members: List[Tuple[str, Any]] = []
        for m in el:
            if m.tag == "chain":
                base, tip = m.get("base_link"), m.get("tip_link")
                if not (base and tip):
                    raise FormatError(f"{source}: group {name}: <chain> needs base_link and tip_link")
                members.append(("chain", (base, tip)))
            elif m.tag in ("joint", "link", "group"):
                if not m.get("name"):
                    raise FormatError(f"{source}: group {name}: <{m.tag}> has no name")
                members.append((m.tag, m.get("name")))
        groups[name] = SrdfGroup(name=name, members=tuple(members))
    return groups


def read_group_states(srdf: PathOrXml) -> List[Tuple[str, str, Dict[str, float]]]:
    """The ``<group_state>`` elements of an SRDF (path or XML text): (group, state name, {joint: value (rad or
    m)}) in document order (MoveIt's named states, e.g. a group's ``ready`` or ``home``). A state without a
    name or a group, or with a joint value that is not one finite number, is skipped, as MoveIt skips it, with
    one :class:`gfcs.GfcsWarning` naming the file and the states (SRDFs written for other tools have states
    without a group).

    Raises:
        gfcs.IoError / gfcs.FormatError: as :func:`read_urdf_tree`.
    """
    root_el, source = read_xml(srdf, "SRDF")
    states: List[Tuple[str, str, Dict[str, float]]] = []
    skipped: List[str] = []
    for el in root_el.findall("group_state"):
        name, group = el.get("name"), el.get("group")
        values: Dict[str, float] = {}
        why = None if name and group else "needs name and group"
        for j in el.findall("joint"):
            joint, text = j.get("name"), j.get("value", "")
            try:
                numbers = [float(v) for v in text.split()]
            except ValueError:
                numbers = []
            if not joint or not numbers or not all(math.isfinite(v) for v in numbers):
                why = why or f"joint {joint or '(no name)'}: value {text!r} is not finite numbers"
            elif len(numbers) == 1:
                values[joint] = numbers[0]
        if why is None:
            states.append((str(group), str(name), values))
        else:
            skipped.append(f"{name or '(no name)'} ({why})")
    if skipped:
        warnings.warn(f"SRDF {source}: {len(skipped)} group_state(s) skipped: {'; '.join(skipped)}", GfcsWarning,
                      stacklevel=2)
    return states


def _chain_joints(tree: UrdfTree, base: str, tip: str) -> List[UrdfJoint]:
    """The joints between ``base`` and ``tip``: from the tip up to their deepest common ancestor, and from
    the base up to it (MoveIt's chain, which also joins two end effectors through the root)."""
    up_tip = [tip] + tree.ancestors(tip)
    up_base = [base] + tree.ancestors(base)
    common = next(link for link in up_tip if link in up_base)  # the root is on both lists
    out = []
    for path in (up_tip, up_base):
        for link in path[: path.index(common)]:
            out.append(tree.parent_joint(link))
    return [j for j in out if j is not None]


def _collect(tree: UrdfTree, groups: Dict[str, SrdfGroup], name: str, source: str, stack: Tuple[str, ...],
             skipped: List[str]) -> Tuple[Set[str], List[str]]:
    """(joint names, tips) of group ``name`` with its subgroups; absent links/joints go to ``skipped``."""
    if name in stack:
        raise FormatError(f"{source}: group {name} contains itself (through {' -> '.join(stack + (name,))})")
    group = groups[name]
    links = set(tree.links)
    joints: Set[str] = set()
    tips: List[str] = []
    listed: List[str] = []  # links named by the joint and link lists
    for kind, value in group.members:
        if kind == "chain":
            absent = [f"link {link}" for link in value if link not in links]
            if absent:
                skipped.extend(f"{a} (chain of group {name})" for a in absent)
                continue
            joints.update(j.name for j in _chain_joints(tree, *value))
            tips.append(value[1])
        elif kind == "joint":
            joint = tree.joint(value)
            if joint is None:
                skipped.append(f"joint {value} (group {name})")
                continue
            joints.add(joint.name)
            listed.append(joint.child)
        elif kind == "link":
            if value not in links:
                skipped.append(f"link {value} (group {name})")
                continue
            parent = tree.parent_joint(value)
            if parent is not None:
                joints.add(parent.name)
            listed.append(value)
        else:
            if value not in groups:
                raise FormatError(f"{source}: group {name} names subgroup {value}, which the SRDF does not define "
                                  f"(its groups: {', '.join(groups)})")
            sub_joints, sub_tips = _collect(tree, groups, value, source, stack + (name,), skipped)
            joints |= sub_joints
            tips.extend(sub_tips)
    listed_set = set(listed)
    deepest = [link for link in tree.links if link in listed_set
               and not any(link in tree.ancestors(other) for other in listed_set)]
    tips.extend(deepest)
    return joints, tips


def resolve_group(urdf: PathOrXml, srdf: PathOrXml, group: str) -> GroupResolution:
    """Group ``group`` of ``srdf`` on the joint tree of ``urdf`` (paths or XML text): its active joints and
    tip links (see the module docstring). Entries naming links or joints the URDF lacks are skipped with
    one :class:`gfcs.GfcsWarning` listing them.

    Raises:
        gfcs.LinkError: the SRDF has no group ``group`` (the message lists its groups).
        gfcs.InvalidValueError: the group moves no joint of this URDF.
        gfcs.IoError / gfcs.FormatError: unreadable or malformed files, an undefined or cyclic subgroup.
    """
    tree = read_urdf_tree(urdf)
    groups = read_srdf_groups(srdf)
    source = str(srdf) if not str(srdf).lstrip().startswith("<") else "<SRDF string>"
    if group not in groups:
        raise LinkError(f"{source}: no group named {group!r} (its groups: {', '.join(groups) or 'none'})")
    skipped: List[str] = []
    joint_names, tips = _collect(tree, groups, group, source, (), skipped)
    if skipped:
        warnings.warn(f"{source}: group {group}: skipped {len(skipped)} entr{'y' if len(skipped) == 1 else 'ies'} "
                      f"naming what {tree.source} lacks: {', '.join(skipped)}", GfcsWarning, stacklevel=2)
    active = tuple(j.name for j in tree.joints if j.name in joint_names and j.active)
    if not active:
        raise InvalidValueError(f"{source}: group {group!r} moves no joint of {tree.source} (its joints: "
                                f"{', '.join(sorted(joint_names)) or 'none'}; movable non-mimic ones are planned)")
    unique: List[str] = []
    for tip in tips:
        if tip not in unique:
            unique.append(tip)
    # a tip above another tip is not an end of the group
    ends = tuple(t for t in unique if not any(t in tree.ancestors(o) for o in unique if o != t))
    return GroupResolution(group=group, joints=active, tips=ends, skipped=tuple(skipped))


def group_of(urdf: PathOrXml, srdf: PathOrXml, joint_names: Sequence[str]) -> Optional[str]:
    """The first group of ``srdf`` (document order) whose active joints on ``urdf`` are exactly
    ``joint_names`` (in any order), or None: the ``group_name`` a MoveIt request for a robot with these
    joints carries. Groups naming what the URDF lacks are resolved without them, silently."""
    wanted = set(joint_names)
    for name in read_srdf_groups(srdf):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", GfcsWarning)
            try:
                joints = resolve_group(urdf, srdf, name).joints
            except InvalidValueError:
                continue
        if set(joints) == wanted:
            return name
    return None


def robot_for_group(urdf: PathOrXml, srdf: PathOrXml, group: str, **kwargs: Any) -> Tuple[Any, List[str]]:
    """The robot of ``urdf`` that plans for ``group`` of ``srdf``, and the group's tip links.

    The group's active joints are the robot's (in URDF tree order), its first tip the end-effector link
    (unless ``ee_link`` is given); every other movable joint is locked, held where a request's start state
    puts it (:func:`gfcs.problems.held_as_requested`). ``srdf`` also prunes the self-collision pairs.

    Args:
        urdf, srdf: paths or XML text.
        group: the SRDF group's name (a request's ``group_name``).
        **kwargs: further keyword arguments of :meth:`gfcs.Robot.from_urdf` (``spheres``, ``mesh_dir``,
            ``base_link``, ``ee_link``); ``active_joints`` and ``srdf`` come from the group.

    Returns:
        (robot, tips): the :class:`gfcs.Robot` and the group's tip links, the first one first.

    Raises:
        gfcs.InvalidValueError: ``active_joints`` or ``srdf`` given in ``kwargs``; see :func:`resolve_group`.
    """
    import gfcs

    for key in ("active_joints", "srdf"):
        if key in kwargs:
            raise InvalidValueError(f"robot_for_group: {key} comes from group {group!r}; do not pass it")
    resolved = resolve_group(urdf, srdf, group)
    kwargs.setdefault("ee_link", resolved.tips[0] if resolved.tips else None)
    robot = gfcs.Robot.from_urdf(str(urdf), active_joints=list(resolved.joints), srdf=str(srdf), **kwargs)
    return robot, list(resolved.tips)


def ee_links(problem: Any) -> List[str]:
    """The end-effector links whose hand paths the metrics of ``problem`` report: ``problem.meta["ee_links"]``
    (the tips of the group it was loaded for), else its robot's end effector."""
    links = (getattr(problem, "meta", None) or {}).get("ee_links")
    return list(links) if links else [problem.robot.ee_link]
