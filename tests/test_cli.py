"""The `gfcs` command line: help everywhere, a small solve with JSON on stdout, bench, generate, errors."""

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from gfcs import bench, cli
from gfcs.results import SolveResult, read_rows

SMALL = ["--batches", "1", "--population", "6", "--threads", "1"]


def run(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "gfcs.cli", *args], capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.parametrize("args", [[], ["solve"], ["bench"], ["generate"]])
def test_help(args):
    r = run(*args, "--help")
    assert r.returncode == 0, r.stderr
    assert "usage: gfcs" in r.stdout
    if not args:
        for name in ("solve", "bench", "generate", "train", "view", "experiment"):
            assert name in r.stdout


def test_python_dash_m_gfcs_is_the_command():
    r = subprocess.run([sys.executable, "-m", "gfcs", "generate", "--help"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert "usage: gfcs generate" in r.stdout


def test_help_does_not_import_optional_dependencies():
    code = ("import sys; from gfcs import cli\n"
            "try:\n    cli.main(['--help'])\nexcept SystemExit:\n    pass\n"
            "print('torch' in sys.modules, 'rerun' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.strip().splitlines()[-1] == "False False"


def test_solve_imports_no_heavy_optional_dependency(tmp_path):
    heavy = ["torch", "matplotlib", "rerun", "scipy", "trimesh"]
    code = ("import sys; from gfcs import cli\n"
            f"code = cli.main(['solve', '--json', {str(tmp_path / 'r.json')!r}, *{SMALL!r}])\n"
            f"print([m for m in {heavy!r} if m in sys.modules])")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.stdout.strip().splitlines()[-1] == "[]", r.stdout + r.stderr


def test_solve_json_to_stdout():
    r = run("solve", "--json", "-", *SMALL)
    assert r.returncode in (0, 1), r.stderr
    result = SolveResult.from_json(r.stdout)
    assert result.method == "gfcs" and result.problem.startswith(cli.DEFAULT_DEMO_CLASS + "/")
    assert result.settings["spheres_judge"] is False  # the default preset: the meshes judge
    assert result.trajectory.q.shape[1] == 7 and len(result.trajectory) > 1
    assert "cost" in r.stderr and "EE length" in r.stderr  # the summary went to stderr
    assert r.returncode == (0 if result.success else 1)


def test_solve_selection_and_timing_options_reach_the_result():
    r = run("solve", "--json", "-", "--length-slack", "0.3", "--mesh-margin", "0.004", "--spheres-judge", *SMALL)
    assert r.returncode in (0, 1), r.stderr
    result = SolveResult.from_json(r.stdout)
    assert result.settings["length_slack"] == 0.3 and result.settings["mesh_margin"] == 0.004
    assert result.settings["spheres_judge"] is True
    assert result.wall_time > result.solve_time > 0
    r = run("solve", "--json", "-", "--no-acceleration-limits", "--limit-hold-off", "0.03", *SMALL)
    assert r.returncode in (0, 1), r.stderr
    settings = SolveResult.from_json(r.stdout).settings
    assert settings["limit_acceleration"] is False and settings["limit_hold_off"] == 0.03
    r = run("solve", "--limit-hold-off", "-1", *SMALL)
    assert r.returncode == 2 and "limit_hold_off" in r.stderr and "Traceback" not in r.stderr
    r = run("solve", "--length-slack", "-1", *SMALL)
    assert r.returncode == 2 and "length_slack" in r.stderr and "Traceback" not in r.stderr
    r = run("solve", "--mesh-margin", "-1", *SMALL)
    assert r.returncode == 2 and "mesh_margin" in r.stderr and "Traceback" not in r.stderr
    r = run("solve", "--restarts", "-1", *SMALL)
    assert r.returncode == 2 and "restarts" in r.stderr and "Traceback" not in r.stderr


def panda_with(collision):
    """The shipped Panda's URDF (no collision elements) with one ``<collision>`` geometry on the hand."""
    import gfcs

    return gfcs.panda_urdf().replace('<link name="panda_hand"/>',
                                     f'<link name="panda_hand"><collision><geometry>{collision}'
                                     '</geometry></collision></link>')


def test_solve_validates_with_the_mesh_model_beside_a_spherized_robot(tmp_path):
    spherized = tmp_path / "arm_spherized.urdf"
    spherized.write_text(panda_with('<sphere radius="0.05"/>'))
    r = run("solve", "--method", "gf", "--class", "box", "--robot", str(spherized))
    assert r.returncode in (0, 1), r.stderr
    assert "collision spheres only" in r.stdout
    (tmp_path / "arm.urdf").write_text(panda_with('<box size="0.1 0.2 0.1"/>'))
    r = run("solve", "--method", "gf", "--class", "box", "--robot", str(spherized))
    assert r.returncode in (0, 1), r.stderr
    assert "checked   collision meshes" in r.stdout
    r = run("solve", "--method", "gf", "--class", "box", "--mesh-urdf", str(tmp_path / "missing.urdf"))
    assert r.returncode == 2 and "missing.urdf" in r.stderr and "Traceback" not in r.stderr


def test_solve_takes_the_spheres_of_the_spherized_model_beside_a_mesh_robot(tmp_path):
    """--robot X.urdf without spheres, X_spherized.urdf beside it (MotionBenchMaker's layout): the fabric
    avoids obstacles with the twin's spheres (said on stderr) and X's own geometry validates the motion;
    without a twin, with spheres fitted to X's geometry."""
    mesh_model = tmp_path / "arm.urdf"
    other_arm = tmp_path / "other_arm.urdf"  # not a Panda: its forearm is 1 cm longer
    other_arm.write_text(panda_with('<box size="0.1 0.2 0.1"/>').replace('xyz="0.0825 0 0"', 'xyz="0.0925 0 0"', 1))
    r = run("solve", "--method", "gf", "--class", "box", "--robot", str(other_arm))
    # no twin: spheres fitted to its own geometry (gfcs.sphere_fit), said on stderr
    assert r.returncode in (0, 1), r.stderr
    assert "no collision spheres on 1 link(s)" in r.stderr and "fitted to their geometry" in r.stderr
    assert "checked   collision meshes" in r.stdout
    mesh_model.write_text(panda_with('<box size="0.1 0.2 0.1"/>'))
    (tmp_path / "arm_spherized.urdf").write_text(panda_with('<sphere radius="0.05"/>'))
    r = run("solve", "--method", "gf", "--class", "box", "--robot", str(mesh_model))
    assert r.returncode in (0, 1), r.stderr
    assert "uses those of" in r.stderr and "arm_spherized.urdf" in r.stderr
    assert "checked   collision meshes" in r.stdout


def test_a_mesh_model_with_a_few_sphere_elements_takes_its_twins_spheres(tmp_path):
    """--robot X.urdf whose links are meshes but for one part modelled by a sphere (the Fetch's head): it is a
    mesh model, so the fabric takes X_spherized.urdf's spheres, not that one sphere alone."""
    import gfcs
    from gfcs.problems import links_without_spheres

    text = panda_with('<box size="0.1 0.2 0.1"/>').replace(
        '<link name="panda_link0"/>',
        '<link name="panda_link0"><collision><geometry><sphere radius="0.1"/></geometry></collision></link>')
    assert '<sphere radius="0.1"/>' in text
    mesh_model = tmp_path / "arm.urdf"
    mesh_model.write_text(text)
    robot = gfcs.Robot.from_urdf(str(mesh_model))
    assert len(robot.sphere_radii) == 1 and links_without_spheres(robot) == ["panda_hand"]
    (tmp_path / "arm_spherized.urdf").write_text(panda_with('<sphere radius="0.05"/>'))
    r = run("solve", "--method", "gf", "--class", "box", "--robot", str(mesh_model))
    assert r.returncode in (0, 1), r.stderr
    assert "no collision spheres on panda_hand; the fabric uses those of" in r.stderr
    assert "checked   collision meshes" in r.stdout


def test_a_panda_with_meshes_only_gets_the_shipped_spheres_and_its_own_validation(tmp_path):
    """--robot X.urdf, a Panda with collision geometry but no spheres and no twin (e.g. a Franka
    description): the fabric uses the shipped Panda's spheres (said on stderr), X's geometry validates."""
    mesh_model = tmp_path / "franka.urdf"
    mesh_model.write_text(panda_with('<box size="0.1 0.2 0.1"/>'))
    r = run("solve", "--method", "gf", "--class", "box", "--robot", str(mesh_model))
    assert r.returncode in (0, 1), r.stderr
    assert "shipped Panda's spheres" in r.stderr and "checked   collision meshes" in r.stdout


def test_solve_gf_summary(tmp_path):
    out = tmp_path / "r.json"
    r = run("solve", "--method", "gf", "--class", "box", "--json", str(out))
    assert r.returncode in (0, 1), r.stderr
    assert "method    gf" in r.stdout
    assert SolveResult.from_json(out.read_text()).commands.shape == (0, 7)


def test_user_errors_are_one_line(tmp_path):
    r = run("solve", "--scene", str(tmp_path / "missing.yaml"), "--request", str(tmp_path / "r.yaml"))
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and "missing.yaml" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    r = run("solve", "--class", "kitchen")
    assert r.returncode == 2 and "unknown problem class 'kitchen'" in r.stderr and "Traceback" not in r.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text("[speed]\nno_such_gain = 1.0\n")
    r = run("solve", "--config", str(bad), *SMALL)
    assert r.returncode == 2 and "no_such_gain" in r.stderr and "Traceback" not in r.stderr


def test_generate_then_bench(tmp_path):
    r = run("generate", "--out", str(tmp_path / "suite"), "--classes", "single_shelf", "box", "--n", "1")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "suite" / "box" / "scene0001.yaml").is_file()
    rows_file, md = tmp_path / "rows.jsonl", tmp_path / "table.md"
    r = run("bench", "--problems", str(tmp_path / "suite"), "--batches", "2", "--population", "6",
            "--json", str(rows_file), "--markdown", str(md), "--no-progress")
    assert r.returncode == 0, r.stderr
    rows = read_rows(rows_file.read_text().splitlines())
    labels = {(row["class"], row["label"]) for row in rows}
    want = ("GF", "Ours (1 b)", "Ours (2 b)", "Ours (2 b, retry)")
    assert labels == {(c, lab) for c in ("bookshelf_small", "box") for lab in want}
    for c in ("bookshelf_small", "box"):  # the retry row is the plain row when that succeeded
        plain, retried = ([row for row in rows if row["class"] == c and row["label"] == lab][0]
                          for lab in want[2:])
        if plain["success"]:
            assert retried["cost"] == plain["cost"] and retried["time"] == plain["time"]
    text = md.read_text()
    assert "### box" in text and "| Method | % Success |" in text
    assert "Ours (2 b)" in r.stdout
    assert "Ours (2 b): " in text and "Ours (2 b): " in r.stdout and "whole solve" in r.stdout  # the totals
    r = run("bench", "--problems", str(tmp_path / "suite"), "--classes", "box", "--batches", "1",
            "--population", "4", "--method", "gfcs", "--no-retry", "--json", str(rows_file), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert {row["label"] for row in read_rows(rows_file.read_text().splitlines())} == {"Ours (1 b)"}


def test_a_suite_leaves_out_problems_outside_the_joint_limits(tmp_path, capsys):
    import yaml

    import gfcs
    from gfcs import problems

    assert cli.main(["generate", "--out", str(tmp_path), "--classes", "box", "--n", "2"]) == 0
    request = tmp_path / "box" / "request0002.yaml"
    doc = yaml.safe_load(request.read_text())
    for c in doc["goal_constraints"][0]["joint_constraints"]:
        if c["joint_name"] == "panda_joint4":
            c["position"] = 0.05  # MotionBenchMaker's URDF allows it, Franka's limit is -0.0698
    request.write_text(yaml.safe_dump(doc))
    robot = gfcs.Robot.panda()
    with pytest.raises(gfcs.InvalidValueError, match="problem 'box/0002': goal: joint panda_joint4 = 0.05 rad"):
        problems.load_mbm_dir(tmp_path, robot=robot)
    capsys.readouterr()
    suite = bench.load_mbm_suite(str(tmp_path), None, None, robot)
    assert [p.name for p in suite] == ["box/0001"]
    err = capsys.readouterr().err
    assert "left out 1 problem(s)" in err and "'box/0002': goal: joint panda_joint4" in err
    # gfcs bench: the left-out problem is a row of its own in the JSON lines and a line of the totals
    rows_file = tmp_path / "rows.jsonl"
    assert cli.main(["bench", "--problems", str(tmp_path), "--method", "gf", "--json", str(rows_file),
                     "--no-progress"]) == 0
    out = capsys.readouterr().out
    rows = read_rows(rows_file.read_text().splitlines())
    assert rows[0]["problem"] == "box/0002" and rows[0]["class"] == "box"
    assert "goal: joint panda_joint4" in rows[0]["left_out"] and set(rows[0]) == {"problem", "class", "left_out"}
    assert [(r["problem"], r["label"]) for r in rows[1:]] == [("box/0001", "GF")]
    assert "GF: " in out and "/1 solved" in out and "left out (start or goal not valid for the robot): 1" in out
    # a suite whose every problem is left out says so
    (tmp_path / "box" / "scene0001.yaml").unlink()
    with pytest.raises(ValueError, match="every MotionBenchMaker problem .* outside the joint limits of robot"):
        bench.load_mbm_suite(str(tmp_path), None, None, robot)


def test_failure_hints_name_a_goal_inside_the_margin_and_a_start_in_collision():
    from types import SimpleNamespace

    import gfcs
    from gfcs import generators

    p = generators.generate("bookshelf_small", 1, seed=0, robot=gfcs.Robot.panda())[0]
    result = SimpleNamespace(fabric_config=None)
    assert cli._endpoint_hints(result, p) == []  # generated goals keep 1 cm
    robot = p.robot
    radii = np.asarray(robot.sphere_radii)
    for what, q, other in (("goal", p.goal, p.q0), ("start", p.q0, p.goal)):
        here, there = np.asarray(robot.sphere_centers(q)), np.asarray(robot.sphere_centers(other))
        # the sphere of q farthest from every sphere of the other configuration
        gap = np.linalg.norm(here[:, None] - there[None], axis=2) - radii[None]
        scene = p.scene.copy()
        scene.add_sphere(here[int(np.argmax(gap.min(axis=1)))], 0.01)
        hints = cli._endpoint_hints(result, p.with_scene(scene))
        assert len(hints) == 1 and f"the {what}'s collision spheres overlap the obstacles by" in hints[0], hints
    # a goal 1 mm clear is inside the default 2 mm margin
    center = np.asarray(robot.sphere_centers(p.goal))
    k = int(np.argmax(center[:, 2]))  # the highest sphere: nothing of the arm above it
    scene = p.scene.copy()
    scene.add_sphere(center[k] + [0.0, 0.0, radii[k] + 0.011], 0.01)
    hints = cli._endpoint_hints(result, p.with_scene(scene))
    assert len(hints) == 1 and "the goal's collision spheres are 1.00 mm from the obstacles" in hints[0], hints
    assert "one with collision meshes" not in hints[0]  # the shipped Panda's polytopes: solve tried the contact
    bare = dataclasses.replace(p, mesh_checker=None).with_scene(scene)
    assert "one with collision meshes" in cli._endpoint_hints(result, bare)[0]  # without a checker, the way to it


def test_one_batch_row_is_a_one_batch_solve_sharing_the_first_batch():
    import gfcs
    from gfcs import generators, optimize

    p = generators.generate("box", 1, seed=0, robot=gfcs.Robot.panda())[0]
    rows, results = bench.bench_problem(p, ["gfcs"], batches=2, population=6, seed=0, retry=False)
    one = optimize.solve(p, batches=1, population=6, seed=0, max_commands=1)
    row = [r for r in rows if r["label"] == "Ours (1 b)"][0]
    assert row["cost"] == one.cost and row["success"] == one.success
    assert row["ee_length"] == one.metrics["ee_length"]
    assert results["gfcs"].batch_best_costs[0] == one.batch_best_costs[0]  # the same first batch
    assert row["result"] == "gfcs-1b" and results["gfcs-1b"].metrics["ee_length"] == row["ee_length"]


def test_missing_external_command_is_one_line(monkeypatch, capsys):
    # a missing optional dependency: the message names it and the extra to install
    monkeypatch.setitem(cli.EXTERNAL_COMMANDS, "ghost", (("no_such_dependency_xyz",), "register", "a ghost", "ghost"))
    assert cli.main(["ghost", "--help"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "gfcs[ghost]" in err and "no_such_dependency_xyz" in err
    # a gfcs module absent from this installation: no misleading extra hint
    monkeypatch.setitem(cli.EXTERNAL_COMMANDS, "ghost", (("gfcs.no_such_module",), "register", "a ghost", "ghost"))
    assert cli.main(["ghost"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "gfcs[ghost]" not in err and "gfcs.no_such_module" in err


def test_external_command_registration_is_lazy(monkeypatch):
    monkeypatch.setitem(cli.EXTERNAL_COMMANDS, "ghost", (("gfcs.no_such_module",), "register", "a ghost", None))
    # building the parser for another command never imports the ghost module
    parser = cli.build_parser(["solve"])
    assert parser.parse_args(["solve"]).command == "solve"


def test_solve_rrd_hook(tmp_path):
    out = tmp_path / "run.rrd"
    r = run("solve", "--rrd", str(out), *SMALL)
    try:
        import gfcs.viz  # noqa: F401
    except ImportError:
        assert r.returncode == 2 and "--rrd needs the 'viz' extra" in r.stderr and "Traceback" not in r.stderr
    else:
        assert r.returncode in (0, 1), r.stderr
        assert out.is_file() and out.stat().st_size > 0
