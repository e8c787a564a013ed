"""An endpoint at which two links' collision spheres overlap while their meshes clear each other (two arms
side by side): per-pair self-collision margins, the self-clearance floor of the success criterion, and the
default preset's endpoint self-contact (gfcs.planning.policies.endpoint_self_contact)."""

import dataclasses

import numpy as np
import pytest

import gfcs
from gfcs import metrics, planning
from gfcs.planning.policies import endpoint_self_contact
from gfcs.problems import Problem

SLACK = 0.002
SMALL = dict(batches=2, population=8, threads=1, seed=0)
Q0 = np.array([0.0, 0.0])
#: both arms turned toward each other: their tips 0.1 m apart, their 6 cm spheres 2 cm into each other
GOAL = np.array([np.pi / 2, -np.pi / 2])


def two_arms(separation=0.5):
    """Two one-joint arms on one base, ``separation`` m apart along y, each a 0.2 m box (4 cm thick) whose
    spheres (6 cm) stick 4 cm out of it; the meshes are the boxes."""
    box = '<collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.04 0.04"/></geometry></collision>'
    joint = ('<joint name="{0}" type="revolute"><parent link="base"/><child link="{1}"/><origin xyz="0 {2} 0"/>'
             '<axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="2"/></joint>')
    urdf = (f'<robot name="pair"><link name="base"/><link name="arm_a">{box}</link><link name="arm_b">{box}</link>'
            + joint.format("ja", "arm_a", -separation / 2) + joint.format("jb", "arm_b", separation / 2)
            + "</robot>")
    robot = gfcs.Robot.from_urdf(urdf, ee_link="arm_a", active_joints=["ja", "jb"])
    return robot.with_spheres([(link, [x, 0.0, 0.0], 0.06) for link in ("arm_a", "arm_b") for x in (0.05, 0.15, 0.2)])


@pytest.fixture(scope="module")
def robot():
    return two_arms()


@pytest.fixture(scope="module")
def problem(robot):
    return Problem("pair", robot, gfcs.Scene(), q0=Q0, goal=GOAL, mesh_checker=gfcs.MeshChecker(robot))


def test_the_self_clearance_floor_lets_the_meshes_judge_a_sphere_overlap(robot, problem):
    t, q = np.array([0.0, 0.01]), np.stack([GOAL, GOAL])
    checker = problem.mesh_checker
    strict = metrics.trajectory_metrics(robot, problem.scene, t, q, GOAL, mesh_checker=checker)
    assert strict["min_self_clearance"] == pytest.approx(-0.02) and not strict["success"]
    assert strict["mesh_self_clearance"] > 0.05  # inf: beyond the range the check measures exactly
    floor = metrics.trajectory_metrics(robot, problem.scene, t, q, GOAL, mesh_checker=checker,
                                       self_clearance_floor=-0.024)
    assert floor["success"] and floor["sphere_success"]
    too_deep = metrics.trajectory_metrics(robot, problem.scene, t, q, GOAL, mesh_checker=checker,
                                          self_clearance_floor=-0.019)
    assert not too_deep["sphere_success"]
    with pytest.raises(ValueError, match="self_clearance_floor .* needs a mesh_checker"):
        metrics.trajectory_metrics(robot, problem.scene, t, q, GOAL, self_clearance_floor=-0.024)
    with pytest.raises(ValueError, match="self_clearance_floor must be"):
        metrics.trajectory_metrics(robot, problem.scene, t, q, GOAL, mesh_checker=checker, self_clearance_floor=0.01)


def test_endpoint_self_contact_margins(robot, problem):
    fabric = gfcs.Fabric(robot, problem.scene)
    margin = fabric.config.to_dict()["self_collision"]["margin"]
    margins, floor = endpoint_self_contact(problem, fabric, SLACK, problem.mesh_checker)
    pairs = np.asarray(robot.self_collision_pairs)
    centres, radii = robot.sphere_centers(GOAL[None])[0], np.asarray(robot.sphere_radii)
    gap = np.linalg.norm(centres[pairs[:, 0]] - centres[pairs[:, 1]], axis=1) - radii[pairs].sum(axis=1)
    np.testing.assert_allclose(margins, np.minimum(margin, gap - SLACK))
    assert margins.min() == pytest.approx(-0.022) and floor == pytest.approx(-0.024)
    # no mesh checker, no pair near at either end, or the meshes themselves touching: nothing to lower
    assert endpoint_self_contact(dataclasses.replace(problem, mesh_checker=None), fabric, SLACK, None) is None
    apart = dataclasses.replace(problem, goal=np.array([0.5, -0.5]))
    assert endpoint_self_contact(apart, fabric, SLACK, problem.mesh_checker) is None
    near = two_arms(separation=0.18)  # the boxes cross at GOAL
    crossing = Problem("crossing", near, gfcs.Scene(), q0=Q0, goal=GOAL, mesh_checker=gfcs.MeshChecker(near))
    assert crossing.mesh_checker.min_self_clearance(GOAL[None]) <= 0
    assert endpoint_self_contact(crossing, gfcs.Fabric(near, gfcs.Scene()), SLACK, crossing.mesh_checker) is None


def test_solve_reaches_a_goal_in_sphere_self_contact_with_the_default_preset(problem):
    res = planning.solve(problem, **SMALL)
    assert res.success and res.metrics["final_error"] == 0.0
    assert res.metrics["min_self_clearance"] == pytest.approx(-0.02)
    assert res.settings["self_contact"]["self_clearance_floor"] == pytest.approx(-0.024)
    off = dataclasses.replace(planning.get_preset("default"), endpoint_contact=False)
    without = planning.solve(problem, preset=off, **SMALL)
    # the self-collision barrier holds the spheres apart: the arms stop short of the goal
    assert not without.success and without.metrics["final_error"] > 0.1 and "self_contact" not in without.settings
    assert not planning.get_preset("paper").endpoint_contact


def test_without_spheres_judging_the_meshes_alone_judge_collisions(robot, problem):
    from gfcs.planning.selection import mesh_contact_only, model_success

    t, q = np.array([0.0, 0.01]), np.stack([GOAL, GOAL])
    checker = problem.mesh_checker
    meshes = metrics.trajectory_metrics(robot, problem.scene, t, q, GOAL, mesh_checker=checker, spheres_judge=False)
    assert meshes["success"] and not meshes["spheres_judged"]
    assert meshes["reached_within_limits"] and not meshes["sphere_success"]  # the spheres' own verdict stays
    assert model_success(meshes) and not mesh_contact_only(meshes)
    both = metrics.trajectory_metrics(robot, problem.scene, t, q, GOAL, mesh_checker=checker)
    assert not both["success"] and both["spheres_judged"] and not model_success(both)
    # without meshes to judge, the spheres always do
    alone = metrics.trajectory_metrics(robot, problem.scene, t, q, GOAL, spheres_judge=False)
    assert not alone["success"] and alone["spheres_judged"]
    # meshes that touch fail either way; with the spheres in contact as well, the mesh repair leaves it
    near = two_arms(separation=0.18)
    crossing = metrics.trajectory_metrics(near, gfcs.Scene(), t, q, GOAL, mesh_checker=gfcs.MeshChecker(near),
                                          spheres_judge=False)
    assert not crossing["success"] and crossing["reached_within_limits"] and not mesh_contact_only(crossing)


def test_solve_lets_the_meshes_judge_a_path_through_sphere_contact(problem):
    # a fabric blind to self-collision drives the spheres 2 cm into each other at the goal while the boxes
    # stay apart: a valid motion for a mesh validator
    blind = dataclasses.replace(planning.get_preset("default"), endpoint_contact=False,
                                fabric={"self_collision": {"enabled": False}})
    meshes = planning.solve(problem, preset=blind, policies=[], **SMALL)
    assert meshes.success and meshes.settings["spheres_judge"] is False
    assert meshes.metrics["min_self_clearance"] < -0.01 and not meshes.metrics["sphere_success"]
    spheres = planning.solve(problem, preset=blind, policies=[], spheres_judge=True, **SMALL)
    assert not spheres.success and spheres.settings["spheres_judge"] is True
    assert planning.get_preset("paper").spheres_judge and not planning.get_preset("default").spheres_judge


def test_replay_judges_as_the_solve_judged(problem):
    blind = dataclasses.replace(planning.get_preset("default"), endpoint_contact=False,
                                fabric={"self_collision": {"enabled": False}})
    meshes = planning.solve(problem, preset=blind, policies=[], **SMALL)
    again = planning.replay(meshes, problem.scene, mesh_checker=problem.mesh_checker)
    assert again.success and not again.metrics["spheres_judged"]
    spheres = dataclasses.replace(meshes, settings={**meshes.settings, "spheres_judge": True})
    assert not planning.replay(spheres, problem.scene, mesh_checker=problem.mesh_checker).success
