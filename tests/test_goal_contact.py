"""A goal at which conservative collision spheres overlap an obstacle that the meshes clear: per-sphere
obstacle margins, the clearance floor of the success criterion, and solve's goal-contact attempt."""

import dataclasses

import numpy as np
import pytest

import gfcs
from gfcs import metrics, optimize, planning, problems
from gfcs.planning.policies import endpoint_contact
from gfcs.problems import Problem

Q0 = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
GOAL = Q0 + np.array([0.4, 0.2, -0.3, 0.3, 0.2, -0.2, 0.1])
SMALL = dict(batches=2, population=8, threads=1)


@pytest.fixture(scope="module")
def robot():
    """A Panda whose only collision mesh is a box on the hand, with the shipped (covering) spheres."""
    urdf = gfcs.panda_urdf().replace(
        '<link name="panda_hand"/>',
        '<link name="panda_hand"><collision><geometry><box size="0.05 0.2 0.07"/></geometry></collision></link>')
    return problems.with_shipped_panda_spheres(gfcs.Robot.from_urdf(urdf, ee_link="panda_hand"))


@pytest.fixture(scope="module")
def checker(robot):
    return gfcs.MeshChecker(robot)


def touching(robot, overlap=0.001):
    """A scene whose ball overlaps link 3's first sphere at GOAL by ``overlap`` m, on the side away from
    the base axis (no mesh there), and that sphere's index."""
    k = robot.sphere_links.index("panda_link3")
    c = robot.sphere_centers(GOAL[None])[0, k]
    u = np.array([c[0], c[1], 0.0]) / np.hypot(c[0], c[1])
    scene = gfcs.Scene()
    scene.add_sphere(c + u * (robot.sphere_radii[k] + 0.03 - overlap), 0.03, name="ball")
    return scene, k


def test_the_clearance_floor_lets_the_meshes_judge_a_sphere_overlap(robot, checker):
    scene, _ = touching(robot)
    t, q = np.array([0.0, 0.01]), np.stack([GOAL, GOAL])
    strict = metrics.trajectory_metrics(robot, scene, t, q, GOAL, mesh_checker=checker)
    assert strict["min_clearance"] == pytest.approx(-0.001) and not strict["success"]
    assert strict["mesh_clearance"] > 0.1  # the ball is far from the only mesh (the hand)
    floor = metrics.trajectory_metrics(robot, scene, t, q, GOAL, mesh_checker=checker, clearance_floor=-0.002)
    assert floor["success"] and floor["sphere_success"]
    with pytest.raises(ValueError, match="needs a mesh_checker"):
        metrics.trajectory_metrics(robot, scene, t, q, GOAL, clearance_floor=-0.002)
    with pytest.raises(ValueError, match="clearance_floor must be"):
        metrics.trajectory_metrics(robot, scene, t, q, GOAL, mesh_checker=checker, clearance_floor=0.001)


def test_goal_contact_margins(robot, checker):
    scene, k = touching(robot)
    fabric = gfcs.Fabric(robot, scene)
    margin = fabric.config.to_dict()["obstacles"]["margin"]
    margins, floor = optimize.goal_contact(Problem("p", robot, scene, q0=Q0, goal=GOAL), fabric, 0.002, checker)
    clearance = metrics.sphere_clearances(robot, scene, GOAL[None])[0]
    np.testing.assert_allclose(margins, np.minimum(margin, clearance - 0.002))
    assert margins[k] == pytest.approx(-0.003) and floor == pytest.approx(-0.005)
    assert np.count_nonzero(margins < margin) >= 1 and np.all(margins <= margin)
    far = gfcs.Scene()
    far.add_sphere([-0.6, -0.6, 0.3], 0.1)
    assert optimize.goal_contact(Problem("p", robot, far, q0=Q0, goal=GOAL), fabric, 0.002, checker) is None
    # the goal's meshes must be clear: a ball on the hand box refuses the contact
    hand = robot.link_poses(GOAL[None])[0, robot.link_index("panda_hand")][:3, 3]
    on_hand = scene.copy()
    on_hand.add_sphere(hand, 0.02)
    assert optimize.goal_contact(Problem("p", robot, on_hand, q0=Q0, goal=GOAL), fabric, 0.002, checker) is None


def test_solve_reaches_a_goal_in_contact_only_with_the_goal_contact_attempt(robot, checker):
    scene, _ = touching(robot)
    problem = Problem("touch", robot, scene, q0=Q0, goal=GOAL, mesh_checker=checker)
    # the preset's endpoint contact off and the spheres judging too: the plan attempts fail, the goal-contact
    # retry reaches the goal
    off = dataclasses.replace(planning.get_preset("default"), endpoint_contact=False, spheres_judge=True)
    without = optimize.solve(problem, goal_contact_slack=0.0, preset=off, **SMALL)
    assert not without.success and "goal_contact" not in without.settings
    res = optimize.solve(problem, preset=off, **SMALL)
    assert res.success and res.settings["commands_tried"] == [1, 2, 3, 4, 1]
    contact = res.settings["goal_contact"]
    assert contact["clearance_floor"] == pytest.approx(-0.005)
    assert contact["clearance_floor"] <= res.metrics["min_clearance"] < 0 and res.metrics["mesh_clearance"] > 0.001
    assert np.linalg.norm(res.trajectory.q[-1] - GOAL) <= metrics.DEFAULT_SUCCESS_TOL
    # the overlap the floor accepts is not a collision in the attempt's cost (eq. 4 + collision penalty)
    assert res.settings["collision_tol"] == pytest.approx(0.005) and without.settings["collision_tol"] == 0.0
    assert res.cost == pytest.approx(float(np.sum(res.t_stars)))
    with pytest.raises(ValueError, match="goal_contact_slack"):
        optimize.solve(problem, goal_contact_slack=-1.0, **SMALL)


def test_a_goal_sunk_into_an_obstacle_is_planned_with_its_contact_from_the_first_attempt(robot, checker):
    scene, k = touching(robot)
    problem = Problem("touch", robot, scene, q0=Q0, goal=GOAL, mesh_checker=checker)
    fabric = gfcs.Fabric(robot, scene)
    contact = endpoint_contact(problem, fabric, 0.002, checker)
    # only the overlapping sphere is capped, at its goal clearance minus the slack; the others keep any margin
    assert contact.obstacle_caps[k] == pytest.approx(-0.003) and contact.floor == pytest.approx(-0.005)
    assert np.isinf(np.delete(contact.obstacle_caps, k)).all() and contact.self_margins is None
    res = optimize.solve(problem, **SMALL)
    assert res.success and len(res.attempts) == 1
    assert res.settings["goal_contact"]["clearance_floor"] == pytest.approx(-0.005)
    # a goal within the margin but clear of the obstacle is left to the GoalContact retry
    near, _ = touching(robot, overlap=-0.001)
    assert endpoint_contact(Problem("near", robot, near, q0=Q0, goal=GOAL, mesh_checker=checker), fabric, 0.002,
                            checker) is None
