"""The robot-level planner: :func:`solve` runs attempts (:mod:`gfcs.planning.attempts`) chosen by retry
policies (:mod:`gfcs.planning.policies`) under a preset (:mod:`gfcs.planning.presets`) and a time budget
(:mod:`gfcs.planning.budget`); :func:`replay` re-runs a solved command sequence in a changed scene.

The flow of one solve::

    preset (settings, finish, selection, sampler, models, policies)   problem   time_limit
                         \\                                            |          /
        models_for(problem): planning models (thin, covering), validator, limits, profile
                                          |
        first attempt: first planning model, n_commands ----------------+
                                          |                             |
        run_attempt: Alg. 1 (CMA-ES, deadline) -> select_candidate -> AttemptRecord
                                          |                             |
        success, or the budget leaves no room -> stop                   |
        else the first policy that proposes -> next attempt ------------+
                                          |
        combine_records: the last attempt if it succeeded, else the lowest cost; every record listed

``method="gf"`` is the local baseline: the goal is the only command, nothing is optimised.
"""

from __future__ import annotations

import dataclasses
import os
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from gfcs import metrics as _metrics
from gfcs.errors import InvalidValueError
from gfcs.planning._check import fraction, integer_at_least, non_negative, optional_time_limit, worker_threads
from gfcs.planning.attempts import Attempt, AttemptRecord, OptimOptions, combine_records, run_attempt
from gfcs.planning.budget import Budget
from gfcs.planning.finish import FinishOptions, rollout_commands, with_raw_ldj
from gfcs.planning.gfcop import BatchInfo
from gfcs.planning.models import PlanningModel, RobotModels, model_named, models_for, with_robot
from gfcs.planning.policies import (CONTACT_SLACK, MORE_COMMANDS, MoreCommands, PlanContext, default_policies,
                                    endpoint_contact)
from gfcs.planning.presets import Preset, get_preset
from gfcs.planning.endpoints import check_endpoints, endpoint_grazes
from gfcs.planning.rollout import RolloutSettings, make_fabric
from gfcs.planning.samplers import ApproachSampler, Sampler, UniformSampler
from gfcs.planning.repair import RepairOptions
from gfcs.planning.selection import SelectionOptions
from gfcs.results import SolveResult

__all__ = ["solve", "replay"]


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
    preset: Any = "default",
    policies: Optional[Sequence[Any]] = None,
    time_limit: Optional[float] = None,
    settings: Optional[RolloutSettings] = None,
    finish: Optional[FinishOptions] = None,
    top_m: int = 4,
    sigma0: float = 0.25,
    mesh_candidates: Optional[int] = None,
    length_slack: Optional[float] = None,
    callback: Optional[Callable[[BatchInfo], Optional[bool]]] = None,
    mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN,
    thin_spheres: Optional[bool] = None,
    element_spheres: Optional[bool] = None,
    covering_spheres: Optional[bool] = None,
    record_first_batch: bool = False,
    max_commands: Optional[int] = None,
    mesh_retry_margin: Optional[float] = None,
    mesh_retries: Optional[int] = None,
    goal_contact_slack: Optional[float] = None,
    sphere_fallback: Optional[bool] = None,
    restarts: Optional[int] = None,
    stall_batches: Optional[int] = None,
    stall_tol: float = 0.01,
    endpoint_check: bool = True,
    mesh_repair: Optional[bool] = None,
    spheres_judge: Optional[bool] = None,
    selection_share: Optional[float] = None,
) -> SolveResult:
    """Solve a motion problem with GFCS (Alg. 1 and the preset's retry policies) or with the local fabric
    alone (``method="gf"``).

    Args:
        problem: a :class:`gfcs.problems.Problem` (robot, scene, q0, qd0, goal, optional ``mesh_checker``
            that judges motions on collision meshes).
        method: ``"gfcs"`` or ``"gf"``.
        batches: CMA-ES batches per attempt (the paper reports 1 and 5).
        population: candidates per batch.
        n_commands: free commands n of the first attempt (the paper: 1, sequences of length two).
        seed: seed of the sampler and CMA-ES (every attempt uses it).
        sampler: warm-start sampler (protocol :class:`gfcs.planning.samplers.Sampler`); None: the preset's
            (``default``: :class:`ApproachSampler`, ``paper``: :class:`UniformSampler`).
        fabric_config: fabric gains (None, ``gfcs.FabricConfig``, dict, or file path); the preset's
            overrides (``paper``: the paper's barriers) apply on top.
        threads: worker threads of the batch evaluation (None: all cores).
        progress: a tqdm bar over the batches.
        preset: ``"default"`` or ``"paper"`` (:mod:`gfcs.planning.presets`), or a :class:`Preset`.
        policies: retry policies in order (:mod:`gfcs.planning.policies`); None: the preset's; ``[]``: no
            retry.
        time_limit: budget of this call [s] (None: none). The solve returns the best motion found within
            it; attempts the budget left no room for are listed as not run (:mod:`gfcs.planning.budget`).
        settings: :class:`RolloutSettings` (None: the preset's).
        finish: :class:`FinishOptions` (None: the preset's).
        top_m: best candidates kept in ``result.top`` (Alg. 1's output).
        sigma0: initial CMA-ES step as a fraction of the joint ranges.
        mesh_candidates: with a mesh checker, at most this many candidates judged on the meshes (None: the
            preset's, 32 / 1).
        length_slack: ε ≥ 0 of the near-optimal shortest-hand-path preference (None: the preset's, 0.1 / 0).
        callback: called after every batch with a :class:`BatchInfo`; True stops that attempt's batches.
        mesh_margin: clearance [m] the collision meshes must keep for success.
        thin_spheres: plan on the robot's thinner sphere model first, when it has one and the problem a
            mesh checker (None: the preset's).
        element_spheres: plan on the validator's collision spheres where its robot description has any, in
            place of the sphere model's spheres inside them (:func:`gfcs.planning.models.models_for`; None:
            the preset's, on / off).
        covering_spheres: plan on spheres fitted around the validator's meshes first where the robot's own
            leave them centimetres uncovered (:func:`gfcs.planning.models.covering_model`; None: the preset's,
            on / off).
        record_first_batch: also select and judge what each attempt held after its first batch
            (``attempt_records[i].first_batch``; ``gfcs bench``'s "1 b" row). That work counts neither in
            the attempts' times nor in ``wall_time``.
        max_commands, mesh_retry_margin, mesh_retries, goal_contact_slack, sphere_fallback, restarts:
            parameters of the default policies (:func:`gfcs.planning.policies.default_policies`), used when
            ``policies`` is None: the most free commands (default n + 3 with the preset's sampler, n with
            one of your own), the wider-margin step [m] and rounds (0.002, 2), the goal-contact slack [m]
            (0.002), whether the model cascade runs (True), and the IPOP restarts once every other policy
            declined (2; :class:`gfcs.planning.policies.Restart`).
        stall_batches, stall_tol: early stop of each attempt's optimisation once ``stall_batches`` batches
            in a row lowered the best cost by at most ``stall_tol`` of it
            (:func:`gfcs.planning.gfcop.stalled`); None: the preset's (0 for both presets: every batch
            runs).
        endpoint_check: refuse a start or goal whose collision meshes are in contact
            (:func:`gfcs.planning.endpoints.check_endpoints`) before planning; False plans anyway.
        mesh_repair: with a mesh checker, move candidates that fail only on the meshes off their contacts
            when no candidate succeeds (:mod:`gfcs.planning.repair`); None: the preset's (on / off), True:
            the preset's options or the defaults of :class:`gfcs.planning.repair.RepairOptions`.
        spheres_judge: with a mesh checker, a motion's sphere clearances must hold too for success; False:
            the collision meshes alone judge collisions, as a mesh validator does (None: the preset's,
            off / on; :attr:`gfcs.planning.selection.SelectionOptions.spheres_judge`).
        selection_share: the share (in (0, 1]) of the time left that an attempt's candidate selection may
            spend while another attempt would still fit after it (None: the preset's, 0.75 / 1; 1: up to the
            end of the budget; :meth:`gfcs.planning.budget.Budget.selection_deadline`).

    Returns:
        :class:`gfcs.results.SolveResult` (the chosen attempt's motion and metrics; ``attempts``: every
        attempt's label, settings, outcome and time; ``solve_time`` the optimisation; ``wall_time`` this
        call).

    Raises:
        gfcs.InvalidValueError: a bad argument (the message names it).
        gfcs.CollisionError: the start or the goal is in collision on the meshes (``endpoint_check``).
    """
    # Long only by its docstring, which documents every argument of the public API; the work is in helpers.
    budget = Budget(optional_time_limit(time_limit))
    chosen = get_preset(preset)
    if method not in ("gfcs", "gf"):
        raise InvalidValueError(f"method must be 'gfcs' or 'gf', got {method!r}")
    mesh_margin = non_negative("mesh_margin", mesh_margin, " [m]")
    seed = integer_at_least("seed", seed, 0)
    threads = worker_threads(threads)
    if endpoint_check:
        check_endpoints(problem)
    settings = settings if settings is not None else dataclasses.replace(chosen.settings)
    finish = finish if finish is not None else dataclasses.replace(chosen.finish)
    fabric = _preset_fabric(problem, fabric_config, chosen)
    judge = chosen.spheres_judge if spheres_judge is None else bool(spheres_judge)
    recorded = {"preset": chosen.name, "time_limit": budget.limit, "mesh_margin": mesh_margin,
                "spheres_judge": judge, **finish.to_dict()}
    if method == "gf":
        result = _solve_gf(problem, fabric, settings, finish, mesh_margin, judge, seed, recorded)
    else:
        n_commands = integer_at_least("n_commands", n_commands, 1)
        plan = _policies(chosen, policies, sampler, n_commands, max_commands, mesh_retry_margin, mesh_retries,
                         goal_contact_slack, sphere_fallback, restarts)
        slack = non_negative("length_slack", chosen.length_slack if length_slack is None else length_slack)
        checks = integer_at_least("mesh_candidates",
                                  chosen.mesh_candidates if mesh_candidates is None else mesh_candidates, 1)
        stall = integer_at_least("stall_batches",
                                 chosen.stall_batches if stall_batches is None else stall_batches, 0)
        sweep_time = chosen.sweep_time
        if sweep_time is not None and chosen.grazing_sweep_time is not None \
                and endpoint_grazes(problem, mesh_margin):
            sweep_time = max(sweep_time, chosen.grazing_sweep_time)
        repair = chosen.repair if mesh_repair is None else (chosen.repair or RepairOptions()) if mesh_repair else None
        options = OptimOptions(batches, population, seed, threads, progress, top_m, sigma0, callback,
                               SelectionOptions(slack, checks, mesh_margin, repair=repair,
                                                sweep_time=sweep_time, spheres_judge=judge),
                               bool(record_first_batch),
                               stall, non_negative("stall_tol", stall_tol),
                               fraction("selection_share", chosen.selection_share if selection_share is None
                                        else selection_share))
        recorded.update(batches=int(batches), population=int(population), sigma0=float(sigma0),
                        top_m=int(top_m), length_slack=slack, mesh_repair=repair is not None,
                        sweep_time=sweep_time, selection_share=options.selection_share,
                        **({"stall_batches": stall, "stall_tol": float(stall_tol)} if stall else {}))
        models = models_for(problem, chosen.thin_spheres if thin_spheres is None else bool(thin_spheres),
                            chosen.element_spheres if element_spheres is None else bool(element_spheres),
                            chosen.covering_spheres if covering_spheres is None else bool(covering_spheres))
        planner = _Planner(problem, models, fabric, n_commands, sampler, chosen, settings, finish, options,
                           recorded, budget)
        result = combine_records(planner.run(plan))
    measuring = sum(r.measuring_time for r in result.attempt_records)  # record_first_batch's own work
    return dataclasses.replace(result, wall_time=time.perf_counter() - budget.start - measuring,
                               preset=chosen.name, time_limit=budget.limit)


def _preset_fabric(problem: Any, fabric_config: Any, preset: Preset) -> Any:
    """The fabric of ``problem`` with ``fabric_config`` and the preset's overrides on top."""
    fabric = make_fabric(problem, fabric_config)
    if preset.fabric:
        fabric = make_fabric(problem, fabric.config.replace(preset.fabric))
    return fabric


def _common(problem: Any, robot: Any, fabric: Any, seed: int) -> Dict[str, Any]:
    """The SolveResult fields every attempt of a solve shares (robot and configuration: the attempt's)."""
    return dict(problem=str(problem.name), cls=str(getattr(problem, "cls", "")), seed=int(seed),
                q0=np.asarray(problem.q0, dtype=np.float64), qd0=np.asarray(problem.qd0, dtype=np.float64),
                goal=np.asarray(problem.goal, dtype=np.float64), fabric_config=fabric.config.to_dict(),
                robot=robot, joint_names=list(robot.joint_names),
                pose_goal=(getattr(problem, "meta", None) or {}).get("pose_goal"))


def _solve_gf(problem: Any, fabric: Any, settings: RolloutSettings, finish: FinishOptions, mesh_margin: float,
              spheres_judge: bool, seed: int, recorded: Dict[str, Any]) -> SolveResult:
    """The GF baseline: one rollout toward the goal, judged as a GFCS motion of the preset is."""
    robot, dof = problem.robot, int(problem.robot.dof)
    common = _common(problem, robot, fabric, seed)
    start = time.perf_counter()
    traj, cost, reached, t_stars = rollout_commands(fabric, common["q0"], common["qd0"], common["goal"],
                                                    np.zeros((0, dof)), settings, finish)
    elapsed = time.perf_counter() - start
    met = _metrics.trajectory_metrics(robot, problem.scene, traj.t, traj.q, common["goal"],
                                      mesh_checker=getattr(problem, "mesh_checker", None), mesh_margin=mesh_margin,
                                      ee_links=(getattr(problem, "meta", None) or {}).get("ee_links"),
                                      spheres_judge=spheres_judge)
    with_raw_ldj(met, robot, traj, settings.dt)
    return SolveResult(method="gf", commands=np.zeros((0, dof)), cost=cost, reached=reached, t_stars=t_stars,
                       trajectory=traj, success=bool(met["success"]), metrics=met, n_evaluations=1,
                       solve_time=elapsed, settings={**dataclasses.asdict(settings), **recorded}, **common)


def _policies(preset: Preset, policies: Optional[Sequence[Any]], sampler: Any, n_commands: int,
              max_commands: Optional[int], mesh_retry_margin: Optional[float], mesh_retries: Optional[int],
              goal_contact_slack: Optional[float], sphere_fallback: Optional[bool],
              restarts: Optional[int]) -> List[Any]:
    """The policy list of a solve: ``policies``, else the default policies with the given parameters when
    any is given, else the preset's; without the preset's sampler, no :class:`MoreCommands` (a sampler of
    your own proposes a fixed number of commands)."""
    given = {k: v for k, v in (("max_commands", max_commands), ("mesh_retry_margin", mesh_retry_margin),
                               ("mesh_retries", mesh_retries), ("goal_contact_slack", goal_contact_slack),
                               ("sphere_fallback", sphere_fallback), ("restarts", restarts)) if v is not None}
    if policies is not None:
        if given:
            raise InvalidValueError(f"{', '.join(given)}: parameters of the default policies; with policies= "
                                    "given, set them on the policy objects")
        chosen = list(policies)
        if sampler is not None and any(isinstance(p, MoreCommands) for p in chosen):
            raise InvalidValueError("policies: MoreCommands needs the preset's sampler; a sampler of your own "
                                    f"proposes {n_commands} command(s) per candidate")
        return chosen
    if not given:
        chosen = preset.policies()
        return [p for p in chosen if not isinstance(p, MoreCommands)] if sampler is not None else chosen
    default_max = n_commands + MORE_COMMANDS if sampler is None else n_commands
    most = integer_at_least("max_commands", default_max if max_commands is None else max_commands, 1)
    if most < n_commands:
        raise InvalidValueError(f"max_commands must be ≥ n_commands ({n_commands}), got {max_commands}")
    if sampler is not None and most != n_commands:
        raise InvalidValueError("max_commands > n_commands needs the default sampler: a sampler of your own "
                                f"proposes {n_commands} command(s) per candidate")
    step = non_negative("mesh_retry_margin", 0.002 if mesh_retry_margin is None else mesh_retry_margin, " [m]")
    rounds = integer_at_least("mesh_retries", 2 if mesh_retries is None else mesh_retries, 0)
    slack = non_negative("goal_contact_slack", 0.002 if goal_contact_slack is None else goal_contact_slack, " [m]")
    cascade = True if sphere_fallback is None else bool(sphere_fallback)
    return default_policies(more_commands=most - n_commands, margin_step=step, margin_rounds=rounds,
                            goal_contact_slack=slack, cascade=cascade,
                            restarts=2 if restarts is None else restarts)


class _Planner:
    """Runs one solve's attempts: the first on the first planning model, then what the policies propose,
    until an attempt succeeds, no policy proposes, or the budget leaves no room."""

    def __init__(self, problem: Any, models: RobotModels, fabric: Any, n_commands: int, sampler: Any,
                 preset: Preset, settings: RolloutSettings, finish: FinishOptions, options: OptimOptions,
                 recorded: Dict[str, Any], budget: Budget) -> None:
        self.problem, self.models, self.fabric, self.n_commands = problem, models, fabric, n_commands
        self.sampler, self.preset, self.settings, self.finish = sampler, preset, settings, finish
        self.options, self.recorded, self.budget = options, recorded, budget
        self.base_margin = float(fabric.config.to_dict()["obstacles"]["margin"])
        self._fabrics: Dict[Tuple[str, int], Any] = {}
        self._contact: Dict[str, Any] = {}
        self.context = PlanContext(problem, models, n_commands, options.selection.mesh_margin,
                                   lambda model: self.fabric_for(Attempt(model, n_commands)), self.problem_for,
                                   budget.limit)

    def problem_for(self, model: PlanningModel) -> Any:
        return with_robot(self.problem, model.robot)

    def fabric_for(self, attempt: Attempt) -> Any:
        """The fabric of ``attempt``'s model at its obstacle margin (goal contact and cover: with per-sphere
        margins; cover: with per-pair self-collision margins too)."""
        key = (attempt.model.name, attempt.margin_round)
        if key not in self._fabrics:
            if attempt.model.margin_offset == 0 and attempt.margin_round == 0:
                fabric = make_fabric(self.problem_for(attempt.model), self.fabric.config)
            else:
                margin = attempt.obstacle_margin(self.base_margin)
                config = self.fabric.config.replace({"obstacles": {"margin": margin}})
                fabric = make_fabric(self.problem_for(attempt.model), config)
            self._fabrics[key] = fabric
        fabric = self._fabrics[key]
        if attempt.obstacle_margins is not None:
            fabric = fabric.with_obstacle_margins(np.asarray(attempt.obstacle_margins, dtype=np.float64))
        if attempt.self_margins is not None:
            fabric = fabric.with_self_margins(np.asarray(attempt.self_margins, dtype=np.float64))
        return fabric

    def sampler_for(self, n: int) -> Any:
        if self.sampler is not None:
            return self.sampler
        return ApproachSampler(n) if self.preset.sampler == "approach" else UniformSampler(n)

    def endpoint_contact(self, attempt: Attempt) -> Attempt:
        """``attempt`` with its model's endpoint contacts (the preset's ``endpoint_contact``;
        :func:`gfcs.planning.policies.endpoint_contact`): each pair's and each sphere's margin the lower of
        the contact's and the attempt's own, and the lower floors; unchanged without such contacts."""
        name = attempt.model.name
        if name not in self._contact:
            self._contact[name] = None if not self.preset.endpoint_contact else endpoint_contact(
                self.problem_for(attempt.model), self.fabric_for(Attempt(attempt.model, self.n_commands)),
                CONTACT_SLACK, self.models.validator, self.options.selection.mesh_margin)
        contact = self._contact[name]
        if contact is None:
            return attempt
        changes: Dict[str, Any] = {}
        if contact.self_margins is not None:
            own = contact.self_margins if attempt.self_margins is None else \
                np.minimum(contact.self_margins, np.asarray(attempt.self_margins, dtype=np.float64))
            changes.update(self_margins=tuple(float(m) for m in own),
                           self_clearance_floor=min(contact.self_floor, attempt.self_clearance_floor))
        if contact.obstacle_caps is not None:
            current = np.full(len(contact.obstacle_caps), attempt.obstacle_margin(self.base_margin)) \
                if attempt.obstacle_margins is None else np.asarray(attempt.obstacle_margins, dtype=np.float64)
            changes.update(obstacle_margins=tuple(float(m) for m in np.minimum(current, contact.obstacle_caps)),
                           clearance_floor=min(contact.floor, attempt.clearance_floor))
        return dataclasses.replace(attempt, **changes)

    def attempt(self, attempt: Attempt, policy: str) -> AttemptRecord:
        attempt = self.endpoint_contact(attempt)
        fabric = self.fabric_for(attempt)
        model_fabric = self.fabric_for(dataclasses.replace(attempt, obstacle_margins=None, self_margins=None))
        common = _common(self.problem, attempt.model.robot, model_fabric, self.options.seed)
        record = run_attempt(self.problem_for(attempt.model), fabric, self.models.validator, common, attempt,
                             self.sampler_for(attempt.n_commands), self.settings, self.finish, self.options,
                             self.recorded, self.budget)
        record.policy, record.base_margin = policy, self.base_margin
        return record

    def run(self, policies: Sequence[Any]) -> List[AttemptRecord]:
        records: List[AttemptRecord] = []
        proposal: Optional[Attempt] = Attempt(self.models.planning[0], self.n_commands)
        policy = ""
        while proposal is not None:
            if records and not self.budget.allows_attempt():
                records.append(AttemptRecord(proposal, policy, base_margin=self.base_margin))
                break
            records.append(self.attempt(proposal, policy))
            if records[-1].success:
                break
            proposal, policy = None, ""
            for p in policies:
                proposal = p.propose(self.context, records)
                if proposal is not None:
                    policy = p.name
                    break
        return records


def replay(
    result: SolveResult,
    scene: Any,
    robot: Any = None,
    fabric_config: Any = None,
    settings: Optional[RolloutSettings] = None,
    commands: Optional[Any] = None,
    mesh_checker: Optional[Any] = None,
    mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN,
    finish: Optional[FinishOptions] = None,
) -> SolveResult:
    """Replay a solved command sequence in another scene without re-optimising (GFCS Sec. V, Fig. 4).

    The fabric's local avoidance reacts to obstacles the optimisation never saw; the commands stay fixed.

    Args:
        result: a :class:`SolveResult` (from :func:`solve` or :meth:`SolveResult.from_json`).
        scene: the new ``gfcs.Scene``.
        robot: the robot; default ``result.robot`` (results loaded from JSON need it passed). A result
            planned on the thin spheres (``settings["sphere_model"] == "thin"``) replays on the thin model
            of it (:func:`gfcs.planning.models.planned_robot`), the fabric it was planned with.
        fabric_config: default: the configuration stored in ``result``.
        settings, finish: default: those stored in ``result``.
        commands: (n, dof) commands to replay instead of ``result.commands``.
        mesh_checker: optional :class:`gfcs.MeshChecker`: the replay's metrics then include the mesh
            clearances, and success requires them > ``mesh_margin`` [m].

    Returns:
        A copy of ``result`` whose trajectory, cost, reached flag, t_stars, metrics and success are those of
        the replay (optimisation data unchanged).

    Raises:
        gfcs.InvalidValueError: no robot.
    """
    robot = robot if robot is not None else result.robot
    if robot is None:
        raise InvalidValueError("robot: this result carries no robot (loaded from JSON?): pass robot=")
    robot = model_named(robot, result.settings)
    stored = result.settings
    if settings is None:
        names = {f.name for f in dataclasses.fields(RolloutSettings)}
        settings = RolloutSettings(**{k: v for k, v in stored.items() if k in names})
    if finish is None:
        names = {f.name for f in dataclasses.fields(FinishOptions)}
        finish = FinishOptions(**{k: v for k, v in stored.items() if k in names})
    if fabric_config is None:
        fabric_config = result.fabric_config
    import gfcs

    if isinstance(fabric_config, os.PathLike):
        fabric_config = str(fabric_config)
    fabric = gfcs.Fabric(robot, scene, fabric_config)
    cmds = np.asarray(result.commands if commands is None else commands, dtype=np.float64).reshape(-1, result.dof)
    traj, cost, reached, t_stars = rollout_commands(fabric, result.q0, result.qd0, result.goal, cmds, settings,
                                                    finish)
    # judged as the solve judged it (results from before the switch: the spheres judged too)
    met = _metrics.trajectory_metrics(robot, scene, traj.t, traj.q, result.goal, mesh_checker=mesh_checker,
                                      mesh_margin=mesh_margin,
                                      spheres_judge=bool(stored.get("spheres_judge", True)))
    with_raw_ldj(met, robot, traj, settings.dt)
    return dataclasses.replace(result, commands=cmds, trajectory=traj, cost=cost, reached=reached,
                               t_stars=t_stars, metrics=met, success=bool(met["success"]), robot=robot)
