"""Global motion generation by optimising fabric command sequences (GFCS Sec. IV-A, Algorithm 1).

Two layers:

* :func:`solve_gfcop`: Algorithm 1 ("SolveGFCOP with warm-started CMA-ES") for any batched cost
  function over a box. The first batch is the sampler's candidates (the warm start), every later batch is
  drawn from CMA-ES; every candidate and cost is kept, the best so far is reported after every batch
  (anytime, with a per-batch callback), and the top-m candidates are returned.
* :func:`solve`: the robot-level API. The decision variable is y = [q_g¹ᵀ … q_gⁿᵀ]ᵀ (n free commands,
  GFCS eq. 4); the cost of a batch of candidates is computed in Rust, in parallel, by
  ``gfcs.Fabric.evaluate`` (eq. 4-8: Σ tᵢ* + p·1[goal not reached]); the best sequence is then rolled out
  once more to record its trajectory and metrics. ``method="gf"`` is the local baseline (the goal is the
  only command, no optimisation). :func:`replay` re-runs a solved command sequence in a changed scene
  without re-optimising (reactivity, GFCS Sec. V).

Mesh validation: the fabric and the cost see the robot's collision *spheres*; benchmarks judge motions with
its collision *meshes*. When the problem carries a ``mesh_checker`` (:class:`gfcs.MeshChecker`, see
:mod:`gfcs.problems`), :func:`solve` rolls out the evaluated candidates in cost order (the lowest-cost one,
then those that reached the goal, at most ``mesh_candidates``) and returns the first whose full trajectory succeeds with every mesh clear of the obstacles and of the robot
itself (``metrics["success"]``, which then requires ``mesh_clearance`` and ``mesh_self_clearance`` above
``mesh_margin``, 1 mm by default, besides reaching the goal with the spheres clear); if none does, the lowest-cost candidate is returned (and
reported as failed): a mesh-free candidate that misses the goal is no better. ``result.top`` and the per-batch data are the
optimiser's, unchanged (anytime / top-m semantics of Alg. 1).

Near-optimal candidates (``length_slack``): eq. 4 scores time only, and on MotionBenchMaker candidates
within a few per cent of the best time differ by up to 25 % in end-effector path length. :func:`solve`
therefore rolls out the reached candidates whose cost is within ``(1 + length_slack)`` times the best (at
most ``mesh_candidates`` of them) and tries them shortest hand path first, then the others in cost order
(mesh validation, when on, takes that order). ``length_slack = 0`` returns the paper's choice, the
lowest-cost candidate. ``metrics["selection_rank"]`` is the rank of the returned candidate in the
optimiser's cost order (0: the lowest cost) and ``metrics["mesh_candidates_checked"]`` how many were
rolled out.

Goals at a joint limit (``RolloutSettings.limit_hold_off``): the fabric's joint-limit barrier keeps every
joint ``joint_limits.margin`` from its limits and holds it off a goal nearer than that. Every rollout is
therefore commanded :func:`fabric_goal`, the goal with each such joint moved ``limit_hold_off`` further
in, and a reached rollout ends with the goal blend (:mod:`gfcs.blend`) from there to the goal itself, so
the returned trajectory still ends exactly at the goal. Goals farther from the limits are commanded as they
are (every MotionBenchMaker goal for the MBM Panda, whose URDF limits are 0.07 rad wider than Franka's).

Warm start (Alg. 1, first line): CMA-ES runs in normalised coordinates u = (y − lower)/(upper − lower) ∈
[0, 1]^dim with pycma's ``BoundTransform`` box handling. The sampler's candidates are passed to
``CMAEvolutionStrategy.inject(..., force=True)`` as genotypes (``boundary_handler.inverse``), so the first
``ask()`` returns exactly those candidates; they are evaluated and ``tell()`` updates the distribution from
them like from any other batch. The initial mean is the mean of the warm-start candidates and the initial
step size is ``sigma0`` (a fraction of each joint range).

Random numbers: pycma's ``seed`` option would reseed numpy's *global* generator. Instead its normal
variates come from a private ``numpy.random.Generator`` passed through pycma's ``randn`` option (``seed``
is set to NaN: "do nothing"), and the sampler gets a second, independent generator; both derive from
``seed`` through ``numpy.random.SeedSequence``. A solve is therefore reproducible from its seed and never
touches ``numpy.random``'s global state.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import time
import warnings
from dataclasses import dataclass
from typing import Any, Callable, Dict, List, Optional, Protocol, Tuple, Union

import numpy as np

from gfcs import metrics as _metrics
from gfcs import problems as _problems
from gfcs import profile as _profile
from gfcs.blend import append_goal_blend, limit_dynamics, retime_start
from gfcs.results import SolveResult, Trajectory

__all__ = [
    "Sampler",
    "UniformSampler",
    "ApproachSampler",
    "BatchInfo",
    "OptimResult",
    "RolloutSettings",
    "solve_gfcop",
    "solve",
    "combine_attempts",
    "goal_contact",
    "replay",
    "make_fabric",
    "rollout_commands",
    "THIN_SPHERE_MARGIN",
]

#: How much wider [m] than the fabric's obstacle margin :func:`solve` keeps the shipped Panda's thin spheres
#: from obstacles: they miss its meshes by up to 8.3 mm, and at the plain margin (2 mm) a motion in a
#: MotionBenchMaker cage brought a collision polytope 1-6 mm into a bar with every sphere clear; with 6 mm
#: the first batch solved 326 of the 347 problems valid for the shipped Panda, against 296 on its covering
#: spheres (BENCHMARKS.md).
THIN_SPHERE_MARGIN = 0.004


# ----------------------------------------------------------------------------------------- samplers
class Sampler(Protocol):
    """Sampler protocol of Algorithm 1 (``f_sampler``): candidates to warm-start CMA-ES.

    ``sample(problem, n, rng)`` returns an (n, n_free·dof) float array of command sequences
    y = [q_g¹ᵀ … q_gⁿᵀ]ᵀ inside the joint limits of ``problem.robot``; ``rng`` is a
    ``numpy.random.Generator`` owned by the caller (use it for every random draw so that solves are
    reproducible).
    """

    def sample(self, problem: Any, n: int, rng: np.random.Generator) -> np.ndarray:  # pragma: no cover
        ...


@dataclass
class UniformSampler:
    """Uniform samples within the joint limits, U(q_low, q_up) per command (the "No learning" sampler).

    Attributes:
        n_commands: number n of free commands per candidate (output width n·dof).
    """

    n_commands: int = 1

    def sample(self, problem: Any, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, n_commands·dof) uniform candidates."""
        lo = np.tile(np.asarray(problem.robot.lower, dtype=np.float64), self.n_commands)
        up = np.tile(np.asarray(problem.robot.upper, dtype=np.float64), self.n_commands)
        return rng.uniform(lo, up, size=(int(n), lo.shape[0]))


@dataclass
class ApproachSampler:
    """The default warm start: half of the candidates follow the goal's approach corridor, the other half
    leave the start by pulling the hand in toward the robot's base.

    A grasp goal (MotionBenchMaker's shelves, boxes, cages) sits in narrow free space that the fabric
    enters only along the gripper's approach direction, and a start in confined space (under a table) is
    left by folding the arm in; a uniform command almost never does either. Of n candidates:

    * the first round(``fraction``·n) are approach candidates: their last free command is an approach
      configuration (the goal's end-effector pose backed off by one of ``distances`` along ``axis``, see
      :func:`gfcs.approach.approach_configurations`; the distances in turn) and each earlier command backs
      off one ``spacing`` further (spacings in turn), so that a sequence enters the corridor step by step;
      every command gets N(0, (sigma·(q_up − q_low))²) per joint, clipped into the limits;
    * the next round(``retract``·n) (at most the rest) are retract candidates: their first command is a
      retract configuration (:func:`gfcs.approach.retract_configurations`: the hand pulled in toward the
      base axis at about the goal's height), their later commands (n ≥ 2) those of an approach candidate;
    * the others are those of :class:`UniformSampler`.

    ``fraction = retract = 0`` is the uniform sampler (the paper's "No learning"). The retract half
    replaced the uniform one in the ninth session: on the 350 MotionBenchMaker problems (5 batches, seed
    0, with the retry, the spherized MBM Panda) 349 solved against 348, hand paths 1-4 % shorter in five
    classes and 10 % on table under (1.59 -> 1.43 m), box 1.03 -> 1.04 m (BENCHMARKS.md).

    Attributes:
        n_commands: number n of free commands per candidate (output width n·dof).
        fraction: share of approach candidates, in [0, 1].
        retract: share of retract candidates, in [0, 1] (capped at 1 − fraction).
        distances: back-off distances (m) of the last command, ≥ 0.
        spacings: extra back-off (m, ≥ 0) of each earlier command over the next one (n ≥ 2 only).
        sigma: joint noise around the approach configurations as a fraction of each joint range, ≥ 0.
        axis: approach direction in the end-effector frame; None: the robot profile's
            (:func:`gfcs.profile.profile_for`: a data file's, else derived from the gripper's spheres).
    """

    n_commands: int = 1
    fraction: float = 0.5
    retract: float = 0.5
    distances: Tuple[float, ...] = (0.05, 0.10, 0.15, 0.20)
    spacings: Tuple[float, ...] = (0.10, 0.15, 0.20)
    sigma: float = 0.02
    axis: Optional[Tuple[float, float, float]] = None

    def __post_init__(self) -> None:
        if int(self.n_commands) < 1:
            raise ValueError(f"ApproachSampler.n_commands must be >= 1, got {self.n_commands}")
        for name in ("fraction", "retract"):
            if not 0.0 <= float(getattr(self, name)) <= 1.0:
                raise ValueError(f"ApproachSampler.{name} must be in [0, 1], got {getattr(self, name)}")
        if not (math.isfinite(self.sigma) and self.sigma >= 0):
            raise ValueError(f"ApproachSampler.sigma must be a finite number >= 0, got {self.sigma}")
        for name in ("distances", "spacings"):
            values = getattr(self, name)
            if len(values) == 0 or not all(math.isfinite(d) and d >= 0 for d in values):
                raise ValueError(f"ApproachSampler.{name} must be finite numbers >= 0, got {values}")

    def sample(self, problem: Any, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, n_commands·dof) candidates: approach ones for ``problem.goal``, retract ones from
        ``problem.q0``, then uniform ones (see the class docstring)."""
        from gfcs.approach import approach_configurations, retract_configurations

        y = UniformSampler(self.n_commands).sample(problem, n, rng)
        k = int(round(float(self.fraction) * int(n)))
        r = min(int(round(float(self.retract) * int(n))), int(n) - k)
        if k + r == 0:
            return y
        robot = problem.robot
        lo = np.asarray(robot.lower, dtype=np.float64)
        up = np.asarray(robot.upper, dtype=np.float64)
        dof, m = lo.shape[0], int(self.n_commands)
        i = np.arange(k + r)
        # back-off distance of command c of candidate i: the last one's plus (m-1-c) spacings
        last = np.asarray(self.distances, dtype=np.float64)[i % len(self.distances)]
        step = np.asarray(self.spacings, dtype=np.float64)[i % len(self.spacings)]
        back = last[:, None] + step[:, None] * np.arange(m - 1, -1, -1)[None, :]
        levels, index = np.unique(back, return_inverse=True)
        axis = self.axis if self.axis is not None else _profile.profile_for(robot).approach_axis
        approach = approach_configurations(robot, problem.goal, levels, axis)
        rows = approach[index.reshape(k + r, m)]  # (k + r, m, dof)
        noise = rng.standard_normal((k + r, m, dof)) * (float(self.sigma) * (up - lo))
        rows = np.clip(rows + noise, lo, up)
        if r:
            rows[k:, 0] = retract_configurations(robot, problem.q0, problem.goal, r, rng)
        y[: k + r] = rows.reshape(k + r, m * dof)
        return y


# ------------------------------------------------------------------------------- generic Algorithm 1
@dataclass
class BatchInfo:
    """What the per-batch callback of :func:`solve_gfcop` receives.

    Attributes:
        index: batch index j (0-based).
        candidates: (N, dim) candidates of this batch.
        costs: (N,) their costs (NaN reported by the cost function become +inf).
        best_x: (dim,) best candidate so far (all batches).
        best_cost: its cost.
        batch_time: wall time of this batch [s] (ask, evaluate, tell).
        elapsed: wall time since the start of the optimisation [s] (sum of batch times).
    """

    index: int
    candidates: np.ndarray
    costs: np.ndarray
    best_x: np.ndarray
    best_cost: float
    batch_time: float
    elapsed: float


@dataclass
class OptimResult:
    """Result of :func:`solve_gfcop`.

    Attributes:
        best_x: (dim,) lowest-cost candidate; best_cost: its cost.
        top_x: (m, dim) the m lowest-cost candidates, sorted by cost (ties: evaluation order);
        top_costs: (m,) their costs.
        all_x: (K, dim) every evaluated candidate, in evaluation order; all_costs: (K,);
        all_batches: (K,) batch index of each.
        batch_best_costs: (B,) best cost so far after each batch (non-increasing).
        batch_best_x: (B, dim) best candidate so far after each batch.
        batch_times: (B,) wall time of each batch [s]; the first includes the warm-start sampling.
    """

    best_x: np.ndarray
    best_cost: float
    top_x: np.ndarray
    top_costs: np.ndarray
    all_x: np.ndarray
    all_costs: np.ndarray
    all_batches: np.ndarray
    batch_best_costs: np.ndarray
    batch_best_x: np.ndarray
    batch_times: np.ndarray

    @property
    def n_evaluations(self) -> int:
        """Number of evaluated candidates K."""
        return int(self.all_costs.shape[0])


InitialCandidates = Union[None, np.ndarray, Callable[[int, np.random.Generator], np.ndarray]]


def _box(lower: Any, upper: Any, dim: int) -> Tuple[np.ndarray, np.ndarray]:
    lo = np.asarray(lower, dtype=np.float64).reshape(-1)
    up = np.asarray(upper, dtype=np.float64).reshape(-1)
    if lo.shape == (1,):
        lo = np.full(dim, lo[0])
    if up.shape == (1,):
        up = np.full(dim, up[0])
    if lo.shape != (dim,) or up.shape != (dim,):
        raise ValueError(f"lower/upper: expected shape ({dim},), got {lo.shape} and {up.shape}")
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(up))):
        raise ValueError("lower/upper contain NaN or infinite values")
    if not np.all(up > lo):
        bad = int(np.argmax(~(up > lo)))
        raise ValueError(f"upper must exceed lower in every coordinate (coordinate {bad}: "
                         f"lower={lo[bad]}, upper={up[bad]})")
    return lo, up


def _initial_batch(sampler: InitialCandidates, n: int, dim: int, rng: np.random.Generator,
                   lo: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The warm-start batch (n, dim): from the sampler, topped up uniformly, clipped into the box."""
    if sampler is None:
        y = rng.uniform(lo, up, size=(n, dim))
    else:
        y = np.asarray(sampler(n, rng) if callable(sampler) else sampler, dtype=np.float64)
        if y.ndim == 1 and y.shape[0] == dim:
            y = y[None, :]
        if y.ndim != 2 or y.shape[1] != dim:
            raise ValueError(f"sampler: expected candidates of shape ({n}, {dim}), got {y.shape}")
        if not np.all(np.isfinite(y)):
            raise ValueError("sampler: candidates contain NaN or infinite values")
        y = y[:n]
        if y.shape[0] < n:
            y = np.vstack([y, rng.uniform(lo, up, size=(n - y.shape[0], dim))])
    return np.clip(y, lo, up)


#: Modules pycma imports at its top level for features Alg. 1 does not use (surrogate models' rank
#: correlation, plotting); together they were 0.75 of its 0.95 s import time.
#: Blocked while pycma is imported, when not loaded yet. "matplotlib" itself too: pycma's
#: ``from matplotlib import pyplot`` loads the package (0.25 s) before it finds pyplot missing.
_CMA_OPTIONAL_IMPORTS = ("scipy.stats", "matplotlib", "matplotlib.pyplot")


def _import_cma() -> Any:
    """pycma, imported (once per process) without :data:`_CMA_OPTIONAL_IMPORTS` when they are not loaded
    yet: pycma falls back to its own rank correlation and skips its plotting shortcuts (``cma.s``), and the
    modules stay importable for everyone else. Keeps ``gfcs solve`` from spending most of its wall time on
    imports."""
    if "cma" in sys.modules:
        return sys.modules["cma"]
    blocked = [name for name in _CMA_OPTIONAL_IMPORTS if name not in sys.modules]
    for name in blocked:
        sys.modules[name] = None  # type: ignore[assignment]  # makes `import name` raise ImportError
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # pycma warns that it cannot plot
            import cma
    finally:
        for name in blocked:
            if sys.modules.get(name, 0) is None:
                del sys.modules[name]
    return cma


def solve_gfcop(
    cost_fn: Callable[[np.ndarray], Any],
    dim: int,
    lower: Any,
    upper: Any,
    sampler: InitialCandidates = None,
    batches: int = 5,
    population: int = 32,
    sigma0: float = 0.25,
    seed: int = 0,
    top_m: int = 4,
    callback: Optional[Callable[[BatchInfo], Optional[bool]]] = None,
) -> OptimResult:
    """Algorithm 1 (SolveGFCOP) with warm-started CMA-ES over the box [lower, upper].

    Args:
        cost_fn: batched cost, (N, dim) candidates -> (N,) costs (lower is better; NaN counts as +inf).
            For GFCS it evaluates eq. 4 for every candidate command sequence in parallel.
        dim: number of decision variables (n·dof for n free commands).
        lower, upper: (dim,) box bounds (or scalars), lower < upper, finite.
        sampler: the warm start ``f_sampler``: None (uniform in the box), a callable ``(n, rng) ->
            (n, dim)``, or an array (k, dim) of candidates (the first ``population`` are used; fewer are
            topped up uniformly). Candidates are clipped into the box.
        batches: number of batches N_iters ≥ 1 (the first is the sampler's).
        population: candidates per batch N_samp ≥ 2 (CMA-ES ``popsize``).
        sigma0: initial CMA-ES step size as a fraction of each coordinate's range (0 < sigma0).
        seed: non-negative integer seed of the sampler and CMA-ES generators.
        top_m: number m of best candidates returned (≥ 1; fewer if fewer were evaluated).
        callback: called after every batch with a :class:`BatchInfo`; returning True stops early
            (anytime use).

    Returns:
        :class:`OptimResult` with all candidates, the top-m and the per-batch best costs and times.
    """
    cma = _import_cma()
    dim = int(dim)
    if dim < 1:
        raise ValueError(f"dim must be ≥ 1, got {dim}")
    if int(batches) < 1:
        raise ValueError(f"batches must be ≥ 1, got {batches}")
    if int(population) < 2:
        raise ValueError(f"population must be ≥ 2, got {population}")
    if int(top_m) < 1:
        raise ValueError(f"top_m must be ≥ 1, got {top_m}")
    if not (math.isfinite(sigma0) and sigma0 > 0):
        raise ValueError(f"sigma0 must be a positive number, got {sigma0}")
    if int(seed) < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed}")
    lo, up = _box(lower, upper, dim)
    span = up - lo
    sampler_rng, cma_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(2))

    # The warm start is part of the first batch (Alg. 1 line 2), so its time counts in batch 0's.
    start = time.perf_counter()
    y0 = _initial_batch(sampler, int(population), dim, sampler_rng, lo, up)
    sampling_time = time.perf_counter() - start
    u0 = (y0 - lo) / span
    options = {
        "bounds": [0.0, 1.0],
        "popsize": int(population),
        "seed": math.nan,  # do not touch numpy's global RNG; randn below is our own generator
        "randn": lambda *shape: cma_rng.standard_normal(shape),
        "verbose": -9,
    }
    es = cma.CMAEvolutionStrategy(np.clip(u0.mean(axis=0), 0.0, 1.0).tolist(), float(sigma0), options)

    all_x: List[np.ndarray] = []
    all_c: List[np.ndarray] = []
    all_b: List[np.ndarray] = []
    best_costs: List[float] = []
    best_xs: List[np.ndarray] = []
    times: List[float] = []
    best_x, best_cost = y0[0].copy(), math.inf
    elapsed = 0.0
    for j in range(int(batches)):
        start = time.perf_counter()
        if j == 0:
            es.inject([es.boundary_handler.inverse(u) for u in u0], force=True)
        asked = es.ask()
        y = y0 if j == 0 else np.clip(lo + np.asarray(asked) * span, lo, up)
        costs = np.asarray(cost_fn(y), dtype=np.float64).reshape(-1)
        if costs.shape != (y.shape[0],):
            raise ValueError(f"cost_fn: expected {y.shape[0]} costs, got shape {costs.shape}")
        costs = np.where(np.isnan(costs), math.inf, costs)
        finite = costs[np.isfinite(costs)]
        worst = float(finite.max()) if finite.size else 0.0
        # CMA-ES ranks candidates; infinite costs rank last, one step behind the worst finite one
        es.tell(asked, np.where(np.isfinite(costs), costs, worst + 1.0 + abs(worst)).tolist())
        batch_time = time.perf_counter() - start + (sampling_time if j == 0 else 0.0)
        elapsed += batch_time

        k = int(np.argmin(costs))
        if costs[k] < best_cost:
            best_cost, best_x = float(costs[k]), y[k].copy()
        all_x.append(y.copy())
        all_c.append(costs)
        all_b.append(np.full(y.shape[0], j))
        best_costs.append(best_cost)
        best_xs.append(best_x.copy())
        times.append(batch_time)
        if callback is not None:
            stop = callback(BatchInfo(j, y.copy(), costs.copy(), best_x.copy(), best_cost, batch_time, elapsed))
            if stop:
                break

    xs, cs, bs = np.vstack(all_x), np.concatenate(all_c), np.concatenate(all_b)
    order = np.argsort(cs, kind="stable")[: int(top_m)]
    return OptimResult(
        best_x=best_x,
        best_cost=best_cost,
        top_x=xs[order],
        top_costs=cs[order],
        all_x=xs,
        all_costs=cs,
        all_batches=bs,
        batch_best_costs=np.asarray(best_costs),
        batch_best_x=np.vstack(best_xs),
        batch_times=np.asarray(times),
    )


# ---------------------------------------------------------------------------------- robot-level API
@dataclass
class RolloutSettings:
    """Rollout parameters of GFCS eq. 1-8 (defaults: the paper's, Sec. V).

    Attributes:
        dt: integration step [s] (Euler at 100 Hz in the paper).
        t_max: time budget per command [s] (7 s in the paper).
        tol: ε of eq. 3 for the final goal [rad]. Default 0.02: a reached trajectory ends with a short
            quintic blend onto the goal (:mod:`gfcs.blend`), so what :func:`solve` returns ends exactly at
            the goal, at rest, whatever ε; success is judged at ``metrics.DEFAULT_SUCCESS_TOL`` (0.01 rad)
            on that trajectory. With ε = 0.01 the fabric's last approach to goals held off by the barrier
            potentials of objects in contact (grasps) stopped 0.013–0.036 rad short on MotionBenchMaker
            (cage 20 and 47, bookshelf_small 19, seeds 0 and 1: 6 failures, 1 with 0.02); the 0.02 → 0.01
            tail took a median 0.21 s of each successful rollout.
        waypoint_tol: ε for the intermediate commands [rad] (looser: a command only steers; 0.1 before,
            0.3 gave up to 5 % shorter times to goal in 6 of 7 MotionBenchMaker classes, success unchanged).
        penalty: p of eq. 4/8 added when the goal is not reached [s].
        collision_penalty: added when the sphere model collides (min clearance < −``collision_tol``) [s].
            An extension of eq. 4 (the paper's cost has no collision term): success requires a
            collision-free motion, so colliding candidates must rank behind collision-free ones.
        collision_tol: sphere overlap [m], ≥ 0, that does not count as a collision in the cost (0: none).
            An attempt with a clearance floor below 0 (:func:`solve`'s goal-contact attempt) raises it to
            the overlap the floor accepts, so that the candidates it may return are not penalised like
            those that collide deeper.
        distance_penalty: added per rad of the closest approach to the goal when the goal is not reached
            [s/rad]. An extension of eq. 4 (default 0, the paper's cost): eq. 4 ranks failed candidates
            only by their waypoint times, so a batch without a success tells CMA-ES nothing; this term
            ranks them by how near they came. Not the default: on the 20 MotionBenchMaker problems that
            5 batches failed, 20 s/rad solved 6-7 against 8 without it, in more time.
        blend_time: at each handover the fabric's command moves from the previous command to the next
            along a smoothstep over this time [s] instead of jumping (an extension of eq. 7; 0 = the
            paper's switch): the jump of the command was a jump of the acceleration that dominated the
            jerk of the trajectories.
        integrator: ``"euler"`` (semi-implicit Euler, the paper's) or ``"rk4"``.
        stall_window, stall_progress: a rollout stops as "stalled" (t* = t_max, not reached) when its
            distance to the command has not shrunk by ``stall_progress`` [rad] over ``stall_window`` [s]
            (0 = off): it saves the steps of candidates stuck at a local minimum.
        limit_acceleration: slow the recorded trajectory down locally until every joint is within its
            acceleration limit (:func:`gfcs.blend.limit_dynamics`: the same path, re-timed; not part of
            the cost, which is the fabric's own time). On MotionBenchMaker (350 problems, 5 batches) 101
            trajectories exceeded the Panda's limits, by up to 3.4 times, mostly at their command
            handovers; re-timed, the motions of a class last 0-2 % longer and their LDJ rises by up to 0.35.
        acceleration_limits: (dof,) limits [rad/s²], inf where none; None: the robot profile's
            (:func:`gfcs.profile.acceleration_limits`). The URDF velocity limits always hold: every
            recorded trajectory is re-timed within them, whatever this setting.
        velocity_limits: (dof,) limits [rad/s or m/s] that tighten the URDF's (e.g. a MoveIt
            ``joint_limits.yaml``, :func:`gfcs.profile.read_joint_limits_yaml`), inf where none; None: the
            URDF's and the robot profile's (:func:`gfcs.profile.velocity_limits`).
        limit_hold_off: a goal joint nearer a limit than the fabric's joint-limit margin plus this [rad]
            is commanded at that distance instead (:func:`fabric_goal`), and the goal blend covers the
            rest: the limit barrier holds the fabric off a goal at its limit (MotionBenchMaker's cage goals
            put joint 5 at 2.8973 rad, the shipped Panda's limit; the fabric stopped 0.03-0.05 rad short).
            Goals farther from the limits are commanded as they are.

    The defaults equal the core's (``RolloutOptions`` / ``SequenceOptions`` in ``fabric-core``) except
    ``collision_penalty`` (0 in the core) and ``tol`` (0.01 in the core, whose rollouts have no blend).
    """

    dt: float = 0.01
    t_max: float = 7.0
    tol: float = 0.02
    waypoint_tol: float = 0.3
    penalty: float = 100.0
    collision_penalty: float = 100.0
    collision_tol: float = 0.0
    distance_penalty: float = 0.0
    blend_time: float = 0.5
    integrator: str = "euler"
    stall_window: float = 0.5
    stall_progress: float = 0.005
    limit_acceleration: bool = True
    acceleration_limits: Optional[Tuple[float, ...]] = None
    velocity_limits: Optional[Tuple[float, ...]] = None
    limit_hold_off: float = 0.015

    def as_kwargs(self) -> Dict[str, Any]:
        """Keyword arguments for ``gfcs.Fabric.rollout_sequence`` / ``evaluate``."""
        return {
            "dt": self.dt,
            "t_max": self.t_max,
            "tol": self.tol,
            "waypoint_tol": self.waypoint_tol,
            "penalty": self.penalty,
            "collision_penalty": self.collision_penalty,
            "collision_tol": self.collision_tol,
            "distance_penalty": self.distance_penalty,
            "blend_time": self.blend_time,
            "integrator": self.integrator,
            "stall_window": self.stall_window,
            "stall_progress": self.stall_progress,
        }


def make_fabric(problem: Any, fabric_config: Any = None, scene: Any = None) -> Any:
    """A ``gfcs.Fabric`` for ``problem`` (or for ``problem.robot`` in another ``scene``).

    Args:
        problem: a :class:`gfcs.problems.Problem`.
        fabric_config: None (defaults), a ``gfcs.FabricConfig``, a dict, or a path to a TOML/YAML/JSON file.
        scene: replaces ``problem.scene`` when given.
    """
    import gfcs

    config = str(fabric_config) if isinstance(fabric_config, os.PathLike) else fabric_config
    return gfcs.Fabric(problem.robot, problem.scene if scene is None else scene, config)


def fabric_goal(fabric: Any, goal: Any, hold_off: float) -> np.ndarray:
    """The configuration (dof,) [rad] the fabric is commanded for ``goal`` (dof,): each joint at least
    ``joint_limits.margin`` + ``hold_off`` [rad, ≥ 0] from its limits (``goal`` itself when every joint is
    that far already, or when the fabric's limit barrier is off). The barrier holds the fabric off any
    configuration nearer its limit than that, so a rollout could not reach such a goal; the goal blend
    (:func:`finish_rollout`) then covers the rest. A joint whose range is narrower than twice that room
    keeps its goal."""
    goal = np.asarray(goal, dtype=np.float64)
    hold_off = _metrics._non_negative("limit_hold_off", hold_off, " [rad]")
    limits = fabric.config.to_dict()["joint_limits"]
    if not limits["enabled"]:
        return goal
    room = float(limits["margin"]) + hold_off
    robot = fabric.robot
    lower = np.asarray(robot.lower, dtype=np.float64) + room
    upper = np.asarray(robot.upper, dtype=np.float64) - room
    return np.where(lower <= upper, np.minimum(np.maximum(goal, lower), upper), goal)


def rollout_commands(
    fabric: Any, q0: Any, qd0: Any, goal: Any, commands: Any, settings: RolloutSettings
) -> Tuple[Trajectory, float, bool, np.ndarray]:
    """Roll out a command sequence q_g¹..q_gⁿ then the goal (GFCS eq. 5-7) and record it. The recorded
    trajectory is finished by :mod:`gfcs.blend`: a start from rest re-timed over its first 0.3 s along the
    same path, when the goal is reached a blend ending exactly at the goal, at rest, and a re-timing within
    the robot's velocity limits (and, with ``settings.limit_acceleration``, its acceleration limits).

    Args:
        fabric: a ``gfcs.Fabric``.
        q0, qd0, goal: (dof,) start state and goal.
        commands: (n, dof) free commands (n may be 0: the GF baseline).
        settings: :class:`RolloutSettings`.

    Returns:
        (trajectory, cost of eq. 4, goal reached, t_stars (n + 1,)). The fabric is commanded
        :func:`fabric_goal` for the goal (``settings.limit_hold_off``); the blend ends at ``goal``.
    """
    dof = int(np.asarray(goal).shape[0])
    cmds = np.asarray(commands, dtype=np.float64).reshape(-1, dof)
    seq = fabric.rollout_sequence(q0, qd0, cmds, fabric_goal(fabric, goal, settings.limit_hold_off),
                                  **settings.as_kwargs())
    return finish_rollout(fabric, seq, goal, settings)


def finish_rollout(
    fabric: Any, seq: Any, goal: Any, settings: RolloutSettings
) -> Tuple[Trajectory, float, bool, np.ndarray]:
    """The recorded ``gfcs.SequenceRollout`` ``seq`` of ``fabric`` finished as :func:`rollout_commands`
    describes: (trajectory, cost of eq. 4, goal reached, t_stars (n + 1,))."""
    t, q, qd, qdd = np.asarray(seq.t), np.asarray(seq.q), np.asarray(seq.qd), np.asarray(seq.qdd)
    # Leave rest smoothly (see gfcs.blend): the same path, re-timed over its first 0.3 s.
    t, q, qd = retime_start(t, q, qd, qdd, settings.dt)
    if seq.reached:
        # End exactly at the goal, at rest (see gfcs.blend): the fabric only converges asymptotically.
        t, q, qd = append_goal_blend(t, q, qd, qdd[-1], np.asarray(goal, dtype=np.float64),
                                     settings.dt, np.asarray(fabric.robot.lower), np.asarray(fabric.robot.upper))
    robot = fabric.robot
    accel = None
    if settings.limit_acceleration:
        accel = settings.acceleration_limits
        accel = _profile.acceleration_limits(robot) if accel is None else accel
    velocity = _profile.velocity_limits(robot)
    if settings.velocity_limits is not None:
        velocity = np.minimum(velocity, np.asarray(settings.velocity_limits, dtype=np.float64))
    t, q, qd = limit_dynamics(t, q, qd, settings.dt, velocity=velocity, acceleration=accel)
    traj = Trajectory(t, q, qd)
    return traj, float(seq.cost), bool(seq.reached), np.asarray(seq.t_stars, dtype=np.float64)


def _settings_dict(settings: RolloutSettings, **extra: Any) -> Dict[str, Any]:
    d = dataclasses.asdict(settings)
    d.update(extra)
    return d


def _select_candidate(
    fabric: Any, problem: Any, opt: OptimResult, n_commands: int, settings: RolloutSettings,
    mesh_checker: Any, mesh_candidates: int, length_slack: float = 0.0, threads: Optional[int] = None,
    mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN, clearance_floor: float = 0.0,
) -> Tuple[np.ndarray, Trajectory, float, bool, np.ndarray, Dict[str, Any]]:
    """The candidate :func:`solve` returns, rolled out: (commands (n, dof), trajectory, cost, reached,
    t_stars, metrics).

    The order of preference (see the module docstring): the reached candidates with cost ≤
    (1 + ``length_slack``) × the lowest, shortest end-effector path first, then the others in cost order
    (after the lowest-cost one only those that reached the goal); at most ``mesh_candidates`` are
    considered. Without a mesh checker the first of that order is returned; with one, the first whose
    trajectory succeeds with meshes included, or, if none does, the first of the order.
    ``clearance_floor``: see :func:`gfcs.metrics.trajectory_metrics`.
    """
    robot, scene = problem.robot, problem.scene
    dof = int(robot.dof)
    q0, qd0 = np.asarray(problem.q0, dtype=np.float64), np.asarray(problem.qd0, dtype=np.float64)
    goal = np.asarray(problem.goal, dtype=np.float64)
    commanded = fabric_goal(fabric, goal, settings.limit_hold_off)
    order = np.argsort(opt.all_costs, kind="stable")
    keep = [int(order[0])] + [int(k) for k in order[1:] if opt.all_costs[k] < settings.penalty]
    keep = keep[:max(1, int(mesh_candidates))]
    rolled: Dict[int, Tuple[np.ndarray, Trajectory, float, bool, np.ndarray]] = {}

    def roll(*ks: int) -> Tuple[np.ndarray, Trajectory, float, bool, np.ndarray]:
        """Roll out candidates ``ks`` not rolled yet in one parallel batch; the last one's rollout."""
        todo = [k for k in dict.fromkeys(ks) if k not in rolled]
        if todo:
            x = np.stack([np.asarray(opt.all_x[k], dtype=np.float64) for k in todo])
            *_, seqs = fabric.evaluate(q0, qd0, commanded, x, threads=threads, return_trajectories=True,
                                       **settings.as_kwargs())
            for k, row, seq in zip(todo, x, seqs):
                rolled[k] = (row.reshape(n_commands, dof), *finish_rollout(fabric, seq, goal, settings))
        return rolled[ks[-1]]

    best = float(opt.all_costs[keep[0]])
    if length_slack > 0 and best < settings.penalty:
        near = [k for k in keep if opt.all_costs[k] <= (1.0 + length_slack) * best]
        roll(*near)
        hand = {k: _metrics.path_length(robot.ee_position(roll(k)[1].q)) for k in near}
        near.sort(key=lambda k: hand[k])  # stable: equal lengths stay in cost order
        keep = near + [k for k in keep if k not in hand]
    if mesh_checker is None:
        keep = keep[:1]
    first = None
    for checked, k in enumerate(keep, start=1):
        commands, traj, cost, reached, t_stars = roll(k)
        met = _metrics.trajectory_metrics(robot, scene, traj.t, traj.q, goal, mesh_checker=mesh_checker,
                                          mesh_margin=mesh_margin, clearance_floor=clearance_floor)
        met["selection_rank"] = int(np.flatnonzero(order == k)[0])
        if mesh_checker is not None:
            met["mesh_candidates_checked"] = checked
        chosen = (commands, traj, cost, reached, t_stars, met)
        if first is None:
            first = chosen
        if mesh_checker is None or met["success"]:
            return chosen
    if first is None:  # unreachable: `keep` has at least one entry
        raise RuntimeError("no candidate to roll out")
    first[5]["mesh_candidates_checked"] = len(keep)
    return first


def solve(
    problem: Any,
    method: str = "gfcs",
    batches: int = 5,
    population: int = 32,
    n_commands: int = 1,
    seed: int = 0,
    sampler: Optional[Sampler] = None,
    fabric_config: Any = None,
    threads: Optional[int] = None,
    progress: bool = False,
    *,
    settings: Optional[RolloutSettings] = None,
    top_m: int = 4,
    sigma0: float = 0.25,
    mesh_candidates: int = 32,
    length_slack: float = 0.1,
    callback: Optional[Callable[[BatchInfo], Optional[bool]]] = None,
    max_commands: Optional[int] = None,
    mesh_retry_margin: float = 0.002,
    mesh_retries: int = 2,
    mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN,
    goal_contact_slack: float = 0.002,
    thin_spheres: bool = True,
    sphere_fallback: bool = True,
) -> SolveResult:
    """Solve a motion problem with GFCS (Alg. 1) or with the local fabric alone (``method="gf"``).

    Args:
        problem: a :class:`gfcs.problems.Problem` (robot, scene, q0, qd0, goal; with a ``mesh_checker``
            the returned candidate is the best mesh-collision-free one of the top-m, see the module
            docstring).
        method: ``"gfcs"``: optimise n free commands with CMA-ES, cost eq. 4 evaluated in Rust;
            ``"gf"``: roll the fabric out toward the goal only (no optimisation).
        batches: CMA-ES batches (the paper reports 1 and 5).
        population: candidates per batch.
        n_commands: number n of free commands (the paper: 1, i.e. sequences of length two).
        seed: seed of the sampler and CMA-ES (see the module docstring).
        sampler: warm-start sampler (protocol :class:`Sampler`), default :class:`ApproachSampler`
            (pass ``UniformSampler(n_commands)`` for the paper's uniform warm start).
        fabric_config: fabric gains (None, ``gfcs.FabricConfig``, dict, or file path).
        threads: worker threads for the batch evaluation (None: all cores).
        progress: show a tqdm progress bar over the batches.
        settings: :class:`RolloutSettings` (dt, t_max, tolerances, penalty).
        top_m: number of best candidates kept in ``result.top`` (Alg. 1 output).
        sigma0: initial CMA-ES step as a fraction of the joint ranges.
        mesh_candidates: with a mesh checker, at most this many candidates (in cost order, reached ones)
            are rolled out and checked against the meshes before giving up (see the module docstring).
            32: on MotionBenchMaker the 9th to 19th reaching candidate was the first mesh-clear one for 6
            problems (8 left them failed); each extra check costs one rollout and 0.05-0.3 s of mesh
            distances, after the solve.
        length_slack: relative cost slack ε ≥ 0: among the reached candidates with cost ≤ (1 + ε) × the
            lowest, the one with the shortest end-effector path is preferred (see the module docstring).
            0.1: on all 350 MotionBenchMaker problems (5 batches) hand paths 2-5 % shorter per class,
            C-space paths 2-6 % and motions 1-5 % longer (BENCHMARKS.md); 0 returns the lowest-cost
            candidate (the paper's Alg. 1).
        callback: called after every batch with a :class:`BatchInfo`; True stops early.
        max_commands: when the returned candidate with n free commands does not succeed, solve again
            with n + 1, up to ``max_commands`` (default: ``n_commands + 1`` with the default sampler,
            whose approach candidates then enter the goal's corridor in two steps; ``n_commands``, no
            retry, with a sampler of your own, which proposes a fixed number of commands). The first
            success is returned, else the lowest-cost attempt; ``solve_time`` and ``n_evaluations``
            then cover every attempt and ``settings["commands_tried"]`` lists them.
        mesh_retry_margin: when every attempt failed and one of them only because a collision *mesh*
            touched (the goal reached with the spheres clear), solve again (``n_commands``, then one more
            up to ``max_commands`` as above) with the fabric's obstacle margin (``obstacles.margin``)
            raised by this much [m], ≥ 0 (0: no such attempt); ``settings["obstacle_margins_tried"]`` then
            lists the margin of every attempt. The
            spheres leave up to 12-20 mm of the MBM Panda's meshes uncovered (:func:`gfcs.problems.mbm_panda`);
            0.002: on MotionBenchMaker cage 48, which no candidate of either attempt solved with seed 1,
            solved with 4 mm for seeds 0-2, while 4 mm for every problem lost cage 47 (BENCHMARKS.md).
        mesh_retries: how many such rounds, ≥ 0, the k-th with the margin raised by k ×
            ``mesh_retry_margin``; a round runs only while the previous one failed with a mesh-only
            failure among its attempts. 2: the shipped Panda's thin spheres on MotionBenchMaker cage 13
            touched a bar with their meshes at +2 mm and solved it at +4 mm (BENCHMARKS.md).
        mesh_margin: with a mesh checker, the clearance [m] the collision meshes must keep for a trajectory
            to succeed (:func:`gfcs.metrics.trajectory_metrics`); candidates closer than that are passed
            over like colliding ones. Default :data:`gfcs.metrics.DEFAULT_MESH_MARGIN` (1 mm); 0: contact
            only.
        goal_contact_slack: the goal-contact attempt [m], ≥ 0 (0: none). When every attempt failed, the
            problem has a mesh checker, the goal's meshes clear the obstacles and each other by more than
            ``mesh_margin``, and some collision spheres at the goal come nearer the obstacles than the
            fabric's margin plus this slack (conservative spheres overlapping an object the meshes clear,
            e.g. a grasp), solve once more with those spheres' obstacle margins lowered to their goal
            clearance minus the slack (:meth:`gfcs.Fabric.with_obstacle_margins`; possibly negative), so
            that the goal keeps the barrier ``slack`` away, and judge the spheres against the obstacles down
            to the goal's deepest overlap minus twice the slack (semi-implicit Euler overshoots a barrier by
            a millimetre or two; ``clearance_floor`` of
            :func:`gfcs.metrics.trajectory_metrics`); the meshes judge the rest. ``settings["goal_contact"]``
            of that attempt holds the margins and the floor.
        thin_spheres: when the robot is the shipped Panda and the problem has its mesh checker
            (:func:`gfcs.problems.thin_sphere_model`), the fabric runs on its thin spheres, which reach
            beyond the meshes far less than the covering ones and miss them by up to 8 mm, with the obstacle
            margin raised by :data:`THIN_SPHERE_MARGIN`; the collision polytopes judge the motion. The
            result's ``robot`` is then that model and ``settings["sphere_model"]`` is ``"thin"``. The
            covering spheres close gaps the arm passes through (a MotionBenchMaker cage's bars); the thin
            ones solved 30 more of the 347 MotionBenchMaker problems in one batch (BENCHMARKS.md).
            ``method="gf"`` keeps the robot's own spheres.
        sphere_fallback: when the thin-sphere solve failed (retries included), solve again on the
            robot's own spheres and return the better of the two (:func:`combine_attempts`).

    Returns:
        :class:`gfcs.results.SolveResult` (trajectory of the best sequence, metrics, per-batch data;
        ``solve_time`` the optimisation, ``wall_time`` this whole call).

    Raises:
        ValueError: bad arguments, or a robot without collision spheres in a scene with obstacles (the
            fabric would not see them).
    """
    called = time.perf_counter()

    def done(result: SolveResult) -> SolveResult:
        return dataclasses.replace(result, wall_time=time.perf_counter() - called)

    settings = settings or RolloutSettings()
    if method not in ("gfcs", "gf"):
        raise ValueError(f"method must be 'gfcs' or 'gf', got {method!r}")
    mesh_margin = _metrics._non_negative("mesh_margin", mesh_margin, " [m]")
    robot, scene = problem.robot, problem.scene
    dof = int(robot.dof)
    q0 = np.asarray(problem.q0, dtype=np.float64)
    qd0 = np.asarray(problem.qd0, dtype=np.float64)
    goal = np.asarray(problem.goal, dtype=np.float64)
    fabric = make_fabric(problem, fabric_config)
    mesh_checker = getattr(problem, "mesh_checker", None)
    common = dict(problem=str(problem.name), cls=str(getattr(problem, "cls", "")), seed=int(seed),
                  q0=q0, qd0=qd0, goal=goal, fabric_config=fabric.config.to_dict(), robot=robot,
                  joint_names=list(robot.joint_names),
                  pose_goal=(getattr(problem, "meta", None) or {}).get("pose_goal"))

    if method == "gf":
        start = time.perf_counter()
        traj, cost, reached, t_stars = rollout_commands(fabric, q0, qd0, goal, np.zeros((0, dof)), settings)
        elapsed = time.perf_counter() - start
        met = _metrics.trajectory_metrics(robot, scene, traj.t, traj.q, goal, mesh_checker=mesh_checker,
                                          mesh_margin=mesh_margin)
        return done(SolveResult(method="gf", commands=np.zeros((0, dof)), cost=cost, reached=reached,
                                t_stars=t_stars, trajectory=traj, success=bool(met["success"]), metrics=met,
                                n_evaluations=1, solve_time=elapsed,
                                settings=_settings_dict(settings, mesh_margin=mesh_margin), **common))

    n_commands = int(n_commands)
    if n_commands < 1:
        raise ValueError(f"n_commands must be ≥ 1 for method 'gfcs', got {n_commands}")
    length_slack = _metrics._non_negative("length_slack", length_slack, "")
    if max_commands is None:
        max_commands = n_commands + 1 if sampler is None else n_commands
    max_commands = int(max_commands)
    if max_commands < n_commands:
        raise ValueError(f"max_commands must be ≥ n_commands ({n_commands}), got {max_commands}")
    if sampler is not None and max_commands != n_commands:
        raise ValueError("max_commands > n_commands needs the default sampler: a sampler of your own "
                         f"proposes {n_commands} command(s) per candidate")
    mesh_retry_margin = _metrics._non_negative("mesh_retry_margin", mesh_retry_margin, " [m]")
    if isinstance(mesh_retries, bool) or not isinstance(mesh_retries, (int, np.integer)) or mesh_retries < 0:
        raise ValueError(f"mesh_retries must be an integer ≥ 0, got {mesh_retries!r}")
    mesh_retries = int(mesh_retries)
    goal_contact_slack = _metrics._non_negative("goal_contact_slack", goal_contact_slack, " [m]")
    options = dict(batches=batches, population=population, seed=seed, threads=threads, progress=progress,
                   settings=settings, top_m=top_m, sigma0=sigma0, mesh_candidates=mesh_candidates,
                   length_slack=length_slack, mesh_margin=mesh_margin,
                   callback=callback)

    def margin_raised(by: float) -> Any:  # the fabric's configuration, obstacles kept ``by`` m further off
        margin = float(common["fabric_config"]["obstacles"]["margin"]) + by
        return fabric.config.replace({"obstacles": {"margin": margin}})

    def attempt(n: int, fab: Any = fabric, info: Dict[str, Any] = common, floor: float = 0.0) -> SolveResult:
        return _solve_commands(problem, fab, mesh_checker, info, n,
                               sampler if sampler is not None else ApproachSampler(n), clearance_floor=floor,
                               **options)

    thin = (_problems.thin_sphere_model(robot) if thin_spheres and mesh_checker is not None
            and dataclasses.is_dataclass(problem) else None)
    if thin is not None:
        def again(prob: Any, config: Any) -> SolveResult:
            return solve(prob, method, batches, population, n_commands, seed, sampler, config, threads, progress,
                         settings=settings, top_m=top_m, sigma0=sigma0, mesh_candidates=mesh_candidates,
                         length_slack=length_slack, callback=callback, max_commands=max_commands,
                         mesh_retry_margin=mesh_retry_margin, mesh_retries=mesh_retries, mesh_margin=mesh_margin,
                         goal_contact_slack=goal_contact_slack, thin_spheres=False)

        thin_result = again(dataclasses.replace(problem, robot=thin), margin_raised(THIN_SPHERE_MARGIN))
        thin_result = dataclasses.replace(thin_result, settings={**thin_result.settings, "sphere_model": "thin"})
        if thin_result.success or not sphere_fallback:
            return done(thin_result)
        return done(combine_attempts([thin_result, again(problem, fabric.config)]))

    def one_round(fab: Any = fabric, info: Dict[str, Any] = common) -> List[SolveResult]:
        """n_commands free commands, then one more up to max_commands, until an attempt succeeds."""
        results: List[SolveResult] = []
        for n in range(n_commands, max_commands + 1):
            results.append(attempt(n, fab, info))
            if results[-1].success:
                break
        return results

    rounds = [one_round()]
    for k in range(1, mesh_retries + 1):  # mesh retries: the obstacle margin k × mesh_retry_margin wider
        last = rounds[-1]
        if last[-1].success or mesh_retry_margin == 0 or not any(map(_mesh_collision_only, last)):
            break
        wider = make_fabric(problem, margin_raised(k * mesh_retry_margin))
        rounds.append(one_round(wider, {**common, "fabric_config": wider.config.to_dict()}))
    attempts = [result for round_ in rounds for result in round_]
    contact = None
    if not attempts[-1].success and goal_contact_slack > 0 and mesh_checker is not None:
        contact = goal_contact(problem, fabric, goal_contact_slack, mesh_checker, mesh_margin)
    if contact is not None:
        margins, floor = contact
        attempts.append(attempt(n_commands, fabric.with_obstacle_margins(margins), floor=floor))
    return done(combine_attempts(attempts))


def goal_contact(problem: Any, fabric: Any, slack: float, mesh_checker: Any,
                 mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN) -> Optional[Tuple[np.ndarray, float]]:
    """Per-sphere obstacle margins for a goal at which collision spheres come nearer the obstacles than
    ``fabric``'s margin (see ``goal_contact_slack`` of :func:`solve`): (margins (S,) m, clearance floor m),
    or None when no sphere does, when the goal's meshes do not clear the obstacles and each other by more
    than ``mesh_margin``, or when a sphere's centre lies within ``slack`` of an obstacle's inside (the sphere
    model cannot describe that contact).

    margin_i = min(m, c_i − slack) with m = ``obstacles.margin`` and c_i the clearance of sphere i at the
    goal; floor = min(0, min_i c_i) − 2·slack (the barrier's slack, and as much again for the overshoot of
    semi-implicit Euler steps into a barrier: on MotionBenchMaker's cage with the shipped Panda's spheres,
    0.3-1.3 mm beyond the barrier for 6 motions whose meshes stayed 2.2-6.8 mm clear).
    """
    goal = np.asarray(problem.goal, dtype=np.float64)
    robot, scene = problem.robot, problem.scene
    clearance = _metrics.sphere_clearances(robot, scene, goal[None])[0]
    margin = float(fabric.config.to_dict()["obstacles"]["margin"])
    margins = np.minimum(margin, clearance - slack)
    radii = np.asarray(robot.sphere_radii, dtype=np.float64)
    if not np.any(margins < margin) or np.any(margins <= -radii):
        return None
    if not _metrics.mesh_verdict(mesh_checker, scene, goal, mesh_margin)[2]:
        return None
    return margins, float(min(0.0, clearance.min()) - 2.0 * slack)


def _mesh_collision_only(result: SolveResult) -> bool:
    """``result`` failed only because a collision mesh touched: validated against meshes, and a success
    under the sphere model (goal reached, spheres clear, joint limits kept)."""
    m = result.metrics
    return "mesh_clearance" in m and not result.success and bool(m["sphere_success"])


def combine_attempts(attempts: List[SolveResult]) -> SolveResult:
    """The result of solving one problem in several attempts, in order (:func:`solve`'s retry): the last
    attempt if it succeeded, else the lowest-cost one, with ``solve_time`` and ``n_evaluations`` summed
    over all attempts and ``settings["commands_tried"]`` listing their command counts (and, when the
    attempts' fabrics differ in ``obstacles.margin``, ``settings["obstacle_margins_tried"]`` their margins
    [m]). One attempt is returned unchanged.
    """
    if len(attempts) == 1:
        return attempts[0]
    best = attempts[-1] if attempts[-1].success else min(attempts, key=lambda r: r.cost)
    commands: List[int] = []
    margins: List[Optional[float]] = []
    for r in attempts:  # an attempt that combines attempts itself contributes each of them
        tried = r.settings.get("commands_tried", [int(r.settings["n_commands"])])
        commands += tried
        margin = r.fabric_config["obstacles"]["margin"] if r.fabric_config else None
        margins += r.settings.get("obstacle_margins_tried", [margin] * len(tried))
    extra = {"obstacle_margins_tried": margins} if len(set(margins)) > 1 else {}
    return dataclasses.replace(
        best,
        solve_time=float(sum(r.solve_time for r in attempts)),
        n_evaluations=int(sum(r.n_evaluations for r in attempts)),
        settings={**best.settings, "commands_tried": commands, **extra},
    )


def _solve_commands(
    problem: Any, fabric: Any, mesh_checker: Any, common: Dict[str, Any], n_commands: int, sampler: Sampler,
    *, batches: int, population: int, seed: int, threads: Optional[int], progress: bool,
    settings: RolloutSettings, top_m: int, sigma0: float, mesh_candidates: int, length_slack: float,
    mesh_margin: float, callback: Optional[Callable[[BatchInfo], Optional[bool]]],
    clearance_floor: float = 0.0,
) -> SolveResult:
    """GFCS with exactly ``n_commands`` free commands (the body of :func:`solve`). A ``clearance_floor``
    below 0 also raises ``settings.collision_tol`` to its overlap: what success accepts is no collision in
    the cost either."""
    if clearance_floor < 0.0:
        settings = dataclasses.replace(settings, collision_tol=max(settings.collision_tol, -clearance_floor))
    robot = problem.robot
    dof = int(robot.dof)
    q0, qd0, goal = common["q0"], common["qd0"], common["goal"]
    dim = n_commands * dof
    lower = np.tile(np.asarray(robot.lower, dtype=np.float64), n_commands)
    upper = np.tile(np.asarray(robot.upper, dtype=np.float64), n_commands)
    eval_kwargs = settings.as_kwargs()
    commanded = fabric_goal(fabric, goal, settings.limit_hold_off)

    def cost_fn(y: np.ndarray) -> np.ndarray:
        costs, _reached, _clearance = fabric.evaluate(q0, qd0, commanded, y, threads=threads, **eval_kwargs)
        return np.asarray(costs, dtype=np.float64)

    def warm_start(n: int, rng: np.random.Generator) -> np.ndarray:
        y = np.asarray(sampler.sample(problem, n, rng), dtype=np.float64)
        if y.ndim != 2 or y.shape[1] != dim:
            raise ValueError(f"sampler {type(sampler).__name__}: expected shape ({n}, {dim}) "
                             f"({n_commands} commands × {dof} joints), got {y.shape}")
        # The last candidate commands the goal itself: the local fabric (GF) is always among the
        # candidates, so GFCS is never worse than its local baseline.
        y = y.copy()
        y[-1] = np.tile(np.asarray(goal, dtype=np.float64), n_commands)
        return y

    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=int(batches), desc=f"{problem.name} ({n_commands} cmd)", unit="batch", leave=False)

    def on_batch(info: BatchInfo) -> Optional[bool]:
        if bar is not None:
            bar.update(1)
            bar.set_postfix(best=f"{info.best_cost:.3g}")
        return callback(info) if callback is not None else None

    try:
        opt = solve_gfcop(cost_fn, dim, lower, upper, sampler=warm_start, batches=batches,
                          population=population, sigma0=sigma0, seed=seed, top_m=top_m,
                          callback=on_batch)
    finally:
        if bar is not None:
            bar.close()

    commands, traj, cost, reached, t_stars, met = _select_candidate(
        fabric, problem, opt, n_commands, settings, mesh_checker, mesh_candidates, length_slack, threads,
        mesh_margin, clearance_floor)
    contact = {} if fabric.obstacle_margins is None else {
        "goal_contact": {"clearance_floor": clearance_floor,
                         "obstacle_margins": np.asarray(fabric.obstacle_margins).tolist()}}
    return SolveResult(
        method="gfcs",
        commands=commands,
        cost=cost,
        reached=reached,
        t_stars=t_stars,
        trajectory=traj,
        success=bool(met["success"]),
        metrics=met,
        top=[(x.copy(), float(c)) for x, c in zip(opt.top_x, opt.top_costs)],
        batch_times=opt.batch_times,
        batch_best_costs=opt.batch_best_costs,
        batch_best_commands=opt.batch_best_x,
        n_evaluations=opt.n_evaluations,
        solve_time=float(np.sum(opt.batch_times)),
        settings=_settings_dict(settings, batches=int(batches), population=int(population),
                                n_commands=n_commands, sigma0=float(sigma0), top_m=int(top_m),
                                length_slack=float(length_slack), mesh_margin=mesh_margin,
                                sampler=type(sampler).__name__, **contact),
        **common,
    )


def replay(
    result: SolveResult,
    scene: Any,
    robot: Any = None,
    fabric_config: Any = None,
    settings: Optional[RolloutSettings] = None,
    commands: Optional[Any] = None,
    mesh_checker: Optional[Any] = None,
    mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN,
) -> SolveResult:
    """Replay a solved command sequence in another scene without re-optimising (GFCS Sec. V, Fig. 4).

    The fabric's local avoidance reacts to obstacles the optimisation never saw; the commands stay fixed.

    Args:
        result: a :class:`SolveResult` (from :func:`solve` or :meth:`SolveResult.from_json`).
        scene: the new ``gfcs.Scene`` (e.g. the original plus new obstacles).
        robot: the robot; default ``result.robot`` (set by :func:`solve`; results loaded from JSON
            need it passed explicitly). A result planned on the shipped Panda's thin spheres
            (``settings["sphere_model"] == "thin"``) replays on :func:`gfcs.problems.thin_sphere_model`
            of it, the fabric it was planned with.
        fabric_config: default: the configuration stored in ``result``.
        settings: default: the rollout settings stored in ``result``.
        commands: (n, dof) commands to replay instead of ``result.commands`` (e.g. a row of
            ``result.batch_best_commands`` to get the first-batch solution).
        mesh_checker: optional :class:`gfcs.MeshChecker` (e.g. ``problem.mesh_checker``): the replay's
            metrics then include the mesh clearances, and success requires them > ``mesh_margin`` [m].

    Returns:
        A copy of ``result`` whose trajectory, cost, reached flag, t_stars, metrics and success are those
        of the replay (optimisation data unchanged).

    Raises:
        ValueError: no robot, or a robot without collision spheres in a scene with obstacles (the fabric
            would not see them).
    """
    robot = robot if robot is not None else result.robot
    if robot is None:
        raise ValueError("replay: this result carries no robot (loaded from JSON?): pass robot=")
    if result.settings.get("sphere_model") == "thin":
        robot = _problems.thin_sphere_model(robot) or robot
    if settings is None:
        names = {f.name for f in dataclasses.fields(RolloutSettings)}
        settings = RolloutSettings(**{k: v for k, v in result.settings.items() if k in names})
    if fabric_config is None:
        fabric_config = result.fabric_config
    import gfcs

    if isinstance(fabric_config, os.PathLike):
        fabric_config = str(fabric_config)
    fabric = gfcs.Fabric(robot, scene, fabric_config)
    dof = result.dof
    cmds = np.asarray(result.commands if commands is None else commands, dtype=np.float64).reshape(-1, dof)
    traj, cost, reached, t_stars = rollout_commands(fabric, result.q0, result.qd0, result.goal, cmds, settings)
    met = _metrics.trajectory_metrics(robot, scene, traj.t, traj.q, result.goal, mesh_checker=mesh_checker,
                                      mesh_margin=mesh_margin)
    return dataclasses.replace(result, commands=cmds, trajectory=traj, cost=cost, reached=reached,
                               t_stars=t_stars, metrics=met, success=bool(met["success"]), robot=robot)
