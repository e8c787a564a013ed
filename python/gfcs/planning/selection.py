"""Which of the optimiser's candidates an attempt returns (after Alg. 1, before the result is built).

Eq. 4 scores time only. The ``paper`` preset returns the lowest-cost candidate (``length_slack = 0``, no mesh
model). The ``default`` preset prefers, among the reached candidates whose cost is within
``(1 + length_slack)`` times the lowest, the one with the shortest end-effector path (near-equal times differ
much more in hand path), and with a mesh checker returns the first candidate of that order whose trajectory
succeeds with the collision meshes included (the fabric sees spheres; a validator sees meshes).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

import numpy as np

from gfcs import metrics as _metrics
from gfcs.planning.finish import FinishOptions, finish_rollout, with_raw_ldj
from gfcs.planning.gfcop import OptimResult
from gfcs.planning.rollout import RolloutSettings, fabric_goal
from gfcs.results import Trajectory

__all__ = ["Candidate", "SelectionOptions", "select_candidate"]


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
    """

    length_slack: float = 0.1
    mesh_candidates: int = 32
    mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN
    clearance_floor: float = 0.0


class _Rollouts:
    """Rolls candidates of ``opt`` out on demand, several in one parallel batch, each once."""

    def __init__(self, fabric: Any, problem: Any, opt: OptimResult, n_commands: int, settings: RolloutSettings,
                 finish: FinishOptions, threads: Optional[int]) -> None:
        self.fabric, self.opt, self.n, self.settings, self.finish = fabric, opt, n_commands, settings, finish
        self.threads = threads
        self.q0 = np.asarray(problem.q0, dtype=np.float64)
        self.qd0 = np.asarray(problem.qd0, dtype=np.float64)
        self.goal = np.asarray(problem.goal, dtype=np.float64)
        self.commanded = fabric_goal(fabric, self.goal, settings.limit_hold_off)
        self.done: Dict[int, Candidate] = {}

    def __call__(self, *ks: int) -> Candidate:
        """Roll out the candidates ``ks`` not rolled yet; the last one's :class:`Candidate`."""
        todo = [k for k in dict.fromkeys(ks) if k not in self.done]
        if todo:
            x = np.stack([np.asarray(self.opt.all_x[k], dtype=np.float64) for k in todo])
            *_, seqs = self.fabric.evaluate(self.q0, self.qd0, self.commanded, x, threads=self.threads,
                                            return_trajectories=True, **self.settings.as_kwargs())
            dof = self.goal.shape[0]
            for k, row, seq in zip(todo, x, seqs):
                traj, cost, reached, t_stars = finish_rollout(self.fabric, seq, self.goal, self.settings.dt,
                                                              self.finish)
                self.done[k] = Candidate(k, row.reshape(self.n, dof), traj, cost, reached, t_stars)
        return self.done[ks[-1]]


def _preference(opt: OptimResult, penalty: float, options: SelectionOptions, roll: _Rollouts,
                robot: Any, deadline: Optional[float]) -> List[int]:
    """Candidate indices in the order they are tried (see the module docstring): the lowest-cost one, then
    those that reached the goal (cost < ``penalty``), at most ``mesh_candidates``; with ``length_slack`` the
    near-optimal ones first, shortest hand path first. The near-optimal reordering rolls every near-optimal
    candidate out in one batch; it is skipped when the longest optimiser batch would not end before the
    deadline."""
    order = np.argsort(opt.all_costs, kind="stable")
    keep = [int(order[0])] + [int(k) for k in order[1:] if opt.all_costs[k] < penalty]
    keep = keep[:max(1, int(options.mesh_candidates))]
    best = float(opt.all_costs[keep[0]])
    longest = float(np.max(opt.batch_times)) if len(opt.batch_times) else 0.0
    if options.length_slack > 0 and best < penalty and not _past(deadline, longest):
        near = [k for k in keep if opt.all_costs[k] <= (1.0 + options.length_slack) * best]
        roll(*near)
        hand = {k: _metrics.path_length(robot.ee_position(roll(k).trajectory.q)) for k in near}
        near.sort(key=lambda k: hand[k])  # stable: equal lengths stay in cost order
        keep = near + [k for k in keep if k not in hand]
    return keep


def _past(deadline: Optional[float], needed: float = 0.0) -> bool:
    """Whether work of ``needed`` seconds started now would end after ``deadline``."""
    return deadline is not None and time.perf_counter() + needed > deadline


def select_candidate(fabric: Any, problem: Any, opt: OptimResult, n_commands: int, settings: RolloutSettings,
                     mesh_checker: Any, options: SelectionOptions, finish: Optional[FinishOptions] = None,
                     threads: Optional[int] = None, deadline: Optional[float] = None) -> Candidate:
    """The candidate an attempt returns, rolled out, finished and judged.

    Without a mesh checker the first candidate of the preference order (see the module docstring) is
    returned; with one, the first whose trajectory succeeds with meshes included, or, if none does, the
    first of the order. With a ``deadline`` (a ``time.perf_counter()`` value) a further candidate is judged
    only when the longest judgement so far would end before it; the first candidate always is.
    """
    roll = _Rollouts(fabric, problem, opt, n_commands, settings, finish or FinishOptions(), threads)
    order = np.argsort(opt.all_costs, kind="stable")
    keep = _preference(opt, settings.penalty, options, roll, problem.robot, deadline)
    if mesh_checker is None:
        keep = keep[:1]
    goal = np.asarray(problem.goal, dtype=np.float64)
    first: Optional[Candidate] = None
    chosen: Optional[Candidate] = None
    checked, judging = 0, 0.0
    for k in keep:
        if first is not None and _past(deadline, judging):
            break
        checked += 1
        started = time.perf_counter()
        candidate = roll(k)
        traj = candidate.trajectory
        met = _metrics.trajectory_metrics(problem.robot, problem.scene, traj.t, traj.q, goal,
                                          mesh_checker=mesh_checker, mesh_margin=options.mesh_margin,
                                          clearance_floor=options.clearance_floor,
                                          ee_links=(getattr(problem, "meta", None) or {}).get("ee_links"),
                                          deadline=deadline)
        met["selection_rank"] = int(np.flatnonzero(order == k)[0])
        if mesh_checker is not None:
            met["mesh_candidates_checked"] = checked
        candidate.metrics = met
        judging = max(judging, time.perf_counter() - started)
        if first is None:
            first = candidate
        if mesh_checker is None or met["success"]:
            chosen = candidate
            break
    if chosen is None:
        assert first is not None  # `keep` holds at least the lowest-cost candidate, and it is always judged
        first.metrics["mesh_candidates_checked"] = checked
        chosen = first
    # the fabric's own smoothness, for the returned candidate only (an FK pass over its rollout)
    with_raw_ldj(chosen.metrics, problem.robot, chosen.trajectory, settings.dt)
    return chosen
