"""A small generated robot with every joint kind MoveIt robots have: a prismatic lift (metres, 0.1 m/s), two
revolute joints, a continuous wrist (no position limits), a locked prismatic finger and a mimic finger.
solve() plans it end to end and the returned motion keeps MoveIt's semantics."""

import math

import numpy as np
import pytest

import gfcs
from gfcs import optimize, problems
from gfcs.joints import continuous_mask, unwrap_goal
from gfcs.metrics import velocity_ratio

URDF = """<robot name="kinds">
  <link name="base"><collision><geometry><sphere radius="0.08"/></geometry></collision></link>
  <link name="column"><collision><origin xyz="0 0 0.15"/><geometry><sphere radius="0.06"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="0.15 0 0"/><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="fore"><collision><origin xyz="0.12 0 0"/><geometry><sphere radius="0.04"/></geometry></collision></link>
  <link name="hand"><collision><origin xyz="0.05 0 0"/><geometry><sphere radius="0.03"/></geometry></collision></link>
  <link name="finger_l"><collision><origin xyz="0.02 0 0"/><geometry><sphere radius="0.01"/></geometry></collision></link>
  <link name="finger_r"><collision><origin xyz="0.02 0 0"/><geometry><sphere radius="0.01"/></geometry></collision></link>
  <joint name="lift" type="prismatic"><parent link="base"/><child link="column"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="0.4" velocity="0.1" effort="1"/></joint>
  <joint name="shoulder" type="revolute"><parent link="column"/><child link="upper"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" velocity="1.0" effort="1"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.3 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-2.0" upper="2.0" velocity="1.0" effort="1"/></joint>
  <joint name="roll" type="continuous"><parent link="fore"/><child link="hand"/><origin xyz="0.25 0 0"/>
    <axis xyz="1 0 0"/><limit velocity="2.0" effort="1"/></joint>
  <joint name="finger_l_joint" type="prismatic"><parent link="hand"/><child link="finger_l"/>
    <origin xyz="0.08 0.02 0"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" velocity="0.1" effort="1"/></joint>
  <joint name="finger_r_joint" type="prismatic"><parent link="hand"/><child link="finger_r"/>
    <origin xyz="0.08 -0.02 0"/><axis xyz="0 -1 0"/><limit lower="0" upper="0.04" velocity="0.1" effort="1"/>
    <mimic joint="finger_l_joint"/></joint>
</robot>"""


@pytest.fixture(scope="module")
def robot():
    return gfcs.Robot.from_urdf(URDF, ee_link="hand")


def test_the_robot_has_the_expected_joints_units_and_limits(robot):
    assert robot.joint_names == ["lift", "shoulder", "elbow", "roll"]
    assert robot.locked_positions == {"finger_l_joint": 0.0}
    np.testing.assert_allclose(robot.velocity_limits, [0.1, 1.0, 1.0, 2.0])
    # the continuous joint: the core's sampling box, not a limit
    assert robot.lower[3] == -math.tau and robot.upper[3] == math.tau


def test_the_mimic_finger_follows_the_locked_one(robot):
    opened = robot.with_locked_positions({"finger_l_joint": 0.03})
    poses = np.asarray(opened.link_poses(np.zeros(4)))
    names = opened.link_names
    left, right = poses[names.index("finger_l"), :3, 3], poses[names.index("finger_r"), :3, 3]
    assert left[1] - right[1] == pytest.approx(0.04 + 2 * 0.03)  # both moved out by 0.03 m


def test_solve_plans_a_prismatic_and_a_continuous_joint_within_their_semantics(robot):
    q0 = np.array([0.05, -1.0, 0.5, math.pi])  # the wrist held at +π, as MoveIt requests store it
    goal_request = np.array([0.35, 1.0, -0.5, -math.pi + 0.3])  # 0.3 rad further round, written near −π
    goal = unwrap_goal(q0, goal_request, continuous_mask(robot))
    assert goal[3] == pytest.approx(math.pi + 0.3)  # the short way: +0.3 rad, not −2π + 0.3
    p = problems.Problem("kinds", robot, gfcs.Scene(), q0, goal)
    r = optimize.solve(p, batches=2, population=16, seed=0)
    assert r.success, r.metrics
    t, q = r.trajectory.t, r.trajectory.q
    np.testing.assert_array_equal(q[0], q0)
    assert (q[-1, 3] - goal_request[3]) % math.tau == pytest.approx(0.0, abs=1e-9)
    assert r.metrics["final_error"] == pytest.approx(0.0, abs=1e-9)
    # the lift moves 0.3 m at most 0.1 m/s: at least 3 s, and no joint beyond its velocity limit
    assert velocity_ratio(t, q, robot.velocity_limits) <= 1.0 and t[-1] >= 3.0
    assert np.all(q[:, 0] >= -1e-9) and np.all(q[:, 0] <= 0.4 + 1e-9)  # metres, within the lift's range
    # the C-space length mixes metres and radians as the paper's metric does; recomputed here
    assert r.metrics["cspace_length"] == pytest.approx(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())


def test_onto_bounds_moves_rounding_past_a_bound_onto_it_and_nothing_else(robot):
    from gfcs.planning.finish import onto_bounds

    q = np.zeros((4, 4))
    q[0] = [-1e-10, 0.0, 0.0, 0.0]  # the robot's state: kept whatever it is
    q[1] = [-1e-10, 2.5 + 1e-9, -2.0 - 1e-12, 7.0]  # rounding past three bounds; the wrist is continuous
    q[2] = [-1e-3, 0.0, 0.0, -7.0]  # 1 mm below the lift's bound: a real violation, left for the check
    q[3] = [0.4 + 5e-7, 0.0, 0.0, math.pi]
    out = onto_bounds(robot, q)
    np.testing.assert_array_equal(out[0], q[0])
    np.testing.assert_array_equal(out[1], [0.0, 2.5, -2.0, 7.0])
    np.testing.assert_array_equal(out[2], q[2])
    np.testing.assert_array_equal(out[3], [0.4, 0.0, 0.0, math.pi])
    inside = np.array([[0.1, 0.2, 0.3, 0.4]] * 2)
    assert onto_bounds(robot, inside) is inside  # nothing to move: the same array
    # resampled from a path that keeps the lift within its bounds: the 1 mm below is interpolation, moved
    given = np.array([[0.0, 0.0, 0.0, 0.0], [0.4, 2.5, 0.0, 9.0]])
    out = onto_bounds(robot, q, given)
    np.testing.assert_array_equal(out[2], [0.0, 0.0, 0.0, -7.0])
    np.testing.assert_array_equal(out[0], q[0])
    # ... and a path that itself leaves the bound keeps the values beyond it, for the limit check
    np.testing.assert_array_equal(onto_bounds(robot, q, np.vstack([given, [-0.01, 0, 0, 0]]))[2], q[2])


def test_the_retiming_of_a_path_held_on_a_bound_stays_within_it(robot):
    """A path that runs along the lift's lower bound at speed (a repaired path clipped there, its velocity
    still pointing out) is resampled by a cubic Hermite curve that crosses the bound between samples; the
    returned trajectory keeps the bound exactly."""
    from gfcs.blend import limit_dynamics
    from gfcs.planning.finish import FinishOptions, retime_within_limits

    t = np.arange(0.0, 1.0, 0.01)
    q = np.zeros((t.size, 4))
    q[:, 1] = 1.5 * t  # the shoulder moves at 1.5 rad/s, beyond its 1 rad/s: the re-timing slows the path
    q[:, 0] = np.clip(0.005 * np.sin(12.0 * t), 0.0, None)  # the lift touches its lower bound, then rests on it
    qd = np.gradient(q, t, axis=0)
    qd[:, 0] = 0.06 * np.cos(12.0 * t)  # the velocity of the unclipped path: outward where clipped
    qd[0] = 0.0  # from rest
    velocity = np.asarray(robot.velocity_limits)
    _, interpolated, _ = limit_dynamics(t, q, qd, 0.01, velocity=velocity)
    assert interpolated[:, 0].min() < -1e-6  # the interpolation crosses the bound by more than rounding
    _, out, _ = retime_within_limits(robot, t, q, qd, 0.01, FinishOptions())
    assert out[:, 0].min() >= 0.0 and np.all(out[:, 1:3] <= np.asarray(robot.upper)[1:3])


def test_a_motion_to_a_goal_on_a_bound_keeps_every_state_within_the_bounds_exactly(robot):
    q0 = np.array([0.2, -1.0, 0.5, 0.0])
    goal = np.array([0.0, 2.5, -0.5, 0.5])  # the lift at its lower bound, the shoulder at its upper one
    p = problems.Problem("kinds-bound", robot, gfcs.Scene(), q0, goal)
    r = optimize.solve(p, batches=2, population=16, seed=0)
    assert r.success, r.metrics
    q = r.trajectory.q
    assert np.all(q[:, :3] >= robot.lower[:3]) and np.all(q[:, :3] <= robot.upper[:3])
    np.testing.assert_array_equal(q[-1], goal)


def test_every_re_timing_leaves_the_path_within_the_bounds(robot):
    """retime_within_limits, which finishing and the mesh repair both end with, moves rounding past a bound
    onto it whatever re-timing it does (none here: no limits kept)."""
    from gfcs.planning.finish import FinishOptions, retime_within_limits

    t = np.array([0.0, 0.01, 0.02])
    q = np.array([[0.1, 0.0, 0.0, 0.0], [-1e-10, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    none = FinishOptions(limit_velocity=False, limit_acceleration=False)
    _, out, _ = retime_within_limits(robot, t, q, np.zeros_like(q), 0.01, none)
    assert out[1, 0] == 0.0
