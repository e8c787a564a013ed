"""Which of the optimiser's candidates an attempt returns (after Alg. 1, before the result is built).

Eq. 4 scores time only. The ``paper`` preset returns the lowest-cost candidate (``length_slack = 0``, no mesh
model). The ``default`` preset prefers, among the reached candidates whose cost is within
``(1 + length_slack)`` times the lowest, the one with the shortest end-effector path (near-equal times differ
much more in hand path), and with a mesh checker returns the first candidate of that order whose trajectory
succeeds with the collision meshes included (the fabric sees spheres; a validator sees meshes). When none does
and :attr:`SelectionOptions.repair` is set, the first candidates that failed only on the meshes are moved off
their contacts (:mod:`gfcs.planning.repair`), re-timed and judged again.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

import numpy as np

from gfcs import metrics as _metrics
from gfcs.planning.finish import FinishOptions, finish_rollout, retime_within_limits, with_raw_ldj
from gfcs.planning.gfcop import OptimResult
from gfcs.planning.repair import RepairOptions, repair_path
from gfcs.planning.rollout import RolloutSettings, fabric_goal
from gfcs.results import Trajectory

__all__ = ["Candidate", "SelectionOptions", "select_candidate", "mesh_contact_only"]


@dataclass
class Candidate:
    """One candidate command sequence, rolled out, finished and judged.

    Attributes:
        index: its index in the optimiser's candidates (``OptimResult.all_x``).
        commands: (n, dof) free commands [rad].
        trajectory: the finished trajectory (:func:`gfcs.planning.finish.finish_rollout`).
        cost: eq. 4 cost [s]; reached: the rollout reached the goal; t_stars: (n + 1,) time per command.
        metrics: :func:`gfcs.metrics.trajectory_metrics` of the trajectory (empty until judged), with
            ``selection_rank`` (its rank in cost order, 0: the lowest) and, with a mesh checker,
            ``mesh_candidates_checked``.
    """

    index: int
    commands: np.ndarray
    trajectory: Trajectory
    cost: float
    reached: bool
    t_stars: np.ndarray
    metrics: Dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """The judged trajectory succeeds (False until judged)."""
        return bool(self.metrics.get("success", False))


@dataclass
class SelectionOptions:
    """How :func:`select_candidate` chooses.

    Attributes:
        length_slack: ε ≥ 0 of the near-optimal preference (0: the lowest cost first, eq. 4's choice).
        mesh_candidates: with a mesh checker, at most this many candidates are judged (≥ 1).
        mesh_margin: clearance [m] the collision meshes must keep for success.
        clearance_floor: how far [m, ≤ 0] the spheres may overlap obstacles (the goal-contact attempt).
        repair: with a mesh checker, how candidates that failed only on the meshes are repaired
            (:func:`gfcs.planning.repair.repair_path`) when no candidate succeeds; None: not at all.
        sweep_time: with a mesh checker, the time [s] the continuous check of one candidate may take
            (:func:`gfcs.metrics.mesh_check`): a candidate it cannot certify by then fails on the meshes
            (and may be repaired); None: up to the attempt's deadline.
        self_clearance_floor: how far [m, ≤ 0] the spheres may overlap each other (an endpoint in sphere
            self-contact that the meshes clear: :func:`gfcs.planning.policies.endpoint_self_contact`).
        spheres_judge: with a mesh checker, the sphere clearances must hold too (the floors above); False:
            the meshes alone judge collisions (``spheres_judge`` of :func:`gfcs.metrics.trajectory_metrics`).
    """

    length_slack: float = 0.1
    mesh_candidates: int = 32
    mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN
    clearance_floor: float = 0.0
    repair: Optional[RepairOptions] = None
    sweep_time: Optional[float] = None
    self_clearance_floor: float = 0.0
    spheres_judge: bool = True


class _Rollouts:
    """Rolls candidates of ``opt`` out on demand, several in one parallel batch, each once, and finishes a
    candidate (:func:`gfcs.planning.finish.finish_rollout`) only when it is asked for: the near-optimal
    ordering reads the fabric's own rollouts, and usually one candidate is finished and judged."""

    def __init__(self, fabric: Any, problem: Any, opt: OptimResult, n_commands: int, settings: RolloutSettings,
                 finish: FinishOptions, threads: Optional[int]) -> None:
        self.fabric, self.opt, self.n, self.settings, self.finish = fabric, opt, n_commands, settings, finish
        self.threads = threads
        self.q0 = np.asarray(problem.q0, dtype=np.float64)
        self.qd0 = np.asarray(problem.qd0, dtype=np.float64)
        self.goal = np.asarray(problem.goal, dtype=np.float64)
        self.commanded = fabric_goal(fabric, self.goal, settings.limit_hold_off)
        self.rolled: Dict[int, Any] = {}
        self.done: Dict[int, Candidate] = {}

    def rollouts(self, *ks: int) -> List[Any]:
        """The recorded ``gfcs.SequenceRollout`` of each of ``ks``, those not rolled yet in one batch."""
        todo = [k for k in dict.fromkeys(ks) if k not in self.rolled]
        if todo:
            x = np.stack([np.asarray(self.opt.all_x[k], dtype=np.float64) for k in todo])
            *_, seqs = self.fabric.evaluate(self.q0, self.qd0, self.commanded, x, threads=self.threads,
                                            return_trajectories=True, **self.settings.as_kwargs())
            self.rolled.update(zip(todo, seqs))
        return [self.rolled[k] for k in ks]

    def __call__(self, k: int) -> Candidate:
        """Candidate ``k`` rolled out and finished."""
        if k not in self.done:
            seq = self.rollouts(k)[0]
            traj, cost, reached, t_stars = finish_rollout(self.fabric, seq, self.goal, self.settings.dt,
                                                          self.finish)
            commands = np.asarray(self.opt.all_x[k], dtype=np.float64).reshape(self.n, self.goal.shape[0])
            self.done[k] = Candidate(k, commands, traj, cost, reached, t_stars)
        return self.done[k]


def _preference(opt: OptimResult, penalty: float, options: SelectionOptions, roll: _Rollouts,
                robot: Any, deadline: Optional[float]) -> List[int]:
    """Candidate indices in the order they are tried (see the module docstring): the lowest-cost one, then
    those that reached the goal (cost < ``penalty``), at most ``mesh_candidates``; with ``length_slack`` the
    near-optimal ones first, shortest hand path of the fabric's rollout first (finishing re-times that path
    and appends the goal blend, a few millimetres at most). The near-optimal reordering rolls every
    near-optimal candidate out in one batch; it is skipped when the longest optimiser batch would not end
    before the deadline."""
    order = np.argsort(opt.all_costs, kind="stable")
    keep = [int(order[0])] + [int(k) for k in order[1:] if opt.all_costs[k] < penalty]
    keep = keep[:max(1, int(options.mesh_candidates))]
    best = float(opt.all_costs[keep[0]])
    longest = float(np.max(opt.batch_times)) if len(opt.batch_times) else 0.0
    if options.length_slack > 0 and best < penalty and not _past(deadline, longest):
        near = [k for k in keep if opt.all_costs[k] <= (1.0 + options.length_slack) * best]
        hand = {k: _metrics.path_length(robot.ee_position(np.asarray(seq.q)))
                for k, seq in zip(near, roll.rollouts(*near))}
        near.sort(key=lambda k: hand[k])  # stable: equal lengths stay in cost order
        keep = near + [k for k in keep if k not in hand]
    return keep


def _past(deadline: Optional[float], needed: float = 0.0) -> bool:
    """Whether work of ``needed`` seconds started now would end after ``deadline``."""
    return deadline is not None and time.perf_counter() + needed > deadline


def _judge(problem: Any, trajectory: Trajectory, mesh_checker: Any, options: SelectionOptions,
           deadline: Optional[float]) -> Dict[str, Any]:
    """:func:`gfcs.metrics.trajectory_metrics` of a candidate's trajectory, as the selection judges it."""
    return _metrics.trajectory_metrics(problem.robot, problem.scene, trajectory.t, trajectory.q,
                                       np.asarray(problem.goal, dtype=np.float64), mesh_checker=mesh_checker,
                                       mesh_margin=options.mesh_margin, clearance_floor=options.clearance_floor,
                                       ee_links=(getattr(problem, "meta", None) or {}).get("ee_links"),
                                       deadline=deadline, sweep_time=options.sweep_time,
                                       self_clearance_floor=options.self_clearance_floor,
                                       spheres_judge=options.spheres_judge)


def model_success(metrics: Dict[str, Any]) -> bool:
    """The verdict of ``metrics`` (of :func:`gfcs.metrics.trajectory_metrics`) before the meshes: the goal
    reached and the limits kept, and the spheres clear where they judge too."""
    key = "sphere_success" if metrics.get("spheres_judged", True) else "reached_within_limits"
    return bool(metrics.get(key))


def mesh_contact_only(metrics: Dict[str, Any]) -> bool:
    """Whether ``metrics`` (of :func:`gfcs.metrics.trajectory_metrics`) are those of a motion that failed only
    because a collision mesh came too near: judged with meshes, a success under the sphere model (goal
    reached, spheres clear, limits kept) and the mesh check finished. These are the candidates the mesh
    repair moves, whether or not the spheres judge success: a path whose spheres overlap an obstacle as well
    sits deeper in it than a local correction reaches (UR5 cage problems: repairing such candidates first
    spent the budget that the repair of a sphere-clear one needed)."""
    return (not metrics.get("success") and bool(metrics.get("sphere_success"))
            and "mesh_clearance" in metrics and bool(metrics.get("mesh_check_complete", True)))


def _repair(problem: Any, candidate: Candidate, mesh_checker: Any, options: SelectionOptions, finish: FinishOptions,
            dt: float, deadline: Optional[float]) -> Optional[Candidate]:
    """``candidate`` moved off its mesh contacts (:func:`gfcs.planning.repair.repair_path`), re-timed within the
    limits ``finish`` keeps, and judged; None when the repair or the judgement fails. Either way the record of
    the repair is kept in ``candidate.metrics["mesh_repair"]``."""
    assert options.repair is not None
    traj = candidate.trajectory
    moved, record = repair_path(problem.robot, problem.scene, mesh_checker, traj.t, traj.q, options.repair,
                                options.mesh_margin, options.clearance_floor, deadline,
                                options.self_clearance_floor)
    candidate.metrics["mesh_repair"] = record
    if moved is None or _past(deadline):
        return None
    qd = traj.qd + np.gradient(moved - traj.q, traj.t, axis=0) if len(traj) > 1 else traj.qd.copy()
    qd[0], qd[-1] = traj.qd[0], traj.qd[-1]
    t, q, qd = retime_within_limits(problem.robot, traj.t, moved, qd, dt, finish)
    repaired = Trajectory(t, q, qd, raw_q=traj.raw_q)
    met = _judge(problem, repaired, mesh_checker, options, deadline)
    if not met["success"]:
        candidate.metrics["mesh_repair"] = {**record, "judged": "failed"}
        return None
    met.update(mesh_repair={**record, "judged": "success"}, selection_rank=candidate.metrics.get("selection_rank"),
               mesh_candidates_checked=candidate.metrics.get("mesh_candidates_checked"))
    return dataclasses.replace(candidate, trajectory=repaired, metrics=met)


def select_candidate(fabric: Any, problem: Any, opt: OptimResult, n_commands: int, settings: RolloutSettings,
                     mesh_checker: Any, options: SelectionOptions, finish: Optional[FinishOptions] = None,
                     threads: Optional[int] = None, deadline: Optional[float] = None,
                     timing: Optional[Dict[str, float]] = None) -> Candidate:
    """The candidate an attempt returns, rolled out, finished and judged.

    Without a mesh checker the first candidate of the preference order (see the module docstring) is
    returned; with one, the first whose trajectory succeeds with meshes included, else, with
    ``options.repair``, the first repaired one that does, or, if none does, the first of the order. With a
    ``deadline`` (a ``time.perf_counter()`` value) a further candidate is judged only when the longest
    judgement so far would end before it; the first candidate always is. A ``timing`` dict receives
    ``first_verdict``: the seconds from the call to the first candidate's verdict (what any selection costs;
    :class:`gfcs.planning.budget.Budget` reserves it).
    """
    began = time.perf_counter()
    finish = finish or FinishOptions()
    roll = _Rollouts(fabric, problem, opt, n_commands, settings, finish, threads)
    order = np.argsort(opt.all_costs, kind="stable")
    keep = _preference(opt, settings.penalty, options, roll, problem.robot, deadline)
    if mesh_checker is None:
        keep = keep[:1]
    judged: List[Candidate] = []
    chosen: Optional[Candidate] = None
    judging = 0.0
    for k in keep:
        if judged and _past(deadline, judging):
            break
        started = time.perf_counter()
        candidate = roll(k)
        met = _judge(problem, candidate.trajectory, mesh_checker, options, deadline)
        met["selection_rank"] = int(np.flatnonzero(order == k)[0])
        if mesh_checker is not None:
            met["mesh_candidates_checked"] = len(judged) + 1
        candidate.metrics = met
        judging = max(judging, time.perf_counter() - started)
        if timing is not None and not judged:
            timing["first_verdict"] = time.perf_counter() - began
        judged.append(candidate)
        if mesh_checker is None or met["success"]:
            chosen = candidate
            break
    # a stand-in checker without per-part distances (duck-typed) is not repaired against
    repairable = all(hasattr(mesh_checker, m) for m in ("shape_clearances", "pair_clearances"))
    if chosen is None and options.repair is not None and repairable:
        for candidate in [c for c in judged if mesh_contact_only(c.metrics)][:options.repair.candidates]:
            if _past(deadline, judging):  # a repair ends with a judgement of the moved path
                break
            chosen = _repair(problem, candidate, mesh_checker, options, finish, settings.dt, deadline)
            if chosen is not None:
                break
    if chosen is None:
        chosen = judged[0]  # `keep` holds at least the lowest-cost candidate, and it is always judged
        chosen.metrics["mesh_candidates_checked"] = len(judged)
    # the fabric's own smoothness, for the returned candidate only (an FK pass over its rollout)
    with_raw_ldj(chosen.metrics, problem.robot, chosen.trajectory, settings.dt)
    return chosen
