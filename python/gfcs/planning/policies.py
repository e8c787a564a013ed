"""Retry policies: named objects that propose a solve's next attempt from what the earlier ones gave.

After each failed attempt :func:`gfcs.planning.solve.solve` asks its policies, in order, for the next
attempt; the first proposal runs, and the solve ends when an attempt succeeds, when no policy proposes one,
or when the time budget leaves no room for another. An empty list is a solve without retries. The
``default`` preset's list, in order (:func:`default_policies`):

* :class:`ModelShare`: with a time limit, the next planning model once the current one's attempts used their
  share of the budget (asked first, so that one model cannot spend the budget the next one needs);
* :class:`MoreCommands`: the same attempt with one more free command, up to :data:`MORE_COMMANDS` more than
  the solve's n (an approach corridor entered in steps, the arm led around a board by the extra commands);
* :class:`WiderMargin`: after a round whose attempts failed only because a collision *mesh* touched
  (spheres clear, goal reached), a new round with the obstacle margin one step wider;
* :class:`GoalContact`: when the goal itself puts collision spheres nearer the obstacles than the fabric's
  margin while its meshes clear them (conservative spheres at a grasp), one attempt with those spheres'
  margins lowered to the goal's clearance and the meshes judging the contact;
* :class:`MeshCover`: after a mesh-only failure that the other retries did not fix, a round in which each
  sphere keeps its own extra distance from obstacles, how far the validator's meshes stick out of it, and
  each self-collision pair the sum of its two;
* :class:`ModelCascade`: when every attempt on one planning model failed, start again on the next one
  (thin spheres, then the covering spheres: :mod:`gfcs.planning.models`);
* :class:`Restart`: when all of that failed and budget is left, the whole sequence again with a fresh seed
  and a doubled population (IPOP-CMA-ES), up to twice.

A policy sees a :class:`PlanContext` and the records so far; it proposes only from the attempts of the
model being tried (the last record's), so the cascade restarts every other policy on the next model.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable, List, Optional, Protocol, Sequence, Tuple

import numpy as np

from gfcs import metrics as _metrics
from gfcs.errors import InvalidValueError
from gfcs.planning._check import integer_at_least, non_negative
from gfcs.planning.attempts import Attempt, AttemptRecord
from gfcs.planning.models import RobotModels

__all__ = ["Policy", "PlanContext", "MoreCommands", "WiderMargin", "GoalContact", "MeshCover", "ModelCascade",
           "ModelShare", "Restart", "default_policies", "goal_contact", "endpoint_self_contact", "endpoint_contact",
           "EndpointContact", "cover_self_margins", "mesh_contacts", "CONTACT_SLACK", "MORE_COMMANDS"]

#: The default policies' most free commands beyond the solve's n (:class:`MoreCommands`). Three: the Fetch's
#: shelf and cage problems that two commands leave unsolved are solved with a third or fourth, each attempt
#: ending early on its stalled optimisation (measured in docs/tuning.md).
MORE_COMMANDS = 3


@dataclass
class PlanContext:
    """What policies know about the solve.

    Attributes:
        problem: the problem as given (its robot is the robot's own model).
        models: its :class:`gfcs.planning.models.RobotModels`.
        n_commands: the solve's free commands n (a round starts there).
        mesh_margin: the clearance [m] the meshes must keep for success.
        model_fabric: ``model_fabric(model)``: the fabric of a planning model at its own margin.
        model_problem: ``model_problem(model)``: the problem with that model's robot.
        time_limit: the solve's budget [s], or None.
    """

    problem: Any
    models: RobotModels
    n_commands: int
    mesh_margin: float
    model_fabric: Callable[[Any], Any]
    model_problem: Callable[[Any], Any]
    time_limit: Optional[float] = None


class Policy(Protocol):
    """A retry policy: ``name`` and ``propose(context, records)`` -> the next :class:`Attempt` or None."""

    name: str

    def propose(self, context: PlanContext, records: Sequence[AttemptRecord]) -> Optional[Attempt]:
        ...  # pragma: no cover


#: Attempt kinds that make up rounds of n_commands upward (the others are one-off attempts).
_ROUND_KINDS = ("plan", "cover")


def _same_model(records: Sequence[AttemptRecord]) -> List[AttemptRecord]:
    """The records of the last record's planning model."""
    model = records[-1].attempt.model
    return [r for r in records if r.attempt.model == model]


def mesh_contacts(record: AttemptRecord, mesh_margin: float) -> Tuple[str, ...]:
    """What the meshes of a mesh-only failure (:attr:`AttemptRecord.mesh_collision_only`) came too near:
    ``"obstacles"`` and/or ``"self"`` (two links), each whose clearance lies within ``mesh_margin`` +
    :data:`gfcs.metrics.INTERPOLATION_ALLOWANCE` (the range the continuous check judges); both when neither
    does; () for any other record."""
    if not record.mesh_collision_only:
        return ()
    m = record.result.metrics
    near = mesh_margin + _metrics.INTERPOLATION_ALLOWANCE
    kinds = tuple(kind for kind, key in (("obstacles", "mesh_clearance"), ("self", "mesh_self_clearance"))
                  if float(m.get(key, np.inf)) <= near)
    return kinds or ("obstacles", "self")


@dataclass
class MoreCommands:
    """After a failed plan attempt with n < ``n_commands + extra`` commands: the same with n + 1."""

    extra: int = MORE_COMMANDS
    name: str = "more commands"

    def __post_init__(self) -> None:
        self.extra = integer_at_least("MoreCommands.extra", self.extra, 0)

    def propose(self, context: PlanContext, records: Sequence[AttemptRecord]) -> Optional[Attempt]:
        last = records[-1].attempt
        if last.kind not in _ROUND_KINDS or last.n_commands >= context.n_commands + self.extra:
            return None
        return dataclasses.replace(last, n_commands=last.n_commands + 1)


@dataclass
class WiderMargin:
    """After a round of plan attempts (one margin, n_commands upward) that failed with a mesh contact with
    obstacles among them (:func:`mesh_contacts`): a new round with the obstacle margin ``step`` [m] wider,
    at most ``rounds`` times. The thin and covering sphere models miss parts of the meshes; a wider margin
    keeps those parts clear. Contacts between links alone are left to :class:`MeshCover`."""

    step: float = 0.002
    rounds: int = 2
    name: str = "wider margin"

    def __post_init__(self) -> None:
        self.step = non_negative("WiderMargin.step", self.step, " [m]")
        self.rounds = integer_at_least("WiderMargin.rounds", self.rounds, 0)

    def propose(self, context: PlanContext, records: Sequence[AttemptRecord]) -> Optional[Attempt]:
        last = records[-1].attempt
        k = last.margin_round
        if last.kind not in _ROUND_KINDS or self.step == 0 or k >= self.rounds:
            return None
        round_ = [r for r in _same_model(records) if r.attempt.kind == "plan" and r.attempt.margin_round == k]
        if not any("obstacles" in mesh_contacts(r, context.mesh_margin) for r in round_):
            return None
        return Attempt(last.model, context.n_commands, margin_round=k + 1, margin_step=self.step,
                       restart=last.restart)


def goal_contact(problem: Any, fabric: Any, slack: float, mesh_checker: Any,
                 mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN) -> Optional[Tuple[np.ndarray, float]]:
    """Per-sphere obstacle margins for a goal at which collision spheres come nearer the obstacles than
    ``fabric``'s margin: (margins (S,) m, clearance floor m), or None when no sphere does, when the goal's
    meshes do not clear the obstacles and each other by more than ``mesh_margin``, or when a sphere's centre
    lies within ``slack`` of an obstacle's inside (the sphere model cannot describe that contact).

    margin_i = min(m, c_i − slack) with m = ``obstacles.margin`` and c_i the clearance of sphere i at the
    goal; floor = min(0, min_i c_i) − 2·slack: the barrier's slack, and as much again for semi-implicit
    Euler steps overshooting a barrier by a millimetre or so.
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


#: The slack [m] of :func:`endpoint_contact`'s margins below the endpoints' sphere clearances.
CONTACT_SLACK = 0.002


def endpoint_self_contact(problem: Any, fabric: Any, slack: float, mesh_checker: Any,
                          mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN) -> Optional[Tuple[np.ndarray, float]]:
    """Per-pair self-collision margins for a start or goal at which two links' collision spheres come nearer
    each other than ``fabric``'s self-collision margin while the links' meshes clear each other (coarse
    spheres of two arms side by side, a folded wrist): (margins (P,) m in the order of
    ``robot.self_collision_pairs``, self-clearance floor m), or None when no pair does, without a mesh
    checker, when such an endpoint's meshes keep no more than ``mesh_margin`` from each other, or when two
    sphere centres lie within ``slack`` of each other's sphere.

    With the configured margin the fabric's self-collision barrier keeps such a pair apart, so a goal where
    it overlaps is never reached and a start where it does is pushed out of. margin_k = min(m, g_k − slack)
    with m = ``self_collision.margin`` and g_k the pair's least clearance over the start and the goal;
    floor = min(0, min_k g_k) − 2·``slack`` (:func:`goal_contact`'s floor, for pairs of spheres): below it
    the spheres count as in collision, above it the meshes judge.
    """
    robot = problem.robot
    pairs = np.asarray(robot.self_collision_pairs, dtype=np.int64).reshape(-1, 2)
    if mesh_checker is None or len(pairs) == 0:
        return None
    margin = float(fabric.config.to_dict()["self_collision"]["margin"])
    radii = np.asarray(robot.sphere_radii, dtype=np.float64)
    reach = radii[pairs[:, 0]] + radii[pairs[:, 1]]
    gap = np.full(len(pairs), np.inf)
    for q in (problem.q0, problem.goal):
        q = np.asarray(q, dtype=np.float64)
        c = np.asarray(robot.sphere_centers(q), dtype=np.float64)
        g = np.linalg.norm(c[pairs[:, 0]] - c[pairs[:, 1]], axis=1) - reach
        if np.any(g < margin + slack):
            if _metrics.mesh_verdict(mesh_checker, problem.scene, q[None], mesh_margin)[1] <= mesh_margin:
                return None
            gap = np.minimum(gap, g)
    margins = np.minimum(margin, gap - slack)
    if not np.any(margins < margin) or np.any(margins <= -reach):
        return None
    return margins, float(min(0.0, gap.min()) - 2.0 * slack)


@dataclass(frozen=True)
class EndpointContact:
    """The sphere contacts of a problem's endpoints that its meshes clear (:func:`endpoint_contact`), which
    every attempt on one planning model plans with.

    Attributes:
        self_margins: (P,) self-collision margins [m] (:func:`endpoint_self_contact`), or None.
        self_floor: how far [m, ≤ 0] spheres may overlap each other for success.
        obstacle_caps: (S,) upper bounds [m] on the spheres' obstacle margins (+inf for spheres the goal
            keeps clear; :func:`goal_contact`), or None.
        floor: how far [m, ≤ 0] spheres may overlap obstacles for success.
    """

    self_margins: Optional[np.ndarray] = None
    self_floor: float = 0.0
    obstacle_caps: Optional[np.ndarray] = None
    floor: float = 0.0


def endpoint_contact(problem: Any, fabric: Any, slack: float, mesh_checker: Any,
                     mesh_margin: float = _metrics.DEFAULT_MESH_MARGIN) -> Optional[EndpointContact]:
    """The endpoint contacts that no attempt with the configured margins can end in, or None: sphere pairs
    the start or the goal brings nearer than the self-collision margin (:func:`endpoint_self_contact`), and
    spheres the goal sinks into an obstacle while the meshes clear it (:func:`goal_contact`: a motion ending
    there counts as a collision on the spheres). A goal whose spheres come within the obstacle margin
    without overlapping is left to the :class:`GoalContact` retry."""
    own = endpoint_self_contact(problem, fabric, slack, mesh_checker, mesh_margin)
    goal = None
    if mesh_checker is not None and len(problem.scene):
        clearance = _metrics.sphere_clearances(problem.robot, problem.scene,
                                               np.asarray(problem.goal, dtype=np.float64)[None])[0]
        if clearance.min() < 0.0:
            goal = goal_contact(problem, fabric, slack, mesh_checker, mesh_margin)
    if own is None and goal is None:
        return None
    contact = EndpointContact()
    if own is not None:
        contact = dataclasses.replace(contact, self_margins=own[0], self_floor=own[1])
    if goal is not None:
        margin = float(fabric.config.to_dict()["obstacles"]["margin"])
        caps = np.where(goal[0] < margin, goal[0], np.inf)
        contact = dataclasses.replace(contact, obstacle_caps=caps, floor=goal[1])
    return contact


@dataclass
class GoalContact:
    """Once per model, after its plan attempts failed: if the goal is in sphere contact that the meshes
    clear (:func:`goal_contact` with ``slack`` [m]), one attempt with n_commands commands, the contact
    spheres' margins lowered, and spheres judged down to the clearance floor (the meshes judge the rest).
    Needs a mesh validator."""

    slack: float = 0.002
    name: str = "goal contact"

    def __post_init__(self) -> None:
        self.slack = non_negative("GoalContact.slack", self.slack, " [m]")

    def propose(self, context: PlanContext, records: Sequence[AttemptRecord]) -> Optional[Attempt]:
        last = records[-1].attempt
        validator = context.models.validator
        if self.slack == 0 or validator is None or last.kind not in _ROUND_KINDS:
            return None
        if any(r.attempt.kind == "goal_contact" for r in _same_model(records)) or last.clearance_floor < 0:
            return None  # tried, or every attempt plans with the goal's contact (endpoint_contact)
        found = goal_contact(context.model_problem(last.model), context.model_fabric(last.model), self.slack,
                             validator, context.mesh_margin)
        if found is None:
            return None
        margins, floor = found
        return Attempt(last.model, context.n_commands, kind="goal_contact",
                       obstacle_margins=tuple(float(m) for m in margins), clearance_floor=floor,
                       restart=last.restart)


def cover_self_margins(robot: Any, deficits: np.ndarray, base: float, max_extra: float,
                       states: Sequence[Any], slack: float = 0.002) -> np.ndarray:
    """(P,) self-collision margins [m] that cover the meshes, in the order of ``robot.self_collision_pairs``:
    base + min(e_a + e_b, ``max_extra``) for the pair of spheres a, b with mesh deficits e (S,) m
    (:func:`gfcs.coverage.sphere_deficits`), lowered, where a configuration of ``states`` (the start and the
    goal, (dof,) each) holds the pair's spheres nearer than that, to their clearance there − ``slack`` (but
    not below ``base``): the barrier must hold at both ends."""
    pairs = np.asarray(robot.self_collision_pairs, dtype=np.int64).reshape(-1, 2)
    radii = np.asarray(robot.sphere_radii, dtype=np.float64)
    e = np.asarray(deficits, dtype=np.float64)
    margins = base + np.minimum(e[pairs[:, 0]] + e[pairs[:, 1]], max_extra)
    for q in states:
        c = np.asarray(robot.sphere_centers(np.asarray(q, dtype=np.float64)))
        gap = np.linalg.norm(c[pairs[:, 0]] - c[pairs[:, 1]], axis=1) - radii[pairs[:, 0]] - radii[pairs[:, 1]]
        margins = np.minimum(margins, np.maximum(base, gap - slack))
    return margins


@dataclass
class MeshCover:
    """Once per model, after an attempt on it failed only because a collision mesh came too near and the
    other mesh retries did not help: a round (n_commands upward, with :class:`MoreCommands`) in which every
    sphere keeps the model's obstacle margin plus its mesh deficit from obstacles: how far the validator's
    meshes stick out of that sphere (:func:`gfcs.coverage.sphere_deficits`), at most ``max_extra`` [m];
    with ``self_pairs``, every self-collision sphere pair likewise keeps the sum of its two deficits
    (:func:`cover_self_margins`, kept feasible at the start and the goal). A uniformly wider margin
    (:class:`WiderMargin`) covers millimetres; a sphere model made for another checker can miss its robot's
    meshes by centimetres on some links only. Needs a mesh validator; skipped when no sphere misses the
    meshes by more than ``min_deficit`` [m]."""

    min_deficit: float = 0.001
    max_extra: float = 0.03
    self_pairs: bool = True
    name: str = "mesh cover"

    def __post_init__(self) -> None:
        self.min_deficit = non_negative("MeshCover.min_deficit", self.min_deficit, " [m]")
        self.max_extra = non_negative("MeshCover.max_extra", self.max_extra, " [m]")

    def propose(self, context: PlanContext, records: Sequence[AttemptRecord]) -> Optional[Attempt]:
        from gfcs.coverage import sphere_deficits

        last = records[-1].attempt
        validator = context.models.validator
        same = _same_model(records)
        if (validator is None or self.max_extra == 0 or any(r.attempt.kind == "cover" for r in same)
                or not any(r.mesh_collision_only for r in same)):
            return None
        problem = context.model_problem(last.model)
        deficits = sphere_deficits(problem.robot, validator.robot)
        if not np.any(deficits > self.min_deficit):
            return None
        config = context.model_fabric(last.model).config.to_dict()
        margins = float(config["obstacles"]["margin"]) + np.minimum(deficits, self.max_extra)
        pairs = None
        if self.self_pairs:
            pairs = tuple(float(m) for m in cover_self_margins(
                problem.robot, deficits, float(config["self_collision"]["margin"]), self.max_extra,
                (problem.q0, problem.goal)))
        return Attempt(last.model, context.n_commands, kind="cover",
                       obstacle_margins=tuple(float(m) for m in margins), self_margins=pairs,
                       restart=last.restart)


@dataclass
class ModelCascade:
    """When the attempts on one planning model failed and no other policy proposes more: the first attempt
    on the next model (:attr:`gfcs.planning.models.RobotModels.planning`)."""

    name: str = "model cascade"

    def propose(self, context: PlanContext, records: Sequence[AttemptRecord]) -> Optional[Attempt]:
        return _next_model(context, records[-1].attempt)


def _next_model(context: PlanContext, last: Attempt) -> Optional[Attempt]:
    """The first attempt on the planning model after ``last``'s (n_commands, ``last``'s restart), or None
    after the last model."""
    planning = list(context.models.planning)
    i = planning.index(last.model)
    if i + 1 >= len(planning):
        return None
    return Attempt(planning[i + 1], context.n_commands, restart=last.restart)


@dataclass
class ModelShare:
    """With a time budget and another planning model left: once the attempts on the current model (its last
    uninterrupted run of records) have used their share of the budget, the first attempt on the next model,
    before any other policy's proposal. A model's share is an equal part of the time that was left when its
    run started, among it and the models after it: with two models, the first may use half the budget. A
    model's attempts can fail on one problem until the budget ends where the next model's succeed within a
    second (the covering and the robot's own spheres on the Fetch's shelves and under its tables,
    docs/tuning.md). A model one of whose attempts in the run failed only because a collision mesh touched
    (:attr:`AttemptRecord.mesh_collision_only`: the goal reached, the spheres clear) is near a solution that
    the mesh retries work on: it may use up to ``near_miss`` times its share."""

    near_miss: float = 2.0
    name: str = "model share"

    def __post_init__(self) -> None:
        self.near_miss = non_negative("ModelShare.near_miss", self.near_miss)
        if self.near_miss < 1.0:
            raise InvalidValueError(f"ModelShare.near_miss must be ≥ 1 (a factor on the share), got {self.near_miss!r}")

    def propose(self, context: PlanContext, records: Sequence[AttemptRecord]) -> Optional[Attempt]:
        last = records[-1].attempt
        following = _next_model(context, last)
        if context.time_limit is None or following is None:
            return None
        start = len(records)
        while start > 0 and records[start - 1].attempt.model == last.model:
            start -= 1
        before = sum(r.time for r in records[:start])
        used = sum(r.time for r in records[start:])
        models_left = len(context.models.planning) - list(context.models.planning).index(last.model)
        share = max(0.0, float(context.time_limit) - before) / models_left
        if any(r.mesh_collision_only for r in records[start:]):
            share *= self.near_miss
        return following if used >= share else None


@dataclass
class Restart:
    """When every other policy declined (each model's attempts failed): start the whole sequence again,
    from the first planning model and n_commands, with a fresh optimiser seed and twice the population of
    the previous restart (IPOP-CMA-ES: Auger & Hansen 2005), at most ``rounds`` times. A solve whose
    attempts all failed early has budget left (`time_limit`); a larger population explores more command
    sequences per batch. The budget ends a restart it cannot afford."""

    rounds: int = 2
    name: str = "restart"

    def __post_init__(self) -> None:
        self.rounds = integer_at_least("Restart.rounds", self.rounds, 0)

    def propose(self, context: PlanContext, records: Sequence[AttemptRecord]) -> Optional[Attempt]:
        k = max(r.attempt.restart for r in records)
        if k >= self.rounds:
            return None
        return Attempt(context.models.planning[0], context.n_commands, restart=k + 1)


def default_policies(more_commands: int = MORE_COMMANDS, margin_step: float = 0.002, margin_rounds: int = 2,
                     goal_contact_slack: float = 0.002, cascade: bool = True,
                     mesh_cover: float = 0.0, restarts: int = 2) -> List[Any]:
    """The ``default`` preset's policies in order: :class:`ModelShare`, :class:`MoreCommands`,
    :class:`WiderMargin`, :class:`GoalContact`, :class:`MeshCover` (``mesh_cover`` > 0: its ``max_extra``; off
    by default, docs/tuning.md), :class:`ModelCascade`, :class:`Restart` (``restarts`` rounds); a policy whose
    parameter turns it off (0 extra commands, a 0 step or 0 rounds, a 0 slack, a 0 ``mesh_cover``,
    ``cascade=False`` for both model policies, 0 restarts) is left out."""
    policies: List[Any] = [ModelShare()] if cascade else []
    if integer_at_least("more_commands", more_commands, 0) > 0:
        policies.append(MoreCommands(more_commands))
    if non_negative("margin_step", margin_step, " [m]") > 0 and integer_at_least("margin_rounds", margin_rounds, 0):
        policies.append(WiderMargin(margin_step, margin_rounds))
    if non_negative("goal_contact_slack", goal_contact_slack, " [m]") > 0:
        policies.append(GoalContact(goal_contact_slack))
    if non_negative("mesh_cover", mesh_cover, " [m]") > 0:
        policies.append(MeshCover(max_extra=mesh_cover))
    if cascade:
        policies.append(ModelCascade())
    if integer_at_least("restarts", restarts, 0) > 0:
        policies.append(Restart(restarts))
    return policies
