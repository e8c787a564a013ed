"""GFCS Sec. V reactivity (gfcs.experiments.reactivity): the blocking sphere, the replay, the totals and
the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

import gfcs
from gfcs import cli, generators, metrics, optimize
from gfcs.experiments import reactivity as rx


@pytest.fixture(scope="module")
def problem():
    return generators.generate("table_under_pick", 1, seed=2, robot=gfcs.Robot.panda())[0]


def test_the_sphere_sits_on_the_solved_hand_path_and_leaves_start_and_goal_clear(problem):
    result = optimize.solve(problem, batches=2, seed=0)
    assert result.success
    sphere = rx.blocking_sphere(problem, result, np.random.default_rng(0))
    assert sphere is not None and rx.RADII[0] <= sphere["radius"] <= rx.RADII[1]
    hand = np.asarray(problem.robot.ee_position(np.asarray(result.trajectory.q)))
    assert np.min(np.linalg.norm(hand - sphere["centre"], axis=1)) < 1e-12  # a point of the path
    ends = np.stack([problem.q0, problem.goal])
    assert np.all(metrics.obstacle_clearance(problem.robot, sphere["scene"], ends) >= rx.START_GOAL_CLEARANCE)
    assert len(sphere["scene"]) == len(problem.scene) + 1  # a copy: the problem's scene is untouched


def test_react_blocks_the_solved_motion_and_replays_the_same_commands(problem):
    row = rx.react(problem, seed=0, batches=2)
    assert row["solved"] and not row["no_block"] and row["blocked"] and row["solved_clearance"] < 0
    # the replay is judged on the new scene: recompute its clearance independently
    result = optimize.solve(problem, batches=2, seed=0)
    scene = problem.scene.copy()
    scene.add_sphere(row["centre"], row["radius"])
    again = optimize.replay(result, scene, robot=problem.robot)
    assert again.metrics["min_clearance"] == pytest.approx(row["replay_clearance"])
    assert row["replay_collision_free"] == (again.metrics["min_clearance"] >= 0
                                            and again.metrics["min_self_clearance"] >= 0)
    np.testing.assert_array_equal(again.commands, result.commands)
    assert rx.react(problem, seed=0, batches=2) == row  # seeded


def test_totals_count_only_blocked_replays():
    rows = [{"class": "a", "solved": False},
            {"class": "a", "solved": True, "no_block": True},
            {"class": "b", "solved": True, "no_block": False, "blocked": True, "replay_collision_free": True,
             "replay_reached": True, "replay_success": False}]
    t = rx.totals(rows)
    assert t["a"] == {"problems": 2, "solved": 1, "no_block": 1, "blocked": 0, "collision_free": 0,
                      "reached": 0, "success": 0}
    assert t["all"]["problems"] == 3 and t["all"]["blocked"] == 1 and t["all"]["success"] == 0
    assert rx.summary_text(rows).splitlines()[-1].startswith("all")


def test_cli_experiment_reactivity(tmp_path, capsys):
    out, js = tmp_path / "r.png", tmp_path / "r.json"
    assert cli.main(["experiment", "reactivity", "--classes", "box", "--limit", "1", "--batches", "1",
                     "--out", str(out), "--json", str(js)]) == 0
    assert "box" in capsys.readouterr().out and out.stat().st_size > 5_000
    d = json.loads(js.read_text())
    assert d["totals"]["all"]["problems"] == 1 and d["rows"][0]["problem"].startswith("box/")
