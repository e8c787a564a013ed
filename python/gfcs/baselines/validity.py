"""Collision checks of the sampling-based baselines: the project's sphere model, batched.

A configuration q (dof,) is valid when it lies within the joint bounds, every collision sphere of the
planning model keeps at least ``margin`` [m] from the obstacles (scene signed distance of its centre minus
its radius, positive outside) and no self-collision pair of spheres overlaps (``Robot.self_clearance`` ≥ 0):
the sphere criterion of :func:`gfcs.metrics.trajectory_metrics`, with the fabric's obstacle margin on top.

A straight joint-space segment a → b is valid when its interpolated states are, checked the way OMPL's
``DiscreteMotionValidator`` does (and MoveIt through it): ⌈‖b − a‖ / step⌉ equal steps, every state after
``a`` checked (``a`` itself is valid by construction), where ``step`` = longest-valid-segment fraction ×
the state space's maximum extent. The states of a segment go to the core in batches, at most two calls
(``Robot.sphere_centers`` and ``Scene.signed_distance`` over (N, S) points, ``Robot.self_clearance`` over N
configurations), instead of one call per state.

Pure numpy over the documented methods of :class:`gfcs.Robot` and :class:`gfcs.Scene`; no OMPL here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Dict

import numpy as np

__all__ = ["SphereValidity", "MOVEIT_SEGMENT_FRACTION", "SEGMENT_STRIDE", "segment_states"]

#: MoveIt's default ``longest_valid_segment_fraction``: segments are checked at this fraction of the state
#: space's maximum extent (for the Panda's 7 joints, extent 13.04 rad, a step of 0.065 rad).
MOVEIT_SEGMENT_FRACTION = 0.005
#: A segment check first visits every this-many-th state (:meth:`SphereValidity.segment_valid`): on
#: MotionBenchMaker problems about half the segments the planners try are invalid, with ~40 states each and
#: the first invalid one ~20 in, so a first call over an eighth of the states settles most of them.
SEGMENT_STRIDE = 8


def segment_states(a: np.ndarray, b: np.ndarray, step: float) -> np.ndarray:
    """The states OMPL's discrete motion check visits on a → b: (n, dof), n = max(1, ⌈‖b − a‖ / step⌉), the
    k-th at a + (k / n)(b − a), k = 1..n (the last is ``b``; ``a`` is not included)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    n = max(1, int(math.ceil(float(np.linalg.norm(b - a)) / step - 1e-12)))
    u = np.arange(1, n + 1, dtype=np.float64) / n
    out = a + u[:, None] * (b - a)
    out[-1] = b
    return out


@dataclass
class SphereValidity:
    """Validity of configurations of ``robot`` in ``scene`` (see the module docstring).

    Attributes:
        robot: the planning model (a :class:`gfcs.Robot` with collision spheres).
        scene: the :class:`gfcs.Scene`.
        margin: clearance [m] every sphere must keep from the obstacles (≥ 0).
        lower, upper: (dof,) bounds of the state space [rad or m].
        step: resolution [rad or m, Euclidean in joint space] of a segment check.
    """

    robot: Any
    scene: Any
    margin: float
    lower: np.ndarray
    upper: np.ndarray
    step: float

    def __post_init__(self) -> None:
        self.radii = np.asarray(self.robot.sphere_radii, dtype=np.float64)
        self.has_self_pairs = len(np.asarray(self.robot.self_collision_pairs)) > 0
        #: configurations and segments checked so far (for the result's record)
        self.counts: Dict[str, int] = {"states": 0, "segments": 0}

    def clearances(self, q: np.ndarray) -> np.ndarray:
        """(N,) smallest sphere clearance [m] to the obstacles of each row of ``q`` (N, dof); +inf without
        obstacles or spheres."""
        q = np.atleast_2d(np.asarray(q, dtype=np.float64))
        if len(self.scene) == 0 or self.radii.size == 0:
            return np.full(q.shape[0], math.inf)
        centres = np.asarray(self.robot.sphere_centers(q), dtype=np.float64).reshape(-1, 3)
        d = np.asarray(self.scene.signed_distance(centres), dtype=np.float64).reshape(q.shape[0], -1)
        return (d - self.radii[None, :]).min(axis=1)

    def self_clearances(self, q: np.ndarray) -> np.ndarray:
        """(N,) smallest clearance [m] between the self-collision sphere pairs; +inf without pairs."""
        q = np.atleast_2d(np.asarray(q, dtype=np.float64))
        if not self.has_self_pairs:
            return np.full(q.shape[0], math.inf)
        return np.asarray(self.robot.self_clearance(q), dtype=np.float64).reshape(q.shape[0])

    def valid(self, q: np.ndarray) -> np.ndarray:
        """(N,) bool: each row of ``q`` (N, dof) within the bounds, ``margin`` from the obstacles, and free of
        self-collision."""
        q = np.atleast_2d(np.asarray(q, dtype=np.float64))
        self.counts["states"] += q.shape[0]
        ok = np.all((q >= self.lower) & (q <= self.upper), axis=1)
        if not np.any(ok):
            return ok
        ok &= self.clearances(q) >= self.margin
        if np.any(ok):
            ok &= self.self_clearances(q) >= 0.0
        return ok

    def segment_valid(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the segment a → b is valid at resolution ``step`` (``a`` assumed valid).

        The states are checked in two batched calls: every :data:`SEGMENT_STRIDE`-th one and the last, then
        the others when those were valid. The verdict is that of checking all states; an invalid segment
        usually fails in the first, small call (as OMPL's validator, which visits the states in bisection
        order, stops at the first invalid one)."""
        self.counts["segments"] += 1
        states = segment_states(a, b, self.step)
        first = np.zeros(states.shape[0], dtype=bool)
        first[SEGMENT_STRIDE - 1::SEGMENT_STRIDE] = True
        first[-1] = True
        if not np.all(self.valid(states[first])):
            return False
        return bool(first.all() or np.all(self.valid(states[~first])))

    def why_invalid(self, q: np.ndarray, what: str) -> str:
        """A sentence saying why ``q`` (dof,) is not valid ("" when it is), naming it ``what``."""
        q = np.asarray(q, dtype=np.float64)
        outside = np.flatnonzero((q < self.lower) | (q > self.upper))
        if outside.size:
            return f"{what} outside the joint bounds at joint(s) {outside.tolist()}"
        clear = float(self.clearances(q)[0])
        if clear < self.margin:
            return (f"{what} in collision for the planning spheres: clearance {clear * 1000:.1f} mm < margin "
                    f"{self.margin * 1000:.1f} mm")
        self_clear = float(self.self_clearances(q)[0])
        if self_clear < 0.0:
            return f"{what} in self-collision for the planning spheres ({self_clear * 1000:.1f} mm)"
        return ""
