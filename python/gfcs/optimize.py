"""Compatibility module: the planner lives in :mod:`gfcs.planning`; these names are re-exported from it.

``gfcs.optimize.solve`` is :func:`gfcs.planning.solve`, and so on for the samplers, Algorithm 1, the
rollout settings, the finishing options, replay and the goal-contact margins.
"""

from gfcs.planning import (THIN_SPHERE_MARGIN, ApproachSampler, BatchInfo, Candidate, FinishOptions,
                           OptimResult, RolloutSettings, Sampler, SelectionOptions, UniformSampler,
                           combine_attempts, fabric_goal, finish_rollout, goal_contact, make_fabric, replay,
                           rollout_commands, select_candidate, solve, solve_gfcop)
from gfcs.planning.gfcop import _import_cma

__all__ = [
    "Sampler",
    "UniformSampler",
    "ApproachSampler",
    "BatchInfo",
    "OptimResult",
    "RolloutSettings",
    "FinishOptions",
    "Candidate",
    "SelectionOptions",
    "select_candidate",
    "solve_gfcop",
    "solve",
    "combine_attempts",
    "goal_contact",
    "replay",
    "make_fabric",
    "fabric_goal",
    "rollout_commands",
    "finish_rollout",
    "THIN_SPHERE_MARGIN",
    "_import_cma",
]
