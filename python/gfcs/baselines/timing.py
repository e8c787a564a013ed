"""Time parameterisation of a planner's geometric path: a piecewise-linear joint path → a trajectory sampled
every ``dt``, at rest at both ends, within the joint velocity limits (and the acceleration limits, where
known), so that its metrics compare with those of a GFCS trajectory (:mod:`gfcs.metrics`).

1. Nominal timing: segment k of the path takes τ_k = max_j |Δq_kj| / v_j, the time of its slowest joint at
   its velocity limit v_j (the path then runs at the velocity limits, as a time-optimal parameterisation
   does on its straight parts; a joint without a limit is timed at the largest limit of the others).
2. Start and stop: the path parameter u (nominal time) advances at rate u̇(t) ∈ [0, 1] that rises from 0 to 1
   over a ramp of R = min(``ramp``, U) seconds as the smoothstep 3x² − 2x³ (x = t/R), holds 1, and falls
   back to 0 the same way (U: the nominal duration; each ramp covers R/2 of it, so the motion lasts U + R).
3. :func:`gfcs.blend.limit_dynamics`: the trajectory is re-timed along the same path (local time dilation)
   until every joint keeps its velocity and acceleration limits; the corners of the path, where a
   piecewise-linear path turns at full speed, are where it slows down.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from gfcs.blend import START_WINDOW, limit_dynamics
from gfcs.errors import InvalidValueError
from gfcs.results import Trajectory

__all__ = ["time_path"]


def _ramp_progress(t: np.ndarray, ramp: float, total: float) -> tuple:
    """(u(t), u̇(t)) of step 2 of the module docstring, for the nominal duration ``total``."""
    end = total + ramp

    def up(s: np.ndarray) -> tuple:
        x = np.clip(s / ramp, 0.0, 1.0)
        return ramp * (x**3 - 0.5 * x**4), 3 * x**2 - 2 * x**3

    u_in, v_in = up(t)
    u_out, v_out = up(end - t)
    head = t <= ramp
    tail = t >= end - ramp
    u = np.where(head, u_in, np.where(tail, total - u_out, t - 0.5 * ramp))
    v = np.where(head, v_in, np.where(tail, v_out, 1.0))
    return u, v


def time_path(waypoints: Any, velocity: Any, acceleration: Optional[Any] = None, dt: float = 0.01,
              ramp: float = START_WINDOW) -> Trajectory:
    """A trajectory along the piecewise-linear path through ``waypoints`` (see the module docstring).

    Args:
        waypoints: (K, dof) joint positions [rad or m], K ≥ 1; the trajectory passes through each.
        velocity: (dof,) velocity limits [rad/s or m/s], positive (inf: none).
        acceleration: (dof,) acceleration limits [rad/s² or m/s²], inf where unknown; None: none.
        dt: sample period [s].
        ramp: length [s] of the speed ramps at the start and the end.

    Returns:
        The :class:`gfcs.results.Trajectory`: first sample ``waypoints[0]``, last ``waypoints[-1]``, both
        at rest, the samples in between on the path (a straight line between two samples may cut a corner
        of the path by up to one sample's step); a single sample when the path does not move.
    """
    w = np.atleast_2d(np.asarray(waypoints, dtype=np.float64))
    v = np.asarray(velocity, dtype=np.float64).reshape(-1)
    if v.shape != (w.shape[1],) or not np.all(v > 0):
        raise InvalidValueError(f"velocity limits: expected {w.shape[1]} values > 0 (inf: none), got {v.tolist()}")
    finite = v[np.isfinite(v)]
    # a joint without a limit is timed at the largest limit of the others (1 rad/s when none has one)
    nominal = np.where(np.isfinite(v), v, finite.max() if finite.size else 1.0)
    steps = np.max(np.abs(np.diff(w, axis=0)) / nominal, axis=1) if w.shape[0] > 1 else np.zeros(0)
    keep = np.concatenate([[True], steps > 0])
    w, steps = w[keep], steps[steps > 0]
    knots = np.concatenate([[0.0], np.cumsum(steps)])
    total = float(knots[-1])
    if total <= 0.0:
        return Trajectory(np.zeros(1), w[:1].copy(), np.zeros((1, w.shape[1])))
    r = min(float(ramp), total)
    n = max(3, int(np.ceil((total + r) / dt - 1e-9)))
    t = np.linspace(0.0, total + r, n + 1)
    u, u_dot = _ramp_progress(t, r, total)
    u = np.clip(u, 0.0, total)
    seg = np.clip(np.searchsorted(knots, u, side="right") - 1, 0, len(steps) - 1)
    slope = np.diff(w, axis=0) / steps[:, None]
    q = w[seg] + (u - knots[seg])[:, None] * slope[seg]
    qd = slope[seg] * u_dot[:, None]
    q[0], q[-1] = w[0], w[-1]
    qd[0], qd[-1] = 0.0, 0.0
    t, q, qd = limit_dynamics(t, q, qd, dt, velocity=v, acceleration=acceleration)
    return Trajectory(t, q, qd)
