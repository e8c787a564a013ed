"""Algorithm 1 of GFCS (Sec. IV-A, "SolveGFCOP with warm-started CMA-ES") for any batched cost over a box.

The first batch is the sampler's candidates (the warm start), every later batch is drawn from CMA-ES;
every candidate and cost is kept, the best so far is reported after every batch (anytime, with a
per-batch callback), and the top-m candidates are returned.

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

Early stop: ``stall_batches`` > 0 ends the optimisation once that many batches in a row have not lowered
the best cost by more than ``stall_tol`` relative (:func:`stalled`); off by default, so the paper's
fixed batch count holds unless asked.

Time budget: with a ``deadline``, batches stop when no candidate fits before it, and the last batch is cut
to the candidates that fit (see :func:`solve_gfcop`).
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from dataclasses import dataclass
from typing import Any, Callable, List, Optional, Tuple, Union

import numpy as np

from gfcs.errors import InvalidValueError

__all__ = ["BatchInfo", "OptimResult", "InitialCandidates", "solve_gfcop", "stalled"]


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

    def first_batches(self, b: int) -> "OptimResult":
        """This optimisation as it stood after its first ``b`` batches (≥ 1): what a run with ``batches=b``
        and the same seed returns, since every batch depends only on the ones before it."""
        keep = self.all_batches < int(b)
        xs, cs = self.all_x[keep], self.all_costs[keep]
        m = self.top_x.shape[0]
        order = np.argsort(cs, kind="stable")[:m]
        return OptimResult(best_x=self.batch_best_x[:b][-1].copy(), best_cost=float(self.batch_best_costs[:b][-1]),
                           top_x=xs[order], top_costs=cs[order], all_x=xs, all_costs=cs,
                           all_batches=self.all_batches[keep], batch_best_costs=self.batch_best_costs[:b],
                           batch_best_x=self.batch_best_x[:b], batch_times=self.batch_times[:b])


InitialCandidates = Union[None, np.ndarray, Callable[[int, np.random.Generator], np.ndarray]]


def _box(lower: Any, upper: Any, dim: int) -> Tuple[np.ndarray, np.ndarray]:
    lo = np.asarray(lower, dtype=np.float64).reshape(-1)
    up = np.asarray(upper, dtype=np.float64).reshape(-1)
    if lo.shape == (1,):
        lo = np.full(dim, lo[0])
    if up.shape == (1,):
        up = np.full(dim, up[0])
    if lo.shape != (dim,) or up.shape != (dim,):
        raise InvalidValueError(f"lower/upper: expected shape ({dim},), got {lo.shape} and {up.shape}")
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(up))):
        raise InvalidValueError("lower/upper contain NaN or infinite values")
    if not np.all(up > lo):
        bad = int(np.argmax(~(up > lo)))
        raise InvalidValueError(f"upper must exceed lower in every coordinate (coordinate {bad}: "
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
            raise InvalidValueError(f"sampler: expected candidates of shape ({n}, {dim}), got {y.shape}")
        if not np.all(np.isfinite(y)):
            raise InvalidValueError("sampler: candidates contain NaN or infinite values")
        y = y[:n]
        if y.shape[0] < n:
            y = np.vstack([y, rng.uniform(lo, up, size=(n - y.shape[0], dim))])
    return np.clip(y, lo, up)


#: Modules pycma imports at its top level for features Alg. 1 does not use (surrogate models' rank
#: correlation, plotting); together they take 0.75 s of its 0.95 s import time.
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


# pycma (~35 ms) is imported with the planner, once per process, not by its first solve: a solve's time is
# its optimisation and selection.
_import_cma()


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
    deadline: Optional[float] = None,
    reserve_batches: float = 0.0,
    stall_batches: int = 0,
    stall_tol: float = 0.01,
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
        deadline: a ``time.perf_counter()`` value by which the optimisation should end (None: none). The
            first batch always runs; before each later one, the time per candidate measured so far says
            how many candidates fit before the deadline: none -> stop, fewer than ``population`` -> that
            many of CMA-ES's candidates are evaluated as the last batch (no update follows it).
        reserve_batches: with a deadline, the time of this many whole batches (as measured) is left free
            before it, for what the caller does after the optimisation (rolling the best candidates out).
        stall_batches: early stop (0: off, every batch runs): after batch j ≥ ``stall_batches``, stop when
            the best cost has fallen by at most ``stall_tol`` · |best cost| over the last ``stall_batches``
            batches (see :func:`stalled`).
        stall_tol: the relative improvement below which batches count as stalled (≥ 0).

    Returns:
        :class:`OptimResult` with all candidates, the top-m and the per-batch best costs and times.
    """
    cma = _import_cma()
    dim = _check_arguments(dim, batches, population, top_m, sigma0, seed)
    if int(stall_batches) < 0 or not (math.isfinite(stall_tol) and stall_tol >= 0):
        raise InvalidValueError(f"stall_batches must be ≥ 0 and stall_tol a number ≥ 0, got {stall_batches} "
                                f"and {stall_tol}")
    lo, up = _box(lower, upper, dim)
    span = up - lo
    sampler_rng, cma_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(2))

    # The warm start is part of the first batch (Alg. 1 line 2), so its time counts in batch 0's.
    start = time.perf_counter()
    y0 = _initial_batch(sampler, int(population), dim, sampler_rng, lo, up)
    sampling_time = time.perf_counter() - start
    u0 = (y0 - lo) / span
    es = _strategy(cma, u0, float(sigma0), int(population), cma_rng)

    history = _History(y0[0])
    per_candidate = 0.0
    for j in range(int(batches)):
        fit = int(population) if j == 0 else _candidates_before(deadline, per_candidate, int(population),
                                                                reserve_batches)
        if fit == 0:
            break
        start = time.perf_counter()
        if j == 0:
            es.inject([es.boundary_handler.inverse(u) for u in u0], force=True)
        asked = es.ask()
        y = y0 if j == 0 else np.clip(lo + np.asarray(asked) * span, lo, up)[:fit]
        costs = _evaluate(cost_fn, y)
        if fit == int(population):  # a cut batch is the last: nothing to update
            _tell(es, asked, costs)
        per_candidate = max(per_candidate, (time.perf_counter() - start) / y.shape[0])
        info = history.add(j, y, costs, time.perf_counter() - start + (sampling_time if j == 0 else 0.0))
        if (callback is not None and callback(info)) or fit < int(population):
            break
        if stalled(history.best_costs, int(stall_batches), float(stall_tol)):
            break
    return history.result(int(top_m))


def stalled(best_costs: List[float], batches: int, tol: float) -> bool:
    """The early-stop criterion of :func:`solve_gfcop`: with ``best_costs`` the best cost so far after each
    batch (non-increasing), True when ``batches`` ≥ 1 batches followed another and together lowered the
    best cost by at most ``tol`` times its magnitude: c[-1-batches] − c[-1] ≤ tol · |c[-1-batches]|. An
    infinite best cost (nothing finite yet) never counts as stalled."""
    if batches < 1 or len(best_costs) <= batches:
        return False
    before, now = best_costs[-1 - batches], best_costs[-1]
    return math.isfinite(before) and before - now <= tol * abs(before)


def _check_arguments(dim: Any, batches: Any, population: Any, top_m: Any, sigma0: Any, seed: Any) -> int:
    """The arguments of :func:`solve_gfcop` checked, each error naming its argument; ``dim`` as an int."""
    dim = int(dim)
    if dim < 1:
        raise InvalidValueError(f"dim must be ≥ 1, got {dim}")
    if int(batches) < 1:
        raise InvalidValueError(f"batches must be ≥ 1, got {batches}")
    if int(population) < 2:
        raise InvalidValueError(f"population must be ≥ 2, got {population}")
    if int(top_m) < 1:
        raise InvalidValueError(f"top_m must be ≥ 1, got {top_m}")
    if not (math.isfinite(sigma0) and sigma0 > 0):
        raise InvalidValueError(f"sigma0 must be a positive number, got {sigma0}")
    if int(seed) < 0:
        raise InvalidValueError(f"seed must be a non-negative integer, got {seed}")
    return dim


def _strategy(cma: Any, u0: np.ndarray, sigma0: float, population: int, rng: np.random.Generator) -> Any:
    """CMA-ES in the unit box, its mean at the warm start's mean, its normal variates from ``rng``."""
    options = {
        "bounds": [0.0, 1.0],
        "popsize": population,
        "seed": math.nan,  # do not touch numpy's global RNG; randn below is our own generator
        "randn": lambda *shape: rng.standard_normal(shape),
        "verbose": -9,
    }
    return cma.CMAEvolutionStrategy(np.clip(u0.mean(axis=0), 0.0, 1.0).tolist(), sigma0, options)


def _evaluate(cost_fn: Callable[[np.ndarray], Any], y: np.ndarray) -> np.ndarray:
    """The costs (N,) of the candidates ``y`` (N, dim), NaN as +inf."""
    costs = np.asarray(cost_fn(y), dtype=np.float64).reshape(-1)
    if costs.shape != (y.shape[0],):
        raise InvalidValueError(f"cost_fn: expected {y.shape[0]} costs, got shape {costs.shape}")
    return np.where(np.isnan(costs), math.inf, costs)


def _tell(es: Any, asked: Any, costs: np.ndarray) -> None:
    """Update CMA-ES with a whole batch. CMA-ES ranks candidates; infinite costs rank last, one step behind
    the worst finite one."""
    finite = costs[np.isfinite(costs)]
    worst = float(finite.max()) if finite.size else 0.0
    es.tell(asked, np.where(np.isfinite(costs), costs, worst + 1.0 + abs(worst)).tolist())


class _History:
    """Every candidate, cost and batch of one run of :func:`solve_gfcop`, and the best so far."""

    def __init__(self, first: np.ndarray) -> None:
        self.x: List[np.ndarray] = []
        self.c: List[np.ndarray] = []
        self.b: List[np.ndarray] = []
        self.best_costs: List[float] = []
        self.best_xs: List[np.ndarray] = []
        self.times: List[float] = []
        self.best_x, self.best_cost = first.copy(), math.inf
        self.elapsed = 0.0

    def add(self, j: int, y: np.ndarray, costs: np.ndarray, batch_time: float) -> BatchInfo:
        """Record batch ``j``; what the per-batch callback receives."""
        self.elapsed += batch_time
        k = int(np.argmin(costs))
        if costs[k] < self.best_cost:
            self.best_cost, self.best_x = float(costs[k]), y[k].copy()
        self.x.append(y.copy())
        self.c.append(costs)
        self.b.append(np.full(y.shape[0], j))
        self.best_costs.append(self.best_cost)
        self.best_xs.append(self.best_x.copy())
        self.times.append(batch_time)
        return BatchInfo(j, y.copy(), costs.copy(), self.best_x.copy(), self.best_cost, batch_time, self.elapsed)

    def result(self, top_m: int) -> OptimResult:
        xs, cs, bs = np.vstack(self.x), np.concatenate(self.c), np.concatenate(self.b)
        order = np.argsort(cs, kind="stable")[:top_m]
        return OptimResult(best_x=self.best_x, best_cost=self.best_cost, top_x=xs[order], top_costs=cs[order],
                           all_x=xs, all_costs=cs, all_batches=bs, batch_best_costs=np.asarray(self.best_costs),
                           batch_best_x=np.vstack(self.best_xs), batch_times=np.asarray(self.times))


def _candidates_before(deadline: Optional[float], per_candidate: float, population: int,
                       reserve_batches: float = 0.0) -> int:
    """How many candidates of the next batch fit before ``deadline`` at ``per_candidate`` seconds each, with
    ``reserve_batches`` whole batches' time kept free: the whole ``population`` without a deadline, else
    between 0 and ``population``."""
    if deadline is None:
        return population
    remaining = deadline - time.perf_counter() - reserve_batches * per_candidate * population
    if remaining <= 0.0:
        return 0
    if per_candidate <= 0.0:
        return population
    return int(min(population, remaining // per_candidate))
