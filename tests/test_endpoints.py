"""A start or goal whose collision meshes are in contact is refused before planning (gfcs.CollisionError)."""

import dataclasses
import json

import numpy as np
import pytest

import gfcs
from gfcs import generators, planning
from gfcs.planning.endpoints import check_endpoints


@pytest.fixture(scope="module")
def problem():
    return generators.generate("box", 1, seed=0)[0]


def _self_contact(problem):
    """A configuration of the problem's robot whose meshes touch each other (seeded search)."""
    robot, checker = problem.robot, problem.mesh_checker
    rng = np.random.default_rng(0)
    lo, up = np.asarray(robot.lower), np.asarray(robot.upper)
    for _ in range(5000):
        q = rng.uniform(lo, up)
        if checker.self_contacts(q, 0.0):
            return q
    raise AssertionError("no self-contact configuration found")


def test_a_start_in_self_contact_is_refused_naming_the_links(problem):
    q = _self_contact(problem)
    a, b, depth = problem.mesh_checker.self_contacts(q, 0.0)[0]
    assert depth <= 0.0 and float(problem.mesh_checker.self_clearance(q)) <= 0.0
    bad = dataclasses.replace(problem, q0=q)
    with pytest.raises(gfcs.CollisionError, match=rf"start state is in collision.*'{a}' and '{b}'"):
        check_endpoints(bad)
    with pytest.raises(gfcs.CollisionError, match=problem.name):
        planning.solve(bad, batches=1, population=4, policies=[])
    # self_contacts lists every pair nearer than `within`, nearest first
    near = problem.mesh_checker.self_contacts(q, 0.05)
    assert len(near) >= 1 and [d for _, _, d in near] == sorted(d for _, _, d in near)
    with pytest.raises(gfcs.InvalidValueError, match="within"):
        problem.mesh_checker.self_contacts(q, -1.0)


def test_a_goal_inside_an_obstacle_is_refused(problem):
    hand = problem.robot.link_poses(problem.goal)[problem.robot.link_index(problem.robot.ee_link)][:3, 3]
    scene = gfcs.Scene()
    scene.add_sphere(hand, 0.05)
    bad = dataclasses.replace(problem, scene=scene)
    with pytest.raises(gfcs.CollisionError, match="goal state is in collision.*obstacle"):
        check_endpoints(bad)


def test_clear_endpoints_pass_and_the_check_has_a_switch(problem):
    check_endpoints(problem)  # the generator keeps both states clear
    bad = dataclasses.replace(problem, q0=_self_contact(problem))
    result = planning.solve(bad, batches=1, population=4, policies=[], endpoint_check=False)
    assert not result.success  # planned anyway; the meshes judge the start
    check_endpoints(dataclasses.replace(problem, mesh_checker=None))  # nothing to judge with


def test_the_cli_and_bench_report_a_start_in_collision_by_name(problem, tmp_path, capsys):
    from gfcs import cli

    bad = dataclasses.replace(problem, q0=_self_contact(problem))
    generators.write_problems([bad], tmp_path)
    folder = tmp_path / problem.cls
    scene, request = folder / "scene0001.yaml", folder / "request0001.yaml"
    assert cli.main(["solve", "--scene", str(scene), "--request", str(request), "--batches", "1"]) == 2
    assert "start state is in collision" in capsys.readouterr().err
    # a bench records the problem as failed, with the message, and goes on
    out = tmp_path / "rows.jsonl"
    code = cli.main(["bench", "--problems", str(tmp_path), "--batches", "1", "--population", "4",
                     "--no-progress", "--json", str(out)])
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert code == 0 and rows and all(not r["success"] for r in rows if r.get("method") == "gfcs")
    assert any("start state is in collision" in str(r.get("error", "")) for r in rows)
