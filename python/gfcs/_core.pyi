"""Type stubs of the compiled extension ``gfcs._core`` (Rust, PyO3).

Conventions: SI units (m, rad, s); arrays are float64 numpy arrays, C-contiguous, row-major; any
array-like convertible to float64 is accepted as input. Shapes are given in the docstrings: ``dof`` is
``Robot.dof``, ``L`` the number of links, ``S`` the number of collision spheres, ``N`` a batch size.
Signed distance is positive outside obstacles. A pose is a (4, 4) homogeneous matrix or a pair
``(position (3,), quaternion (4,) [x, y, z, w])``. Frames: every pose and position is in the robot base
frame (= world frame of the scene).

Errors (see ``gfcs.errors``): wrong shapes raise ``ShapeError`` naming the argument and the expected
shape; NaN/inf raise ``NonFiniteError``; unknown links/joints ``LinkError``; malformed files
``UrdfError`` / ``FormatError`` / ``MeshError`` / ``IoError``; out-of-range values ``InvalidValueError``.
"""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, TypedDict, Union

from typing_extensions import Unpack

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
PathLike = Union[str, "os.PathLike[str]"]
Pose = Union[ArrayLike, Tuple[ArrayLike, ArrayLike]]
LinkRef = Union[str, int]

__version__: str
#: The ``header.frame_id`` values that mean the planning frame (the robot's root frame), besides the root
#: link's own name: accepted for a scene's collision objects and for pose goals.
PLANNING_FRAMES: Tuple[str, ...]

# --------------------------------------------------------------------------------------------- errors

class GfcsError(Exception):
    """Base class of every gfcs error; a Rust panic surfaces as ``GfcsError("internal error: ...")``."""

class UrdfError(GfcsError):
    """Malformed or inconsistent URDF."""

class LinkError(GfcsError, KeyError):
    """Unknown link or joint name (or link index out of range)."""

class MeshError(GfcsError, OSError):
    """Missing or unreadable mesh file."""

class ShapeError(GfcsError, ValueError):
    """Array of the wrong shape (message: ``"<arg>: expected shape (7,) or (N, 7), got (3,)"``)."""

class NonFiniteError(GfcsError, ValueError):
    """NaN or infinite input (message names the argument)."""

class FormatError(GfcsError, ValueError):
    """Malformed field in a data file (message: ``"<file>: field '<dotted.path>': ..."``)."""

class InvalidValueError(GfcsError, ValueError):
    """Value outside its valid range (negative radius, zero time step, unknown option, ...)."""

ConfigError = InvalidValueError

class IoError(GfcsError, OSError):
    """I/O failure on a path."""

class GfcsWarning(UserWarning):
    """Input accepted but not fully applied (a MoveIt field, SRDF entries for links the robot lacks), or an
    argument adjusted (a thread count above 4 x the cores)."""

def _raise_internal_panic() -> None:
    """Test hook: panics in Rust; raises ``GfcsError("internal error: ...")``."""

def _raise_core_error(variant: str) -> None:
    """Test hook: raises the exception mapped from the core error ``variant`` (e.g. "MissingLink")."""

# ---------------------------------------------------------------------------------------------- robot

def panda_urdf() -> str:
    """The URDF text of the shipped Panda (``Robot.panda()``; its fingers are locked at 0.04 m there)."""

def panda_srdf() -> str:
    """The SRDF text of the shipped Panda: the self-collision pairs ``Robot.panda()`` disables."""

class Robot:
    """Immutable robot model: URDF kinematic tree, active joints (q order), limits, collision spheres
    (centres in link frames) and self-collision sphere pairs."""

    @staticmethod
    def panda() -> Robot:
        """The shipped Franka Emika Panda: 7 dof, base ``panda_link0``, end effector ``panda_hand``."""
    @staticmethod
    def from_urdf(
        path_or_xml: Union[PathLike, str],
        base_link: Optional[str] = None,
        ee_link: Optional[str] = None,
        active_joints: Optional[Sequence[str]] = None,
        mesh_dir: Optional[PathLike] = None,
        srdf: Optional[Union[PathLike, str]] = None,
        spheres: Optional[Union[PathLike, Sequence[Tuple[LinkRef, ArrayLike, float]]]] = None,
    ) -> Robot:
        """Load from a URDF path or XML text (a string starting with ``<``).

        ``spheres``: JSON sphere file ``{"spheres": [{"link", "center", "radius"}]}`` or a list of
        ``(link, centre (3,) m in the link frame, radius m)``; replaces URDF ``<collision><sphere>``.
        ``srdf``: path or XML; its ``<disable_collisions>`` prune the self-collision pairs.
        """
    def with_spheres(self, spheres: Union[PathLike, Sequence[Tuple[LinkRef, ArrayLike, float]]]) -> Robot:
        """A copy with other collision spheres (self-collision pairs recomputed)."""
    def with_srdf(self, srdf: Union[PathLike, str]) -> Robot:
        """A copy whose self-collision pairs follow the SRDF (path or XML text)."""
    def with_disabled_pairs(self, pairs: Sequence[Tuple[str, str]]) -> Robot:
        """A copy whose self-collision checks also leave out these (link, link) pairs, besides the SRDF's
        (``LinkError`` for an unknown link)."""
    def with_locked_positions(self, positions: Dict[str, float]) -> Robot:
        """A copy with inactive joints held at other positions {joint: rad or m} (e.g. a gripper opened as a
        request's start state says), rebuilt from the same URDF; collision spheres and self-collision pairs
        kept. ``LinkError`` for an unknown joint, ``InvalidValueError`` for an active, fixed or mimic one."""
    @property
    def locked_positions(self) -> Dict[str, float]:
        """{joint: position} of the inactive movable joints that are not mimic joints (rad or m)."""
    @property
    def name(self) -> str: ...
    @property
    def dof(self) -> int:
        """Number of active joints (length of q)."""
    @property
    def joint_names(self) -> List[str]:
        """Active joint names, in q order."""
    @property
    def link_names(self) -> List[str]:
        """All link names (index = link index; base link first)."""
    @property
    def lower(self) -> FloatArray:
        """(dof,) lower joint limits, rad or m."""
    @property
    def upper(self) -> FloatArray:
        """(dof,) upper joint limits, rad or m."""
    @property
    def velocity_limits(self) -> FloatArray:
        """(dof,) velocity limits, rad/s or m/s (inf when absent)."""
    @property
    def continuous(self) -> npt.NDArray[np.bool_]:
        """(dof,) bool: URDF ``continuous`` joints (no position limits; ``lower`` / ``upper`` of ∓2π are their
        sampling range). A revolute joint whose limits happen to be ∓2π is not."""
    @property
    def ee_link(self) -> str: ...
    @property
    def base_link(self) -> str: ...
    def link_index(self, name: str) -> int:
        """Index of a link in ``link_names`` (``LinkError`` if absent)."""
    @property
    def sphere_radii(self) -> FloatArray:
        """(S,) collision sphere radii, m."""
    @property
    def sphere_links(self) -> List[str]:
        """Link name of each collision sphere (length S)."""
    @property
    def sphere_centers_local(self) -> FloatArray:
        """(S, 3) sphere centres in their link frames, m."""
    @property
    def self_collision_pairs(self) -> IntArray:
        """(P, 2) int64 sphere index pairs (i < j) checked for self-collision."""
    def self_clearance(self, q: ArrayLike) -> FloatArray:
        """Self-collision clearance [m] of the spheres: min over ``self_collision_pairs`` of
        ‖c_a − c_b‖ − r_a − r_b (negative: overlap; +inf without pairs); () for q (dof,), (N,) for (N, dof)."""
    def link_poses(self, q: ArrayLike) -> FloatArray:
        """World poses of every link: (L, 4, 4) for q (dof,), (N, L, 4, 4) for q (N, dof)."""
    def sphere_centers(self, q: ArrayLike) -> FloatArray:
        """World sphere centres: (S, 3) for q (dof,), (N, S, 3) for q (N, dof), m."""
    def ee_position(self, q: ArrayLike) -> FloatArray:
        """End-effector link origin: (3,) for q (dof,), (N, 3) for q (N, dof), m."""
    def inverse_kinematics(
        self, q_init: ArrayLike, positions: ArrayLike, link: Optional[LinkRef] = None,
        axes: Optional[ArrayLike] = None, iterations: Optional[int] = None, damping: Optional[float] = None,
        tolerance: Optional[float] = None, axis_weight: Optional[float] = None,
    ) -> FloatArray:
        """Damped least-squares IK of ``link``'s origin (default the end-effector link) from ``q_init``
        (dof,) or (N, dof) to ``positions`` (3,) or (N, 3) m, optionally with the link's x and z axes
        along ``axes`` (2, 3) or (N, 2, 3): e = [p* − p; w (x* − x); w (z* − z)], w = ``axis_weight`` m,
        Δq = Jᵀ (J Jᵀ + damping I)⁻¹ e, clipped into the limits; at most ``iterations`` steps, fewer when
        ‖e‖ < ``tolerance``; None: the core's defaults (30 steps, 1e-3 m², 1e-5, 0.3 m). Returns (dof,) or
        (N, dof); batches run in parallel."""
    def point_ik(
        self, q: ArrayLike, position: ArrayLike, link: Optional[LinkRef] = None,
        point: Optional[ArrayLike] = None, axis: Optional[ArrayLike] = None,
        approach: Optional[ArrayLike] = None, cone_deg: float = 25.0, lower: Optional[ArrayLike] = None,
        upper: Optional[ArrayLike] = None, iterations: Optional[int] = None, damping: Optional[float] = None,
        tolerance: Optional[float] = None, axis_weight: Optional[float] = None, max_step: Optional[float] = None,
    ) -> Tuple[FloatArray, bool]:
        """One damped least-squares descent from ``q`` (dof,) of the point ``point`` (3,) m of ``link``
        (default: the end-effector link's origin) to ``position`` (3,) m, and with ``approach`` (3,) of the
        link axis ``axis`` (default z) toward it within ``cone_deg`` degrees (0-180, default 25): e = [x* − x; w (a* − R·axis)],
        Δq = Jᵀ (J Jᵀ + damping I)⁻¹ e scaled to ≤ ``max_step`` rad, clipped into [lower, upper] (default
        the joint limits). None: 150 steps, damping 0.0025 m², tolerance 2e-3 m, w 0.5, max_step 0.3.
        Returns (q, converged)."""
    def point_jacobian(self, q: ArrayLike, link: LinkRef, point: Optional[ArrayLike] = None) -> FloatArray:
        """(3, dof) Jacobian ∂x/∂q of the point ``point`` (3,) (default origin) fixed in ``link``."""
    def point_jdot_qdot(
        self, q: ArrayLike, qd: ArrayLike, link: LinkRef, point: Optional[ArrayLike] = None
    ) -> FloatArray:
        """(3,) J̇q̇ of a link-fixed point (ẍ = J q̈ + J̇q̇, GF eq. 11-12), m/s²."""
    def axis_jacobian(self, q: ArrayLike, link: LinkRef, axis: ArrayLike) -> FloatArray:
        """(3, dof) Jacobian of the world direction R_link · axis."""
    def axis_jdot_qdot(self, q: ArrayLike, qd: ArrayLike, link: LinkRef, axis: ArrayLike) -> FloatArray:
        """(3,) J̇q̇ of the world direction R_link · axis."""
    def collision_geometry(self) -> List[Dict[str, Any]]:
        """URDF ``<collision>`` elements: dicts ``link`` (str), ``type`` ("mesh" | "box" | "cylinder" |
        "capsule" | "sphere"), ``origin`` (4, 4) in the link frame, ``size`` ((3,) full box edges;
        (2,) [length, radius]; (1,) [radius]; None for meshes), ``path`` (resolved mesh path or None),
        ``scale`` ((3,) or None), ``exists`` (bool)."""

# ---------------------------------------------------------------------------------------------- scene

class Scene:
    """Obstacles with poses and linear velocities (world frame) and signed-distance queries."""

    def __init__(self) -> None: ...
    @staticmethod
    def from_moveit_yaml(path: PathLike, root_frame: Optional[str] = None) -> Scene:
        """MoveIt PlanningScene YAML (MotionBenchMaker): box = full sizes, cylinder = [height, radius],
        quaternions [x, y, z, w]. Objects with several shapes give obstacles ``id/0``, ``id/1``, ...
        An object's ``header.frame_id`` must be absent, "world", "/world" or ``root_frame`` (the robot's
        root link); ``robot_state.attached_collision_objects`` must be empty (gfcs.FormatError)."""
    @staticmethod
    def from_moveit_yaml_str(text: str, source: str = "<string>", root_frame: Optional[str] = None) -> Scene: ...
    def add_sphere(
        self, center: ArrayLike, radius: float, name: Optional[str] = None, velocity: Optional[ArrayLike] = None
    ) -> int:
        """Sphere of ``radius`` m at ``center`` (3,) m. Returns the obstacle id."""
    def add_box(
        self, size: ArrayLike, pose: Optional[Pose] = None, name: Optional[str] = None,
        velocity: Optional[ArrayLike] = None,
    ) -> int:
        """Box of FULL edge lengths ``size`` (3,) m centred at the pose origin."""
    def add_cylinder(
        self, height: float, radius: float, pose: Optional[Pose] = None, name: Optional[str] = None,
        velocity: Optional[ArrayLike] = None,
    ) -> int:
        """Cylinder of full ``height`` along the local z axis, centred at the pose origin."""
    def add_capsule(
        self, height: float, radius: float, pose: Optional[Pose] = None, name: Optional[str] = None,
        velocity: Optional[ArrayLike] = None,
    ) -> int:
        """Capsule: segment of length ``height`` along local z swept by a ball of ``radius``."""
    def add_halfspace(
        self, normal: Optional[ArrayLike] = None, offset: float = 0.0, pose: Optional[Pose] = None,
        name: Optional[str] = None,
    ) -> int:
        """Half-space {p : n·p <= offset} (free side +n), or the solid z <= 0 of ``pose``."""
    def add_mesh(
        self, mesh: Union[PathLike, Tuple[ArrayLike, ArrayLike]], pose: Optional[Pose] = None,
        name: Optional[str] = None, scale: Optional[ArrayLike] = None, velocity: Optional[ArrayLike] = None,
    ) -> int:
        """Triangle mesh from an .obj/.stl/.dae path or (vertices (V, 3), faces (F, 3)); solid when closed."""
    def add_point_cloud(
        self, points: ArrayLike, radius: float = 0.0, pose: Optional[Pose] = None, name: Optional[str] = None,
        velocity: Optional[ArrayLike] = None,
    ) -> int:
        """Point cloud (P, 3) m in the pose frame, each point thickened by ``radius``."""
    def remove(self, id: int) -> Dict[str, Any]:
        """Remove an obstacle; returns its description."""
    def set_pose(self, id: int, pose: Pose) -> None: ...
    def set_velocity(self, id: int, velocity: ArrayLike) -> None:
        """Linear velocity (3,) m/s, world frame."""
    def advance(self, dt: float) -> None:
        """Move every obstacle by velocity · dt."""
    def ids(self) -> List[int]: ...
    def obstacles(self) -> List[Dict[str, Any]]:
        """Dicts ``id``, ``name``, ``type`` ("sphere" | "box" | "cylinder" | "capsule" | "half_space" |
        "mesh" | "point_cloud"), ``size`` (box (3,) full edges; cylinder/capsule [height, radius]; sphere
        [radius]; mesh [vertices, triangles]; point cloud [points, radius]), ``pose`` (4, 4),
        ``velocity`` (3,)."""
    def get(self, id: int) -> Dict[str, Any]: ...
    def __len__(self) -> int: ...
    def signed_distance(self, points: ArrayLike) -> Union[FloatArray, float]:
        """Minimum signed distance (m): (N,) for points (N, 3), float for one point (3,); inf if empty."""
    def distance_details(self, point: ArrayLike, max_distance: float = ...) -> List[Dict[str, Any]]:
        """Obstacles within ``max_distance`` of ``point`` (3,), sorted: dicts ``obstacle`` (id),
        ``distance``, ``gradient`` (3,) ∂d/∂p, ``hessian`` (3, 3), ``velocity`` (3,)."""
    def surface_points(self, spacing: float) -> FloatArray:
        """(P, 3) points on the obstacle surfaces about ``spacing`` m apart."""
    def copy(self) -> Scene: ...
    def __copy__(self) -> Scene: ...
    def __deepcopy__(self, memo: Any) -> Scene: ...

def load_motion_plan_request(path: PathLike) -> Dict[str, Any]:
    """MoveIt MotionPlanRequest YAML: ``{"group": str, "start": {joint: pos}, "goal": {joint: pos},
    "pose_goal": None | dict, "ignored": [str]}``. ``goal`` is empty for a pose goal (``goal_constraints[0]`` with position and
    optionally orientation constraints): ``pose_goal`` then has ``link``, ``frame`` (``header.frame_id``,
    "" when absent), ``offset`` (3,) m in the link frame, ``region`` (list of ``{"type": "box" | "sphere" |
    "cylinder", "size", "pose" (4, 4)}`` in ``frame``, sizes as :attr:`Scene.obstacles`) and
    ``orientation`` (None or ``{"quaternion": (4,) [x, y, z, w], "tolerance": (3,) rad,
    "parameterization": "xyz_euler" | "rotation_vector"}``). ``ignored``: field paths of the constraints
    that are not applied (non-empty ``path_constraints.*``, ``trajectory_constraints.constraints``, and
    ``goal_constraints[1..]``: only the first goal is used)."""

# --------------------------------------------------------------------------------------------- config

class FabricConfig:
    """Fabric gains (GF Sec. VII-A, App. E-B). ``FabricConfig(d)`` merges the nested dict ``d`` over the
    defaults; sections: mode, joint_attraction, ee_position, ee_orientation, joint_limits,
    self_collision, obstacles, speed."""

    def __init__(self, values: Optional[Dict[str, Any]] = None) -> None: ...
    @staticmethod
    def defaults() -> FabricConfig: ...
    @staticmethod
    def from_file(path: PathLike) -> FabricConfig:
        """.toml, .yaml/.yml or .json by extension; missing fields keep their defaults."""
    @staticmethod
    def from_dict(values: Dict[str, Any]) -> FabricConfig: ...
    @staticmethod
    def from_str(text: str, format: str = "toml", source: str = "<string>") -> FabricConfig: ...
    def to_dict(self) -> Dict[str, Any]: ...
    def to_json(self) -> str: ...
    def replace(self, changes: Optional[Dict[str, Any]] = None, **kwargs: Any) -> FabricConfig:
        """A copy with nested changes merged in."""
    def __eq__(self, other: object) -> bool: ...

# ---------------------------------------------------------------------------------------------- fabric

class Rollout:
    """One rollout toward one command (GFCS eq. 1-3); arrays empty when not recorded."""

    @property
    def t(self) -> FloatArray:
        """(T,) times, s."""
    @property
    def q(self) -> FloatArray:
        """(T, dof) configurations."""
    @property
    def qd(self) -> FloatArray:
        """(T, dof) velocities."""
    @property
    def qdd(self) -> FloatArray:
        """(T, dof) accelerations applied from each row to the next."""
    @property
    def t_star(self) -> float:
        """t* = min(t, t_max), s (eq. 2)."""
    @property
    def t_end(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def reason(self) -> str:
        """"reached" | "timeout" | "non_finite" | "stalled" (no progress toward the command over the stall window: counted as not reached)."""
    @property
    def reached(self) -> bool: ...
    @property
    def min_distance(self) -> float:
        """Closest approach ‖q − command‖ over the states, rad (below tol when reached)."""
    @property
    def min_clearance(self) -> float:
        """Minimum over the states of min(sphere-obstacle, self-collision) clearance, m (< 0: collision)."""
    @property
    def q_final(self) -> FloatArray: ...
    @property
    def qd_final(self) -> FloatArray: ...
    def __len__(self) -> int: ...

class SequenceRollout:
    """One command sequence (GFCS eq. 4-8): n free commands then the goal."""

    @property
    def t(self) -> FloatArray: ...
    @property
    def q(self) -> FloatArray: ...
    @property
    def qd(self) -> FloatArray: ...
    @property
    def qdd(self) -> FloatArray: ...
    @property
    def cost(self) -> float:
        """Σ tᵢ* + (penalty + distance_penalty·goal_distance)·[goal not reached]
        + collision_penalty·[collided], s (eq. 4, 8)."""
    @property
    def goal_distance(self) -> float:
        """Closest approach ‖q − goal‖ of the final rollout, rad (below tol when reached)."""
    @property
    def t_stars(self) -> FloatArray:
        """(n + 1,) tᵢ*, s."""
    @property
    def reasons(self) -> List[str]: ...
    @property
    def reached(self) -> bool: ...
    @property
    def success(self) -> bool:
        """Reached without collision."""
    @property
    def collided(self) -> bool:
        """min_clearance < -collision_tol."""
    @property
    def min_clearance(self) -> float: ...
    @property
    def q_final(self) -> FloatArray: ...
    @property
    def qd_final(self) -> FloatArray: ...
    def __len__(self) -> int: ...

class Rmpflow:
    """RMPflow (Cheng et al. 2018) of a robot in a scene (held by value): the GF Sec. VII comparison
    controller on the fabric's robot, scene and task maps. ``config``: a nested dict merged over
    :meth:`defaults` (sections cspace_target, joint_limits, target, obstacles, self_collision, damping);
    unknown fields and negative gains raise ``FormatError`` naming the field."""

    def __init__(self, robot: Robot, scene: Optional[Scene] = None, config: Optional[Dict[str, Any]] = None) -> None: ...
    @staticmethod
    def defaults() -> Dict[str, Any]:
        """Every gain with its default (the hand-designed Franka RMPflow of RMP²)."""
    @property
    def config(self) -> Dict[str, Any]: ...
    @property
    def robot(self) -> Robot: ...
    @property
    def dof(self) -> int: ...
    @property
    def scene(self) -> Scene:
        """A copy of the policy's scene."""
    def set_scene(self, scene: Scene) -> None:
        """Replace the scene (copied)."""
    def update_obstacle(self, id: int, pose: Optional[Pose] = None, velocity: Optional[ArrayLike] = None) -> None:
        """Move / set the velocity of an obstacle of the policy's scene."""
    def acceleration(
        self, q: ArrayLike, qd: ArrayLike, command: ArrayLike, ee_target: Optional[Pose] = None
    ) -> FloatArray:
        """(dof,) q̈ = M⁺f, rad/s²: posture toward ``command``, hand toward the position of ``ee_target``
        (default: the hand position at ``command``), joint limits, collisions, damping."""
    def diagnostics(self) -> Optional[Dict[str, float]]:
        """Of the last ``acceleration`` call: min_clearance, min_self_clearance, min_joint_margin, leaves."""
    def rollout(
        self, q0: ArrayLike, qd0: Optional[ArrayLike], command: ArrayLike, ee_target: Optional[Pose] = None,
        record: bool = True, **options: Unpack[RolloutOptions],
    ) -> Rollout:
        """rollout_t (GFCS eq. 1-3) as :meth:`Fabric.rollout`, the hand aimed at ``ee_target`` if given."""
    def evaluate(
        self, q0: ArrayLike, qd0: Optional[ArrayLike], goal: ArrayLike, candidates: ArrayLike,
        threads: Optional[int] = None, return_trajectories: bool = False, **options: Unpack[SequenceOptions],
    ) -> Union[
        Tuple[FloatArray, BoolArray, FloatArray],
        Tuple[FloatArray, BoolArray, FloatArray, List[SequenceRollout]],
    ]:
        """Candidates (N, n·dof) under RMPflow, as :meth:`Fabric.evaluate`."""

class Fabric:
    """Geometric fabric of a robot in a scene (held by value). Construction and ``set_scene`` raise
    ``InvalidValueError`` (a ``ValueError``) for a robot without collision spheres in a scene with
    obstacles while the obstacle barrier is enabled: the barrier acts on the spheres only."""

    def __init__(
        self, robot: Robot, scene: Optional[Scene] = None,
        config: Optional[Union[FabricConfig, Dict[str, Any], PathLike]] = None,
    ) -> None: ...
    @property
    def robot(self) -> Robot: ...
    @property
    def config(self) -> FabricConfig: ...
    @property
    def dof(self) -> int: ...
    @property
    def scene(self) -> Scene:
        """A copy of the fabric's scene."""
    def set_scene(self, scene: Scene) -> None:
        """Replace the scene (copied); the same check as the constructor."""
    def update_obstacle(self, id: int, pose: Optional[Pose] = None, velocity: Optional[ArrayLike] = None) -> None:
        """Move / set the velocity of an obstacle of the fabric's scene."""
    def with_obstacle_margins(self, margins: Optional[ArrayLike]) -> Fabric:
        """A copy (same robot, configuration, scene) whose obstacle barrier uses one margin per robot sphere:
        ``margins`` (S,) m in the order of ``robot.sphere_radii``, each > −radius (negative: the sphere may
        sink into obstacles by that much), replacing ``config.obstacles.margin``; None: the configured one."""
    @property
    def obstacle_margins(self) -> Optional[FloatArray]:
        """(S,) m of :meth:`with_obstacle_margins`, or None (the configured margin for every sphere)."""
    def with_self_margins(self, margins: Optional[ArrayLike]) -> Fabric:
        """A copy whose self-collision barrier uses one margin per sphere pair: ``margins`` (P,) m in the order
        of ``robot.self_collision_pairs``, each > −(r_a + r_b), replacing ``config.self_collision.margin``;
        None: the configured one."""
    @property
    def self_margins(self) -> Optional[FloatArray]:
        """(P,) m of :meth:`with_self_margins`, or None (the configured margin for every pair)."""
    def with_joint_scales(self, scales: Optional[ArrayLike]) -> Fabric:
        """A copy whose joint attractor (GF VII-A1) acts on x = S (q − q_g), S = diag(``scales``) (dof,),
        each > 0 (units of x per rad or per m; :func:`gfcs.joints.velocity_scales`: v_ref / v_i); None: S = I."""
    @property
    def joint_scales(self) -> Optional[FloatArray]:
        """(dof,) scales of :meth:`with_joint_scales`, or None (S = I, the paper's attractor)."""
    def acceleration(
        self, q: ArrayLike, qd: ArrayLike, command: ArrayLike, ee_target: Optional[Pose] = None
    ) -> FloatArray:
        """(dof,) q̈ = f(q, q̇; command) (GFCS eq. 1), rad/s². ``ee_target``: the end-effector link's target
        pose for its attractors (default: its pose at ``command``); with ``config.speed.goal_space`` "ee"
        the goal damper switches on the hand's distance to that target [m] instead of ‖q − command‖
        (task-space reaching, GF Sec. VII: ``command`` then only postures the arm)."""
    def diagnostics(self, potential: bool = True) -> Optional[Dict[str, float]]:
        """Of the last ``acceleration`` call: energy, exec_energy, potential, min_clearance,
        min_self_clearance, min_joint_margin, alpha_le, alpha_ex0, alpha_expsi, eta, s_beta, beta,
        alpha_boost, alpha_reg, leaves. The forcing potential ψ is evaluated here at the last call's state
        (one more fabric evaluation); ``potential=False`` skips it (``potential`` is then NaN)."""
    def metric(self) -> Optional[FloatArray]:
        """(dof, dof) root metric M̃ of the last successful ``acceleration`` call (GF eq. 17), or None before it."""
    def rollout(
        self, q0: ArrayLike, qd0: Optional[ArrayLike], command: ArrayLike, record: bool = True,
        **options: Unpack[RolloutOptions],
    ) -> Rollout:
        """rollout_t (GFCS eq. 1-3) from (q0, qd0) (``qd0`` None: rest) toward ``command`` (dof,) until
        ‖q − command‖ < tol or t_max. ``options``: :class:`RolloutOptions` (defaults:
        :func:`rollout_option_defaults`)."""
    def rollout_sequence(
        self, q0: ArrayLike, qd0: Optional[ArrayLike], commands: ArrayLike, goal: ArrayLike, record: bool = True,
        **options: Unpack[SequenceOptions],
    ) -> SequenceRollout:
        """Commands (n, dof) then the goal (dof,) (GFCS eq. 4-8). Cost: Σ tᵢ* + penalty + distance_penalty ×
        the closest approach to the goal, both when the goal is not reached, + collision_penalty when
        min_clearance < −collision_tol. At each handover the fabric's command moves to the next along a
        smoothstep over ``blend_time`` s (0 = the paper's jump). ``options``: :class:`SequenceOptions`."""
    def evaluate(
        self, q0: ArrayLike, qd0: Optional[ArrayLike], goal: ArrayLike, candidates: ArrayLike,
        threads: Optional[int] = None, return_trajectories: bool = False, **options: Unpack[SequenceOptions],
    ) -> Union[
        Tuple[FloatArray, BoolArray, FloatArray],
        Tuple[FloatArray, BoolArray, FloatArray, List[SequenceRollout]],
    ]:
        """Candidates (N, n·dof) -> (costs (N,), reached (N,) bool, min_clearance (N,)) [+ N
        SequenceRollout when ``return_trajectories``]; parallel, deterministic, GIL released.
        ``options``: :class:`SequenceOptions`."""

class RolloutOptions(TypedDict, total=False):
    """Keyword options of ``Fabric.rollout`` (GFCS eq. 1-3); None or absent: the core default
    (:func:`rollout_option_defaults`). ``gfcs.planning.RolloutSettings`` holds the same names."""

    dt: Optional[float]
    """integration step [s] (> 0)"""
    t_max: Optional[float]
    """time budget of the rollout [s]"""
    tol: Optional[float]
    """ε of eq. 3: reached when ‖q − command‖ < tol [rad]"""
    stall_window: Optional[float]
    """stop as "stalled" (t* = t_max) when ‖q − command‖ has not shrunk by ``stall_progress`` over this
    window [s] (0: off)"""
    stall_progress: Optional[float]
    """progress a window must make [rad]"""
    capture_tol: Optional[float]
    """goal capture [rad] (0: off): a stall within this distance of the command counts as reached, t* the
    time it stalled (a command tolerance looser than it, as a waypoint's, is not affected)"""
    integrator: Optional[str]
    """``"euler"`` (semi-implicit, the papers') or ``"rk4"``"""

class SequenceOptions(RolloutOptions, total=False):
    """Keyword options of ``Fabric.rollout_sequence`` and ``Fabric.evaluate`` (GFCS eq. 4-8): those of
    :class:`RolloutOptions` and these."""

    waypoint_tol: Optional[float]
    """hand-over tolerance of the intermediate commands [rad]"""
    penalty: Optional[float]
    """p of eq. 4/8, added when the goal is not reached [s]"""
    collision_penalty: Optional[float]
    """added when min_clearance < −collision_tol [s]"""
    collision_tol: Optional[float]
    """sphere overlap that does not count as a collision [m]"""
    distance_penalty: Optional[float]
    """added per rad of the closest approach to the goal when it is not reached [s/rad]"""
    blend_time: Optional[float]
    """smoothstep time of the command at each handover [s] (0: the paper's switch of eq. 7)"""

def max_threads() -> int:
    """The most worker threads a batch runs on (4 × the cores); a larger ``threads`` warns
    (``GfcsWarning``) and runs on this many."""

def rollout_option_defaults() -> Dict[str, Union[float, str]]:
    """The core's default of every option of :class:`SequenceOptions` (hence of :class:`RolloutOptions`),
    by name: the one set of defaults ``gfcs.planning.RolloutSettings`` starts from."""

class MeshChecker:
    """Clearance of a robot's URDF collision meshes and primitives (not its spheres), m.

    ``MeshChecker(robot, max_distance=0.5)`` loads every ``<collision>`` element once (``MeshError`` naming
    the file and link for a missing mesh; ``InvalidValueError`` for a robot without collision geometry).
    Clearances above ``max_distance`` are reported as ``inf``.
    """

    def __init__(self, robot: Robot, max_distance: float = 0.5) -> None: ...
    @property
    def num_shapes(self) -> int:
        """Number of collision shapes S."""
    @property
    def shape_links(self) -> List[str]:
        """(S,) link name of each shape."""
    @property
    def num_self_pairs(self) -> int:
        """Shape pairs checked by ``self_clearance`` (non-adjacent, not disabled by the SRDF)."""
    @property
    def max_distance(self) -> float: ...
    @property
    def dof(self) -> int: ...
    @property
    def joint_names(self) -> List[str]: ...
    @property
    def robot(self) -> Robot: ...
    def clearance(
        self, scene: Scene, q: ArrayLike, threads: Optional[int] = None, cutoff: Optional[float] = None
    ) -> Union[float, FloatArray]:
        """q (dof,) -> float, q (T, dof) -> (T,): min distance of the shapes to the scene, m (≤ 0: contact;
        inf: nothing within max_distance). Trajectories in parallel, GIL released. With ``cutoff`` [m] a value
        is exact only below it (some value at or above it otherwise): cheaper away from contact."""
    def self_clearance(
        self, q: ArrayLike, threads: Optional[int] = None, cutoff: Optional[float] = None
    ) -> Union[float, FloatArray]:
        """q (dof,) -> float, q (T, dof) -> (T,): min distance over the self-collision shape pairs, m (negative:
        penetration depth); ``cutoff`` as in :meth:`clearance`."""
    def shape_clearances(
        self, scene: Scene, q: ArrayLike, threads: Optional[int] = None, cutoff: Optional[float] = None
    ) -> FloatArray:
        """q (dof,) -> (S,), q (T, dof) -> (T, S): clearance of each collision shape (``shape_links`` order) to
        the scene, m; exact below ``cutoff`` (None: ``max_distance``), inf where no obstacle lies that near; the
        row minimum is :meth:`clearance`."""
    def pair_clearances(
        self, q: ArrayLike, threads: Optional[int] = None, cutoff: Optional[float] = None, depth: bool = True
    ) -> FloatArray:
        """q (dof,) -> (P,), q (T, dof) -> (T, P): distance of each checked self-collision shape pair
        (``self_pair_links`` order), m; negative penetration depth in contact (``depth=False``: 0 for two
        meshes in contact that are not both convex, a verdict without the costly depth), inf beyond ``cutoff``;
        the row minimum is :meth:`self_clearance`."""
    @property
    def self_pair_links(self) -> List[Tuple[str, str]]:
        """(link a, link b) of each checked self-collision shape pair, in :meth:`pair_clearances` order."""
    def self_contacts(self, q: ArrayLike, within: float = 0.0, depth: bool = True) -> List[Tuple[str, str, float]]:
        """The checked self-collision shape pairs nearer than ``within`` m (≥ 0) at q (dof,): (link a, link b,
        distance m), nearest first; ≤ 0 in contact (negative: penetration depth; ``depth=False``: 0 for two
        meshes in contact that are not both convex, a verdict without the costly depth)."""
    def held_contacts(self, q: ArrayLike, within: float = 0.0, depth: bool = True) -> List[Tuple[str, str, float]]:
        """The link pairs that joints outside the active joints (locked at their held values) hold still
        relative to each other, nearer than ``within`` m (≥ 0) at q (dof,): (link a, link b, distance m), nearest
        first. No motion changes them; one in contact puts every state in collision, as MoveIt checks it."""
    def adjacent_contacts(self, q: ArrayLike, within: float = 0.0, depth: bool = True) -> List[Tuple[str, str, float]]:
        """The link pairs on adjacent rigid bodies (one movable joint between them) that the robot's SRDF leaves
        enabled, nearer than ``within`` m (≥ 0) at q (dof,): (link a, link b, distance m), nearest first. The
        planner does not measure them; MoveIt checks them. Empty without an SRDF."""
    def min_clearance(
        self, scene: Scene, q: ArrayLike, threads: Optional[int] = None, cutoff: Optional[float] = None
    ) -> float:
        """min over the states of q (T, dof) of ``clearance``, m (equal to ``clearance(scene, q).min()``
        where that is ≤ ``cutoff`` m (None: always), faster: states farther than the closest of every
        eighth state are culled, and so are shape pairs beyond the cutoff); inf when nothing comes within
        the cutoff, and for T = 0."""
    def min_self_clearance(
        self, q: ArrayLike, threads: Optional[int] = None, cutoff: Optional[float] = None
    ) -> float:
        """min over the states of q (T, dof) of ``self_clearance``, m, as ``min_clearance``."""
    def sweep(
        self, scene: Scene, q: ArrayLike, margin: float = 0.001, threads: Optional[int] = None,
        time_limit: Optional[float] = None,
    ) -> Dict[str, Any]:
        """Continuous verdict on the path through the states of q (T, dof), straight between them: whether
        every configuration on it keeps the geometry more than ``margin`` m from the scene and itself (a
        motion bound certifies each segment; uncertified ones are halved). {ok, complete (False when
        ``time_limit`` s ran out), clearance, self_clearance (m, least measured; inf: none near), measured}."""

# ------------------------------------------------------------------------------------------- particles

def particle_acceleration(
    variant: str, q: ArrayLike, qd: ArrayLike, speed: Optional[float] = None, **params: Any
) -> FloatArray:
    """(2,) q̈ of a GF Sec. VI particle; variant "unbent_riemannian" | "unbent_finsler" |
    "bent_riemannian" | "bent_finsler"; params override ``particle_defaults()``."""

def particle_rollout(
    variant: str, speed: float, q0: ArrayLike, qd0: Optional[ArrayLike] = None, dt: Optional[float] = None,
    t_max: Optional[float] = None, tol: Optional[float] = None, integrator: str = "euler", **params: Any,
) -> Union[Rollout, List[Rollout]]:
    """Particles from q0 (2,) -> Rollout, or (N, 2) -> list of N Rollouts, toward the target."""

def particle_defaults() -> Dict[str, Any]:
    """Default particle parameters (GF Sec. VI set-up)."""
