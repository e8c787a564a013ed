"""Finishing a reached trajectory exactly at the goal, at rest.

A fabric converges to its goal asymptotically: a rollout stops when ‖q − q_g‖ < ε (GFCS eq. 3), still a few
millimetres-radians away and still moving. Consumers (trajectory followers, validators with tight joint
tolerances) expect the last state to be the goal itself with zero velocity, so the returned trajectory ends
with a short quintic blend from the reached state (q, q̇, q̈) to (q_g, 0, 0). The blend moves at most about
ε plus the distance the current velocity carries over its duration, so it adds no meaningful path length.
"""

from __future__ import annotations

from typing import Tuple

import numpy as np

__all__ = ["blend_duration", "quintic_to_rest", "append_goal_blend"]


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
