"""Mesh repair: a planned path whose collision meshes come too near, moved clear by a few millimetres.

The fabric plans on collision spheres and the validator judges the meshes. A sphere model made for another
checker leaves bits of the meshes uncovered, so a motion that keeps every sphere clear can bring a mesh a
few millimetres into an obstacle or into another link: the attempt then fails on the meshes although the
motion is nearly right. :func:`repair_path` moves such a path off its contacts, keeping its two ends, in the
manner of the collision terms of CHOMP and TrajOpt (a path deformed along distance gradients), with the
gradients taken by finite differences of the exact mesh distances.

A configuration q is clear when every term of h(q) is ≥ 0 (:func:`path_constraint`):

    d_i(q) − m − c  for each collision shape i (its mesh distance to the obstacles) and each checked
                    pair i of shapes (their distance; negative in contact),
    s_j(q) − f      for each collision sphere j (its clearance to the obstacles),
    s_self(q) − f_s the least clearance between the self-collision sphere pairs,

with m the mesh margin of success, c the clearance the repair aims for beyond it
(:attr:`RepairOptions.clearance`) and f, f_s the clearance floors of the success criterion
(:func:`gfcs.metrics.trajectory_metrics` judges the spheres too). One term per part lets one step move two
links off two obstacles at once. Each iteration:

1. evaluates the terms at the states a collision check visits (:func:`gfcs.metrics.checked_indices`) that
   it does not know yet or that moved;
2. takes the states with a negative term, between the ends, at least σ/3 samples apart (the spread of
   step 3 moves the ones between), their gradients G (terms × dof) by forward differences (step
   :attr:`RepairOptions.fd_step`, every displaced configuration in one batched call), and at each the least
   joint step that brings every term below c/2 to c/2 to first order, δ = Gₐᵀ (Gₐ Gₐᵀ + εI)⁻¹ (c/2 − hₐ)
   over those terms a (the near ones take part, so that a step off one contact does not walk into
   another), each joint's part capped at :attr:`RepairOptions.max_step`;
3. spreads the steps over the path, D = (w ∗ Δ) / max(1, w ∗ 1_B), w(s) = exp(−s² / 2σ²) with σ =
   :attr:`RepairOptions.smoothing` seconds in samples (peak 1), Δ the steps at their samples, 1_B the
   indicator of those samples: a lone state's step fades over its neighbours, a run of states moves
   together by their mean step; D is then tapered linearly to 0 over σ at the first and the last sample
   (the start and the goal stay where they are);
4. moves q ← q + D, within the position limits (continuous joints have none).

It stops when no visited state has h < 0; it gives up after :attr:`RepairOptions.iterations` iterations,
once a joint moved farther than :attr:`RepairOptions.max_displacement` from the given path, when from the
third iteration on the least h is below the first one's (the steps walk into other contacts), or at the
deadline. The caller re-times the moved path within the limits and judges it in full (the repair's own
states are not a verdict).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from gfcs import metrics as _metrics
from gfcs.errors import InvalidValueError
from gfcs.joints import continuous_mask
from gfcs.planning._check import integer_at_least, non_negative

__all__ = ["RepairOptions", "repair_path", "path_constraint", "EXACT_RANGE"]

#: How far [m] above its target a mesh term of h is measured exactly (:func:`path_constraint`): enough for a
#: finite-difference step from a violated state; farther shape pairs are not measured.
EXACT_RANGE = 0.001


@dataclass
class RepairOptions:
    """How :func:`repair_path` moves a path off its mesh contacts (see the module docstring).

    Attributes:
        candidates: mesh-contact candidates of one attempt repaired at most (best first).
        iterations: most deformation steps per path.
        clearance: clearance [m] beyond the mesh margin the repaired states aim for.
        smoothing: σ [s] of the Gaussian that spreads a state's step over its neighbours.
        max_step: largest step [rad or m] of one joint at one state in one iteration.
        max_displacement: the repair gives up once a joint moved this far [rad or m] from the path it was
            given: it is a local correction, not a new path.
        fd_step: forward-difference step [rad or m] of the gradients.
    """

    candidates: int = 2
    iterations: int = 8
    clearance: float = 0.002
    smoothing: float = 0.1
    max_step: float = 0.05
    max_displacement: float = 0.1
    fd_step: float = 1e-4

    def __post_init__(self) -> None:
        self.candidates = integer_at_least("RepairOptions.candidates", self.candidates, 1)
        self.iterations = integer_at_least("RepairOptions.iterations", self.iterations, 1)
        self.clearance = non_negative("RepairOptions.clearance", self.clearance, " [m]")
        for name in ("smoothing", "max_step", "max_displacement", "fd_step"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise InvalidValueError(f"RepairOptions.{name} must be a finite number > 0, got {value!r}")


def path_constraint(robot: Any, scene: Any, mesh_checker: Any, q: np.ndarray, mesh_margin: float,
                    clearance: float, floor: float, self_floor: float = 0.0) -> np.ndarray:
    """The terms (N, terms) of h (module docstring) at the configurations ``q`` (N, dof) [m], one per
    collision shape (mesh to obstacles), per checked pair of shapes (mesh to mesh), per collision sphere
    (to obstacles) and one for the sphere pairs; h is their minimum, ≥ 0 where a state is clear. One term
    per part lets a step move two links off two obstacles at once. The mesh terms are exact up to
    :data:`EXACT_RANGE` above 0 (measured with a cutoff there) and +inf or some larger value beyond."""
    q = np.atleast_2d(q)
    n = q.shape[0]
    target = mesh_margin + clearance
    cutoff = target + EXACT_RANGE
    return np.concatenate([
        np.asarray(mesh_checker.shape_clearances(scene, q, cutoff=cutoff), dtype=np.float64).reshape(n, -1) - target,
        np.asarray(mesh_checker.pair_clearances(q, cutoff=cutoff), dtype=np.float64).reshape(n, -1) - target,
        _metrics.sphere_clearances(robot, scene, q) - floor,
        _metrics.self_clearance(robot, q)[:, None] - self_floor,
    ], axis=1)


def _gradients(constraint: Any, q: np.ndarray, values: np.ndarray, step: float) -> np.ndarray:
    """Forward-difference gradients (N, terms, dof) of ``constraint`` (→ (M, terms)) at the rows of ``q``
    (N, dof), whose values are ``values`` (N, terms): one batched call over the N·dof displaced
    configurations."""
    n, dof = q.shape
    probes = (q[:, None, :] + np.eye(dof)[None] * step).reshape(-1, dof)
    shifted = constraint(probes).reshape(n, dof, -1)
    with np.errstate(invalid="ignore"):  # inf − inf of a term beyond the cutoff: not used
        return np.swapaxes((shifted - values[:, None, :]) / step, 1, 2)


def _thinned(samples: np.ndarray, stride: int) -> np.ndarray:
    """The increasing sample indices ``samples`` thinned so that kept ones lie at least ``stride`` apart (the
    first of each run kept): the spread of step 3 moves the states between them."""
    keep: List[int] = []
    for k in samples.tolist():
        if not keep or k - keep[-1] >= stride:
            keep.append(k)
    return np.asarray(keep, dtype=np.int64)


def _least_steps(values: np.ndarray, grads: np.ndarray, aim: float) -> np.ndarray:
    """Per state (N,) the least joint step δ (N, dof) that brings every term below ``aim`` ≥ 0 (in
    ``values`` (N, terms)) to ``aim`` to first order (gradients ``grads`` (N, terms, dof)): δ = Gᵀ (G Gᵀ +
    εI)⁻¹ (aim − h) over those terms' rows G. The terms that hold but lie below ``aim`` take part, so that a
    step off one contact does not walk into another (a mesh part the spheres miss on one side, a sphere
    that sticks out of the mesh on the other); 0 where no term lies below ``aim`` or G vanishes."""
    n, terms, dof = grads.shape
    out = np.zeros((n, dof))
    for k in range(n):
        rows = np.flatnonzero((values[k] < aim) & np.all(np.isfinite(grads[k]), axis=1))
        g = grads[k, rows]
        gram = g @ g.T
        if rows.size == 0 or np.trace(gram) <= 1e-12:
            continue
        need = aim - values[k, rows]
        out[k] = g.T @ np.linalg.solve(gram + 1e-9 * np.trace(gram) * np.eye(rows.size), need)
    return out


def _spread(steps: np.ndarray, at: np.ndarray, length: int, sigma: float) -> np.ndarray:
    """D (length, dof) of step 3 of the module docstring: the ``steps`` (K, dof) at samples ``at`` (K,)
    spread with a Gaussian of ``sigma`` samples, tapered to 0 at both ends."""
    dof = steps.shape[1]
    radius = int(np.ceil(3.0 * sigma))
    w = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma) ** 2)
    delta = np.zeros((length, dof))
    hit = np.zeros(length)
    np.add.at(delta, at, steps)
    np.add.at(hit, at, 1.0)

    def smooth(x: np.ndarray) -> np.ndarray:
        # centred on the samples whatever their count (mode "same" returns the kernel's length when the
        # path is shorter than the kernel)
        return np.convolve(x, w, mode="full")[radius:radius + length]

    weight = smooth(hit)
    d = np.stack([smooth(delta[:, j]) for j in range(dof)], axis=1)
    d /= np.maximum(1.0, weight)[:, None]
    s = np.arange(length, dtype=np.float64)
    taper = np.clip(np.minimum(s, length - 1 - s) / max(sigma, 1.0), 0.0, 1.0)
    return d * taper[:, None]


def repair_path(robot: Any, scene: Any, mesh_checker: Any, t: np.ndarray, q: np.ndarray, options: RepairOptions,
                mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN, floor: float = 0.0,
                deadline: Optional[float] = None, self_floor: float = 0.0,
                ) -> Tuple[Optional[np.ndarray], Dict[str, Any]]:
    """Move the path ``q`` (T, dof), sampled at times ``t`` (T,) [s], off its mesh contacts (see the module
    docstring).

    Returns:
        (the moved path (T, dof), or None when a visited state between the ends still has h < 0 after the
        iterations or at the deadline; a record: ``iterations``, ``states_moved`` (visited states that
        needed a step), ``states_left`` (those still below 0),
        ``max_displacement`` [rad or m, over joints and samples], ``min_h`` [m] of the last iteration,
        ``time`` [s]).
    """
    started = time.perf_counter()
    q = np.array(q, dtype=np.float64, copy=True)
    length = q.shape[0]
    bounded = ~continuous_mask(robot)
    lower = np.asarray(robot.lower, dtype=np.float64)[bounded]
    upper = np.asarray(robot.upper, dtype=np.float64)[bounded]
    dt = float(np.median(np.diff(t))) if length > 1 else 1.0
    sigma = max(1.0, options.smoothing / dt) if dt > 0 else 1.0
    stride = max(1, int(sigma / 3))

    def constraint(x: np.ndarray) -> np.ndarray:
        return path_constraint(robot, scene, mesh_checker, x, mesh_margin, options.clearance, floor, self_floor)

    known: Optional[np.ndarray] = None  # (T, terms) of h at visited samples, NaN where unknown or moved
    original = q.copy()
    record: Dict[str, Any] = {"iterations": 0, "states_moved": 0, "states_left": 0, "max_displacement": 0.0,
                              "min_h": np.nan}
    first_min = np.nan
    # no iteration starts that would end past the deadline at the pace of the longest so far
    longest, top = 0.0, time.perf_counter()
    for it in range(options.iterations + 1):
        now = time.perf_counter()
        longest, top = max(longest, now - top), now
        visit = _metrics.checked_indices(q)
        if known is None:
            values = constraint(q[visit])
            known = np.full((length, values.shape[1]), np.nan)
            known[visit] = values
        todo = visit[np.isnan(known[visit, 0])]
        if todo.size:
            known[todo] = constraint(q[todo])
        h = known[visit].min(axis=1)
        record["min_h"] = float(np.min(h)) if h.size else np.nan
        bad = visit[(h < 0.0) & (visit > 0) & (visit < length - 1)]
        record["states_left"] = int(bad.size)
        first_min = record["min_h"] if it == 0 else first_min
        diverged = it >= 2 and record["min_h"] < first_min
        if (bad.size == 0 or it == options.iterations or diverged
                or np.max(np.abs(q - original)) > options.max_displacement
                or (deadline is not None and time.perf_counter() + longest > deadline)):
            break
        at = _thinned(bad, stride)
        steps = _least_steps(known[at], _gradients(constraint, q[at], known[at], options.fd_step),
                             options.clearance / 2)
        moving = np.any(steps != 0.0, axis=1)
        if not np.any(moving):
            break
        steps = steps[moving] / np.maximum(1.0, np.max(np.abs(steps[moving]), axis=1) / options.max_step)[:, None]
        d = _spread(steps, at[moving], length, sigma)
        q += d
        q[:, bounded] = np.clip(q[:, bounded], lower, upper)
        known[np.any(d != 0.0, axis=1)] = np.nan
        record["iterations"] = it + 1
        record["states_moved"] += int(moving.sum())
    record["max_displacement"] = float(np.max(np.abs(q - original))) if length else 0.0
    record["time"] = time.perf_counter() - started
    ok = record["states_left"] == 0
    return (q if ok else None), record
