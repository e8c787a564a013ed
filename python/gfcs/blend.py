"""Finishing a fabric trajectory: a smooth start from rest, and an end exactly at the goal, at rest.

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
"""

from __future__ import annotations

from typing import Tuple

import numpy as np

__all__ = ["blend_duration", "quintic_to_rest", "append_goal_blend", "retime_start", "START_WINDOW"]

#: Length [s] of the rollout's start that :func:`retime_start` re-times.
START_WINDOW = 0.3
#: The re-timed start lasts at least this many times (arc length / junction speed), i.e. its mean speed is
#: at most 2/3 of the junction speed (a linear ramp would take 2; the quintic's zero start acceleration
#: needs more than 1), and at least ``START_WINDOW``; longer when needed to keep the speed non-negative.
_START_STRETCH = 1.5


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
                      dt: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Append the blend to a trajectory sampled every ``dt``.

    Args:
        t: (T,) times [s]; q, qd: (T, dof); qdd_last: (dof,) acceleration at the last row; goal: (dof,).

    Returns:
        (t, q, qd) extended so that the last row is exactly (goal, 0) at rest.
    """
    duration = blend_duration(q[-1], qd[-1], goal, dt)
    k = int(round(duration / dt))
    s = dt * np.arange(1, k + 1)
    pos, vel = quintic_to_rest(q[-1], qd[-1], qdd_last, goal, duration, s)
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
