"""Intermediate configurations for the GFCS warm start (:class:`gfcs.optimize.ApproachSampler`), by
inverse kinematics.

* Approach configurations: the goal's end-effector pose backed off along its approach axis. A grasp goal
  (MotionBenchMaker's shelves, boxes, cages, tables) sits in narrow free space that the arm can enter only
  along the gripper's approach direction. The configuration whose end effector has the goal's orientation
  but stands ``distance`` metres back along that axis (a pre-grasp) lies at the mouth of that corridor,
  and makes a good intermediate command.
* Retract configurations: the hand pulled in toward the robot's vertical base axis, at about the goal
  hand's height. A start in confined space (MotionBenchMaker's table under: the hand below the table top)
  is left by folding the arm in before reaching out again; a uniform command almost never does that, and it is what the learned
  sampler came to propose on MotionBenchMaker's table-under problems (docs/tuning.md).

Inverse kinematics (``Robot.inverse_kinematics``, in the core: damped least squares, each step clipped
into the joint limits): approach configurations on the stacked task e = [p* − p; w (x* − x); w (z* − z)]
(EE position and two EE axes, world frame; w = ``AXIS_WEIGHT`` m per unit of axis error), started at the
goal configuration and continued from one distance to the next; retract configurations on the EE position
alone, all rows in one parallel call.
"""

from __future__ import annotations

from typing import Any, Sequence, Tuple

import numpy as np

from gfcs.errors import InvalidValueError, ShapeError

__all__ = ["approach_configurations", "retract_configurations", "AXIS_WEIGHT", "RETRACT_BLEND", "RETRACT_SCALE",
           "RETRACT_HEIGHT_SIGMA"]

#: Weight (m) of an EE-axis error relative to a position error of 1 m.
AXIS_WEIGHT = 0.3
#: Range of the start-to-goal blend a of a retract configuration (uniform).
RETRACT_BLEND = (0.2, 0.8)
#: Range of the share of its horizontal distance from the base axis that a retract target keeps (uniform).
RETRACT_SCALE = (0.25, 0.65)
#: Standard deviation (m) of a retract target's height about the goal hand's.
RETRACT_HEIGHT_SIGMA = 0.1
_DAMPING = 1e-3
_TOL = 1e-5
#: Damping (m²) and stopping tolerance (m) of the position-only steps of the retract configurations.
_RETRACT_DAMPING = 1e-2
_RETRACT_TOL = 1e-3


def _configuration(robot: Any, name: str, q: Any) -> np.ndarray:
    """``q`` as a new float64 (dof,) array; ValueError naming ``name`` unless it has dof finite values."""
    dof = len(robot.lower)
    out = np.array(q, dtype=np.float64)
    if out.shape != (dof,) or not np.all(np.isfinite(out)):
        raise ShapeError(f"{name}: expected {dof} finite values, got shape {out.shape}")
    return out


def approach_configurations(
    robot: Any,
    q_goal: Any,
    distances: Sequence[float],
    axis: Sequence[float] = (0.0, 0.0, 1.0),
    iterations: int = 30,
    links: Sequence[Tuple[str, Sequence[float]]] = (),
) -> np.ndarray:
    """Configurations whose end effector keeps the goal's orientation and backs off along ``axis``.

    Args:
        robot: a ``gfcs.Robot`` (its ``ee_link`` is the end effector).
        q_goal: (dof,) goal configuration, rad (or m for prismatic joints).
        distances: back-off distances d ≥ 0 (m), solved in the given order, each starting from the
            previous solution (sort them ascending for the shortest continuation).
        axis: approach direction in the end-effector frame (unit vector after normalisation; default its z
            axis, the Panda gripper's). The target position is p_goal − d · R_goal · axis.
        iterations: damped least-squares steps per distance (fewer when the task error falls below 1e-5).
        links: further end effectors backed off the same way, (link, its approach axis in its own frame)
            each (a group spanning two arms: the second hand), solved after ``robot.ee_link`` at each
            distance, each from the configuration the one before it left.

    Returns:
        (len(distances), dof) configurations inside the joint limits. Where the target cannot be reached
        (limits, singularities) the row is the closest configuration the iteration found.

    Raises:
        ValueError: ``q_goal`` of the wrong shape or not finite, a negative or non-finite distance, a zero
            or non-finite axis.
    """
    q = _configuration(robot, "q_goal", q_goal)
    d = np.asarray(distances, dtype=np.float64).reshape(-1)
    if not (np.all(np.isfinite(d)) and np.all(d >= 0)):
        raise InvalidValueError(f"distances must be finite and >= 0, got {d.tolist()}")
    poses = np.asarray(robot.link_poses(q))
    hands = []  # (link, its goal position, its goal x and z axes, its unit approach axis in the world frame)
    for link, ax in [(robot.ee_link, axis), *links]:
        a = np.asarray(ax, dtype=np.float64).reshape(-1)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
            raise InvalidValueError(f"axis{'' if link == robot.ee_link else f' of {link}'}: expected a non-zero "
                                    f"3-vector, got {np.asarray(ax).tolist()}")
        pose = poses[robot.link_index(link)]
        hands.append((link, pose[:3, 3], np.stack([pose[:3, 0], pose[:3, 2]]), pose[:3, :3] @ (a / np.linalg.norm(a))))
    out = np.empty((d.shape[0], q.shape[0]))
    for row, dist in enumerate(d):
        for link, position, axes, away in hands:
            q = robot.inverse_kinematics(q, position - dist * away, link=link, axes=axes, iterations=int(iterations),
                                         damping=_DAMPING, tolerance=_TOL, axis_weight=AXIS_WEIGHT)
        out[row] = q
    return out


def retract_configurations(
    robot: Any,
    q_start: Any,
    q_goal: Any,
    n: int,
    rng: np.random.Generator,
    iterations: int = 15,
    links: Sequence[str] = (),
) -> np.ndarray:
    """``n`` configurations with the end effector pulled in toward the base axis at about the goal's height.

    For each row: a ~ U(``RETRACT_BLEND``) blends start and goal, q_a = (1 − a) q_start + a q_goal and
    p_a = (1 − a) p(q_start) + a p(q_goal) (EE positions, base = world frame); the target keeps a share
    s ~ U(``RETRACT_SCALE``) of p_a's horizontal offset from the base's z axis, at the height
    z(q_goal) + N(0, ``RETRACT_HEIGHT_SIGMA``²); position-only damped least squares from q_a reaches it.

    Args:
        robot: a ``gfcs.Robot`` (its ``ee_link`` is the end effector).
        q_start, q_goal: (dof,) start and goal configurations, rad (or m for prismatic joints).
        n: number of configurations (≥ 0).
        rng: numpy Generator (the draws: a, s and the height per row, in that order).
        iterations: damped least-squares steps per row (fewer when within 1 mm of the target).
        links: further end effectors pulled in the same way, each after the one before (a group spanning
            two arms: the second hand), with the same a and s as the end effector and a height of their own.

    Returns:
        (n, dof) configurations inside the joint limits; where a target is out of reach, the closest
        configuration the iteration found.

    Raises:
        ValueError: a configuration of the wrong shape or not finite, a negative ``n``.
    """
    ends = [_configuration(robot, "q_start", q_start), _configuration(robot, "q_goal", q_goal)]
    if int(n) < 0:
        raise InvalidValueError(f"n must be >= 0, got {n}")
    q0, q1 = ends
    hands = [robot.ee_link, *links]
    positions = [np.asarray(robot.ee_position(np.stack(ends)))] + [
        np.asarray(robot.link_poses(np.stack(ends)))[:, robot.link_index(link), :3, 3] for link in links]
    blends, targets = np.empty(int(n)), np.empty((len(hands), int(n), 3))
    for row in range(int(n)):
        blends[row] = rng.uniform(*RETRACT_BLEND)
        scale = rng.uniform(*RETRACT_SCALE)
        for h, (p0, p1) in enumerate(positions):
            height = p1[2] + rng.normal(0.0, RETRACT_HEIGHT_SIGMA)
            blend = (1.0 - blends[row]) * p0 + blends[row] * p1
            targets[h, row] = [scale * blend[0], scale * blend[1], height]
    if int(n) == 0:
        return np.empty((0, ends[0].shape[0]))
    q = (1.0 - blends[:, None]) * q0 + blends[:, None] * q1
    for h, link in enumerate(hands):
        q = np.asarray(robot.inverse_kinematics(q, targets[h], link=link, iterations=int(iterations),
                                                damping=_RETRACT_DAMPING, tolerance=_RETRACT_TOL))
    return q
