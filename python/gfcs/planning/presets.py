"""Presets: named sets of planner settings.

* ``default``: the planner as the project ships it: the approach/retract warm start, the command blend, the
  near-optimal shortest-hand-path choice, mesh-validated candidate selection with the repair of candidates
  that fail only on the meshes (:mod:`gfcs.planning.repair`), the finished trajectory
  (smooth start, goal blend, velocity and acceleration re-timing), the thin-then-covering sphere models,
  every retry policy (:func:`gfcs.planning.policies.default_policies`), and an attempt's optimisation ended
  once two batches in a row lowered its best cost by at most 1 % (:func:`gfcs.planning.gfcop.stalled`).
* ``paper``: GFCS as the paper writes it (GFCS Sec. IV-A, Alg. 1): a uniform first batch (or the learned
  sampler when one is given), the lowest-cost candidate of eq. 4, the command switch of eq. 7 (no blend),
  the goal tolerance ε = 0.01 rad, the goal commanded as it is, eq. 4's cost without a collision term, no
  stall exit, the paper's
  barriers (no braking cap or damper, exact curvature: ``braking_time`` and ``min_curvature_radius`` 0),
  the robot's own spheres, no retries, no mesh repair and the trajectory as the fabric integrates it (no re-timing, no
  blend), every batch run. With a mesh model the returned motion is still judged on the meshes; it is not
  chosen by them.

Both presets keep a time budget when one is given (``time_limit``): a budget bounds how long a solve may
run, it does not change the method. :func:`gfcs.planning.solve.solve` has no budget unless asked;
``gfcs solve`` and ``gfcs bench`` default to 5 s for both presets.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional

from gfcs.errors import InvalidValueError
from gfcs.planning.finish import FinishOptions
from gfcs.planning.policies import default_policies
from gfcs.planning.repair import RepairOptions
from gfcs.planning.rollout import RolloutSettings

__all__ = ["Preset", "PRESETS", "get_preset", "PAPER_BARRIERS"]

#: Fabric configuration of the paper's barriers (GF Sec. VII-A): no braking cap or damper, the exact
#: curvature of the distance field.
PAPER_BARRIERS: Dict[str, Dict[str, float]] = {
    "obstacles": {"braking_time": 0.0, "min_curvature_radius": 0.0},
    "self_collision": {"braking_time": 0.0, "min_curvature_radius": 0.0},
    "joint_limits": {"braking_time": 0.0},
}


@dataclass(frozen=True)
class Preset:
    """A named set of planner settings (see the module docstring).

    Attributes:
        name: ``"default"`` or ``"paper"``.
        settings: the rollout settings (a solve given ``settings`` uses those instead).
        finish: the finishing options (a solve given ``finish`` uses those instead).
        length_slack: ε of the near-optimal preference (0: the lowest cost, eq. 4).
        mesh_candidates: at most this many candidates judged on the meshes (1: the lowest-cost one only).
        sampler: the first batch without a sampler given: ``"approach"`` or ``"uniform"``.
        thin_spheres: plan on a thinner sphere model first when the robot has one.
        element_spheres: every planning model carries the validator's collision spheres in place of its own
            spheres inside them (:func:`gfcs.planning.models.models_for`).
        covering_spheres: plan on spheres fitted around the validator's meshes too, when the robot's own
            spheres leave them uncovered (:func:`gfcs.planning.models.covering_model`).
        policies: ``policies()`` -> the retry policies, in order.
        fabric: configuration overrides applied over the fabric configuration given to the solve.
        stall_batches: early stop of the optimisation after this many stalled batches (0: every batch
            runs; :func:`gfcs.planning.gfcop.stalled`).
        repair: the repair of candidates that fail only on the meshes (None: none).
        sweep_time: the time [s] the continuous mesh check of one candidate may take before the candidate
            counts as too near (:attr:`gfcs.planning.selection.SelectionOptions.sweep_time`; None: no cap).
        grazing_sweep_time: the continuous check's cap [s] instead of ``sweep_time`` when the start or the goal
            itself keeps its meshes within the margin + 1 mm of contact
            (:func:`gfcs.planning.endpoints.endpoint_grazes`): every path then needs the sweep there, and a cap
            that no candidate meets refuses them all (None: ``sweep_time`` always).
        endpoint_contact: every attempt plans with the endpoints' sphere contacts that the meshes clear: the
            self-collision margins of the sphere pairs the start or the goal brings nearer than the margin
            lowered, and the obstacle margins of the spheres the goal sinks into an obstacle, and the meshes
            judge those contacts (:func:`gfcs.planning.policies.endpoint_contact`).
        spheres_judge: with a mesh checker, a candidate's sphere clearances must hold too; False: the meshes
            alone judge collisions, as the validator does, and a motion whose spheres overlap where its
            meshes keep the margin succeeds (:attr:`gfcs.planning.selection.SelectionOptions.spheres_judge`).
        selection_share: the share (in (0, 1]) of the time left that an attempt's candidate selection may
            spend while another attempt would still fit after it, so that the retry policies get time
            (:meth:`gfcs.planning.budget.Budget.selection_deadline`); 1: up to the end of the budget.
    """

    name: str
    settings: RolloutSettings
    finish: FinishOptions
    length_slack: float
    mesh_candidates: int
    sampler: str
    thin_spheres: bool
    policies: Callable[[], List[Any]]
    fabric: Dict[str, Any] = field(default_factory=dict)
    stall_batches: int = 0
    repair: Optional[RepairOptions] = None
    sweep_time: Optional[float] = None
    grazing_sweep_time: Optional[float] = None
    endpoint_contact: bool = False
    element_spheres: bool = False
    covering_spheres: bool = False
    spheres_judge: bool = True
    selection_share: float = 1.0


PRESETS: Dict[str, Preset] = {
    # tol 0.02: a reached trajectory ends with a quintic blend onto the goal that stays within the ball
    # around it through the reached state (gfcs.blend), so what is returned ends exactly at the goal whatever
    # ε, and the looser ε spares the slow last approach; capture_tol 0.05: a rollout that comes to rest
    # within 0.05 rad of the goal, held off by the barriers of nearby obstacles (a hand deep in a shelf),
    # counts as reached and the blend covers the rest. Success is judged at metrics.DEFAULT_SUCCESS_TOL
    # (0.01 rad) on the finished trajectory, spheres and meshes included. collision_penalty 100 s: success
    # requires a collision-free motion, so colliding candidates rank behind collision-free ones.
    # stall_batches 2: the best cost of most solves is found in the first batches, so later batches cost time
    # for paths within a few percent (measured in docs/tuning.md), and a failing attempt hands over to the next
    # retry sooner.
    "default": Preset("default", RolloutSettings(tol=0.02, capture_tol=0.05, collision_penalty=100.0,
                                                 limit_hold_off=0.015),
                      FinishOptions(), length_slack=0.1, mesh_candidates=32,
                      sampler="approach", thin_spheres=True, policies=default_policies,
                      repair=RepairOptions(), sweep_time=0.25, grazing_sweep_time=1.0, endpoint_contact=True,
                      element_spheres=True, covering_spheres=True, spheres_judge=False, selection_share=0.75,
                      stall_batches=2),
    "paper": Preset("paper",
                    RolloutSettings(blend_time=0.0, stall_window=0.0),
                    FinishOptions(retime_start=False, goal_blend=False, limit_velocity=False,
                                  limit_acceleration=False),
                    length_slack=0.0, mesh_candidates=1, sampler="uniform", thin_spheres=False,
                    policies=list, fabric=PAPER_BARRIERS, stall_batches=0),
}


def get_preset(preset: Any) -> Preset:
    """A :class:`Preset` by name (or the preset itself); InvalidValueError naming ``preset`` otherwise."""
    if isinstance(preset, Preset):
        return preset
    if preset not in PRESETS:
        raise InvalidValueError(f"preset must be one of {sorted(PRESETS)}, got {preset!r}")
    return PRESETS[preset]
