"""gfcs.approach: approach configurations by inverse kinematics, checked with the forward kinematics."""

import numpy as np
import pytest

import gfcs
from gfcs.approach import RETRACT_HEIGHT_SIGMA, RETRACT_SCALE, approach_configurations, retract_configurations

GOAL = np.array([0.3, 0.4, -0.2, -1.9, 0.1, 2.2, 0.6])


@pytest.fixture(scope="module")
def robot():
    return gfcs.Robot.panda()


def ee_pose(robot, q):
    return np.asarray(robot.link_poses(q))[robot.link_index(robot.ee_link)]


@pytest.mark.parametrize("axis", [(0.0, 0.0, 1.0), (1.0, 1.0, 0.0)])
def test_end_effector_backs_off_along_the_axis_with_the_goal_orientation(robot, axis):
    distances = (0.0, 0.05, 0.1, 0.15)
    qs = approach_configurations(robot, GOAL, distances, axis=axis)
    assert qs.shape == (4, 7)
    assert np.all(qs >= np.asarray(robot.lower)) and np.all(qs <= np.asarray(robot.upper))
    goal = ee_pose(robot, GOAL)
    a = np.asarray(axis) / np.linalg.norm(axis)
    for d, q in zip(distances, qs):
        pose = ee_pose(robot, q)
        np.testing.assert_allclose(pose[:3, 3], goal[:3, 3] - d * goal[:3, :3] @ a, atol=1e-4)
        np.testing.assert_allclose(pose[:3, :3], goal[:3, :3], atol=1e-3)
    np.testing.assert_allclose(qs[0], GOAL, atol=1e-12)  # d = 0: the goal itself
    # continuation: each configuration is near the previous one, not a jump to another IK branch
    assert np.all(np.linalg.norm(np.diff(qs, axis=0), axis=1) < 0.5)


def test_unreachable_target_returns_a_configuration_within_limits(robot):
    q = approach_configurations(robot, GOAL, (3.0,))[0]  # 3 m back: out of reach
    assert np.all(np.isfinite(q))
    assert np.all(q >= np.asarray(robot.lower)) and np.all(q <= np.asarray(robot.upper))


@pytest.mark.parametrize("kwargs, match", [
    ({"q_goal": np.zeros(6)}, "q_goal"), ({"q_goal": np.full(7, np.nan)}, "q_goal"),
    ({"distances": (-0.1,)}, "distances"), ({"distances": (np.inf,)}, "distances"),
    ({"axis": (0.0, 0.0, 0.0)}, "axis"), ({"axis": (1.0, 0.0)}, "axis"),
])
def test_bad_input(robot, kwargs, match):
    args = {"q_goal": GOAL, "distances": (0.1,), **kwargs}
    with pytest.raises(ValueError, match=match):
        approach_configurations(robot, **args)


def test_retract_configurations_pull_the_hand_in_at_the_goal_height(robot):
    q0 = np.array([0.0, 0.6, 0.0, -1.2, 0.0, 1.8, 0.8])
    qs = retract_configurations(robot, q0, GOAL, 50, np.random.default_rng(0))
    assert qs.shape == (50, 7)
    assert np.all(qs >= np.asarray(robot.lower)) and np.all(qs <= np.asarray(robot.upper))
    ends = [ee_pose(robot, q)[:3, 3] for q in (q0, GOAL)]
    hands = np.array([ee_pose(robot, q)[:3, 3] for q in qs])
    radius = np.linalg.norm(hands[:, :2], axis=1)
    # the targets keep 25-65 % of a blend of the ends' horizontal offsets: every hand is pulled in
    assert radius.max() < RETRACT_SCALE[1] * max(np.linalg.norm(p[:2]) for p in ends) + 0.01
    # heights scatter about the goal hand's by RETRACT_HEIGHT_SIGMA
    assert abs(np.mean(hands[:, 2]) - ends[1][2]) < 3 * RETRACT_HEIGHT_SIGMA / np.sqrt(50) + 0.01
    assert 0.5 * RETRACT_HEIGHT_SIGMA < np.std(hands[:, 2]) < 1.5 * RETRACT_HEIGHT_SIGMA
    # reproducible from the generator; none for n = 0
    np.testing.assert_array_equal(qs, retract_configurations(robot, q0, GOAL, 50, np.random.default_rng(0)))
    assert retract_configurations(robot, q0, GOAL, 0, np.random.default_rng(0)).shape == (0, 7)


@pytest.mark.parametrize("args, match", [((np.zeros(6), GOAL, 3), "q_start"), ((np.zeros(7), [np.nan] * 7, 3), "q_goal"),
                                         ((np.zeros(7), GOAL, -1), "n must be")])
def test_retract_configurations_reject_bad_input(robot, args, match):
    with pytest.raises(ValueError, match=match):
        retract_configurations(robot, *args, np.random.default_rng(0))


@pytest.fixture(scope="module")
def two_arms():
    """The two-arm Panda (one base, 14 joints), its hands and a goal of both arms."""
    from gfcs import generators

    robot, tips = generators.two_arm_robot()
    problem = generators.two_arm_problems(1, seed=0)[0]
    return robot, tips, np.asarray(problem.q0), np.asarray(problem.goal)


def link_pose(robot, q, link):
    return np.asarray(robot.link_poses(q))[robot.link_index(link)]


def test_every_hand_of_a_two_arm_group_backs_off_along_its_axis(two_arms):
    robot, tips, _, goal = two_arms
    other = next(t for t in tips if t != robot.ee_link)
    distances = (0.0, 0.05, 0.1)
    qs = approach_configurations(robot, goal, distances, axis=(0.0, 0.0, 1.0), links=[(other, (0.0, 0.0, 1.0))])
    assert qs.shape == (3, 14)
    for link in tips:
        g = link_pose(robot, goal, link)
        for d, q in zip(distances, qs):
            pose = link_pose(robot, q, link)
            np.testing.assert_allclose(pose[:3, 3], g[:3, 3] - d * g[:3, 2], atol=1e-4)
            np.testing.assert_allclose(pose[:3, :3], g[:3, :3], atol=1e-3)
    # one hand only: the other arm keeps its goal joints
    one = approach_configurations(robot, goal, (0.1,))[0]
    np.testing.assert_allclose(link_pose(robot, one, other), link_pose(robot, goal, other), atol=1e-12)
    with pytest.raises(ValueError, match=f"axis of {other}"):
        approach_configurations(robot, goal, (0.1,), links=[(other, (0.0, 0.0, 0.0))])


def test_every_hand_of_a_two_arm_group_is_pulled_in(two_arms):
    robot, tips, q0, goal = two_arms
    other = next(t for t in tips if t != robot.ee_link)
    qs = retract_configurations(robot, q0, goal, 20, np.random.default_rng(1), links=[other])
    one = retract_configurations(robot, q0, goal, 20, np.random.default_rng(1))
    for link in tips:
        ends = [link_pose(robot, q, link)[:3, 3] for q in (q0, goal)]
        hands = np.array([link_pose(robot, q, link)[:3, 3] for q in qs])
        reach = RETRACT_SCALE[1] * max(np.linalg.norm(p[:2]) for p in ends) + 0.01
        assert np.linalg.norm(hands[:, :2], axis=1).max() < reach, link
    # the second hand draws its own height after the first's: the first hand's targets differ from a
    # one-hand draw only from the second row on, so the first row's first hand is the same
    np.testing.assert_allclose(link_pose(robot, qs[0], robot.ee_link), link_pose(robot, one[0], robot.ee_link),
                               atol=1e-12)
