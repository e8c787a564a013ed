"""Finishing a fabric trajectory: a smooth start from rest, an end exactly at the goal, at rest, and the
robot's acceleration limits.

End: a fabric converges to its goal asymptotically: a rollout stops when ‖q − q_g‖ < ε (GFCS eq. 3), still a
few millimetres-radians away and still moving. Consumers (trajectory followers, validators with tight joint
tolerances) expect the last state to be the goal itself with zero velocity, so the returned trajectory ends
with a short quintic blend from the reached state (q, q̇, q̈) to (q_g, 0, 0). The blend moves at most about
ε plus the distance the current velocity carries over its duration, so it adds no meaningful path length.

Start: from rest the fabric's acceleration jumps to its full value (10-20 rad/s² on MotionBenchMaker
problems) in one step, and the speed controller cuts it within a step or two when the speed reaches v_d;
those two events were most of ∫‖q⃛‖² of a GFCS trajectory. :func:`retime_start` re-times the first
``START_WINDOW`` seconds along the same path (same configurations, in the same order) with a quintic speed
profile that leaves rest with zero acceleration and joins the rollout with its speed and tangential
acceleration. Only the timing changes, so clearances and path lengths do not.

Velocity and acceleration limits: the fabric's speed is set by its own speed control, not by the robot's
joint velocity limits (URDF ``<limit velocity>``: 2.2-2.6 rad/s on the Panda, 0.5 rad/s on some UR5 arms,
0.1 m/s on a Fetch torso), and where a command sequence hands over from one command to the next the fabric
turns the arm onto the new command within about 0.1 s, at up to 25 rad/s². :func:`limit_dynamics` is the
time parameterisation every returned trajectory gets: it slows the trajectory down locally (a smooth time
dilation, the same configurations in the same order) until every joint is within its velocity limit and,
where known (:mod:`gfcs.profile`), its acceleration limit.
"""

from __future__ import annotations

from typing import Any, Optional, Tuple

import numpy as np

from gfcs.errors import InvalidValueError

__all__ = ["blend_duration", "quintic_to_rest", "append_goal_blend", "retime_start", "START_WINDOW",
           "limit_dynamics", "first_difference_speed", "second_difference"]

#: Length [s] of the rollout's start that :func:`retime_start` re-times.
START_WINDOW = 0.3
#: The re-timed start lasts at least this many times (arc length / junction speed), i.e. its mean speed is
#: at most 2/3 of the junction speed (a linear ramp would take 2; the quintic's zero start acceleration
#: needs more than 1), and at least ``START_WINDOW``; longer when needed to keep the speed non-negative.
_START_STRETCH = 1.5
#: :func:`limit_dynamics` re-times toward this fraction of the limits.
_LIMIT_TARGET = 0.95


def blend_duration(q: np.ndarray, qd: np.ndarray, goal: np.ndarray, dt: float) -> float:
    """Blend time [s]: long enough to stop from speed ‖q̇‖ at about 4 rad/s² and to cover the gap at
    ‖Δq‖ / 0.05 s⁻¹ (capped to 1 s), at least 10 steps; a whole number of steps of ``dt``."""
    speed = float(np.linalg.norm(qd))
    gap = float(np.linalg.norm(np.asarray(goal) - np.asarray(q)))
    t = max(10 * dt, min(1.0, max(speed / 4.0 * 2.0, gap / 0.05)))
    return float(np.ceil(t / dt - 1e-9) * dt)


def quintic_to_rest(q0: np.ndarray, v0: np.ndarray, a0: np.ndarray, q1: np.ndarray, duration: float,
                    times: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Per-joint quintic p(s), s ∈ [0, T], with p(0) = q0, p'(0) = v0, p''(0) = a0, p(T) = q1,
    p'(T) = p''(T) = 0.

    Args:
        q0, v0, a0, q1: (dof,) start position [rad], velocity [rad/s], acceleration [rad/s²], end position.
        duration: T [s] > 0.
        times: (K,) sample times s in [0, T].

    Returns:
        (positions (K, dof), velocities (K, dof)).
    """
    T = float(duration)
    d = np.asarray(q1, dtype=np.float64) - q0
    c3 = (20 * d - 12 * v0 * T - 3 * a0 * T**2) / (2 * T**3)
    c4 = (-30 * d + 16 * v0 * T + 3 * a0 * T**2) / (2 * T**4)
    c5 = (12 * d - 6 * v0 * T - a0 * T**2) / (2 * T**5)
    s = np.asarray(times, dtype=np.float64)[:, None]
    pos = q0 + v0 * s + 0.5 * a0 * s**2 + c3 * s**3 + c4 * s**4 + c5 * s**5
    vel = v0 + a0 * s + 3 * c3 * s**2 + 4 * c4 * s**3 + 5 * c5 * s**4
    return pos, vel


def append_goal_blend(t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd_last: np.ndarray, goal: np.ndarray,
                      dt: float, lower: Optional[np.ndarray] = None,
                      upper: Optional[np.ndarray] = None) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Append the blend to a trajectory sampled every ``dt``.

    The blend stays in the ball around the goal through its first state (C-space, radius ‖q_T − q_g‖ ≤ ε):
    a quintic of duration T from velocity v₀ coasts about 0.2 ‖v₀‖ T past the straight way to the goal
    (along v₀, it overshoots the goal once ‖v₀‖ T > 2.5 ‖q_g − q_T‖), and a rollout that reaches ε at
    1 rad/s beside an obstacle would carry the arm into it. The blend is therefore shortened (×0.8 at a
    time, down to 2 steps) until every state lies within that ball and within the joint limits; a short
    blend is a steep stop, which :func:`limit_dynamics` then spreads over the path before it where
    acceleration limits are known.

    Args:
        t: (T,) times [s]; q, qd: (T, dof); qdd_last: (dof,) acceleration at the last row; goal: (dof,).
        lower, upper: (dof,) joint limits [rad] the blend must keep, or None. A quintic that arrives with
            speed toward a goal at a limit passes it before it comes back (by a few mrad).

    Returns:
        (t, q, qd) extended so that the last row is exactly (goal, 0) at rest.
    """
    duration = blend_duration(q[-1], qd[-1], goal, dt)
    radius = float(np.linalg.norm(np.asarray(goal) - q[-1])) * (1.0 + 1e-9) + 1e-12
    while True:
        k = int(round(duration / dt))
        s = dt * np.arange(1, k + 1)
        pos, vel = quintic_to_rest(q[-1], qd[-1], qdd_last, goal, duration, s)
        within = ((lower is None or np.all(pos >= np.minimum(lower, q[-1])))
                  and (upper is None or np.all(pos <= np.maximum(upper, q[-1])))
                  and np.all(np.linalg.norm(pos - goal, axis=1) <= radius))
        if within or k <= 2:
            break
        duration = max(2 * dt, float(np.floor(0.8 * duration / dt + 1e-9) * dt))
    pos[-1] = goal
    vel[-1] = 0.0
    return (np.concatenate([t, t[-1] + s]), np.vstack([q, pos]), np.vstack([qd, vel]))


def _hermite(knots: np.ndarray, q: np.ndarray, u: np.ndarray, s: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The C¹ cubic Hermite curve through (knots_k, q_k) with derivatives u_k, and its derivative, at s."""
    k = np.clip(np.searchsorted(knots, s, side="right") - 1, 0, len(knots) - 2)
    h = (knots[k + 1] - knots[k])[:, None]
    x = (s - knots[k])[:, None] / h
    pos = ((2 * x**3 - 3 * x**2 + 1) * q[k] + (x**3 - 2 * x**2 + x) * h * u[k]
           + (3 * x**2 - 2 * x**3) * q[k + 1] + (x**3 - x**2) * h * u[k + 1])
    der = ((6 * x**2 - 6 * x) / h * (q[k] - q[k + 1]) + (3 * x**2 - 4 * x + 1) * u[k]
           + (3 * x**2 - 2 * x) * u[k + 1])
    return pos, der


def retime_start(t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, dt: float,
                 window: float = START_WINDOW) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Re-time the first ``window`` seconds of a trajectory that starts at rest (see the module docstring).

    The path of samples 0..J (t_J = ``window``) is parametrised by arc length s (C-space, rad) as a C¹ cubic
    Hermite curve through the samples with the unit directions of q̇ (of q̈ at the start) as tangents; the new
    timing is the quintic s(τ) with s = ṡ = s̈ = 0 at τ = 0 and s = s_J, ṡ = ‖q̇_J‖, s̈ = q̈_J·q̇_J/‖q̇_J‖ at
    the junction, after which the rollout continues unchanged (shifted in time).

    Args:
        t: (T,) times [s], uniform steps of ``dt``; q, qd, qdd: (T, dof) positions, velocities,
            accelerations of the rollout (``qdd`` only up to row J is used).
        dt: sample period [s].
        window: re-timed length of the rollout [s].

    Returns:
        (t, q, qd), re-timed; the input unchanged when it does not start at rest, is shorter than the window,
        or stops moving within it.
    """
    J = int(round(window / dt))
    if len(t) < J + 2 or np.any(qd[0] != 0.0):
        return t, q, qd
    speed = np.linalg.norm(qd[1:J + 1], axis=1)
    a0 = float(np.linalg.norm(qdd[0]))
    if a0 == 0.0 or np.any(speed == 0.0):
        return t, q, qd
    knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q[:J + 1], axis=0), axis=1))])
    tangents = np.vstack([qdd[0] / a0, qd[1:J + 1] / speed[:, None]])
    s_j, v_j = knots[-1], speed[-1]
    a_j = float(qdd[J] @ qd[J]) / v_j
    duration = max(window, _START_STRETCH * s_j / v_j)
    while True:
        n = int(np.ceil(duration / dt - 1e-9))
        T = n * dt
        tau = dt * np.arange(n + 1)
        # s(τ) run backwards from the junction is a quintic to rest at s = 0: r(σ) = s(T − σ) has r(0) = s_J,
        # r'(0) = −ṡ_J, r''(0) = s̈_J and r = r' = r'' = 0 at σ = T
        r, r_dot = quintic_to_rest(np.array([s_j]), np.array([-v_j]), np.array([a_j]), np.zeros(1), T,
                                   T - tau)
        s_new, v_new = r[:, 0], -r_dot[:, 0]
        s_new[0] = v_new[0] = 0.0  # at rest by construction (the polynomial leaves rounding there)
        if np.all(v_new >= 0.0):
            break
        if duration > 10.0 * window:  # no monotone profile: keep the rollout's own start
            return t, q, qd
        duration *= 1.2
    pos, der = _hermite(knots, q[:J + 1], tangents, np.clip(s_new, 0.0, s_j))
    vel = der * v_new[:, None]
    pos[0], vel[0] = q[0], 0.0
    pos[-1], vel[-1] = q[J], qd[J]
    return (np.concatenate([tau, t[J + 1:] - t[J] + T]), np.vstack([pos, q[J + 1:]]),
            np.vstack([vel, qd[J + 1:]]))


def _widen_and_smooth(x: np.ndarray, half: int) -> np.ndarray:
    """Running maximum over ±``half`` samples, then two running means over ±``half`` (a C¹ envelope that
    stays at least as large as x wherever x has a plateau of the window's width)."""
    if half < 1:
        return x
    kernel = np.ones(2 * half + 1) / (2 * half + 1)
    pad = np.pad(x, half, mode="edge")
    y = np.max(np.lib.stride_tricks.sliding_window_view(pad, 2 * half + 1), axis=1)
    for _ in range(2):
        y = np.convolve(np.pad(y, half, mode="edge"), kernel, mode="valid")
    return y


def second_difference(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """q̈ [rad/s²] estimated at every sample by the three-point second difference of positions (the
    estimate with no smoothing: 2 ((q_{k+1} − q_k)/h_k − (q_k − q_{k−1})/h_{k−1}) / (h_k + h_{k−1}), which is
    (q_{k+1} − 2 q_k + q_{k−1}) / h² on a uniform grid); the end samples take their neighbour's value.

    Args:
        t: (T,) increasing times [s], T ≥ 3; q: (T, dof) positions.

    Returns:
        (T, dof) accelerations.
    """
    h = np.diff(t)[:, None]
    slope = np.diff(q, axis=0) / h
    inner = 2.0 * np.diff(slope, axis=0) / (h[1:] + h[:-1])
    return np.vstack([inner[:1], inner, inner[-1:]])


def _limit_vector(limits: Any, dof: int, what: str, unit: str) -> Optional[np.ndarray]:
    """``limits`` as a (dof,) float array with +inf for "no limit" (None: no limits at all); ValueError
    naming ``what`` unless every value is positive (NaN and values ≤ 0 are rejected)."""
    if limits is None:
        return None
    a = np.asarray(limits, dtype=np.float64)
    if a.shape != (dof,) or np.any(np.isnan(a)) or np.any(a <= 0):
        raise InvalidValueError(f"{what} limits: expected {dof} positive values [{unit}] (inf: none), "
                                f"got {np.asarray(limits).tolist()}")
    return None if np.all(np.isinf(a)) else a


def first_difference_speed(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """|q̇| [rad/s or m/s] at every sample as a validator measures it: the larger of the two finite-difference
    speeds |q_{k+1} − q_k| / (t_{k+1} − t_k) of the segments that meet at sample k (the end samples take
    their one segment's).

    Args:
        t: (T,) increasing times [s], T ≥ 2; q: (T, dof) positions.

    Returns:
        (T, dof) speeds, ≥ 0.
    """
    seg = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
    return np.maximum(np.vstack([seg[:1], seg]), np.vstack([seg, seg[-1:]]))


def limit_dynamics(t: np.ndarray, q: np.ndarray, qd: np.ndarray, dt: float, velocity: Any = None,
                   acceleration: Any = None, window: float = 0.1, max_iterations: int = 12,
                   ) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Re-time a trajectory along its own path until every joint keeps its velocity and acceleration limits
    (a time parameterisation by local time dilation; see the module docstring).

    Each pass measures the speeds by :func:`first_difference_speed` and the accelerations by
    :func:`second_difference` of q (as a validator would), takes the slow-down factor λ_k = max(1,
    max_j |q̇_kj| / (0.95 v_j), max_j sqrt(|q̈_kj| / (0.95 a_j))) that would bring sample k to 95 % of the
    limits (velocities scale as 1/λ and accelerations as 1/λ² under a time dilation), widens and smooths it
    over ±``window`` seconds (λ then varies slowly and adds little acceleration of its own), re-times the
    samples by dτ = λ dt, and resamples at ``dt`` along the C¹ cubic Hermite curve through the samples with
    velocities q̇/λ. Passes repeat until the limits hold or ``max_iterations`` passes were made; the last
    passes dilate uniformly if the velocity limits still do not hold, so the velocity limits always hold
    on return (the acceleration limits after at most ``max_iterations`` passes).

    A trajectory that starts moving (q̇_0 ≠ 0: a start velocity the robot already has) keeps its first
    state: λ ramps from 1 at the first sample to its measured value over ``window`` seconds, so the start
    velocity is exactly q̇_0 and the limits hold from the end of that ramp on. The first and last positions
    are kept exactly (a trajectory at rest at its ends stays so).

    Args:
        t: (T,) increasing times [s]; q, qd: (T, dof) positions [rad or m] and velocities.
        dt: sample period of the result [s] (the re-timed duration divided into a whole number of equal
            steps, each within dt / (2n) of ``dt``).
        velocity: (dof,) velocity limits v_j > 0 [rad/s or m/s], inf where a joint has none; None: none.
        acceleration: (dof,) acceleration limits a_j > 0 [rad/s² or m/s²], inf where unknown; None: none.
        window: half-width of the smoothing of λ [s].
        max_iterations: most non-uniform passes.

    Returns:
        (t, q, qd): the input itself when it already keeps the limits; else the re-timed trajectory,
        starting at t[0].

    Raises:
        ValueError: limits not (dof,) positive values, ``dt`` / ``window`` not positive, or a start velocity
            beyond a velocity limit (no re-timing can change the state the robot starts in).
    """
    dof = q.shape[1]
    v = _limit_vector(velocity, dof, "velocity", "rad/s or m/s")
    a = _limit_vector(acceleration, dof, "acceleration", "rad/s² or m/s²")
    if not (dt > 0 and window > 0):
        raise InvalidValueError(f"dt and window must be > 0, got {dt}, {window}")
    if v is not None and np.any(np.abs(qd[0]) > v):
        j = int(np.argmax(np.abs(qd[0]) / v))
        raise InvalidValueError(f"start velocity {qd[0][j]:.6g} of joint {j} exceeds its velocity limit {v[j]:.6g}: "
                                "the robot cannot be in that state")
    half = int(round(window / dt))
    moving_start = bool(np.any(qd[0] != 0.0))

    def ratios(t: np.ndarray, q: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """(velocity ratio (T,), acceleration ratio (T,)) of the samples; zeros without limits."""
        rv = np.max(first_difference_speed(t, q) / v, axis=1) if v is not None else np.zeros(len(t))
        ra = np.max(np.abs(second_difference(t, q)) / a, axis=1) if a is not None else np.zeros(len(t))
        return rv, ra

    def dilate(t: np.ndarray, q: np.ndarray, qd: np.ndarray, lam: np.ndarray):
        """Re-time by dτ = λ dt and resample at dt; a moving start keeps λ = 1 at its first sample,
        reached smoothly over ``window``."""
        if moving_start:
            ramp = np.clip((t - t[0]) / window, 0.0, 1.0)
            lam = 1.0 + (lam - 1.0) * ramp * ramp * (3.0 - 2.0 * ramp)
        tau = np.concatenate([[t[0]], t[0] + np.cumsum(np.diff(t) * 0.5 * (lam[1:] + lam[:-1]))])
        # a uniform grid from the first to the last knot, its step within dt / (2n) of dt
        n = max(1, int(round((tau[-1] - tau[0]) / dt)))
        times = np.linspace(tau[0], tau[-1], n + 1)
        pos, vel = _hermite(tau, q, qd / lam[:, None], times)
        pos[0], vel[0] = q[0], qd[0] / lam[0]
        pos[-1], vel[-1] = q[-1], qd[-1] / lam[-1]
        return times, pos, vel

    if len(t) < 3 or (v is None and a is None):
        return t, q, qd
    for _ in range(int(max_iterations)):
        rv, ra = ratios(t, q)
        if max(rv.max(), ra.max()) <= 1.0:
            return t, q, qd
        # aim a little below the limits so that one or two passes suffice
        lam = np.maximum(1.0, np.maximum(rv / _LIMIT_TARGET, np.sqrt(ra / _LIMIT_TARGET)))
        t, q, qd = dilate(t, q, qd, _widen_and_smooth(lam, half))
    for _ in range(8):  # velocity limits must hold: dilate uniformly by what is left
        rv, _ = ratios(t, q)
        if moving_start:
            rv = rv[min(len(rv) - 1, half + 1):]
        if rv.size == 0 or rv.max() <= 1.0:
            break
        t, q, qd = dilate(t, q, qd, np.full(len(t), rv.max() / _LIMIT_TARGET))
    return t, q, qd
