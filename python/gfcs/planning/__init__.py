"""The GFCS planner (GFCS Sec. IV-A), as a pipeline of small parts.

=====================  =========================================================================================
module                 holds
=====================  =========================================================================================
``gfcop``              Algorithm 1: warm-started CMA-ES over a box, any batched cost, with a deadline
``samplers``           the warm-start samplers (uniform, approach + retract; the learned one lives in learning)
``rollout``            :class:`RolloutSettings` (eq. 1-8), the fabric of a problem, the commanded goal
``finish``             :class:`FinishOptions` and the finishing of a recorded trajectory (via gfcs.blend)
``selection``          which candidate an attempt returns (:class:`Candidate`, :class:`SelectionOptions`)
``models``             a robot's planning models, validator, limits and profile, resolved once per solve
``attempts``           :class:`Attempt` (what it plans with), :class:`AttemptRecord` (what it gave)
``policies``           retry policies: :class:`MoreCommands`, :class:`WiderMargin`, :class:`GoalContact`,
                       :class:`ModelShare`, :class:`ModelCascade`, :class:`Restart`
``presets``            ``default`` and ``paper``
``budget``             the time budget's deadlines
``solve``              :func:`solve` and :func:`replay`
=====================  =========================================================================================
"""

from gfcs.planning.attempts import Attempt, AttemptRecord, combine_attempts
from gfcs.planning.budget import Budget
from gfcs.planning.finish import FinishOptions, finish_rollout, rollout_commands
from gfcs.planning.gfcop import BatchInfo, OptimResult, solve_gfcop
from gfcs.planning.models import THIN_SPHERE_MARGIN, PlanningModel, RobotModels, models_for, planned_robot
from gfcs.planning.policies import (GoalContact, ModelCascade, ModelShare, MoreCommands, PlanContext, Policy, Restart,
                                    WiderMargin, cover_self_margins, default_policies, goal_contact,
                                    mesh_contacts)
from gfcs.planning.presets import PRESETS, Preset, get_preset
from gfcs.planning.rollout import RolloutSettings, fabric_goal, make_fabric
from gfcs.planning.samplers import ApproachSampler, Sampler, UniformSampler
from gfcs.planning.selection import Candidate, SelectionOptions, select_candidate
from gfcs.planning.solve import replay, solve

__all__ = [
    "solve", "replay", "solve_gfcop", "BatchInfo", "OptimResult",
    "Sampler", "UniformSampler", "ApproachSampler",
    "RolloutSettings", "FinishOptions", "make_fabric", "fabric_goal", "rollout_commands", "finish_rollout",
    "Candidate", "SelectionOptions", "select_candidate",
    "PlanningModel", "RobotModels", "models_for", "planned_robot", "THIN_SPHERE_MARGIN",
    "Attempt", "AttemptRecord", "combine_attempts",
    "Policy", "PlanContext", "MoreCommands", "WiderMargin", "GoalContact", "ModelShare", "ModelCascade", "Restart",
    "default_policies", "goal_contact", "cover_self_margins", "mesh_contacts",
    "Preset", "PRESETS", "get_preset", "Budget",
]
