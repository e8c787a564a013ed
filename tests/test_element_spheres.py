"""Element spheres: a collision sphere of the validator's robot description carried exactly by the planning
models (gfcs.coverage.element_spheres / with_element_spheres, gfcs.planning.models.models_for), so that the
fabric keeps the part the validator judges clear and not only the smaller spheres of a sphere model."""

import json

import numpy as np
import pytest

import gfcs
from gfcs import coverage, planning
from gfcs.planning.models import model_named, models_for
from gfcs.problems import Problem

URDF = """<robot name="slider"><link name="base"/><link name="a"/><link name="b">{collision}</link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="a"/><axis xyz="1 0 0"/>
  <limit lower="-1" upper="2" velocity="1" effort="1"/></joint>
  <joint name="y" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/>
  <limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>"""
#: The description models link b by a 0.15 m sphere (and a box that no sphere stands for).
ELEMENTS = ('<collision><origin xyz="0.01 0 0"/><geometry><sphere radius="0.15"/></geometry></collision>'
            '<collision><origin xyz="0 0 0.3"/><geometry><box size="0.1 0.1 0.1"/></geometry></collision>')
#: A sphere model of b: one sphere inside the element, one sticking out of it.
SPHERES = [("b", [0.0, 0.0, 0.0], 0.05), ("b", [0.1, 0.0, 0.0], 0.1)]


@pytest.fixture(scope="module")
def robots():
    mesh_robot = gfcs.Robot.from_urdf(URDF.format(collision=ELEMENTS), ee_link="b")
    robot = gfcs.Robot.from_urdf(URDF.format(collision=""), ee_link="b", spheres=SPHERES)
    return robot, mesh_robot


def gap_problem(robot, mesh_robot):
    """From x = 0 to x = 1 between two balls 0.34 m apart: b's small sphere passes between them, the 0.15 m
    element cannot."""
    scene = gfcs.Scene()
    scene.add_sphere([0.5, 0.17, 0.0], 0.05, name="left")
    scene.add_sphere([0.5, -0.17, 0.0], 0.05, name="right")
    return Problem("gap", robot, scene, q0=np.array([0.0, 0.0]), goal=np.array([1.0, 0.0]),
                   mesh_checker=gfcs.MeshChecker(mesh_robot))


def test_element_spheres_are_the_sphere_elements_of_the_description(robots):
    _, mesh_robot = robots
    assert coverage.element_spheres(mesh_robot) == [("b", [0.01, 0.0, 0.0], 0.15)]
    assert coverage.element_spheres(gfcs.Robot.from_urdf(URDF.format(collision=""))) == []


def test_a_model_carries_the_element_in_place_of_its_spheres_inside_it(robots):
    robot, mesh_robot = robots
    exact = coverage.element_spheres(mesh_robot)
    carried = coverage.with_element_spheres(robot, exact)
    got = sorted((link, tuple(np.round(c, 9)), r) for link, c, r in
                 zip(carried.sphere_links, carried.sphere_centers_local, carried.sphere_radii))
    # the small sphere lies inside the element (0.01 + 0.05 <= 0.15) and goes; the one sticking out stays
    assert got == [("b", (0.01, 0.0, 0.0), 0.15), ("b", (0.1, 0.0, 0.0), 0.1)]
    assert coverage.with_element_spheres(carried, exact) is carried  # nothing left to change
    assert coverage.with_element_spheres(robot, []) is robot
    assert coverage.with_element_spheres(robot, [("no_such_link", [0, 0, 0], 1.0)]) is robot


def test_the_planning_models_carry_the_elements_by_default_and_not_in_the_paper_preset(robots):
    robot, mesh_robot = robots
    problem = gap_problem(robot, mesh_robot)
    assert planning.get_preset("default").element_spheres and not planning.get_preset("paper").element_spheres
    (on,) = models_for(problem).planning
    assert on.element_spheres == (("b", (0.01, 0.0, 0.0), 0.15),) and 0.15 in list(on.robot.sphere_radii)
    assert on.settings()["element_spheres"] == [{"link": "b", "center": [0.01, 0.0, 0.0], "radius": 0.15}]
    (off,) = models_for(problem, element_spheres=False).planning
    assert off.robot is robot and off.element_spheres == () and off.settings() == {}
    # without a validator there is no description to take them from
    plain = Problem("plain", robot, problem.scene, q0=problem.q0, goal=problem.goal)
    assert models_for(plain).planning[0].robot is robot


def test_the_fabric_on_the_carried_model_keeps_the_element_clear(robots):
    """The plain sphere model slides between the balls and the validator's sphere hits them by 3 cm; the
    carried model's fabric stops before them."""
    robot, mesh_robot = robots
    problem = gap_problem(robot, mesh_robot)
    for on, passes in ((False, True), (True, False)):
        model = models_for(problem, element_spheres=on).planning[0]
        q = np.asarray(gfcs.Fabric(model.robot, problem.scene).rollout(problem.q0, None, problem.goal).q)
        clearance = float(np.min(problem.mesh_checker.clearance(problem.scene, q)))
        if passes:
            assert q[-1, 0] > 0.9 and clearance < -0.02
        else:
            assert q[-1, 0] < 0.5 and clearance > 0.0


def test_a_result_records_the_elements_and_its_model_is_rebuilt_from_them(robots):
    robot, mesh_robot = robots
    problem = gap_problem(robot, mesh_robot)
    # the robot's own spheres (the ball model leaves the meshes uncovered, so a solve would plan on covering
    # spheres first: tests/test_sphere_fit.py)
    result = planning.solve(problem, seed=0, batches=1, population=8, threads=1, time_limit=5,
                            covering_spheres=False)
    settings = json.loads(json.dumps(result.settings))  # as a result file holds them
    assert settings["element_spheres"] == [{"link": "b", "center": [0.01, 0.0, 0.0], "radius": 0.15}]
    rebuilt = model_named(robot, settings)
    assert sorted(rebuilt.sphere_radii) == sorted(result.robot.sphere_radii) == [0.1, 0.15]
    off = planning.solve(problem, seed=0, batches=1, population=8, threads=1, time_limit=5, element_spheres=False,
                         covering_spheres=False)
    assert "element_spheres" not in off.settings and model_named(robot, off.settings) is robot


def test_the_sampling_baselines_check_the_carried_model(robots):
    """RRTConnect on the gap problem: with the element the straight way between the balls is invalid, and a
    returned path keeps the validator's sphere clear; on the plain model the planner takes the gap."""
    pytest.importorskip("ompl", reason="the 'baselines' extra (pip install 'gfcs[baselines]') is not installed")
    from gfcs.baselines import plan_ompl

    robot, mesh_robot = robots
    problem = gap_problem(robot, mesh_robot)
    on = plan_ompl(problem, "rrtconnect", 1.0, seed=0)
    assert on.settings["element_spheres"] == [{"link": "b", "center": [0.01, 0.0, 0.0], "radius": 0.15}]
    assert on.success and on.metrics["mesh_clearance"] > 0.0
    assert np.max(np.abs(np.asarray(on.trajectory.q)[:, 1])) > 0.1  # around the balls, not between them
    off = plan_ompl(problem, "rrtconnect", 1.0, seed=0, element_spheres=False)
    assert "element_spheres" not in off.settings
    assert not off.success and off.metrics["mesh_clearance"] < 0.0  # through the gap: the element hits
