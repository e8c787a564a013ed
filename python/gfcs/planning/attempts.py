"""Attempts: one GFCS optimisation (Alg. 1) with a given command count, robot model and fabric, and the
record of what it gave.

An :class:`Attempt` says what it plans with; :func:`run_attempt` runs it (CMA-ES, then candidate
selection) and returns an :class:`AttemptRecord`; :func:`combine_records` turns the records of one solve
into its :class:`gfcs.results.SolveResult` (the last attempt if it succeeded, else the lowest-cost one).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional

import numpy as np

from gfcs.errors import InvalidValueError
from gfcs.planning.finish import FinishOptions
from gfcs.planning.gfcop import BatchInfo, OptimResult, solve_gfcop
from gfcs.planning.models import PlanningModel
from gfcs.planning.rollout import RolloutSettings, fabric_goal
from gfcs.planning.samplers import Sampler
from gfcs.planning.selection import (Candidate, SelectionOptions, mesh_contact_only, model_success,
                                     select_candidate)
from gfcs.results import SolveResult

__all__ = ["Attempt", "AttemptRecord", "OptimOptions", "run_attempt", "combine_records", "combine_attempts"]


@dataclass(frozen=True)
class Attempt:
    """What one attempt plans with.

    Attributes:
        model: the planning model (robot spheres and their margin offset).
        n_commands: free commands n (the decision variable has n·dof entries).
        kind: ``"plan"``, ``"goal_contact"`` (per-sphere margins and a clearance floor, see
            :class:`gfcs.planning.policies.GoalContact`) or ``"cover"`` (per-sphere margins that cover the
            meshes, :class:`gfcs.planning.policies.MeshCover`).
        margin_round: k of the wider-margin policy: the obstacle margin is the model's plus k × ``margin_step``.
        margin_step: [m] the step of that policy (0 for k = 0).
        obstacle_margins: (S,) per-sphere obstacle margins [m] of a goal-contact or cover attempt, else None.
        self_margins: (P,) per-pair self-collision margins [m] of a cover attempt (in the order of
            ``robot.self_collision_pairs``), else None.
        clearance_floor: [m, ≤ 0] how far spheres may overlap obstacles for success (goal contact), else 0.
        self_clearance_floor: [m, ≤ 0] how far spheres may overlap each other for success (an endpoint in
            sphere self-contact, :func:`gfcs.planning.policies.endpoint_self_contact`), else 0.
        restart: k of the restart policy (:class:`gfcs.planning.policies.Restart`): the optimiser runs with
            its own seed and a population 2^k times the solve's (IPOP-CMA-ES); 0 for the solve's own.
    """

    model: PlanningModel
    n_commands: int
    kind: str = "plan"
    margin_round: int = 0
    margin_step: float = 0.0
    obstacle_margins: Optional[tuple] = None
    self_margins: Optional[tuple] = None
    clearance_floor: float = 0.0
    restart: int = 0
    self_clearance_floor: float = 0.0

    @property
    def label(self) -> str:
        """A short description, e.g. ``"thin, 2 commands, margin +2 mm"``."""
        text = f"{self.model.name}, {self.n_commands} command{'s' if self.n_commands != 1 else ''}"
        if self.margin_round:
            text += f", margin +{self.margin_round * self.margin_step * 1000:.3g} mm"
        if self.kind == "goal_contact":
            text += ", goal contact"
        if self.kind == "cover":
            text += ", mesh cover"
        if self.restart:
            text += f", restart {self.restart}"
        return text

    def obstacle_margin(self, base: float) -> float:
        """The obstacle margin [m] of this attempt's fabric, for a configured margin ``base``."""
        margin = float(base) + self.model.margin_offset
        return margin + self.margin_round * self.margin_step if self.margin_round else margin

    def settings(self, base: float) -> Dict[str, Any]:
        """What the attempt plans with, as a JSON-ready dict."""
        return {"model": self.model.name, "n_commands": int(self.n_commands), "kind": self.kind,
                "obstacle_margin": self.obstacle_margin(base), "clearance_floor": float(self.clearance_floor),
                "restart": int(self.restart)}

    def optim_options(self, options: "OptimOptions") -> "OptimOptions":
        """The solve's ``options`` for this attempt: a restart's own seed (derived from the solve's seed and
        k) and population (2^k times the solve's)."""
        if not self.restart:
            return options
        seed = int(np.random.SeedSequence(int(options.seed), spawn_key=(int(self.restart),)).generate_state(1)[0])
        return dataclasses.replace(options, seed=seed, population=int(options.population) * 2 ** int(self.restart))


@dataclass
class AttemptRecord:
    """An attempt and what it gave.

    Attributes:
        attempt: the :class:`Attempt`.
        policy: the name of the policy that proposed it ("" for a solve's first attempt).
        result: its :class:`SolveResult`, or None when it was not run (the time budget ran out).
        time: wall time of the attempt [s] (optimisation, selection and validation).
        first_batch: when asked for, the result the attempt would have returned after its first batch.
        base_margin: the configured obstacle margin [m] the attempt's margin derives from.
        measuring_time: time spent on ``first_batch`` [s], left out of ``time``.
    """

    attempt: Attempt
    policy: str = ""
    result: Optional[SolveResult] = None
    time: float = 0.0
    first_batch: Optional[SolveResult] = None
    base_margin: float = 0.0
    measuring_time: float = 0.0

    @property
    def success(self) -> bool:
        return self.result is not None and bool(self.result.success)

    @property
    def mesh_collision_only(self) -> bool:
        """It failed only because a collision mesh came too near (:func:`gfcs.planning.selection.mesh_contact_only`
        of its metrics)."""
        return self.result is not None and mesh_contact_only(self.result.metrics)

    @property
    def outcome(self) -> str:
        """``"success"``, ``"mesh contact"`` (a success but for the meshes), ``"not validated in time"`` (a
        success before the meshes whose mesh check the budget cut short), ``"failure"`` or
        ``"not run"``."""
        if self.result is None:
            return "not run"
        if self.success:
            return "success"
        if self.mesh_collision_only:
            return "mesh contact"
        m = self.result.metrics
        if model_success(m) and not m.get("mesh_check_complete", True):
            return "not validated in time"
        return "failure"

    def to_dict(self) -> Dict[str, Any]:
        """JSON-ready summary: label, policy, settings, outcome, cost, time, evaluations, batches."""
        r = self.result
        return {"label": self.attempt.label, "policy": self.policy,
                "settings": self.attempt.settings(self.base_margin), "outcome": self.outcome,
                "success": self.success, "cost": float(r.cost) if r is not None else None,
                "time": float(self.time), "n_evaluations": int(r.n_evaluations) if r is not None else 0,
                "batches_run": int(len(r.batch_times)) if r is not None else 0}


@dataclass
class OptimOptions:
    """Options of every attempt of a solve (Alg. 1 and the selection). ``selection_share``: the share of the
    time left that a selection may spend while another attempt would fit after it
    (:meth:`gfcs.planning.budget.Budget.selection_deadline`; 1: up to the solve's end)."""

    batches: int = 5
    population: int = 32
    seed: int = 0
    threads: Optional[int] = None
    progress: bool = False
    top_m: int = 4
    sigma0: float = 0.25
    callback: Optional[Callable[[BatchInfo], Optional[bool]]] = None
    selection: SelectionOptions = field(default_factory=SelectionOptions)
    first_batch: bool = False
    stall_batches: int = 0
    stall_tol: float = 0.01
    selection_share: float = 1.0


def _warm_start(sampler: Sampler, problem: Any, n_commands: int, goal: np.ndarray) -> Callable[..., np.ndarray]:
    """Alg. 1's ``f_sampler`` for ``problem``: the sampler's candidates, the last one replaced by the goal
    itself, so that the local fabric (GF) is always among the candidates and GFCS is never worse than it."""
    dof = int(problem.robot.dof)
    dim = n_commands * dof

    def warm_start(n: int, rng: np.random.Generator) -> np.ndarray:
        y = np.asarray(sampler.sample(problem, n, rng), dtype=np.float64)
        if y.ndim != 2 or y.shape[1] != dim:
            raise InvalidValueError(f"sampler {type(sampler).__name__}: expected shape ({n}, {dim}) "
                                    f"({n_commands} commands × {dof} joints), got {y.shape}")
        y = y.copy()
        y[-1] = np.tile(goal, n_commands)
        return y

    return warm_start


def _optimise(problem: Any, fabric: Any, common: Dict[str, Any], n_commands: int, sampler: Sampler,
              settings: RolloutSettings, options: OptimOptions, deadline: Optional[float]) -> OptimResult:
    """Alg. 1 over n_commands free commands, cost eq. 4 evaluated by ``fabric.evaluate`` in parallel."""
    robot = problem.robot
    q0, qd0, goal = common["q0"], common["qd0"], common["goal"]
    eval_kwargs = settings.as_kwargs()
    commanded = fabric_goal(fabric, goal, settings.limit_hold_off)

    def cost_fn(y: np.ndarray) -> np.ndarray:
        costs, _reached, _clearance = fabric.evaluate(q0, qd0, commanded, y, threads=options.threads,
                                                      **eval_kwargs)
        return np.asarray(costs, dtype=np.float64)

    bar = None
    if options.progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=int(options.batches), desc=f"{problem.name} ({n_commands} cmd)", unit="batch", leave=False)

    def on_batch(info: BatchInfo) -> Optional[bool]:
        if bar is not None:
            bar.update(1)
            bar.set_postfix(best=f"{info.best_cost:.3g}")
        return options.callback(info) if options.callback is not None else None

    try:
        return solve_gfcop(cost_fn, n_commands * int(robot.dof), np.tile(np.asarray(robot.lower), n_commands),
                           np.tile(np.asarray(robot.upper), n_commands),
                           sampler=_warm_start(sampler, problem, n_commands, goal), batches=options.batches,
                           population=options.population, sigma0=options.sigma0, seed=options.seed,
                           top_m=options.top_m, callback=on_batch, deadline=deadline,
                           reserve_batches=0.0 if deadline is None else 1.0,
                           stall_batches=options.stall_batches, stall_tol=options.stall_tol)
    finally:
        if bar is not None:
            bar.close()


def _result(candidate: Candidate, opt: OptimResult, common: Dict[str, Any], settings_dict: Dict[str, Any]
            ) -> SolveResult:
    return SolveResult(
        method="gfcs", commands=candidate.commands, cost=candidate.cost, reached=candidate.reached,
        t_stars=candidate.t_stars, trajectory=candidate.trajectory, success=candidate.success,
        metrics=candidate.metrics, top=[(x.copy(), float(c)) for x, c in zip(opt.top_x, opt.top_costs)],
        batch_times=opt.batch_times, batch_best_costs=opt.batch_best_costs,
        batch_best_commands=opt.batch_best_x, n_evaluations=opt.n_evaluations,
        solve_time=float(np.sum(opt.batch_times)), settings=settings_dict, **common)


def run_attempt(problem: Any, fabric: Any, mesh_checker: Any, common: Dict[str, Any], attempt: Attempt,
                sampler: Sampler, settings: RolloutSettings, finish: FinishOptions, options: OptimOptions,
                recorded: Dict[str, Any], budget: Any = None) -> AttemptRecord:
    """Run ``attempt`` on ``problem`` (whose robot is the attempt's model) with ``fabric`` (its margins
    applied): Alg. 1, then :func:`gfcs.planning.selection.select_candidate`.

    ``common``: the SolveResult fields shared by every attempt of the solve (problem, start, goal, robot,
    fabric configuration, ...). ``recorded``: the result's ``settings`` besides the rollout settings (the
    attempt's own entries are added). ``budget``: the solve's :class:`gfcs.planning.budget.Budget`, or
    None. A ``clearance_floor`` or ``self_clearance_floor`` below 0 also raises ``settings.collision_tol`` to
    its overlap: what success accepts is no collision in the cost either.
    """
    started = time.perf_counter()
    options = attempt.optim_options(options)
    floor, self_floor = float(attempt.clearance_floor), float(attempt.self_clearance_floor)
    if min(floor, self_floor) < 0.0:
        settings = dataclasses.replace(settings, collision_tol=max(settings.collision_tol, -floor, -self_floor))
    n = int(attempt.n_commands)
    settings_dict = {**dataclasses.asdict(settings), **recorded}
    opt = _optimise(problem, fabric, common, n, sampler, settings, options,
                    None if budget is None else budget.optimiser_deadline())
    if budget is not None and len(opt.batch_times):
        budget.observe_first_batch(float(opt.batch_times[0]))
    selection = dataclasses.replace(options.selection, clearance_floor=floor, self_clearance_floor=self_floor)
    first_batch, measuring = None, 0.0
    if options.first_batch:  # measured apart: its time is not the attempt's
        head_at = time.perf_counter()
        one = opt.first_batches(1)
        head = select_candidate(fabric, problem, one, n, settings, mesh_checker, selection, finish,
                                options.threads, None if budget is None else budget.end)
        first_batch = _result(head, one, common, settings_dict)
        measuring = time.perf_counter() - head_at
        first_batch.wall_time = float(one.batch_times[0]) + measuring
        if budget is not None:
            budget.exclude(measuring)
    timing: Dict[str, float] = {}
    deadline = None if budget is None else budget.selection_deadline(options.selection_share)
    candidate = select_candidate(fabric, problem, opt, n, settings, mesh_checker, selection, finish,
                                 options.threads, deadline, timing)
    if budget is not None:
        budget.observe_selection(timing["first_verdict"])
    # per-sphere (and per-pair) margins are recorded under the attempt's kind ("goal_contact" or "cover"; a
    # plan attempt's are the goal's contact, gfcs.planning.policies.endpoint_contact), per-pair margins of an
    # endpoint in sphere self-contact under "self_contact" (once)
    pairs = {} if fabric.self_margins is None else {"self_margins": np.asarray(fabric.self_margins).tolist()}
    contact = {} if fabric.obstacle_margins is None else {
        "goal_contact" if attempt.kind == "plan" else attempt.kind: {
            "clearance_floor": floor, "obstacle_margins": np.asarray(fabric.obstacle_margins).tolist(),
            **({} if self_floor < 0.0 else pairs)}}
    if self_floor < 0.0:
        contact["self_contact"] = {"self_clearance_floor": self_floor, **pairs}
    extra = {"n_commands": n, "sampler": type(sampler).__name__, **contact}
    extra.update(attempt.model.settings())
    result = _result(candidate, opt, common, {**settings_dict, **extra})
    record = AttemptRecord(attempt, result=result, time=time.perf_counter() - started - measuring,
                           first_batch=first_batch, measuring_time=measuring)
    if first_batch is not None:
        first_batch.settings = {**first_batch.settings, **extra, "batches": 1}
    return record


def combine_attempts(attempts: List[SolveResult]) -> SolveResult:
    """The result of solving one problem in several attempts, in order: the last attempt if it succeeded,
    else the lowest-cost one, with ``solve_time`` and ``n_evaluations`` summed over all attempts and
    ``settings["commands_tried"]`` listing their command counts (and, when the attempts' fabrics differ in
    ``obstacles.margin``, ``settings["obstacle_margins_tried"]`` their margins [m]). One attempt is
    returned unchanged.
    """
    if len(attempts) == 1:
        return attempts[0]
    best = attempts[-1] if attempts[-1].success else min(attempts, key=lambda r: r.cost)
    commands: List[int] = []
    margins: List[Optional[float]] = []
    for r in attempts:  # a result that combines attempts itself contributes each of them
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


def combine_records(records: List[AttemptRecord]) -> SolveResult:
    """The solve's result from its attempt records (those run; see :func:`combine_attempts`), with every
    record, run or not, listed in ``attempts`` (and kept in memory in ``attempt_records``)."""
    ran = [r.result for r in records if r.result is not None]
    if not ran:
        raise InvalidValueError("time_limit: no attempt could run within the time budget")
    best = combine_attempts(ran)
    return dataclasses.replace(best, attempts=[r.to_dict() for r in records], attempt_records=list(records))
