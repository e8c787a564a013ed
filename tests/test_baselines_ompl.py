"""The OMPL baselines (gfcs.baselines.plan_ompl) on small generated problems: solved motions judged by the
GFCS metrics, a problem no planner can solve (the hand caged at the goal), invalid goals, seeds, bad
arguments, and the rows and JSON they share with GFCS."""

import math

import numpy as np
import pytest

pytest.importorskip("ompl", reason="the 'baselines' extra (pip install 'gfcs[baselines]') is not installed")

import gfcs  # noqa: E402
from gfcs import generators, metrics  # noqa: E402
from gfcs.baselines import PLANNERS, plan_ompl, planner_label  # noqa: E402
from gfcs.baselines.validity import MOVEIT_SEGMENT_FRACTION  # noqa: E402
from gfcs.problems import Problem  # noqa: E402
from gfcs.results import SolveResult, bench_row  # noqa: E402


@pytest.fixture(scope="module")
def problem():
    return generators.generate("table_pick", 1, seed=2)[0]


def caged_goal_problem():
    """The shipped Panda whose goal holds the hand in a closed shell of 1.5 cm cubes, 1-4 cm from its
    spheres, that leaves room only for the wrist: the goal is valid, but the hand, wider than that room,
    cannot leave or enter, so no planner finds a path."""
    robot = gfcs.Robot.panda()
    goal = np.array([0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.785])
    q0 = np.array([1.2, -0.3, 0.0, -1.8, 0.0, 1.6, 0.785])
    c, rad = robot.sphere_centers(goal), np.asarray(robot.sphere_radii)
    hand = np.isin(np.array(robot.sphere_links), ["panda_hand", "panda_leftfinger", "panda_rightfinger"])
    size = 0.015
    lo = (c[hand] - rad[hand, None]).min(0) - 0.05
    hi = (c[hand] + rad[hand, None]).max(0) + 0.05
    axes = [np.arange(a, b, size) for a, b in zip(lo, hi)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    d_hand = (np.linalg.norm(grid[:, None] - c[None, hand], axis=2) - rad[None, hand]).min(1)
    d_arm = (np.linalg.norm(grid[:, None] - c[None, ~hand], axis=2) - rad[None, ~hand]).min(1)
    half = size * math.sqrt(3) / 2  # a cube lies within this of its centre
    keep = (d_hand >= 0.01 + half) & (d_hand <= 0.04 + half) & (d_arm >= 0.004 + half)
    scene = gfcs.Scene()
    for p in grid[keep]:
        scene.add_box([size] * 3, (p, [0.0, 0.0, 0.0, 1.0]))
    return Problem("caged/0001", robot, scene, q0, goal, cls="caged")


def test_rrtconnect_solves_and_the_metrics_are_gfcs_own(problem):
    r = plan_ompl(problem, "rrtconnect", planner_time=2.0, seed=0)
    assert r.reached and r.success, r.settings.get("failure")
    assert r.method == "rrtconnect" and r.settings["status"] == "Exact solution"
    traj = r.trajectory
    np.testing.assert_allclose(traj.q[0], problem.q0)
    np.testing.assert_allclose(traj.q[-1], problem.goal, atol=1e-12)
    assert np.all(traj.qd[0] == 0) and np.all(traj.qd[-1] == 0)
    # the result's metrics are trajectory_metrics of its trajectory on the planning model and mesh checker
    again = metrics.trajectory_metrics(r.robot, problem.scene, traj.t, traj.q, problem.goal,
                                       mesh_checker=problem.mesh_checker)
    assert again["success"] and again["ee_length"] == pytest.approx(r.metrics["ee_length"])
    assert r.metrics["min_clearance"] >= 0.0 and r.metrics["velocity_ratio"] <= 1.0 + 1e-6
    # the simplified waypoints are collision-free for the planning spheres with the margin
    w = np.asarray(r.settings["waypoints"])
    assert metrics.obstacle_clearance(r.robot, problem.scene, w).min() >= r.settings["obstacle_margin"]
    assert r.solve_time <= r.wall_time and r.cost == pytest.approx(traj.t[-1])
    # same JSON and rows as GFCS
    back = SolveResult.from_json(r.to_json())
    assert back.method == "rrtconnect" and back.success and back.settings["planner"] == "RRTConnect"
    row = bench_row(problem.name, problem.cls, planner_label("rrtconnect", 2.0), r.method, 0, 0, r.solve_time,
                    r.cost, r.metrics, r.wall_time)
    assert row["label"] == "RRTConnect" and row["success"]


def test_check_resolution_is_moveits(problem):
    r = plan_ompl(problem, "rrtconnect", planner_time=1.0, seed=0, thin_spheres=False)
    lower, upper = np.asarray(problem.robot.lower), np.asarray(problem.robot.upper)
    extent = float(np.linalg.norm(upper - lower))  # OMPL's maximum extent of a real-vector box
    assert r.settings["state_space_extent"] == pytest.approx(extent)
    assert r.settings["check_step"] == pytest.approx(MOVEIT_SEGMENT_FRACTION * extent)
    assert r.settings["check_step"] == pytest.approx(0.0652, abs=1e-4)  # the Panda's 7 joints
    assert r.settings["sphere_model"] == "spheres" and r.settings["obstacle_margin"] == pytest.approx(0.002)


@pytest.mark.parametrize("planner", ["biest", "bitstar"])
def test_biest_and_bitstar_solve(problem, planner):
    r = plan_ompl(problem, planner, planner_time=1.5, seed=1)
    assert r.reached, r.settings.get("failure")
    assert r.metrics["sphere_success"], r.metrics
    assert r.settings["planner"] == PLANNERS[planner]


@pytest.mark.parametrize("planner", sorted(PLANNERS))
def test_unsolvable_problem_fails_with_a_reason(planner):
    p = caged_goal_problem()
    r = plan_ompl(p, planner, planner_time=0.3, seed=0)
    assert not r.success and not r.reached and math.isinf(r.cost)
    assert r.settings["failure"].startswith("no path found within 0.3 s")
    assert len(r.trajectory) == 1 and r.settings["states_checked"] > 0
    assert r.solve_time >= 0.3
    row = bench_row(p.name, p.cls, planner_label(planner, 0.3), planner, 0, 0, r.solve_time, r.cost, r.metrics,
                    r.wall_time)
    assert not row["success"]


def test_goal_in_collision_fails_before_planning():
    p = caged_goal_problem()
    blocked = gfcs.Scene()
    hand = p.robot.sphere_centers(p.goal)[-1]
    blocked.add_sphere(hand, 0.05)
    r = plan_ompl(p.with_scene(blocked), "rrtconnect", planner_time=0.5)
    assert not r.success and r.settings["status"] == "Invalid start or goal"
    assert r.settings["failure"].startswith("goal in collision") and r.solve_time == 0.0


@pytest.mark.parametrize("planner", ["rrtconnect", "biest"])
def test_same_seed_same_path(problem, planner):
    a = plan_ompl(problem, planner, planner_time=2.0, seed=5)
    b = plan_ompl(problem, planner, planner_time=2.0, seed=5)
    assert a.reached and b.reached
    np.testing.assert_array_equal(np.asarray(a.settings["waypoints"]), np.asarray(b.settings["waypoints"]))
    c = plan_ompl(problem, planner, planner_time=2.0, seed=6)
    assert c.settings["raw_length"] != a.settings["raw_length"]


def test_bad_arguments_name_themselves(problem):
    with pytest.raises(gfcs.InvalidValueError, match="'prm'"):
        plan_ompl(problem, "prm")
    with pytest.raises(gfcs.InvalidValueError, match="planner_time"):
        plan_ompl(problem, "rrtconnect", planner_time=0.0)
    with pytest.raises(gfcs.InvalidValueError, match="segment_fraction"):
        plan_ompl(problem, "rrtconnect", segment_fraction=2.0)
    moving = Problem(problem.name, problem.robot, problem.scene, problem.q0, problem.goal,
                     qd0=np.full(problem.dof, 0.1))
    with pytest.raises(gfcs.InvalidValueError, match="qd0"):
        plan_ompl(moving, "rrtconnect")


def test_labels():
    assert planner_label("rrtconnect", 1.2) == "RRTConnect"
    assert planner_label("biest", 1.2, with_time=True) == "Bi-EST (1.2 s)"
    assert planner_label("bitstar", 6.0) == "BIT* (6 s)"


def test_bench_rows_of_the_baselines(problem):
    from gfcs.bench import bench_problem, error_rows

    rows, results = bench_problem(problem, ["rrtconnect", "bitstar"], batches=1, population=4, seed=0,
                                  planner_times=(0.3, 0.6))
    assert [r["label"] for r in rows] == ["RRTConnect (0.3 s)", "RRTConnect (0.6 s)", "BIT* (0.3 s)",
                                          "BIT* (0.6 s)"]
    assert [r.settings["planner_time"] for r in results.values()] == [0.3, 0.6, 0.3, 0.6]
    # each planner time's motion has a result file of its own, named by its row
    assert [r["result"] for r in rows] == list(results) == ["rrtconnect-0.3s", "rrtconnect-0.6s", "bitstar-0.3s",
                                                            "bitstar-0.6s"]
    assert all(r["method"] in ("rrtconnect", "bitstar") and r["batches"] == 0 for r in rows)
    failed = error_rows(problem, ["gf", "biest"], 5, 0, "boom", planner_times=(1.2,))
    assert [r["label"] for r in failed] == ["GF", "Bi-EST"] and all(r["error"] == "boom" for r in failed)
    # a refused GFCS solve fails every row a solve would have written, so each row counts the same problems
    failed = error_rows(problem, ["gfcs"], 5, 0, "boom", retry_row=True)
    assert [r["label"] for r in failed] == ["Ours (1 b)", "Ours (5 b)", "Ours (5 b, retry)"]
    assert [r["label"] for r in error_rows(problem, ["gfcs"], 1, 0, "boom")] == ["Ours (1 b)"]


def test_cli_solve_and_bench_with_a_baseline(tmp_path):
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "gfcs.cli", "solve", "--method", "rrtconnect", "--planner-time", "1",
                        "--class", "table_pick", "--json", "-"], capture_output=True, text=True, timeout=300)
    assert r.returncode in (0, 1), r.stderr
    result = SolveResult.from_json(r.stdout)
    assert result.method == "rrtconnect" and "RRTConnect (OMPL)" in r.stderr
    rows_file = tmp_path / "rows.jsonl"
    r = subprocess.run([sys.executable, "-m", "gfcs.cli", "bench", "--method", "gf", "biest", "--planner-time", "0.5",
                        "--classes", "table_pick", "--limit", "1", "--no-progress", "--json", str(rows_file)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    from gfcs.results import read_rows

    rows = read_rows(rows_file.read_text().splitlines())
    assert [row["label"] for row in rows] == ["GF", "Bi-EST"]
    assert "Bi-EST" in r.stdout


def test_continuous_joint_turns_the_short_way_and_prismatic_keeps_its_speed():
    from test_robot_kinds import URDF

    robot = gfcs.Robot.from_urdf(URDF, ee_link="hand")
    q0 = np.array([0.05, -1.0, 0.5, math.pi])  # the wrist at +π
    goal = np.array([0.35, 1.0, -0.5, -math.pi + 0.3])  # 0.3 rad further round, written near −π
    r = plan_ompl(Problem("kinds", robot, gfcs.Scene(), q0, goal), "rrtconnect", planner_time=1.0)
    assert r.success, r.settings.get("failure")
    q = r.trajectory.q
    assert q[-1, 3] == pytest.approx(math.pi + 0.3)  # the same angle as the goal, reached the short way
    assert np.abs(np.diff(q[:, 3])).sum() == pytest.approx(0.3, abs=1e-6)  # an empty scene: a straight path
    assert r.metrics["final_error"] == pytest.approx(0.0, abs=1e-9)
    assert metrics.velocity_ratio(r.trajectory.t, q, robot.velocity_limits) <= 1.0 + 1e-9
    assert r.trajectory.t[-1] >= 3.0  # the lift's 0.3 m at 0.1 m/s
