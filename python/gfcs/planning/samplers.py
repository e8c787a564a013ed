"""Warm-start samplers of Algorithm 1 (``f_sampler``, GFCS Sec. IV-A): candidates for the first CMA-ES batch.

* :class:`UniformSampler`: uniform in the joint limits (the paper's "No learning").
* :class:`ApproachSampler`: the default of the ``default`` preset: half the candidates along the goal's
  approach corridor, half with the hand pulled in toward the base.
* The learned sampler (:class:`gfcs.learning.sampler.EBMSampler`) follows the same :class:`Sampler` protocol.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional, Protocol, Tuple

import numpy as np

from gfcs import profile as _profile
from gfcs.errors import InvalidValueError

__all__ = ["Sampler", "UniformSampler", "ApproachSampler"]


class Sampler(Protocol):
    """Sampler protocol of Algorithm 1 (``f_sampler``): candidates to warm-start CMA-ES.

    ``sample(problem, n, rng)`` returns an (n, n_free·dof) float array of command sequences
    y = [q_g¹ᵀ … q_gⁿᵀ]ᵀ inside the joint limits of ``problem.robot``; ``rng`` is a
    ``numpy.random.Generator`` owned by the caller (use it for every random draw so that solves are
    reproducible).
    """

    def sample(self, problem: Any, n: int, rng: np.random.Generator) -> np.ndarray:  # pragma: no cover
        ...


@dataclass
class UniformSampler:
    """Uniform samples within the joint limits, U(q_low, q_up) per command (the "No learning" sampler).

    Attributes:
        n_commands: number n of free commands per candidate (output width n·dof).
    """

    n_commands: int = 1

    def sample(self, problem: Any, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, n_commands·dof) uniform candidates."""
        lo = np.tile(np.asarray(problem.robot.lower, dtype=np.float64), self.n_commands)
        up = np.tile(np.asarray(problem.robot.upper, dtype=np.float64), self.n_commands)
        return rng.uniform(lo, up, size=(int(n), lo.shape[0]))


@dataclass
class ApproachSampler:
    """The default warm start: half of the candidates follow the goal's approach corridor, the other half
    leave the start by pulling the hand in toward the robot's base.

    A grasp goal (MotionBenchMaker's shelves, boxes, cages) sits in narrow free space that the fabric
    enters only along the gripper's approach direction, and a start in confined space (under a table) is
    left by folding the arm in; a uniform command almost never does either. Of n candidates:

    * the first round(``fraction``·n) are approach candidates: their last free command is an approach
      configuration (the goal's end-effector pose backed off by one of ``distances`` along ``axis``, see
      :func:`gfcs.approach.approach_configurations`; the distances in turn) and each earlier command backs
      off one ``spacing`` further (spacings in turn), so that a sequence enters the corridor step by step;
      every command gets N(0, (sigma·(q_up − q_low))²) per joint, clipped into the limits;
    * the next round(``retract``·n) (at most the rest) are retract candidates: their first command is a
      retract configuration (:func:`gfcs.approach.retract_configurations`: the hand pulled in toward the
      base axis at about the goal's height), their later commands (n ≥ 2) those of an approach candidate;
    * the others are those of :class:`UniformSampler`.

    ``fraction = retract = 0`` is the uniform sampler (the paper's "No learning"). The retract half serves
    starts in confined space, which uniform commands leave no better than the goal's corridor does; on the
    MotionBenchMaker suite it shortens hand paths most where the start is under a table (docs/tuning.md).

    Attributes:
        n_commands: number n of free commands per candidate (output width n·dof).
        fraction: share of approach candidates, in [0, 1].
        retract: share of retract candidates, in [0, 1] (capped at 1 − fraction).
        distances: back-off distances (m) of the last command, ≥ 0.
        spacings: extra back-off (m, ≥ 0) of each earlier command over the next one (n ≥ 2 only).
        sigma: joint noise around the approach configurations as a fraction of each joint range, ≥ 0.
        axis: approach direction in the end-effector frame; None: the robot profile's
            (:func:`gfcs.profile.profile_for`: a data file's, else derived from the gripper's spheres), and
            for the other hands of a group spanning several arms (``problem.meta["ee_links"]``) each derived
            from its own gripper's spheres (:func:`gfcs.profile.derive_approach_axis`).
    """

    n_commands: int = 1
    fraction: float = 0.5
    retract: float = 0.5
    distances: Tuple[float, ...] = (0.05, 0.10, 0.15, 0.20)
    spacings: Tuple[float, ...] = (0.10, 0.15, 0.20)
    sigma: float = 0.02
    axis: Optional[Tuple[float, float, float]] = None

    def __post_init__(self) -> None:
        if int(self.n_commands) < 1:
            raise InvalidValueError(f"ApproachSampler.n_commands must be >= 1, got {self.n_commands}")
        for name in ("fraction", "retract"):
            if not 0.0 <= float(getattr(self, name)) <= 1.0:
                raise InvalidValueError(f"ApproachSampler.{name} must be in [0, 1], got {getattr(self, name)}")
        if not (math.isfinite(self.sigma) and self.sigma >= 0):
            raise InvalidValueError(f"ApproachSampler.sigma must be a finite number >= 0, got {self.sigma}")
        for name in ("distances", "spacings"):
            values = getattr(self, name)
            if len(values) == 0 or not all(math.isfinite(d) and d >= 0 for d in values):
                raise InvalidValueError(f"ApproachSampler.{name} must be finite numbers >= 0, got {values}")

    def sample(self, problem: Any, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, n_commands·dof) candidates: approach ones for ``problem.goal``, retract ones from
        ``problem.q0``, then uniform ones (see the class docstring)."""
        from gfcs.approach import approach_configurations, retract_configurations

        y = UniformSampler(self.n_commands).sample(problem, n, rng)
        k = int(round(float(self.fraction) * int(n)))
        r = min(int(round(float(self.retract) * int(n))), int(n) - k)
        if k + r == 0:
            return y
        robot = problem.robot
        lo = np.asarray(robot.lower, dtype=np.float64)
        up = np.asarray(robot.upper, dtype=np.float64)
        dof, m = lo.shape[0], int(self.n_commands)
        i = np.arange(k + r)
        # back-off distance of command c of candidate i: the last one's plus (m-1-c) spacings
        last = np.asarray(self.distances, dtype=np.float64)[i % len(self.distances)]
        step = np.asarray(self.spacings, dtype=np.float64)[i % len(self.spacings)]
        back = last[:, None] + step[:, None] * np.arange(m - 1, -1, -1)[None, :]
        levels, index = np.unique(back, return_inverse=True)
        axis = self.axis if self.axis is not None else _profile.profile_for(robot).approach_axis
        # the other hands of a group spanning several arms back off and pull in likewise
        others = [link for link in ((getattr(problem, "meta", None) or {}).get("ee_links") or ())
                  if link != robot.ee_link]
        axes = [(link, self.axis if self.axis is not None else _profile.derive_approach_axis(robot, link))
                for link in others]
        approach = approach_configurations(robot, problem.goal, levels, axis, links=axes)
        rows = approach[index.reshape(k + r, m)]  # (k + r, m, dof)
        noise = rng.standard_normal((k + r, m, dof)) * (float(self.sigma) * (up - lo))
        rows = np.clip(rows + noise, lo, up)
        if r:
            rows[k:, 0] = retract_configurations(robot, problem.q0, problem.goal, r, rng, links=others)
        y[: k + r] = rows.reshape(k + r, m * dof)
        return y
