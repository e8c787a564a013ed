"""Trajectory quality metrics of the GFCS evaluation (GFCS Sec. V, Table I).

Pure numpy. Every function documents its array shapes; units are SI (m, rad, s).

* ``path_length``: Σ‖x_{k+1} − x_k‖ of a sampled path. Applied to joint positions (T, dof) it is the
  "C-space length" [rad] of Table I; applied to end-effector positions (T, 3) the "EE length" [m].
* ``log_dimensionless_jerk``: the smoothness measure of Hogan & Sternad (2009) used for "EE-LDJ" and
  "C-space-LDJ" (closer to zero is smoother).
* clearance of the robot's collision-sphere model against obstacles and against itself, joint-limit check,
  and ``trajectory_metrics``, which gathers everything Table I reports for one trajectory plus the success
  criterion (goal reached, no collision, joint limits respected).
* ``mesh_clearance``: the clearance of the robot's collision *meshes* (a :class:`gfcs.MeshChecker`), the
  model independent validators judge motions with; ``trajectory_metrics`` reports it (and the meshes'
  self-clearance) and requires both > 0 when given a checker.

The functions that need a robot or a scene (``obstacle_clearance``, ``self_clearance``,
``trajectory_metrics``) only use the documented methods of :class:`gfcs.Robot` and :class:`gfcs.Scene`
(``sphere_centers``, ``sphere_radii``, ``self_collision_pairs``, ``ee_position``, ``lower``, ``upper``,
``signed_distance``, ``len``) and of :class:`gfcs.MeshChecker` (``clearance``), so this module does not
import the compiled extension.
"""

from __future__ import annotations

import math
import time
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np

from gfcs.errors import InvalidValueError, NonFiniteError, ShapeError
from gfcs.joints import continuous_mask, joint_difference

__all__ = [
    "path_length",
    "dimensionless_jerk",
    "log_dimensionless_jerk",
    "within_limits",
    "sphere_clearances",
    "obstacle_clearance",
    "self_clearance",
    "mesh_clearance",
    "mesh_verdict",
    "uniform_resample",
    "link_path_lengths",
    "trajectory_metrics",
    "DEFAULT_SUCCESS_TOL",
    "DEFAULT_LIMIT_TOL",
    "DEFAULT_MESH_MARGIN",
    "INTERPOLATION_ALLOWANCE",
    "mesh_report_cutoff",
    "checked_indices",
    "checked_states",
]

#: Default tolerance [rad] on ‖q_T − q_goal‖ for a trajectory to count as reaching its goal: the default
#: rollout tolerance ε of GFCS eq. 3 (``RolloutOptions::tol`` in the core, :mod:`gfcs.optimize`).
DEFAULT_SUCCESS_TOL = 0.01
#: Default slack [rad] on the joint limits when checking a trajectory (round-off of the integrator).
DEFAULT_LIMIT_TOL = 1e-6
#: Relative slack on the velocity limits in the success criterion (rounding of the re-timed samples).
VELOCITY_RATIO_TOL = 1e-6
#: How far above the mesh margin [m] :func:`mesh_check` measures mesh clearances exactly; beyond it a
#: clearance is reported as +inf. Small, because the exact distances between detailed meshes cost more the
#: farther out they are measured.
MESH_REPORT_RANGE = 0.002
#: Resolution [rad or m, max over joints] at which collision checks visit a path (:func:`checked_states`):
#: half the 0.01 rad at which validators commonly interpolate a returned trajectory.
MESH_CHECK_STEP = 0.005
#: States of the first mesh-check call when a deadline bounds the check or an order puts the likely contacts
#: first (:func:`mesh_check`); each next call takes twice as many (with a deadline at most as many as the time
#: left allows at the rate measured so far, so that a check overruns its deadline by about one call of this
#: size at most).
MESH_CHECK_CHUNK = 8
#: Default clearance [m] the collision meshes must keep, from the obstacles and between links, at every
#: configuration of a trajectory (its states and the straight segments between them) for it to count as
#: collision-free when a mesh checker is given: above the round-off of distance codes, so that what passes
#: here passes other checkers of the same meshes.
DEFAULT_MESH_MARGIN = 1e-4
#: Clearance [m] beyond the margin that lets a state vouch for the path around it in :func:`mesh_check`:
#: a path whose checked states all keep the margin plus this passes without the continuous check
#: (:meth:`gfcs.MeshChecker.sweep`), which certifies the others segment by segment.
INTERPOLATION_ALLOWANCE = 0.001


def _non_negative(name: str, value: Any, unit: str) -> float:
    """``value`` as a float; ValueError naming ``name`` unless it is a finite number ≥ 0."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v >= 0):
        raise InvalidValueError(f"{name} must be a finite number ≥ 0{unit}, got {value}")
    return v


def _as_path(x: Any, name: str) -> np.ndarray:
    """``x`` as a float64 array of shape (T, k); a 1-D input (T,) becomes (T, 1)."""
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2:
        raise ShapeError(f"{name}: expected shape (T,) or (T, k), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise NonFiniteError(f"{name} contains NaN or infinite values")
    return a


def path_length(x: Any) -> float:
    """Length Σ_k ‖x_{k+1} − x_k‖₂ of the polyline through the samples ``x``.

    Args:
        x: (T, k) samples of a path (or (T,) for a scalar path). Joint positions give the C-space length
            [rad], end-effector positions (T, 3) the EE length [m] of GFCS Table I.

    Returns:
        The length (0.0 for fewer than two samples).
    """
    a = _as_path(x, "x")
    if a.shape[0] < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.diff(a, axis=0), axis=1)))


def dimensionless_jerk(x: Any, dt: float) -> float:
    """Dimensionless jerk DJ = (t₂ − t₁)³ / v_peak² · ∫ ‖x⃛(t)‖² dt of a path sampled every ``dt``.

    This is the peak-speed normalisation of Hogan & Sternad (2009) ("Sensitivity of smoothness measures to
    movement duration, amplitude, and arrests", J. Motor Behavior 41(6)), the form used by the LDJ of
    Balasubramanian et al. (2012, 2015). It is dimensionless: ∫‖x⃛‖²dt has units L²/s⁵, times s³,
    divided by v_peak² (L²/s²). (Writing (t₂ − t₁)⁵ with v_peak² would leave units of s², i.e. the value
    would depend on the time unit; (t₂ − t₁)⁵ goes with the amplitude A² instead of v_peak².)

    Discretisation: x⃛ from third forward differences (x_{k+3} − 3x_{k+2} + 3x_{k+1} − x_k)/dt³ (T − 3
    values; value k approximates x⃛ at t_{k+1.5} and stands for the step [t_{k+1}, t_{k+2}]), the
    integral as dt · (Σ_k ‖x⃛_k‖² + ‖x⃛_first‖² + ‖x⃛_last‖²), the two end steps [t₀, t₁] and [t_{T−2},
    t_{T−1}] taking the nearest value, so that the whole interval is covered (plain Σ·dt would leave an
    O(dt) bias: the jerk is often largest at the ends), v_peak = max_k ‖ẋ_k‖ with ẋ from central
    differences (``numpy.gradient``), t₂ − t₁ = (T − 1)·dt.

    Args:
        x: (T, k) positions (or (T,)) sampled uniformly at ``dt`` seconds.
        dt: sample period [s], > 0.

    Returns:
        DJ ≥ 0, or NaN when it is undefined (fewer than 4 samples, or no motion: v_peak = 0).
    """
    a = _as_path(x, "x")
    if not (math.isfinite(dt) and dt > 0.0):
        raise InvalidValueError(f"dt must be a positive finite number of seconds, got {dt!r}")
    n = a.shape[0]
    if n < 4:
        return math.nan
    v = np.gradient(a, dt, axis=0)
    v_peak = float(np.max(np.linalg.norm(v, axis=1)))
    if v_peak <= 0.0:
        return math.nan
    jerk = (a[3:] - 3.0 * a[2:-1] + 3.0 * a[1:-2] - a[:-3]) / dt**3
    j2 = np.sum(jerk * jerk, axis=1)
    integral = float((np.sum(j2) + j2[0] + j2[-1]) * dt)
    duration = (n - 1) * dt
    return duration**3 / v_peak**2 * integral


def log_dimensionless_jerk(x: Any, dt: float) -> float:
    """Log dimensionless jerk LDJ = −ln(DJ) (see :func:`dimensionless_jerk`); closer to 0 is smoother.

    A minimum-jerk point-to-point motion has DJ = 720 / 1.875² = 204.8, LDJ ≈ −5.322. It is not the largest
    LDJ of a single movement: minimum jerk minimises ∫‖x⃛‖² for a given duration and distance, while DJ
    also divides by the peak speed. A sin² speed profile has DJ = 2π⁴, LDJ ≈ −5.272, and a half-sine speed
    profile (which starts and ends with nonzero acceleration) DJ = π⁴/2, LDJ ≈ −3.886 (tested). More
    sub-movements make it more negative.

    Args:
        x: (T, k) positions (or (T,)) sampled uniformly at ``dt`` seconds.
        dt: sample period [s], > 0.

    Returns:
        LDJ, NaN when DJ is undefined (see :func:`dimensionless_jerk`), +inf when the jerk vanishes
        identically (DJ = 0, e.g. constant velocity).
    """
    dj = dimensionless_jerk(x, dt)
    if math.isnan(dj):
        return math.nan
    if dj <= 0.0:
        return math.inf
    return -math.log(dj)


def raw_ldj(robot: Any, raw_q: Any, dt: float) -> Dict[str, float]:
    """``raw_ee_ldj`` and ``raw_cspace_ldj``: the LDJ of the hand path and of the joint path of the fabric's own
    rollout ``raw_q`` (T, dof) sampled every ``dt`` s, before any finishing (start re-timing, goal blend,
    limit re-timing): how smooth the fabric's motion is, apart from what finishing adds or removes."""
    qa = _as_path(raw_q, "raw_q")
    ee = np.asarray(robot.ee_position(qa), dtype=np.float64).reshape(qa.shape[0], 3)
    return {"raw_ee_ldj": log_dimensionless_jerk(ee, dt), "raw_cspace_ldj": log_dimensionless_jerk(qa, dt)}


def within_limits(q: Any, lower: Any, upper: Any, tol: float = DEFAULT_LIMIT_TOL) -> bool:
    """True when every sample of ``q`` lies in [lower − tol, upper + tol].

    Args:
        q: (T, dof) or (dof,) joint positions [rad or m].
        lower, upper: (dof,) joint limits.
        tol: slack, ≥ 0.
    """
    qa = np.atleast_2d(np.asarray(q, dtype=np.float64))
    lo = np.asarray(lower, dtype=np.float64)
    up = np.asarray(upper, dtype=np.float64)
    if lo.shape != (qa.shape[1],) or up.shape != (qa.shape[1],):
        raise InvalidValueError(
            f"lower/upper: expected shape ({qa.shape[1]},), got {lo.shape} and {up.shape}"
        )
    return bool(np.all(qa >= lo - tol) and np.all(qa <= up + tol))


def velocity_ratio(t: Any, q: Any, limits: Any) -> float:
    """The largest ratio of a joint's finite-difference speed |q_{k+1} − q_k| / (t_{k+1} − t_k) to its
    velocity limit over a trajectory (0 for fewer than two samples or joints without a limit).

    Args:
        t: (T,) increasing times [s]; q: (T, dof) positions [rad or m].
        limits: (dof,) velocity limits [rad/s or m/s] (inf: none).
    """
    from gfcs.blend import first_difference_speed

    ta = np.asarray(t, dtype=np.float64).reshape(-1)
    qa = _as_path(q, "q")
    v = np.asarray(limits, dtype=np.float64).reshape(-1)
    if qa.shape[0] < 2:
        return 0.0
    return float(np.max(first_difference_speed(ta, qa) / v))


def sphere_clearances(robot: Any, scene: Any, q: Any) -> np.ndarray:
    """Clearance of each of the robot's collision spheres to the obstacles, per sample.

    clearance_ki = d(c_i(q_k)) − r_i, with d the scene's signed distance (positive outside) and c_i, r_i
    the centres and radii of the robot's collision spheres. Negative means penetration.

    Args:
        robot: a :class:`gfcs.Robot`.
        scene: a :class:`gfcs.Scene`.
        q: (T, dof) joint positions.

    Returns:
        (T, S) clearances [m] for the S spheres; +inf everywhere when the scene is empty.
    """
    qa = np.atleast_2d(np.asarray(q, dtype=np.float64))
    radii = np.asarray(robot.sphere_radii, dtype=np.float64)
    if len(scene) == 0 or radii.size == 0 or qa.shape[0] == 0:
        return np.full((qa.shape[0], radii.size), math.inf)
    centers = np.asarray(robot.sphere_centers(qa), dtype=np.float64).reshape(qa.shape[0], -1, 3)
    d = np.asarray(scene.signed_distance(centers.reshape(-1, 3)), dtype=np.float64)
    return d.reshape(qa.shape[0], radii.size) - radii[None, :]


def obstacle_clearance(robot: Any, scene: Any, q: Any) -> np.ndarray:
    """Per-sample clearance of the robot's collision spheres to the obstacles: the minimum over the spheres
    of :func:`sphere_clearances`.

    Returns:
        (T,) clearances [m]; +inf for every sample when the scene is empty or the robot has no spheres.
    """
    d = sphere_clearances(robot, scene, q)
    return d.min(axis=1) if d.shape[1] else np.full(d.shape[0], math.inf)


def self_clearance(robot: Any, q: Any) -> np.ndarray:
    """Per-sample clearance between the robot's self-collision sphere pairs.

    clearance_k = min_{(a,b) ∈ pairs} ‖c_a(q_k) − c_b(q_k)‖ − r_a − r_b over ``robot.self_collision_pairs``.

    Args:
        robot: a :class:`gfcs.Robot`.
        q: (T, dof) joint positions.

    Returns:
        (T,) clearances [m]; +inf when the robot has no self-collision pairs.
    """
    qa = np.atleast_2d(np.asarray(q, dtype=np.float64))
    if qa.shape[0] == 0:
        return np.zeros(0)
    return np.asarray(robot.self_clearance(qa), dtype=np.float64).reshape(qa.shape[0])  # in the core


def mesh_clearance(mesh_checker: Any, scene: Any, q: Any) -> np.ndarray:
    """Per-sample clearance of the robot's collision meshes to the obstacles.

    clearance_k = min over the URDF collision shapes of their distance to the scene at q_k (exact mesh
    distances, see :class:`gfcs.MeshChecker`); ≤ 0 means contact, +inf nothing within the checker's
    ``max_distance``.

    Args:
        mesh_checker: a :class:`gfcs.MeshChecker` (joints in the order of ``q``).
        scene: a :class:`gfcs.Scene`.
        q: (T, dof) joint positions.

    Returns:
        (T,) clearances [m].
    """
    qa = np.atleast_2d(np.asarray(q, dtype=np.float64))
    if qa.shape[0] == 0:
        return np.zeros(0)
    return np.asarray(mesh_checker.clearance(scene, qa), dtype=np.float64).reshape(qa.shape[0])


def mesh_report_cutoff(margin: float) -> float:
    """Distance [m] up to which :func:`mesh_check` measures mesh clearances exactly for ``margin``: the
    margin, :data:`INTERPOLATION_ALLOWANCE` and :data:`MESH_REPORT_RANGE`; beyond it a clearance reads +inf."""
    return float(margin) + INTERPOLATION_ALLOWANCE + MESH_REPORT_RANGE


def checked_indices(q: Any, step: float = MESH_CHECK_STEP) -> np.ndarray:
    """Indices (K,) of the rows of ``q`` (T, dof) a collision check visits: the first, the last, and each
    next one that lies at least ``step`` [rad or m, max over joints] from the last one visited. A slowly
    timed path (small steps) is checked at that resolution instead of at every time sample; a path whose
    samples lie farther apart keeps all of them."""
    qa = np.atleast_2d(np.asarray(q, dtype=np.float64))
    n = qa.shape[0]
    if n < 2:
        return np.arange(n, dtype=np.int64)
    steps = np.max(np.abs(np.diff(qa, axis=0)), axis=1)  # steps[k - 1]: row k − 1 to row k
    if n > 2 and np.all(steps[:-1] >= step):
        return np.arange(n, dtype=np.int64)  # every step is that long: every row is visited
    # Rows are compared with the last one visited only where the sum of the steps since then (an upper
    # bound of that distance, the triangle inequality, slackened for its rounding) reaches `step`: the
    # rows of a slow stretch are passed over without a comparison each.
    reach = step * (1.0 - 1e-9)
    rows = qa.tolist()  # plain floats: the same differences as numpy's, without a call per row
    keep, since = [0], 0.0
    for k, s in enumerate(steps[:-1].tolist(), start=1):
        since += s
        if since < reach:
            continue
        last = keep[-1]
        if (s if last == k - 1 else max(abs(a - b) for a, b in zip(rows[k], rows[last]))) >= step:
            keep.append(k)
            since = 0.0
    keep.append(n - 1)
    return np.asarray(keep, dtype=np.int64)


def checked_states(q: Any, step: float = MESH_CHECK_STEP) -> np.ndarray:
    """The rows of ``q`` (T, dof) at :func:`checked_indices`."""
    qa = np.atleast_2d(np.asarray(q, dtype=np.float64))
    return qa[checked_indices(qa, step)]


def mesh_verdict(mesh_checker: Any, scene: Any, q: Any, margin: float = DEFAULT_MESH_MARGIN,
                 deadline: Optional[float] = None) -> Tuple[float, float, bool]:
    """(min obstacle clearance, min self-clearance, verdict) of :func:`mesh_check` (see there)."""
    clear, self_clear, ok, _complete = mesh_check(mesh_checker, scene, q, margin, deadline)
    return clear, self_clear, ok


def mesh_check(mesh_checker: Any, scene: Any, q: Any, margin: float = DEFAULT_MESH_MARGIN,
               deadline: Optional[float] = None, sweep_time: Optional[float] = None,
               likely_contact: Optional[Any] = None) -> Tuple[float, float, bool, bool]:
    """The mesh part of the success criterion over the samples of ``q`` (T, dof).

    The exact mesh distances are computed only up to :func:`mesh_report_cutoff` ``(margin)``: pairs of
    shapes whose bounds lie farther are culled (exact mesh-mesh distances of near but clear pairs are
    most of a mesh check's cost), so a clearance beyond that range is reported as +inf. The verdict is
    the same as with exact distances.

    The states are those of :func:`checked_states` (the path at :data:`MESH_CHECK_STEP` resolution). With
    a ``deadline`` (a ``time.perf_counter()`` value) they are checked in calls of :data:`MESH_CHECK_CHUNK`
    states, then twice as many each time within the time left, and a check that reaches the deadline stops
    there with a negative verdict: exact distances between
    detailed meshes take up to a tenth of a second per state, and a solve's budget bounds its checks too.

    **Contact-first order.** ``likely_contact`` (T,), one value per sample of ``q`` (e.g. the sphere model's
    clearance, :func:`trajectory_metrics` passes it), orders the states: the lowest first, in calls of
    :data:`MESH_CHECK_CHUNK` states, then twice as many each time. The check stops at the first call with a
    state within the margin, so that a path that touches where its spheres come nearest is rejected after
    a few states instead of after every state before the contact (a selection judges many such candidates:
    BENCHMARKS.md "Contact-first mesh checks"). The verdict does not depend on the order (it fails when any
    state is within the margin and is decided on all of them otherwise); on a failure the clearances
    returned are the minima over the states checked until then.

    A path whose checked states all keep more than ``margin`` + :data:`INTERPOLATION_ALLOWANCE` passes;
    one whose states keep more than ``margin``, but not all that much more, passes when the continuous
    check (:meth:`gfcs.MeshChecker.sweep`) certifies every configuration on the straight segments between
    its rows, not only the states, beyond ``margin``. A path that grazes the margin needs the sweep to halve
    its segments many times (its bound must fall below the few micrometres the path keeps); with a
    ``sweep_time`` [s] a sweep that has not certified the path within that time ends it with a final negative
    verdict, the path counting as too near (the selection's repair then moves it clear).

    Returns:
        (min mesh clearance to the obstacles [m], min mesh clearance between links [m], the verdict,
        whether the verdict is final (False: the deadline came before
        every state was checked)), each clearance +inf when no shape comes within
        :func:`mesh_report_cutoff` ``(margin)`` (over the states checked).
    """
    q_all = np.atleast_2d(np.asarray(q, dtype=np.float64))
    rows = checked_indices(q_all)
    if likely_contact is not None:
        order = np.asarray(likely_contact, dtype=np.float64).reshape(-1)
        if order.shape != (q_all.shape[0],):
            raise ShapeError(f"likely_contact: expected shape ({q_all.shape[0]},), got {order.shape}")
        rows = rows[np.argsort(order[rows], kind="stable")]
    qa = q_all[rows]
    cutoff = mesh_report_cutoff(margin)
    n = qa.shape[0]
    chunk = n if deadline is None and likely_contact is None else MESH_CHECK_CHUNK
    clear = self_clear = math.inf
    start, began = 0, time.perf_counter()
    while start < n:
        part = qa[start:start + max(1, chunk)]
        clear = min(clear, float(mesh_checker.min_clearance(scene, part, cutoff=cutoff)))
        self_clear = min(self_clear, float(mesh_checker.min_self_clearance(part, cutoff=cutoff)))
        start += part.shape[0]
        if clear <= margin or self_clear <= margin:
            return clear, self_clear, False, True
        if deadline is None:
            chunk *= 2
        elif start < n:
            now = time.perf_counter()
            if now > deadline:
                return clear, self_clear, False, False
            per_state = (now - began) / start
            chunk = max(MESH_CHECK_CHUNK, min(2 * chunk, int((deadline - now) / max(per_state, 1e-12))))
    if min(clear, self_clear) > margin + INTERPOLATION_ALLOWANCE:
        return clear, self_clear, True, True
    left = None if deadline is None else max(0.0, deadline - time.perf_counter())
    capped = sweep_time is not None and (left is None or sweep_time < left)
    sweep = mesh_checker.sweep(scene, q_all, margin=float(margin), time_limit=sweep_time if capped else left)
    return clear, self_clear, bool(sweep["ok"]), bool(sweep["complete"]) or capped


def link_path_lengths(robot: Any, q: Any, links: Sequence[str]) -> Dict[str, float]:
    """Path length [m] of the origin of each link in ``links`` along the joint path ``q`` (T, dof): the hand
    paths of a robot with several end effectors (e.g. a group spanning two arms).

    Uses ``robot.link_poses`` ((T, L, 4, 4) world poses) and ``robot.link_index``.

    Returns:
        {link name: Σ‖p_{k+1} − p_k‖} in the order of ``links``.
    """
    qa = _as_path(q, "q")
    poses = np.asarray(robot.link_poses(qa), dtype=np.float64).reshape(qa.shape[0], -1, 4, 4)
    return {str(link): path_length(poses[:, int(robot.link_index(link)), :3, 3]) for link in links}


def uniform_resample(t: Any, x: Any) -> "tuple[np.ndarray, float]":
    """Resample a path onto a uniform time grid by linear interpolation (for the LDJ).

    Rollout trajectories are uniform already (fixed step); this only matters for data from elsewhere.

    Args:
        t: (T,) strictly increasing times [s].
        x: (T, k) samples.

    Returns:
        (x_uniform (T, k), dt): samples at t₀ + k·dt with dt = (t_end − t₀)/(T − 1). Returned unchanged
        when ``t`` is already uniform to 1e-9 relative.
    """
    ta = np.asarray(t, dtype=np.float64).reshape(-1)
    xa = _as_path(x, "x")
    if ta.shape[0] != xa.shape[0]:
        raise ShapeError(f"t: expected shape ({xa.shape[0]},), got {ta.shape}")
    if ta.shape[0] < 2:
        return xa, math.nan
    steps = np.diff(ta)
    if np.any(steps <= 0.0):
        raise InvalidValueError("t must be strictly increasing")
    dt = float(ta[-1] - ta[0]) / (ta.shape[0] - 1)
    if np.max(np.abs(steps - dt)) <= 1e-9 * max(dt, 1e-300) + 1e-15:
        return xa, dt
    grid = ta[0] + dt * np.arange(ta.shape[0])
    grid[-1] = ta[-1]
    out = np.column_stack([np.interp(grid, ta, xa[:, j]) for j in range(xa.shape[1])])
    return out, dt


def trajectory_metrics(
    robot: Any,
    scene: Any,
    t: Any,
    q: Any,
    goal: Any,
    tol: float = DEFAULT_SUCCESS_TOL,
    limit_tol: float = DEFAULT_LIMIT_TOL,
    ee: Optional[Any] = None,
    mesh_checker: Optional[Any] = None,
    mesh_margin: float = DEFAULT_MESH_MARGIN,
    clearance_floor: float = 0.0,
    ee_links: Optional[Sequence[str]] = None,
    deadline: Optional[float] = None,
    sweep_time: Optional[float] = None,
    self_clearance_floor: float = 0.0,
    spheres_judge: bool = True,
) -> Dict[str, Any]:
    """Everything GFCS Table I reports about one trajectory, plus the success criterion.

    Args:
        robot: a :class:`gfcs.Robot` (sphere model, limits, end effector).
        scene: a :class:`gfcs.Scene`.
        t: (T,) sample times [s].
        q: (T, dof) joint positions.
        goal: (dof,) goal configuration q_g.
        tol: success tolerance on ‖q_T − q_g‖ [rad].
        limit_tol: slack on the joint limits [rad].
        ee: optional (T, 3) end-effector positions (computed with ``robot.ee_position`` when omitted).
        mesh_checker: optional :class:`gfcs.MeshChecker` of the robot's collision meshes (e.g.
            ``problem.mesh_checker``); when given, every sample is checked against the meshes too.
        mesh_margin: with a checker, the mesh clearances (obstacles and self) must exceed this [m], ≥ 0.
        clearance_floor: the sphere clearance to the obstacles must stay ≥ this [m], ≤ 0 (default 0: no
            penetration). Below 0 only with a checker, whose meshes then judge the contact: for a goal at
            which conservative spheres overlap an obstacle that the meshes clear (:func:`gfcs.optimize.solve`'s
            goal-contact attempt).
        ee_links: the end-effector links whose hand paths ``ee_lengths`` reports (default: just
            ``robot.ee_link``, when the robot has one), e.g. both hands of a two-arm group (``problem.meta["ee_links"]``).
        deadline: with a checker, a ``time.perf_counter()`` value at which the mesh check stops, the
            motion then counting as not validated (:func:`mesh_verdict`); None: no limit.
        sweep_time: with a checker, the continuous check's own time [s] (:func:`mesh_check`); None: up to
            the deadline.
        self_clearance_floor: the spheres' clearance to each other (self-collision pairs) must stay ≥ this
            [m], ≤ 0 (default 0). Below 0 only with a checker, whose link meshes then judge: for an endpoint
            at which two links' spheres overlap while their meshes clear each other
            (:func:`gfcs.planning.policies.endpoint_self_contact`).
        spheres_judge: whether the sphere clearances enter ``success`` when a mesh checker is given (without
            one they always do). False: the collision meshes alone judge collisions, as a mesh validator does,
            and a motion whose spheres overlap an obstacle or each other where the meshes keep their margin
            succeeds (``sphere_success`` still reports the spheres' verdict).

    Returns:
        dict with keys ``success`` (bool: ``sphere_success`` and, with a checker, mesh clearances >
        ``mesh_margin``; with a checker and ``spheres_judge`` False, ``reached_within_limits`` and the mesh
        clearances), ``spheres_judged`` (bool: whether the sphere clearances entered ``success``),
        ``reached_within_limits`` (bool: final error ≤ tol, position and velocity limits respected),
        ``sphere_success`` (bool: ``reached_within_limits``, min sphere clearance ≥ ``clearance_floor``
        against obstacles and ≥ ``self_clearance_floor`` against the robot itself: the verdict of the sphere
        model alone), ``final_error``
        [rad], ``velocity_ratio`` (:func:`velocity_ratio`, ≤ 1 within the velocity limits), ``min_clearance``
        [m] (obstacles, spheres), ``min_self_clearance`` [m], ``within_limits`` (bool), ``duration`` [s],
        ``ee_length`` [m], ``ee_lengths`` ({link: hand path [m]} of each of ``ee_links``, see
        :func:`link_path_lengths`), ``cspace_length`` [rad], ``ee_ldj``, ``cspace_ldj`` (NaN when undefined),
        ``n_samples``, and with a checker ``mesh_clearance`` [m] (min over the samples, see
        :func:`mesh_clearance`) and ``mesh_self_clearance`` [m] (min over the samples of
        ``mesh_checker.self_clearance``: link meshes on non-adjacent bodies not disabled by the SRDF).
    """
    qa = _as_path(q, "q")
    ta = np.asarray(t, dtype=np.float64).reshape(-1)
    if ta.shape[0] != qa.shape[0]:
        raise ShapeError(f"t: expected shape ({qa.shape[0]},), got {ta.shape}")
    g = np.asarray(goal, dtype=np.float64).reshape(-1)
    if g.shape != (qa.shape[1],):
        raise ShapeError(f"goal: expected shape ({qa.shape[1]},), got {g.shape}")
    if qa.shape[0] == 0:
        raise ShapeError("q: expected at least one sample, got shape (0, dof)")
    mesh_margin = _non_negative("mesh_margin", mesh_margin, " [m]")
    floor = float(clearance_floor)
    self_floor = float(self_clearance_floor)
    for name, value in (("clearance_floor", floor), ("self_clearance_floor", self_floor)):
        if not (math.isfinite(value) and value <= 0):
            raise InvalidValueError(f"{name} must be a finite number ≤ 0 [m], got {value}")
        if value < 0 and mesh_checker is None:
            raise InvalidValueError(f"{name} {value} m < 0 needs a mesh_checker: the spheres alone cannot "
                                    "judge a contact")
    ee_a = (
        np.asarray(robot.ee_position(qa), dtype=np.float64).reshape(qa.shape[0], 3)
        if ee is None
        else _as_path(ee, "ee")
    )
    continuous = continuous_mask(robot)
    final_error = float(np.linalg.norm(joint_difference(qa[-1], g, continuous)))
    clear_k = obstacle_clearance(robot, scene, qa)
    self_clear_k = self_clearance(robot, qa)
    clear = float(np.min(clear_k))
    self_clear = float(np.min(self_clear_k))
    # continuous joints have no position limits
    limits_ok = within_limits(qa[:, ~continuous], np.asarray(robot.lower)[~continuous],
                              np.asarray(robot.upper)[~continuous], limit_tol)
    speed_ratio = velocity_ratio(ta, qa, robot.velocity_limits)
    q_u, dt = uniform_resample(ta, qa)
    ee_u, _ = uniform_resample(ta, ee_a)
    ok_dt = math.isfinite(dt) and dt > 0.0
    mesh_ok = True
    extra: Dict[str, Any] = {}
    if mesh_checker is not None:
        # the states where the spheres come nearest to anything first (contact-first order)
        mesh_clear, mesh_self, mesh_ok, complete = mesh_check(mesh_checker, scene, qa, mesh_margin, deadline,
                                                             sweep_time, np.minimum(clear_k, self_clear_k))
        extra["mesh_check_complete"] = complete
        extra["mesh_clearance"] = mesh_clear
        extra["mesh_self_clearance"] = mesh_self
    # every hand's path; a robot object without an end-effector link (a stand-in) reports none. The end
    # effector's own path is ee_a's, already computed (unless the caller gave other positions as ee)
    hands = list(ee_links) if ee_links else ([robot.ee_link] if hasattr(robot, "ee_link") else [])
    if hands:
        known = {robot.ee_link: path_length(ee_a)} if ee is None and robot.ee_link in hands else {}
        rest = [h for h in hands if h not in known]
        known.update(link_path_lengths(robot, qa, rest) if rest else {})
        extra["ee_lengths"] = {str(h): known[h] for h in hands}
    reached_ok = bool(final_error <= tol and limits_ok and speed_ratio <= 1.0 + VELOCITY_RATIO_TOL)
    sphere_ok = bool(reached_ok and clear >= floor and self_clear >= self_floor)
    spheres_judged = bool(spheres_judge) or mesh_checker is None
    return {
        "success": (sphere_ok if spheres_judged else reached_ok) and mesh_ok,
        "spheres_judged": spheres_judged,
        "reached_within_limits": reached_ok,
        "sphere_success": sphere_ok,
        "final_error": final_error,
        "min_clearance": clear,
        "min_self_clearance": self_clear,
        "within_limits": limits_ok,
        "velocity_ratio": speed_ratio,
        "duration": float(ta[-1] - ta[0]),
        "ee_length": path_length(ee_a),
        "cspace_length": path_length(qa),
        "ee_ldj": log_dimensionless_jerk(ee_u, dt) if ok_dt else math.nan,
        "cspace_ldj": log_dimensionless_jerk(q_u, dt) if ok_dt else math.nan,
        "n_samples": int(qa.shape[0]),
        **extra,
    }
