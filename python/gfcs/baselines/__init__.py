"""Sampling-based baselines of GFCS Table I (RRTConnect, Bi-EST, BIT*), planned with OMPL (the ``baselines``
extra: ``pip install 'gfcs[baselines]'``) on the project's collision spheres, and returned as
:class:`gfcs.results.SolveResult` with the same metrics as GFCS.

* :mod:`gfcs.baselines.ompl_planner`: :func:`plan_ompl` (set-up, planning, simplification, timing, metrics).
* :mod:`gfcs.baselines.validity`: batched sphere checks of states and segments (no OMPL needed).
* :mod:`gfcs.baselines.biest`: OMPL's Bi-EST algorithm in numpy (the PyPI wheels bind no class for it).
* :mod:`gfcs.baselines.timing`: time parameterisation of a path within the joint limits.

Importing this package does not import OMPL; :func:`plan_ompl` raises an ImportError naming the extra when
OMPL is missing.
"""

from gfcs.baselines.ompl_planner import DEFAULT_PLANNER_TIME, PLANNERS, is_ompl_method, plan_ompl, planner_label

__all__ = ["plan_ompl", "PLANNERS", "planner_label", "is_ompl_method", "DEFAULT_PLANNER_TIME"]
