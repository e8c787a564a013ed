"""Pose goals of MoveIt motion plan requests: the constraint check and the joint goal found for them.

A request whose ``goal_constraints[0]`` holds a position constraint (and optionally an orientation
constraint) on a link instead of joint constraints is a *pose goal* (``gfcs.load_motion_plan_request``
returns it as ``pose_goal``, see there for the dict). GFCS drives the fabric to a joint configuration, so
:func:`goal_configuration` turns the pose goal into one by inverse kinematics, before any planning; the
returned motion ends exactly there, so it satisfies the pose goal.

Semantics (MoveIt's ``PositionConstraint`` / ``OrientationConstraint``), every quantity in the planning
frame, which must be the robot's root frame (``header.frame_id`` "", "world", "/world" or the root link):

* position: the point ``offset`` [m] fixed in the link lies inside at least one ``region`` primitive (box
  of full edges ``size``, sphere [radius], cylinder [height, radius] along its local z) with its ``pose``;
  :func:`position_violation` is the distance [m] from the point to the nearest primitive (0 inside).
* orientation: with R* the target and R the link's rotation, D = R*ᵀ R expressed as XYZ Euler angles
  (D = Rx(a) Ry(b) Rz(c), ``"xyz_euler"``, MoveIt's default parameterization) or as a rotation vector
  (``"rotation_vector"``) stays within the per-axis ``tolerance`` [rad]; :func:`orientation_violation`
  is the largest excess [rad] (0 when within).

Which configuration: inverse kinematics from the start configuration and from ``attempts − 1`` seeded
random ones, half of them around the start (:data:`NEAR_START_SPREAD`), half uniform within the limits
(damped least squares in the core), kept when it satisfies the constraints (to
:data:`ACCEPT_SLACK`), lies :data:`LIMIT_INSET` inside the joint limits and clears the obstacles and its own
links by the default fabric margins plus :data:`CLEARANCE_SLACK` with its collision spheres (and by the mesh
margin with the collision meshes when a mesh checker is given): the fabric's barriers keep the arm out of
those margins, so a goal inside them could not be reached. With a mesh checker, when no solution keeps the
spheres that far from the obstacles, solutions whose meshes alone clear them are taken (a grasp: the
goal-contact attempt of :func:`gfcs.optimize.solve` reaches them). When none of ``attempts`` descents
gives a valid solution, three times as many more are tried; when those miss too, up to
:data:`EXPLORE_SOLUTIONS` of the solutions that meet the pose but not the limits or the clearances are walked
along their self-motion (a step toward a random configuration, then back onto the constraints by inverse
kinematics, :data:`REFINE_STEPS` times, toward :data:`EXPLORE_AIMS` random configurations each), every state
on the way a candidate (a goal deep in a cage: its solutions meet the pose on one stretch of the
self-motion and touch a bar on the rest). The nearest valid solutions are then walked along their
self-motion toward the start in the same way, and of all valid ones the nearest to the start in joint space
[rad] is the goal: the fabric's motion time grows with that distance.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Dict, List

import numpy as np

from gfcs import metrics as _metrics
from gfcs._core import PLANNING_FRAMES
from gfcs.errors import InvalidValueError, ShapeError

#: Slack [m or rad] on the constraints when accepting an inverse-kinematics solution (numerical noise).
ACCEPT_SLACK = 1e-6
#: Distance [rad] from the joint limits a goal must keep: the fabric's joint-limit margin (0.01 rad by
#: default) plus 0.01 rad.
LIMIT_INSET = 0.02
#: Clearance [m] a goal's collision spheres keep beyond the fabric's obstacle and self-collision margins.
CLEARANCE_SLACK = 0.001
#: Standard deviation [rad] of the starting configurations drawn around the start (half of them).
NEAR_START_SPREAD = 0.5
#: Solutions walked toward the start, steps and the fraction of the way to it per step (module docstring).
REFINE_SOLUTIONS, REFINE_STEPS, REFINE_RATE = 8, 20, 0.3
#: When no descent gives a valid solution: solutions meeting the pose that are walked along their
#: self-motion (toward this many random configurations each) in search of one inside the limits and clear.
EXPLORE_SOLUTIONS, EXPLORE_AIMS = 8, 8


def _rotation_matrix(quaternion_xyzw: Any) -> np.ndarray:
    x, y, z, w = np.asarray(quaternion_xyzw, dtype=np.float64) / np.linalg.norm(quaternion_xyzw)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def xyz_euler(d: np.ndarray) -> np.ndarray:
    """(a, b, c) [rad] with d = Rx(a) Ry(b) Rz(c), b in [−π/2, π/2]."""
    b = math.asin(max(-1.0, min(1.0, float(d[0, 2]))))
    return np.array([math.atan2(-d[1, 2], d[2, 2]), b, math.atan2(-d[0, 1], d[0, 0])])


def quaternion_xyzw(r: Any) -> np.ndarray:
    """Unit quaternions [x, y, z, w] of rotation matrices (Shepperd's method, branch on the largest term).

    Args:
        r: (..., 3, 3) rotation matrices.

    Returns:
        (..., 4) quaternions [x, y, z, w] with w ≥ 0.
    """
    m = np.asarray(r, dtype=np.float64)
    if m.shape[-2:] != (3, 3):
        raise ShapeError(f"r: expected shape (..., 3, 3), got {m.shape}")
    a = m.reshape(-1, 3, 3)
    d0, d1, d2 = a[:, 0, 0], a[:, 1, 1], a[:, 2, 2]
    # 4·x², 4·y², 4·z², 4·w² up to the factor; the largest is the best-conditioned pivot
    pivots = np.stack([1.0 + d0 - d1 - d2, 1.0 - d0 + d1 - d2, 1.0 - d0 - d1 + d2, 1.0 + d0 + d1 + d2], axis=1)
    case = np.argmax(pivots, axis=1)
    s = 2.0 * np.sqrt(np.maximum(pivots[np.arange(a.shape[0]), case], 1e-300))  # = 4 × pivot component
    xy, xz, yz = a[:, 0, 1] + a[:, 1, 0], a[:, 0, 2] + a[:, 2, 0], a[:, 1, 2] + a[:, 2, 1]  # 4xy, 4xz, 4yz
    wx, wy, wz = a[:, 2, 1] - a[:, 1, 2], a[:, 0, 2] - a[:, 2, 0], a[:, 1, 0] - a[:, 0, 1]  # 4wx, 4wy, 4wz
    quarter = 0.25 * s
    forms = [np.stack([quarter, xy / s, xz / s, wx / s], 1),   # pivot x
             np.stack([xy / s, quarter, yz / s, wy / s], 1),   # pivot y
             np.stack([xz / s, yz / s, quarter, wz / s], 1),   # pivot z
             np.stack([wx / s, wy / s, wz / s, quarter], 1)]   # pivot w
    q = np.choose(case[:, None], forms)
    q *= np.where(q[:, 3:4] < 0.0, -1.0, 1.0)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return q.reshape(m.shape[:-2] + (4,))


def rotation_vector(d: np.ndarray) -> np.ndarray:
    """Axis · angle [rad] of the rotation matrix d, angle in [0, π]."""
    q = quaternion_xyzw(d)
    v, w = q[:3], q[3]
    norm = float(np.linalg.norm(v))
    return np.zeros(3) if norm == 0.0 else v * (2.0 * math.atan2(norm, w) / norm)


def position_violation(pose_goal: Dict[str, Any], point: Any) -> float:
    """Distance [m] from ``point`` (3,) in the planning frame to the nearest region primitive (0 inside)."""
    p = np.asarray(point, dtype=np.float64)
    best = math.inf
    for r in pose_goal["region"]:
        pose = np.asarray(r["pose"], dtype=np.float64)
        local = pose[:3, :3].T @ (p - pose[:3, 3])
        size = np.asarray(r["size"], dtype=np.float64)
        if r["type"] == "box":
            outside = np.maximum(np.abs(local) - 0.5 * size, 0.0)
            d = float(np.linalg.norm(outside))
        elif r["type"] == "sphere":
            d = max(0.0, float(np.linalg.norm(local)) - size[0])
        else:  # cylinder [height, radius], axis local z
            radial = max(0.0, float(np.hypot(local[0], local[1])) - size[1])
            axial = max(0.0, abs(float(local[2])) - 0.5 * size[0])
            d = math.hypot(radial, axial)
        best = min(best, d)
    return best


def orientation_violation(pose_goal: Dict[str, Any], rotation: Any) -> float:
    """Largest excess [rad] of the error rotation's components over their tolerances (0: within; 0 when
    the goal has no orientation constraint). ``rotation``: (3, 3) the link's rotation in the planning frame."""
    o = pose_goal.get("orientation")
    if o is None:
        return 0.0
    d = _rotation_matrix(o["quaternion"]).T @ np.asarray(rotation, dtype=np.float64)
    angles = rotation_vector(d) if o["parameterization"] == "rotation_vector" else xyz_euler(d)
    return float(max(0.0, np.max(np.abs(angles) - np.asarray(o["tolerance"], dtype=np.float64))))


def target_point(pose_goal: Dict[str, Any]) -> np.ndarray:
    """The point (3,) [m] the inverse kinematics aims at: the centre of the region's first primitive."""
    return np.asarray(pose_goal["region"][0]["pose"], dtype=np.float64)[:3, 3]


def pose_errors(robot: Any, pose_goal: Dict[str, Any], q: Any) -> np.ndarray:
    """(position violation [m], orientation violation [rad]) of configuration(s) ``q`` (dof,) -> (2,),
    (N, dof) -> (N, 2)."""
    qa = np.atleast_2d(np.asarray(q, dtype=np.float64))
    link = robot.link_index(pose_goal["link"])
    poses = np.asarray(robot.link_poses(qa), dtype=np.float64)[:, link]
    offset = np.asarray(pose_goal["offset"], dtype=np.float64)
    out = np.array([[position_violation(pose_goal, T[:3, :3] @ offset + T[:3, 3]),
                     orientation_violation(pose_goal, T[:3, :3])] for T in poses])
    return out[0] if np.asarray(q).ndim == 1 else out


def check_frame(robot: Any, pose_goal: Dict[str, Any], source: str = "") -> None:
    """ValueError unless the goal's frame is the robot's root frame and its link is the robot's."""
    where = f"{source}: " if source else ""
    root = robot.link_names[0]
    if pose_goal["frame"] not in PLANNING_FRAMES + (root,):
        raise InvalidValueError(f"{where}pose goal frame '{pose_goal['frame']}' is not the planning frame of robot "
                                f"'{robot.name}' (its root link '{root}', or 'world')")
    if pose_goal["link"] not in robot.link_names:
        raise InvalidValueError(f"{where}pose goal link '{pose_goal['link']}' is not a link of robot '{robot.name}'")


def _ik_solver(robot: Any, pose_goal: Dict[str, Any], lo: np.ndarray,
               up: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``ik(qs (N, dof)) -> (N, dof)``: damped least-squares descents from each row toward the pose goal: the
    link origin's full pose when the goal has an orientation, else the goal's point on the link."""
    link = robot.link_index(pose_goal["link"])
    centre = target_point(pose_goal)
    offset = np.asarray(pose_goal["offset"], dtype=np.float64)
    o = pose_goal.get("orientation")
    if o is not None:  # the link origin's target follows from the point's and the rotation
        rot = _rotation_matrix(o["quaternion"])
        origin, axes = centre - rot @ offset, np.stack([rot[:, 0], rot[:, 2]])

        def ik(qs: np.ndarray) -> np.ndarray:
            n = qs.shape[0]
            return np.asarray(robot.inverse_kinematics(
                qs, np.tile(origin, (n, 1)), link=link, axes=np.tile(axes, (n, 1, 1)), iterations=300,
                damping=1e-4, tolerance=1e-9), dtype=np.float64)
        return ik

    def point_ik(qs: np.ndarray) -> np.ndarray:
        return np.array([robot.point_ik(s, centre, link=link, point=offset, lower=lo, upper=up,
                                        iterations=300, damping=1e-4, tolerance=1e-7, max_step=0.3)[0]
                         for s in qs])
    return point_ik


class _Sorter:
    """Sorts inverse-kinematics solutions into the valid tiers of :func:`goal_configuration`, counting why the
    others fail (``reasons``) and keeping those that meet the pose but not the limits or the clearances
    (``met``)."""

    def __init__(self, robot: Any, scene: Any, pose_goal: Dict[str, Any], mesh_checker: Any, fabric_config: Any,
                 lo: np.ndarray, up: np.ndarray) -> None:
        import gfcs

        margins = (gfcs.FabricConfig() if fabric_config is None else fabric_config).to_dict()
        self.clear = margins["obstacles"]["margin"] + CLEARANCE_SLACK
        self.self_clear = margins["self_collision"]["margin"] + CLEARANCE_SLACK
        self.robot, self.scene, self.pose_goal, self.mesh_checker = robot, scene, pose_goal, mesh_checker
        self.lo, self.up = lo, up
        self.reasons = {"constraints": 0, "limits": 0, "collision": 0}
        self.met: List[np.ndarray] = []

    def __call__(self, sols: np.ndarray) -> List[List[np.ndarray]]:
        """The valid solutions: [0: the spheres clear the obstacles by ``clear`` (and the meshes by the mesh
        margin, with a checker); 1: only the meshes clear the obstacles (the goal-contact attempt of
        :func:`gfcs.planning.solve` can reach it)]; both with the spheres ``self_clear`` apart."""
        robot, mesh_checker = self.robot, self.mesh_checker
        out: List[List[np.ndarray]] = [[], []]
        spheres_clear = _metrics.obstacle_clearance(robot, self.scene, sols) >= self.clear
        self_ok = _metrics.self_clearance(robot, sols) >= self.self_clear
        for q, err, free, apart in zip(sols, pose_errors(robot, self.pose_goal, sols), spheres_clear, self_ok):
            if not np.all(err <= ACCEPT_SLACK):
                self.reasons["constraints"] += 1
                continue
            if np.any(q < self.lo - 1e-12) or np.any(q > self.up + 1e-12):
                self.reasons["limits"] += 1
            elif apart and (mesh_checker is None or _metrics.mesh_verdict(mesh_checker, self.scene, q)[2]):
                if free or mesh_checker is not None:
                    out[0 if free else 1].append(q)
                    continue
                self.reasons["collision"] += 1
            else:
                self.reasons["collision"] += 1
            self.met.append(q)
        return out


def _no_solution(sorter: _Sorter, sols: np.ndarray, source: str) -> "PoseGoalError":
    """The error naming the link, the target and what the ``sols`` missed."""
    pose_goal = sorter.pose_goal
    errors = pose_errors(sorter.robot, pose_goal, sols)
    missed = ", ".join(f"{v} {k}" for k, v in sorter.reasons.items() if v)
    where = f"{source}: " if source else ""
    return PoseGoalError(
        f"{where}no joint configuration found for the pose goal of link '{pose_goal['link']}' (point "
        f"{np.round(target_point(pose_goal), 4).tolist()} m in frame '{pose_goal['frame'] or 'world'}'): of "
        f"{len(sols)} inverse-kinematics solutions, {missed} (best position error "
        f"{float(errors[:, 0].min()):.3g} m, orientation excess {float(errors[:, 1].min()):.3g} rad)")


def goal_configuration(
    robot: Any,
    scene: Any,
    q0: Any,
    pose_goal: Dict[str, Any],
    *,
    mesh_checker: Any = None,
    fabric_config: Any = None,
    attempts: int = 64,
    seed: int = 0,
    source: str = "",
) -> np.ndarray:
    """The joint goal [rad] (dof,) for a pose goal: the valid inverse-kinematics solution nearest to ``q0``
    (see the module docstring).

    Args:
        robot: a :class:`gfcs.Robot`; scene: a :class:`gfcs.Scene`; q0: (dof,) start [rad].
        pose_goal: the ``pose_goal`` dict of ``gfcs.load_motion_plan_request``.
        mesh_checker: a :class:`gfcs.MeshChecker` whose meshes must clear too (None: the spheres only).
        fabric_config: the fabric configuration whose margins the goal must clear (None: the defaults).
        attempts: inverse-kinematics descents (the first from ``q0``), ≥ 1.
        seed: seed of the other starting configurations.
        source: the request file, named in errors.

    Raises:
        InvalidValueError: a frame other than the robot's root or an unknown link.
        PoseGoalError: no valid solution (an InvalidValueError; the message names the link, the target and
            what the attempts missed).
    """
    check_frame(robot, pose_goal, source)
    if int(attempts) < 1:
        raise InvalidValueError(f"attempts must be >= 1, got {attempts}")
    q0 = np.asarray(q0, dtype=np.float64)
    lo = np.asarray(robot.lower, dtype=np.float64) + LIMIT_INSET
    up = np.asarray(robot.upper, dtype=np.float64) - LIMIT_INSET
    rng = np.random.default_rng(seed)
    ik = _ik_solver(robot, pose_goal, lo, up)
    tiers = _Sorter(robot, scene, pose_goal, mesh_checker, fabric_config, lo, up)
    dof = q0.shape[0]
    n = int(attempts) - 1
    near = q0 + rng.normal(0.0, NEAR_START_SPREAD, (n // 2, dof))
    sols = ik(np.clip(np.vstack([q0[None, :], near, rng.uniform(lo, up, (n - n // 2, dof))]), lo, up))
    found = tiers(sols)
    if not (found[0] or found[1]):  # a second round, three times as many
        more = ik(rng.uniform(lo, up, (3 * int(attempts), dof)))
        sols = np.vstack([sols, more])
        found = tiers(more)
    # a third: solutions that meet the pose but not the limits or the clearances, walked along their
    # self-motion toward random configurations, every state on the way a candidate, until one clears the
    # obstacles with its spheres
    if not (found[0] or found[1]) and min(len(tiers.met), EXPLORE_SOLUTIONS) > 0:
        met = np.asarray(tiers.met)
        seeds = met[rng.choice(len(met), size=min(len(met), EXPLORE_SOLUTIONS), replace=False)]
        aims = rng.uniform(lo, up, (len(seeds) * EXPLORE_AIMS, dof))
        walked = np.repeat(seeds, EXPLORE_AIMS, axis=0)
        for _ in range(REFINE_STEPS):
            walked = ik(np.clip(walked + REFINE_RATE * (aims - walked), lo, up))
            sols = np.vstack([sols, walked])
            found = [a + b for a, b in zip(found, tiers(walked))]
            if found[0]:
                break
    tier = 0 if found[0] else 1
    valid = found[tier]
    if not valid:
        raise _no_solution(tiers, sols, source)
    # walk the nearest solutions along their self-motion toward q0: a step toward it, then back onto the
    # constraints, REFINE_STEPS times; the walked ones that stay valid (in the same tier or better) compete
    valid.sort(key=lambda q: float(np.linalg.norm(q - q0)))
    walked = np.asarray(valid[:REFINE_SOLUTIONS])
    for _ in range(REFINE_STEPS):
        walked = ik(np.clip(walked + REFINE_RATE * (q0 - walked), lo, up))
    valid += [q for t in tiers(walked)[: tier + 1] for q in t]
    return min(valid, key=lambda q: float(np.linalg.norm(q - q0))).copy()


class PoseGoalError(InvalidValueError):
    """No joint configuration satisfies a pose goal within the limits and clear of the obstacles."""
