"""Motion problems: start, goal, robot and scene (GFCS Sec. V), and MotionBenchMaker loading.

A :class:`Problem` is one GFCOP instance: robot, scene E, start q₀ (and q̇₀, zero by default) and goal q_g
(GFCS eq. 1-8). Problems come from MotionBenchMaker files (MoveIt ``sceneNNNN.yaml`` planning scenes and
``requestNNNN.yaml`` motion plan requests, one folder per class) or from the procedural generators of
:mod:`gfcs.generators`.

A problem may carry a ``mesh_checker`` (:class:`gfcs.MeshChecker`): the robot's collision meshes, against which
:mod:`gfcs.metrics` and :mod:`gfcs.optimize` validate trajectories the way independent benchmarks judge them
(the fabric itself avoids obstacles with collision spheres). :func:`mbm_panda` builds one from the MBM Panda's
``panda.urdf`` and :func:`load_mbm` / :func:`load_mbm_dir` attach it to problems solved with that robot;
problems of the shipped Panda get its collision polytopes (:func:`shipped_panda_checker`). For
a robot of your own, :func:`urdf_mesh_checker` builds one from a URDF with collision meshes and
:func:`mesh_urdf_for` finds that URDF for a robot file (``gfcs solve/bench --robot`` do both).

Problem classes use the MotionBenchMaker folder names (:data:`CLASSES`); :func:`canonical_class`
also accepts the names used in the GFCS paper's Table I (e.g. ``"table_under"``, ``"single_shelf"``).
"""

from __future__ import annotations

import dataclasses
import functools
import weakref
import hashlib
import json
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from gfcs import pose_goal as _pose_goal
from gfcs.errors import InvalidValueError, MissingFileError, NonFiniteError, ShapeError
from gfcs.joints import BOUNDS_TOLERANCE, continuous_mask, snap_to_bounds, unwrap_goal
from gfcs.results import _enc

__all__ = [
    "Problem",
    "CLASSES",
    "CLASS_ALIASES",
    "canonical_class",
    "load_mbm",
    "load_mbm_dir",
    "held_as_requested",
    "mbm_panda",
    "mbm_mesh_checker",
    "mesh_checker_for",
    "shipped_panda_checker",
    "mesh_urdf_for",
    "urdf_mesh_checker",
    "with_shipped_panda_spheres",
    "links_without_spheres",
    "thin_sphere_model",
    "shared_dir",
]

#: Problem classes, MotionBenchMaker folder names, in the order of GFCS Table I (then table_pick).
CLASSES = (
    "table_under_pick",
    "box",
    "bookshelf_tall",
    "cage",
    "bookshelf_thin",
    "bookshelf_small",
    "table_pick",
)
#: Other accepted spellings (GFCS Table I titles) -> class name.
CLASS_ALIASES = {
    "table_under": "table_under_pick",
    "tall_shelf": "bookshelf_tall",
    "thin_shelf": "bookshelf_thin",
    "single_shelf": "bookshelf_small",
    "small_shelf": "bookshelf_small",
}

PathLike = Union[str, "os.PathLike[str]"]


def canonical_class(name: str) -> str:
    """The class name of ``name`` (a class or an alias, case-insensitive; ``-``/space read as ``_``).

    Raises:
        ValueError: unknown class (the message lists the known ones).
    """
    key = re.sub(r"[\s\-]+", "_", str(name).strip().lower())
    key = CLASS_ALIASES.get(key, key)
    if key not in CLASSES:
        raise InvalidValueError(f"unknown problem class '{name}' (known: {', '.join(CLASSES)}; "
                                f"aliases: {', '.join(CLASS_ALIASES)})")
    return key


def _vector(value: Any, what: str, dof: int) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64).reshape(-1) if value is not None else None
    if a is None or a.shape != (dof,):
        got = None if value is None else np.shape(value)
        raise ShapeError(f"{what}: expected shape ({dof},), got {got}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(f"{what} contains NaN or infinite values")
    return a


def _check_within_limits(robot: Any, q: np.ndarray, what: str) -> None:
    """``gfcs.InvalidValueError`` (a ValueError) naming ``what`` and the first joint of ``q`` outside the
    robot's position limits (beyond :data:`gfcs.metrics.DEFAULT_LIMIT_TOL`): no motion within the limits can
    start or end there."""
    from gfcs.errors import InvalidValueError
    from gfcs.metrics import DEFAULT_LIMIT_TOL

    lower, upper = np.asarray(robot.lower, dtype=np.float64), np.asarray(robot.upper, dtype=np.float64)
    bounded = ~continuous_mask(robot)  # continuous joints have no position limits
    outside = np.flatnonzero(bounded & ((q < lower - DEFAULT_LIMIT_TOL) | (q > upper + DEFAULT_LIMIT_TOL)))
    if outside.size:
        j = int(outside[0])
        raise InvalidValueError(f"{what}: joint {robot.joint_names[j]} = {q[j]:.6g} rad lies outside its "
                                f"limits [{lower[j]:.6g}, {upper[j]:.6g}]")


def _check_start_velocity(robot: Any, qd: np.ndarray, what: str) -> None:
    """``gfcs.InvalidValueError`` naming ``what`` and the first joint whose start speed exceeds its velocity
    limit: the robot cannot be in that state, and no time parameterisation can change the state it starts
    in."""
    from gfcs.errors import InvalidValueError

    limits = np.asarray(robot.velocity_limits, dtype=np.float64)
    over = np.flatnonzero(np.abs(qd) > limits)
    if over.size:
        j = int(over[0])
        raise InvalidValueError(f"{what}: joint {robot.joint_names[j]} starts at {qd[j]:.6g} rad/s or m/s, beyond "
                                f"its velocity limit {limits[j]:.6g}")


@dataclass
class Problem:
    """One motion problem (a GFCOP instance, GFCS eq. 4-8).

    Attributes:
        name: identifier, e.g. ``"bookshelf_small/0001"``.
        robot: a :class:`gfcs.Robot`.
        scene: a :class:`gfcs.Scene` (the environment E).
        q0: (dof,) start configuration [rad], within the robot's joint limits.
        goal: (dof,) goal configuration q_g [rad], within the robot's joint limits.
        qd0: (dof,) start velocity [rad/s]; None means zeros.
        cls: problem class (:data:`CLASSES`), "" when unknown.
        meta: free-form provenance (source files, generator parameters, obstacle primitives).
        mesh_checker: optional :class:`gfcs.MeshChecker` of the robot's collision meshes (same joints, same
            order as ``robot``); when set, metrics report ``mesh_clearance`` and success requires it above
            the mesh margin (:data:`gfcs.metrics.DEFAULT_MESH_MARGIN`).

    Raises:
        ValueError: a vector of the wrong shape or not finite, or ``q0`` or ``goal`` outside the joint limits
            (naming the problem, the vector and the joint).
    """

    name: str
    robot: Any
    scene: Any
    q0: np.ndarray
    goal: np.ndarray
    qd0: Optional[np.ndarray] = None
    cls: str = ""
    meta: Dict[str, Any] = field(default_factory=dict)
    mesh_checker: Any = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        dof = int(self.robot.dof)
        if self.mesh_checker is not None and list(self.mesh_checker.joint_names) != list(self.robot.joint_names):
            raise InvalidValueError(f"mesh_checker: joints {list(self.mesh_checker.joint_names)} differ from the "
                                    f"robot's "
                                    f"{list(self.robot.joint_names)} (q must mean the same for both)")
        self.q0 = _vector(self.q0, "q0", dof)
        self.goal = _vector(self.goal, "goal", dof)
        self.qd0 = np.zeros(dof) if self.qd0 is None else _vector(self.qd0, "qd0", dof)
        for what, q in (("q0", self.q0), ("goal", self.goal)):
            _check_within_limits(self.robot, q, f"problem {self.name!r}: {what}")
        _check_start_velocity(self.robot, self.qd0, f"problem {self.name!r}: qd0")

    @property
    def dof(self) -> int:
        """Number of active joints."""
        return int(self.robot.dof)

    def with_scene(self, scene: Any) -> "Problem":
        """A copy of this problem in another scene (e.g. with new obstacles, GFCS Sec. V reactivity)."""
        return dataclasses.replace(self, scene=scene, meta=dict(self.meta))


# ------------------------------------------------------------------------------ MotionBenchMaker
def shared_dir() -> Optional[Path]:
    """The shared data folder (MotionBenchMaker problems, MBM Panda), or None when absent.

    ``$GFCS_SHARED`` when set, else ``<repository root>/../shared`` (for a source checkout).
    """
    path = _default_shared()
    return path if path.is_dir() else None


def _default_shared() -> Path:
    """Where :func:`shared_dir` looks: ``$GFCS_SHARED``, else ``<repository root>/../shared``."""
    env = os.environ.get("GFCS_SHARED")
    return Path(env) if env else Path(__file__).resolve().parents[2].parent / "shared"


def _missing_joint_error(message: str) -> Exception:
    from gfcs.errors import LinkError

    return LinkError(message)


def load_mbm(
    scene_yaml: PathLike,
    request_yaml: PathLike,
    robot: Any = None,
    name: Optional[str] = None,
    cls: Optional[str] = None,
    mesh_checker: Any = None,
) -> Problem:
    """One MotionBenchMaker problem from its scene and request files.

    Args:
        scene_yaml: MoveIt PlanningScene YAML (``sceneNNNN.yaml``).
        request_yaml: MoveIt MotionPlanRequest YAML (``requestNNNN.yaml``): start joint state and a
            joint-space goal, or a pose goal (position and orientation constraints on a link), which
            becomes the joint goal :func:`gfcs.pose_goal.goal_configuration` finds by inverse kinematics
            (``meta["pose_goal"]`` keeps the constraints).
        robot: the robot (default :meth:`gfcs.Robot.panda`); its active joints are looked up by name in
            the request's start state and goal constraints. For the MotionBenchMaker files prefer
            :func:`mbm_panda`: their goals sit 1-3 cm from the obstacles for that robot's spheres, and
            most of them (all of the box and cage goals) collide with the shipped Panda's more
            conservative spheres.
        name: problem name (default ``"<folder>/<NNNN>"``).
        cls: problem class (default: the folder name).
        mesh_checker: the problem's :class:`gfcs.MeshChecker`; default :func:`mesh_checker_for` ``(robot)``
            (the MBM Panda's meshes when ``robot`` came from :func:`mbm_panda`, the shipped Panda's
            polytopes for the shipped Panda, else none).

    Joints the robot (or the checker's robot) holds locked, such as the shipped Panda's fingers, are held
    where the request's start state puts them (:func:`held_as_requested`): the problem's robot is then a
    copy of ``robot``.

    Raises:
        gfcs.LinkError: a joint of the robot is missing from the request's start state or goal, or the goal
            constrains a joint the robot does not have (the message names the joint and the file).
        gfcs.IoError / gfcs.FormatError: unreadable or malformed files (from the core).
        gfcs.InvalidValueError: the request's start or goal lies outside the robot's joint limits, or its
            start state holds a locked joint (e.g. a finger) more than 0.05 outside its limits.
        ValueError: a pose goal in a frame other than the robot's root, on an unknown link, or without a
            valid inverse-kinematics solution.
    """
    return Problem(**_mbm_fields(scene_yaml, request_yaml, robot, name, cls, mesh_checker))


def _mbm_fields(scene_yaml: PathLike, request_yaml: PathLike, robot: Any, name: Optional[str],
                cls: Optional[str], mesh_checker: Any) -> Dict[str, Any]:
    """The :class:`Problem` fields of :func:`load_mbm` (all its file reading and checks but the
    problem's own, which :class:`Problem` makes)."""
    import gfcs

    robot = gfcs.Robot.panda() if robot is None else robot
    scene_path, request_path = Path(scene_yaml), Path(request_yaml)
    scene = gfcs.Scene.from_moveit_yaml(str(scene_path), root_frame=robot.link_names[0])
    request = gfcs.load_motion_plan_request(str(request_path))
    for field_path in request.get("ignored", []):
        warnings.warn(f"{request_path}: {field_path} is not supported and is ignored (the motion does not "
                      "follow it)", gfcs.errors.GfcsWarning, stacklevel=3)
    checker = mesh_checker if mesh_checker is not None else mesh_checker_for(robot)
    try:
        robot = held_as_requested(robot, request["start"])
        if checker is not None:
            checker = held_as_requested(checker, request["start"])
    except gfcs.errors.InvalidValueError as e:
        raise gfcs.errors.InvalidValueError(f"{request_path}: start_state: {e}") from e
    values = {}
    pose_goal = request.get("pose_goal")
    for part in ("start", "goal") if pose_goal is None else ("start",):
        table = request[part]
        missing = [j for j in robot.joint_names if j not in table]
        if missing:
            raise _missing_joint_error(
                f"{request_path}: joint '{missing[0]}' of robot '{robot.name}' is not in the request's "
                f"{'start state' if part == 'start' else 'goal constraints'} (it has: "
                f"{', '.join(sorted(table)) or 'nothing'})"
            )
        values[part] = np.array([table[j] for j in robot.joint_names], dtype=np.float64)
    if pose_goal is None:  # a goal the robot cannot reach in some joint is no goal at all
        known = set(robot.joint_names) | set(robot.locked_positions)
        unknown = [j for j in request["goal"] if j not in known]
        if unknown:
            raise _missing_joint_error(
                f"{request_path}: goal_constraints name joint(s) {', '.join(repr(j) for j in unknown)} that "
                f"robot '{robot.name}' does not have (its joints: {', '.join(robot.joint_names)})"
            )
    moved = []
    for part in values:  # MoveIt's semantics: values rounded just outside a bound lie on it
        values[part], shifts = snap_to_bounds(robot, values[part])
        moved += [f"{part} {m}" for m in shifts]
    if moved:
        warnings.warn(f"{request_path}: {_ON_BOUND} (by at most {BOUNDS_TOLERANCE} rad or m) are planned on the "
                      f"bound: {'; '.join(moved)}", gfcs.errors.GfcsWarning, stacklevel=3)
    if "goal" in values:  # continuous joints turn the short way to the goal's orientation
        values["goal"] = unwrap_goal(values["start"], values["goal"], continuous_mask(robot))
    meta = {"scene_file": str(scene_path), "request_file": str(request_path),
            "group": request.get("group", ""), "start_state": dict(request["start"])}
    if pose_goal is not None:
        values["goal"] = _pose_goal.goal_configuration(robot, scene, values["start"], pose_goal,
                                                       mesh_checker=checker, source=str(request_path))
        meta["pose_goal"] = _enc(pose_goal)
    folder = scene_path.resolve().parent.name
    number = re.sub(r"\D", "", scene_path.stem) or scene_path.stem
    return dict(
        name=name if name is not None else f"{folder}/{number}",
        robot=robot,
        scene=scene,
        q0=values["start"],
        goal=values["goal"],
        cls=cls if cls is not None else folder,
        meta=meta,
        mesh_checker=checker,
    )


#: Robots and mesh checkers rebuilt by :func:`held_as_requested`, keyed by (id of the original, positions);
#: each entry keeps its original alive, so an id is not reused while it is registered.
_HELD: Dict[Tuple[int, Tuple[Tuple[str, float], ...]], Tuple[Any, Any]] = {}


def held_as_requested(model: Any, start: Dict[str, float]) -> Any:
    """``model`` (a :class:`gfcs.Robot`, or a :class:`gfcs.MeshChecker` and its robot) with its locked joints
    where a request's start state puts them, as MoveIt keeps the joints outside the planning group at their
    start values: the shipped Panda holds its fingers at 0.04 m, MotionBenchMaker requests open them to
    0.065 m (its URDF's fixed fingers), and with 0.04 m the fingers of a returned motion could touch what
    the wider hand is placed around. ``model`` itself when nothing differs; one rebuilt copy per model and
    positions (cached).

    Args:
        model: the robot or mesh checker.
        start: {joint name: position} of the request's start state (rad or m).
    """
    import gfcs

    robot = model.robot if isinstance(model, gfcs.MeshChecker) else model
    held = robot.locked_positions
    change = tuple(sorted((j, float(start[j])) for j in held if j in start and float(start[j]) != held[j]))
    if not change:
        return model
    key = (id(model), change)
    entry = _HELD.get(key)
    if entry is None or entry[0] is not model:
        moved = robot.with_locked_positions(dict(change))
        if isinstance(model, gfcs.MeshChecker):
            moved = gfcs.MeshChecker(moved, max_distance=model.max_distance)
        entry = _HELD[key] = (model, moved)
    return entry[1]


_SCENE_RE = re.compile(r"^scene(\d+)\.ya?ml$")


def _class_dirs(directory: Path) -> List[Path]:
    """``directory`` itself when it holds scene files, else its sub-folders that do (sorted)."""
    if any(_SCENE_RE.match(p.name) for p in directory.iterdir()):
        return [directory]
    return sorted(p for p in directory.iterdir()
                  if p.is_dir() and any(_SCENE_RE.match(f.name) for f in p.iterdir()))


#: What the warning of a request says whose values lie just outside their joint bounds (:func:`load_mbm_dir`
#: gathers these warnings into one).
_ON_BOUND = "values just outside their joint bounds"


def load_mbm_dir(
    directory: PathLike,
    classes: Optional[Sequence[str]] = None,
    limit: Optional[int] = None,
    robot: Any = None,
    mesh_checker: Any = None,
    skip: int = 0,
    invalid: Optional[List[Tuple[str, str]]] = None,
) -> List[Problem]:
    """Every problem of a MotionBenchMaker folder, sorted by class then number.

    Args:
        directory: a class folder (``sceneNNNN.yaml`` / ``requestNNNN.yaml`` pairs) or a folder of class
            folders (e.g. ``shared/mbm``).
        classes: keep only these classes (names or aliases, see :func:`canonical_class`; folders with
            other names are kept only when listed verbatim).
        limit: at most this many problems per class (the first ones by number, after ``skip``).
        robot: shared by all problems (default :meth:`gfcs.Robot.panda`).
        mesh_checker: shared by all problems (default: as :func:`load_mbm`).
        skip: leave out the first ``skip`` problems of each class (by number), e.g. ``skip=40`` keeps the
            test problems 41-50 of the GFCS split (train on 1-40, test on 41-50).
        invalid: when a list, problems that cannot be loaded (a malformed file: any :class:`gfcs.GfcsError`),
            whose start or goal lies outside ``robot``'s joint limits, or whose
            pose goal has no valid joint configuration (:class:`gfcs.pose_goal.PoseGoalError`), are left
            out and appended to it as (name, message) instead of raising (MotionBenchMaker's URDF lets
            joint 4 of the Panda reach 0.0873 rad, Franka's limits and :meth:`gfcs.Robot.panda` -0.0698).

    Raises:
        FileNotFoundError: ``directory`` does not exist, or a scene has no matching request.
        gfcs.InvalidValueError: a start or goal outside the joint limits (without ``invalid``).
        gfcs.pose_goal.PoseGoalError: a pose goal without a valid joint configuration (without ``invalid``).
        ValueError: no problems found (the message says where it looked), or every one left out.
    """
    import gfcs

    root = Path(directory)
    if not root.is_dir():
        raise MissingFileError(f"problem folder not found: {root}")
    wanted = None
    if classes:
        wanted = set()
        for c in classes:
            wanted.add(str(c))
            try:
                wanted.add(canonical_class(c))
            except ValueError:
                pass
    robot = gfcs.Robot.panda() if robot is None else robot
    caught: List[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            problems, left_out = _load_classes(root, wanted, skip, limit, robot, mesh_checker, invalid)
    finally:  # outside the recording: the warnings reach the caller's filters
        _rewarn_gathered(caught, root)
    if not problems and left_out:
        raise InvalidValueError(f"every MotionBenchMaker problem under {root} has its start or goal outside the joint "
                                f"limits of robot '{robot.name}', or a pose goal it cannot take ({len(left_out)} "
                                f"problem(s); first: {left_out[0]})")
    if not problems:
        raise InvalidValueError(f"no MotionBenchMaker problems (sceneNNNN.yaml + requestNNNN.yaml) under {root}"
                                + (f" for classes {sorted(wanted)}" if wanted else ""))
    return problems


def _rewarn_gathered(caught: List[warnings.WarningMessage], root: Path) -> None:
    """Issue the warnings ``caught`` while loading the folder ``root`` again, those of requests with values
    just outside their joint bounds as one warning that counts them (a robot whose bounds are ±3.14159 gets
    one for most requests of MoveIt's rounding)."""
    import gfcs

    on_bound = []
    for w in caught:
        if issubclass(w.category, gfcs.errors.GfcsWarning) and _ON_BOUND in str(w.message):
            on_bound.append(w)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if len(on_bound) == 1:
        warnings.warn_explicit(on_bound[0].message, on_bound[0].category, on_bound[0].filename, on_bound[0].lineno)
    elif on_bound:
        warnings.warn(f"{root}: {len(on_bound)} requests hold {_ON_BOUND} (by at most {BOUNDS_TOLERANCE} rad or m), "
                      f"planned on the bound; the first: {on_bound[0].message}", gfcs.errors.GfcsWarning, stacklevel=3)


def _load_classes(root: Path, wanted: Optional[set], skip: int, limit: Optional[int], robot: Any, mesh_checker: Any,
                  invalid: Optional[List[Tuple[str, str]]]) -> Tuple[List[Problem], List[str]]:
    """(problems, messages of those left out) of the class folders under ``root`` (see :func:`load_mbm_dir`)."""
    import gfcs

    problems: List[Problem] = []
    left_out: List[str] = []
    for class_dir in _class_dirs(root):
        if wanted is not None and class_dir.name not in wanted:
            continue
        scenes = sorted((int(m.group(1)), p) for p in class_dir.iterdir() if (m := _SCENE_RE.match(p.name)))
        scenes = scenes[max(int(skip), 0):]
        if limit is not None:
            scenes = scenes[: max(int(limit), 0)]
        for number, scene_path in scenes:
            digits = _SCENE_RE.match(scene_path.name).group(1)  # type: ignore[union-attr]
            request = next((class_dir / f"request{digits}{ext}" for ext in (".yaml", ".yml")
                            if (class_dir / f"request{digits}{ext}").is_file()), None)
            if request is None:
                raise MissingFileError(f"{scene_path}: no matching request{digits}.yaml")
            try:  # a problem that cannot be loaded (malformed file, values outside the limits) is left out
                problems.append(Problem(**_mbm_fields(scene_path, request, robot, f"{class_dir.name}/{digits}",
                                                      class_dir.name, mesh_checker)))
            except (gfcs.GfcsError, _pose_goal.PoseGoalError) as e:
                if invalid is None:
                    raise
                invalid.append((f"{class_dir.name}/{digits}", str(e)))
                left_out.append(str(e))
    return problems, left_out


def _mbm_folder(path: Optional[PathLike]) -> Path:
    """The ``mbm_panda`` folder: ``path``, or ``shared_dir()/robots/mbm_panda``."""
    if path is not None:
        return Path(path)
    base = shared_dir()
    if base is None:
        raise MissingFileError(f"shared data folder not found at {_default_shared()} "
                               "(set GFCS_SHARED to its location)")
    return base / "robots" / "mbm_panda"


#: The mesh checker of each robot model :func:`mbm_panda` built (weakly keyed by the robot object: an entry
#: lives as long as its robot).
_MESH_CHECKERS: "weakref.WeakKeyDictionary[Any, Any]" = weakref.WeakKeyDictionary()


#: Spheres inscribed in the MBM Panda's collision meshes where its spherized model leaves them uncovered
#: (``tools/fill_sphere_gaps.py``; link frames, m), and the :func:`sphere_fingerprint` of the model they were
#: made for (``"for_spheres"``); :func:`with_gap_spheres` adds them to that model only.
MBM_GAP_SPHERES = Path(__file__).with_name("data") / "mbm_panda_gap_spheres.json"


def sphere_fingerprint(robot: Any) -> str:
    """SHA-256 (hex) of a robot's collision spheres: link names, centres (link frames) and radii to 1 µm,
    in model order. Two models with the same fingerprint have the same sphere model."""
    lines = [f"{link} {c[0]:.6f} {c[1]:.6f} {c[2]:.6f} {r:.6f}"
             for link, c, r in zip(robot.sphere_links, robot.sphere_centers_local, robot.sphere_radii)]
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()


def _robot_spheres(robot: Any) -> List[Tuple[str, List[float], float]]:
    """``robot``'s collision spheres as ``Robot.with_spheres`` takes them: (link, centre in its frame m, radius m)."""
    return [(link, [float(x) for x in c], float(r))
            for link, c, r in zip(robot.sphere_links, robot.sphere_centers_local, robot.sphere_radii)]


def _file_spheres(entries: Any) -> List[Tuple[str, List[float], float]]:
    """The ``spheres`` entries of a sphere file ({link, center, radius}) as ``Robot.with_spheres`` takes them."""
    return [(s["link"], [float(x) for x in s["center"]], float(s["radius"])) for s in entries]


def with_gap_spheres(robot: Any, gaps: PathLike = MBM_GAP_SPHERES) -> Any:
    """``robot`` with the gap spheres of ``gaps`` (a ``tools/fill_sphere_gaps.py`` file) added, when its
    sphere model is the one they were made for (same :func:`sphere_fingerprint`); else ``robot`` itself.

    By default: the 22 spheres inscribed in the MBM Panda's meshes, added to MotionBenchMaker's
    ``panda_spherized.urdf`` however it is loaded (:func:`mbm_panda`, or ``gfcs solve --robot`` with that
    file).

    Raises:
        ValueError: ``gaps`` is not such a file (the message names it).
    """
    try:
        data = json.loads(Path(gaps).read_text())
        made_for, spheres = data["for_spheres"], data["spheres"]
        extra = _file_spheres(spheres)
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise InvalidValueError(f"{gaps}: not a gap-sphere file (for_spheres, spheres[link, center, radius]): "
                                f"{e}") from e
    if sphere_fingerprint(robot) != made_for:
        return robot
    return robot.with_spheres(_robot_spheres(robot) + extra)


@functools.lru_cache(maxsize=None)
def _mbm_models(folder: str, fill_gaps: bool = True) -> Tuple[Any, Any]:
    """(spherized robot, mesh checker or None) of one ``mbm_panda`` folder, built once per folder; the
    model with gap spheres is derived from the one without, sharing its mesh checker."""
    import gfcs

    if fill_gaps:
        plain, checker = _mbm_models(folder, False)
        robot = with_gap_spheres(plain)
    else:
        root = Path(folder)
        urdf, srdf = root / "panda_spherized.urdf", root / "panda.srdf"
        for f in (urdf, srdf):
            if not f.is_file():
                raise MissingFileError(f"MBM Panda file not found: {f}")
        robot = gfcs.Robot.from_urdf(str(urdf), ee_link="panda_hand", srdf=str(srdf), mesh_dir=str(root))
        checker = mbm_mesh_checker(root)
    if checker is not None:
        _MESH_CHECKERS[robot] = checker
    return robot, checker


def mbm_mesh_checker(path: Optional[PathLike] = None) -> Any:
    """A :class:`gfcs.MeshChecker` of the MBM Panda's collision meshes, or None without ``panda.urdf``.

    Built from ``panda.urdf`` (collision meshes under ``meshes/collision``, resolved with ``mesh_dir`` = the
    folder) with the same SRDF as :func:`mbm_panda`; its joints match that robot's.

    Args:
        path: the ``mbm_panda`` folder; default ``shared_dir()/robots/mbm_panda``.

    Raises:
        FileNotFoundError: no folder given and the shared data folder is missing.
        gfcs.MeshError: ``panda.urdf`` names a mesh file that is missing or malformed.
    """
    root = _mbm_folder(path)
    urdf, srdf = root / "panda.urdf", root / "panda.srdf"
    if not urdf.is_file():
        return None
    return _mesh_checker(urdf, root, srdf if srdf.is_file() else None)


def _mesh_checker(urdf: Path, mesh_dir: Optional[PathLike], srdf: Optional[PathLike],
                  active_joints: Optional[Sequence[str]] = None) -> Any:
    import gfcs

    robot = gfcs.Robot.from_urdf(str(urdf), mesh_dir=str(mesh_dir or urdf.parent), active_joints=active_joints,
                                 srdf=None if srdf is None else str(srdf))
    return gfcs.MeshChecker(robot)


def urdf_mesh_checker(urdf: PathLike, robot: Any, mesh_dir: Optional[PathLike] = None,
                      srdf: Optional[PathLike] = None) -> Any:
    """A :class:`gfcs.MeshChecker` of the collision geometry (meshes and primitives) in ``urdf``, for
    validating trajectories of ``robot`` (e.g. ``robot`` from a spherized model, ``urdf`` the mesh model).

    Args:
        urdf: URDF file with the collision geometry.
        robot: the robot that moves; its active joints (e.g. those of a planning group) are the checker's,
            the URDF's other movable joints locked.
        mesh_dir: directory resolving ``package://`` mesh paths (default: the URDF's folder).
        srdf: SRDF whose disabled collisions prune the self-collision pairs (as for ``robot``).

    Raises:
        ValueError: the URDF's joints differ from ``robot``'s (the message names both).
        gfcs.IoError / gfcs.FormatError / gfcs.MeshError: unreadable URDF, missing or malformed mesh file.
    """
    checker = _mesh_checker(Path(urdf), mesh_dir, srdf, active_joints=list(robot.joint_names))
    if list(checker.joint_names) != list(robot.joint_names):
        raise InvalidValueError(f"{urdf}: joints {list(checker.joint_names)} differ from robot '{robot.name}''s "
                                f"{list(robot.joint_names)}")
    return checker


#: Collision geometry of a URDF other than spheres: what a mesh checker validates against.
_SOLID_GEOMETRY = ("mesh", "box", "cylinder", "capsule")


def _has_solid_collisions(urdf: Path) -> bool:
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(urdf).getroot()
    except (ET.ParseError, OSError) as e:
        raise InvalidValueError(f"{urdf}: cannot read URDF XML: {e}") from e
    return any(shape.tag in _SOLID_GEOMETRY for collision in root.iter("collision")
               for geometry in collision.iter("geometry") for shape in geometry)


def mesh_urdf_for(urdf: PathLike) -> Optional[Path]:
    """The URDF whose collision geometry validates trajectories of a robot loaded from ``urdf``.

    ``urdf`` itself when one of its ``<collision>`` elements is a mesh, box, cylinder or capsule (the robot's
    spheres are then fitted or given separately); for a spherized model (sphere collisions only) the URDF
    beside it named without the ``_spherized`` suffix, MotionBenchMaker's layout (``panda_spherized.urdf``
    next to ``panda.urdf``), when that one has such geometry; otherwise None.

    Raises:
        ValueError: ``urdf`` or that neighbour is not readable URDF XML (the message names the file).
    """
    path = Path(urdf)
    if _has_solid_collisions(path):
        return path
    if path.stem.endswith("_spherized"):
        plain = path.with_name(path.stem[: -len("_spherized")] + path.suffix)
        if plain.is_file() and _has_solid_collisions(plain):
            return plain
    return None


def spherized_urdf_for(urdf: PathLike) -> Optional[Path]:
    """The spherized model beside a URDF: ``X_spherized.urdf`` next to ``X.urdf`` (MotionBenchMaker's
    layout), when it exists and ``urdf`` is not itself spherized; otherwise None."""
    path = Path(urdf)
    if path.stem.endswith("_spherized"):
        return None
    sibling = path.with_name(path.stem + "_spherized" + path.suffix)
    return sibling if sibling.is_file() else None


def links_without_spheres(robot: Any) -> List[str]:
    """The links of ``robot`` whose collision geometry (``collision_geometry()``) has other elements than
    spheres (meshes, boxes, cylinders) and that carry no collision sphere, in link order. A description that
    models a few parts by spheres (the Fetch's head) and the rest by meshes is a mesh model, not a sphere
    model: its sphere elements leave the arm without any."""
    carried = set(robot.sphere_links)
    shaped = {e["link"] for e in robot.collision_geometry() if e["type"] != "sphere"}
    return [link for link in robot.link_names if link in shaped and link not in carried]


def with_shipped_panda_spheres(robot: Any, srdf: Optional[Union[PathLike, str]] = None,
                               samples: int = 8, tol: float = 1e-6) -> Optional[Any]:
    """``robot`` with the collision spheres of :meth:`gfcs.Robot.panda`, when it has none of its own and is
    a Panda: the same active joints, every link that carries a shipped sphere, and those links move exactly
    as the shipped Panda's do (link poses within ``tol`` m and rad at ``samples`` seeded configurations
    inside both robots' joint limits). The fingers are exempt from the pose check: the shipped spheres sit
    in their link frames, wherever a URDF holds or fixes the finger joints. Otherwise None.

    The shipped spheres cover the Franka collision meshes (``tools/fit_spheres.py``, every vertex inside),
    so such a URDF (e.g. a Franka description with meshes and no spherized twin) runs the fabric on them
    and is validated on its own meshes. Self-collision pairs: pruned by ``srdf`` (path or XML text) when
    given, else by the shipped Panda's SRDF (:func:`gfcs.panda_srdf`).
    """
    import gfcs

    if len(robot.sphere_radii) > 0:
        return None
    shipped = gfcs.Robot.panda()
    if list(robot.joint_names) != list(shipped.joint_names):
        return None
    links = sorted(set(shipped.sphere_links))
    if not set(links) <= set(robot.link_names):
        return None
    # the links that move with the shipped Panda's locked joints (the fingers): exempt from the check
    opened = shipped.with_locked_positions({j: v - 0.01 for j, v in shipped.locked_positions.items()})
    zero = np.zeros((1, shipped.dof))
    moves = np.abs(opened.link_poses(zero)[0] - shipped.link_poses(zero)[0]).max(axis=(1, 2)) > tol
    links = [link for link in links if not moves[shipped.link_index(link)]]
    lower = np.maximum(robot.lower, shipped.lower)
    upper = np.minimum(robot.upper, shipped.upper)
    if np.any(lower > upper):
        return None
    q = np.random.default_rng(0).uniform(lower, upper, size=(samples, len(lower)))
    mine, theirs = robot.link_poses(q), shipped.link_poses(q)
    for link in links:
        if np.max(np.abs(mine[:, robot.link_index(link)] - theirs[:, shipped.link_index(link)])) > tol:
            return None
    return robot.with_spheres(_robot_spheres(shipped)).with_srdf(gfcs.panda_srdf() if srdf is None else srdf)


def mesh_checker_for(robot: Any) -> Any:
    """The mesh checker of ``robot``: the one :func:`mbm_panda` attached to its robot, the shipped Panda's
    collision polytopes (:func:`shipped_panda_checker`, its fingers where ``robot`` holds them) for the
    shipped Panda, None for any other robot."""
    checker = _MESH_CHECKERS.get(robot)
    if checker is not None:
        return checker
    if _moves_as_shipped_panda(robot):
        return held_as_requested(shipped_panda_checker(), robot.locked_positions)
    return None


#: The shipped Panda's collision polytopes, one OBJ per link (``tools/fit_hulls.py``; link frames, m).
PANDA_HULLS = Path(__file__).with_name("data") / "panda_hulls"

#: The link pair the shipped SRDF disables for the covering spheres only: at folded-wrist configurations
#: (joint 6 near its lower limit) link7's mesh reaches link5's — their polytopes overlap at 6 % of uniform
#: samples of the joint box — but the covering spheres of the two links overlap at 39 of
#: MotionBenchMaker's 694 start and goal states, whose meshes keep 20 mm or more apart. The polytope
#: checker and the thin spheres (whose two links keep 12 mm or more apart at those states) check it.
PANDA_WRIST_PAIR = ("panda_link5", "panda_link7")


def panda_srdf_with_wrist_pair() -> str:
    """The shipped SRDF (:func:`gfcs.panda_srdf`) without its ``disable_collisions`` of
    :data:`PANDA_WRIST_PAIR`, for collision models that can tell that pair apart."""
    import xml.etree.ElementTree as ET

    import gfcs

    root = ET.fromstring(gfcs.panda_srdf())
    for element in list(root.iter("disable_collisions")):
        if {element.get("link1"), element.get("link2")} == set(PANDA_WRIST_PAIR):
            root.remove(element)
    return ET.tostring(root, encoding="unicode")


@functools.lru_cache(maxsize=None)
def shipped_panda_checker() -> Any:
    """A :class:`gfcs.MeshChecker` of the shipped Panda (:meth:`gfcs.Robot.panda`, fingers at 0.04 m) whose
    collision shapes are the convex polytopes of :data:`PANDA_HULLS`: each contains its link's Franka
    collision mesh and exceeds that mesh's convex hull by at most 2.7 mm (``tools/fit_hulls.py``: up to
    146 planes per link, fitted to the hull's facets), where the covering spheres the fabric uses reach up
    to 33 mm beyond the mesh. A motion whose polytopes keep ``m`` from the obstacles keeps at least ``m``
    with the Franka meshes. Self-collision shape pairs follow the shipped SRDF, with
    :data:`PANDA_WRIST_PAIR` checked (the Franka meshes of those links can touch). Built once.

    Raises:
        FileNotFoundError: the polytope files are missing from the installation.
    """
    import gfcs

    files = sorted(PANDA_HULLS.glob("*.obj"))
    if not files:
        raise MissingFileError(f"the shipped Panda's collision polytopes are missing: no <link>.obj in "
                               f"{PANDA_HULLS} (a broken installation: reinstall gfcs)")
    text = gfcs.panda_urdf()
    for obj in files:
        element = f'<link name="{obj.stem}"/>'
        if element not in text:
            raise InvalidValueError(f"{obj}: the shipped Panda has no link {obj.stem!r}")
        text = text.replace(element, f'<link name="{obj.stem}"><collision><geometry><mesh filename='
                                     f'"{obj.name}"/></geometry></collision></link>')
    shipped = _shipped_panda()[0]
    robot = gfcs.Robot.from_urdf(text, base_link=shipped.link_names[0], ee_link="panda_hand",
                                 active_joints=shipped.joint_names, mesh_dir=str(PANDA_HULLS),
                                 srdf=panda_srdf_with_wrist_pair())
    return gfcs.MeshChecker(robot.with_locked_positions(shipped.locked_positions))


@functools.lru_cache(maxsize=None)
def _shipped_panda() -> Tuple[Any, str]:
    """The shipped Panda and its :func:`sphere_fingerprint`, built once (robots are immutable)."""
    import gfcs

    shipped = gfcs.Robot.panda()
    return shipped, sphere_fingerprint(shipped)


def _moves_as_shipped_panda(robot: Any, samples: int = 8, tol: float = 1e-9,
                            links: Optional[Sequence[str]] = None) -> bool:
    """Whether ``robot`` is the shipped Panda up to its locked joints' positions: the same sphere model,
    joints, limits and link poses (``samples`` seeded configurations, to ``tol`` m). With ``links``, only
    the sphere model, the joints and the poses of those links count (other links, limits and locked
    joints may differ, as in a Franka description given the shipped spheres)."""
    shipped, fingerprint = _shipped_panda()
    if robot.joint_names != shipped.joint_names or sphere_fingerprint(robot) != fingerprint:
        return False
    if links is None:
        same_limits = np.array_equal(robot.lower, shipped.lower) and np.array_equal(robot.upper, shipped.upper)
        if robot.link_names != shipped.link_names or not same_limits:
            return False
        mine = robot.with_locked_positions(shipped.locked_positions) if robot.locked_positions else robot
        links = list(shipped.link_names)
    elif not set(links) <= set(robot.link_names):
        return False
    else:
        mine = robot
    q = np.random.default_rng(0).uniform(shipped.lower, shipped.upper, size=(samples, shipped.dof))
    at = [list(mine.link_names).index(name) for name in links]
    ref = [list(shipped.link_names).index(name) for name in links]
    return bool(np.max(np.abs(mine.link_poses(q)[:, at] - shipped.link_poses(q)[:, ref])) <= tol)


#: Thin collision spheres for the shipped Panda's links 5-7 and hand, in their link frames (m): fitted by
#: ``tools/fit_spheres.py ../shared/robots/mbm_panda/panda.urdf --links panda_link5 panda_link6 panda_link7
#: panda_hand --gap 0.008 --max-per-link 16 --max-total 48``; they miss the Franka collision meshes by at most
#: 8.3 mm and reach at most 22.9 mm beyond them (the covering spheres: 33.0 mm). See :func:`thin_sphere_model`.
PANDA_THIN_SPHERES = Path(__file__).with_name("data") / "panda_thin_spheres.json"


def thin_sphere_model(robot: Any) -> Optional[Any]:
    """``robot`` with the spheres of the links in :data:`PANDA_THIN_SPHERES` replaced by those thin ones,
    when it has the shipped Panda's covering spheres and joints and moves those links as the shipped
    Panda does (the shipped Panda itself, or a Franka description given its spheres by
    :func:`with_shipped_panda_spheres`, whatever its limits and fingers), else None. Self-collision pairs
    follow the shipped SRDF, with :data:`PANDA_WRIST_PAIR` checked (:func:`panda_srdf_with_wrist_pair`).

    The covering spheres of the forearm, wrist and hand reach up to 33 mm beyond the Franka meshes and
    close gaps the meshes pass through (MotionBenchMaker's cage: 15 of 50 unsolved with them, every retry
    included). A fabric on the thin spheres passes, while its motions can bring a mesh up to 8 mm nearer an
    obstacle than the spheres: :func:`gfcs.optimize.solve` keeps them a wider margin from obstacles
    (:data:`gfcs.optimize.THIN_SPHERE_MARGIN`), and the collision polytopes (:func:`shipped_panda_checker`)
    judge the motion.
    """
    thin = _file_spheres(json.loads(PANDA_THIN_SPHERES.read_text())["spheres"])
    links = {link for link, _, _ in thin}
    if not _moves_as_shipped_panda(robot, links=sorted(links)):
        return None
    kept = [sphere for sphere in _robot_spheres(robot) if sphere[0] not in links]
    return robot.with_spheres(kept + thin).with_srdf(panda_srdf_with_wrist_pair())


def mbm_panda(path: Optional[PathLike] = None, fill_gaps: bool = True) -> Any:
    """The Panda model MotionBenchMaker problems were made for (spherized URDF + SRDF, EE panda_hand).

    The spherized model's 59 spheres leave parts of the collision meshes uncovered, up to 62 mm on
    link5, 32-37 mm on links 1-4 and 19 mm on link6, and the fabric avoids obstacles with the spheres
    only. With ``fill_gaps`` (default) the model gets the 22 spheres of :data:`MBM_GAP_SPHERES`, inscribed
    in the meshes of links 1-6 and the fingers (``tools/fill_sphere_gaps.py``): they lie inside the
    meshes (by 1 mm), so a configuration whose meshes are clear stays clear for them, and the largest gaps
    fall to 12-20 mm. Link6's mesh is not convex, so it gets four; they cost no measurable time per
    fabric step. Their effect on success and hand paths: docs/tuning.md.

    The model is built once per folder and shared (robots are immutable). When the folder also holds the
    mesh model ``panda.urdf``, a :class:`gfcs.MeshChecker` of its collision meshes is attached: see
    :func:`mesh_checker_for`; :func:`load_mbm` and :func:`load_mbm_dir` give it to their problems.

    Args:
        path: the ``mbm_panda`` folder (``panda_spherized.urdf``, ``panda.srdf``, optionally ``panda.urdf``
            and ``meshes/``); default ``shared_dir()/robots/mbm_panda``.
        fill_gaps: add the inscribed gap spheres (False: the spherized URDF's spheres only). They were
            made for MotionBenchMaker's ``panda.urdf`` meshes and ``panda_spherized.urdf``, and another
            model in that layout does not get them (:func:`with_gap_spheres`); make its own with
            ``tools/fill_sphere_gaps.py``.

    Raises:
        FileNotFoundError: the folder or its files are missing.
        gfcs.MeshError: ``panda.urdf`` exists but names a missing or malformed mesh file.
    """
    return _mbm_models(str(_mbm_folder(path).resolve()), bool(fill_gaps))[0]
