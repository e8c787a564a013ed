"""The Python benchmark scripts under ``benches/`` run end to end (their figures are in BENCHMARKS.md).

Run as subprocesses, as a user would; the MotionBenchMaker case follows the shared-data rule of
``conftest.require_shared``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from conftest import REPO_ROOT, load_script

BENCHES = REPO_ROOT / "benches"


def _run(script: str, *args: str, shared: Path = None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    if shared is not None:
        env["GFCS_SHARED"] = str(shared)
    return subprocess.run([sys.executable, str(BENCHES / script), *args], capture_output=True, text=True,
                          env=env, timeout=600, check=True)


def test_fabric_step_counts_steps_and_times_both_thread_counts(tmp_path):
    out = tmp_path / "step.json"
    _run("fabric_step.py", "--generated", "--limit", "1", "--population", "4", "--repeat", "1",
         "--json", str(out))
    figures = json.loads(out.read_text())
    assert figures["steps"] > 7 * 4  # 7 classes × 4 candidates, each at least one step
    assert figures["us_per_step_1_thread"] > 0 and figures["wall_us_per_step_2_threads"] > 0
    assert figures["speedup"] > 0
    assert 0 < figures["warm_start_ms_median"] <= figures["warm_start_ms_max"]


def test_bench_suite_runs_on_motionbenchmaker_problems(tmp_path, shared_dir):
    _run("bench_suite.py", "--classes", "box", "--limit", "1", "--methods", "gf", "--out", str(tmp_path),
         "--no-progress", shared=shared_dir)
    rows = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert [(r["problem"], r["method"]) for r in rows] == [("box/0001", "gf")]
    assert "box" in (tmp_path / "table.md").read_text()


def test_retrieval_baseline_compares_the_warm_starts(tmp_path):
    """A tiny `gfcs train`, then the retrieval diagnostic on one generated problem: every row present."""
    import pytest

    pytest.importorskip("torch")
    from gfcs.cli import main

    model = tmp_path / "model.pt"
    assert main(["train", "--generate", "bookshelf_small", "--n-problems", "2", "--passes", "1", "--n-train", "2",
                 "--batches", "1", "--population", "6", "--epochs", "2", "--hidden", "16", "16", "--n-neg", "4",
                 "--out", str(model), "--no-progress"]) == 0
    out = tmp_path / "rows.jsonl"
    _run("retrieval_baseline.py", "--checkpoint", str(tmp_path / "model.ckpt.pt"), "--model", str(model),
         "--classes", "bookshelf_small", "--limit", "1", "--seeds", "0", "--population", "4",
         "--sgld-iters", "2", "--json", str(out))
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["sampler"] for r in rows] == ["uniform", "retrieval", "ebm", "retrieval+sgld"]
    assert all(r["problems"] == 1 and 0 <= r["solved"] <= 1 for r in rows)


def test_retrieval_sampler_returns_the_nearest_contexts_targets():
    """Without noise the candidates are the buffer targets in order of context distance, repeated when
    the batch is larger than the buffer, and always inside the joint limits."""
    from types import SimpleNamespace

    import numpy as np

    mod = load_script("benches/retrieval_baseline.py")
    robot = SimpleNamespace(lower=[-1.0, -1.0], upper=[1.0, 1.0])
    contexts = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    targets = np.array([[0.1, 0.1], [0.2, 0.2], [3.0, -3.0]])  # the last outside the limits
    sampler = mod.RetrievalSampler(contexts, targets, lambda p: p.context, sigma=0.0)
    problem = SimpleNamespace(robot=robot, context=np.array([4.0, 4.0]))
    y = sampler.sample(problem, 4, np.random.default_rng(0))
    np.testing.assert_allclose(y, [[1.0, -1.0], [0.2, 0.2], [0.1, 0.1], [1.0, -1.0]])


def test_compare_fabrics_times_the_gfcs_side(tmp_path, shared_dir):
    """The gfcs half of benches/compare_fabrics.py (the `fabrics` half needs that package's own environment):
    the arm moves, every sphere and obstacle is in, and both timings are positive."""
    out = tmp_path / "gfcs.json"
    _run("compare_fabrics.py", "--engine", "gfcs", "--steps", "50", "--obstacles", "3", "--json", str(out),
         shared=shared_dir)
    figures = json.loads(out.read_text())
    assert figures["spheres"] == 81 and figures["obstacles"] == 3 and figures["rollout_steps"] == 50
    assert figures["median_us"] > 0 and figures["rollout_us_per_step"] > 0


def test_pose_goal_ik_times_generated_pose_goals(tmp_path):
    out = tmp_path / "ik.json"
    _run("pose_goal_ik.py", "--generated", "--limit", "1", "--repeat", "1", "--json", str(out))
    figures = json.loads(out.read_text())
    assert figures["problems"] == 7 and figures["source"] == "generated"
    assert 0 < figures["ms_median"] <= figures["ms_max"]
    assert 0 < figures["goal_distance_ratio_median"] <= figures["goal_distance_ratio_max"]


def test_scaling_curves_have_every_point_and_fit_exponents(tmp_path):
    """benches/scaling.py: every point of the obstacle, sphere and batch curves is timed, and the fitted
    exponent of a power law is recovered exactly."""
    scaling = load_script("benches/scaling.py")
    rows = [{"x": x, "y": 3.0 * x ** 2} for x in (1.0, 2.0, 5.0, 10.0)]
    assert abs(scaling.slope(rows, "x", "y") - 2.0) < 1e-12
    out = tmp_path / "scaling.json"
    _run("scaling.py", "--curves", "obstacles", "spheres", "batch", "--repeat", "1", "--json", str(out))
    curves = json.loads(out.read_text())
    assert [r["obstacles"] for r in curves["obstacles"]] == [1, 3, 10, 30, 100, 300, 1000]
    assert [r["spheres"] for r in curves["spheres"]] == [57, 114, 228, 456]
    assert [r["candidates"] for r in curves["batch"]] == [8, 16, 32, 64, 128]
    for name, keys in (("obstacles", ("rollout_us", "python_us")), ("spheres", ("rollout_us",)),
                       ("batch", ("ms_1t", "ms_2t"))):
        assert all(r[k] > 0 for r in curves[name] for k in keys), name


def test_benchmarks_md_is_what_the_report_writes():
    """BENCHMARKS.md holds only figures from result files: `python benches/report.py` rewrites it exactly."""
    import importlib.util

    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("report", root / "benches" / "report.py")
    report = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(report)
    assert (root / "BENCHMARKS.md").read_text() == report.render(), "run: python benches/report.py"


def test_report_judges_each_row_on_the_result_file_it_names(tmp_path, monkeypatch):
    """A row that names its result file gets the validator's verdict on that file (a first batch the solve
    did not return included); a row of an older run without a name is judged only when its motion was the
    one returned (the last row of its problem and method), else it keeps gfcs's own verdict."""
    report = load_script(REPO_ROOT / "benches" / "report.py")
    folder = tmp_path / "table1"
    folder.mkdir()
    checker = load_script(REPO_ROOT / "tools" / "check_trajectories.py")
    monkeypatch.setattr(report, "RESULTS", tmp_path)
    monkeypatch.setattr(report, "ROOT", tmp_path)
    monkeypatch.setattr(report, "_checker", lambda: checker)

    def row(label, result=None, success=True):
        r = {"problem": "box/0001", "class": "box", "label": label, "method": "gfcs", "success": success}
        return r if result is None else {**r, "result": result}

    def verdict(name, valid):
        return {"file": f"runs/{name}.json", "claimed_success": True, "valid": valid, "start_error": 0.0,
                "goal_reached": valid, "limit_margin": 0.1, "speed_ratio": 0.5, "clearance": 0.01,
                "self_clearance": 0.01}

    def write(name, rows):
        (folder / name).write_text("".join(json.dumps(r) + "\n" for r in rows))

    write("bot.new.jsonl", [row("Ours (1 b)", "gfcs-1b"), row("Ours (5 b)", "gfcs"), row("Ours (5 b, retry)", "gfcs")])
    write("bot.new.validated.jsonl", [verdict("box_0001.gfcs-1b", False), verdict("box_0001.gfcs", True)])
    write("bot.old.jsonl", [row("Ours (1 b)"), row("Ours (5 b)")])
    write("bot.old.validated.jsonl", [verdict("box_0001.gfcs", False)])
    rows, _, _ = report.judged_rows("bot")
    got = {(r["label"].split(" (")[0], r["label"].split(" (")[1]): (r["judged"], r["success"]) for r in rows}
    assert got[("GFCS new", "1 b)")] == (True, False)  # its own file, which the validator failed
    assert got[("GFCS new", "5 b)")] == (True, True) and got[("GFCS new", "5 b, retry)")] == (True, True)
    assert got[("GFCS old", "1 b)")] == (False, True)  # no file: gfcs's own verdict, marked †
    assert got[("GFCS old", "5 b)")] == (True, False)


def test_report_leaves_a_refused_problem_out_of_every_row_of_its_run(tmp_path, monkeypatch):
    """A problem whose solve was refused (an error row, written for some labels only) counts in no row of that
    run, so every row of the run has the same denominator, and the report lists it."""
    report = load_script(REPO_ROOT / "benches" / "report.py")
    folder = tmp_path / "table1"
    folder.mkdir()
    monkeypatch.setattr(report, "RESULTS", tmp_path)
    monkeypatch.setattr(report, "ROOT", tmp_path)
    rows = [{"problem": f"box/000{i}", "class": "box", "label": label, "method": "gfcs", "success": True,
             "time": 0.1, "wall_time": 0.2}
            for i in (1, 2) for label in ("Ours (1 b)", "Ours (5 b)")]
    rows[3] = {**rows[3], "success": False, "error": "CollisionError: the goal state is in collision"}
    del rows[2]  # as `gfcs bench` wrote them: the refused problem has its 5 b row only
    (folder / "bot.new.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    judged, _, refused = report.judged_rows("bot")
    assert sorted((r["problem"], r["label"]) for r in judged) == [("box/0001", "GFCS new (1 b)"),
                                                                  ("box/0001", "GFCS new (5 b)")]
    assert list(refused) == ["box/0002"] and "collision" in refused["box/0002"]


def test_speed_section_marks_each_target_from_the_figures():
    """benches/speed.py's page from given measurements: every target marked met or not by its own figure, the
    fabrics ratio the median of the runs' ratios, and every table present."""
    import argparse

    speed = load_script("benches/speed.py")
    machine = {"cpu": "test CPU", "cores": 2, "commit": "abc1234", "date": "2026-01-01", "load": 0.1}
    crit = {"mbm_panda_free_space": {"psi": 2.1, "_no_psi": 1.9}, "mbm_panda_cage_scene": {"psi": 8.0, "_no_psi": 7.5},
            "budget": {"obstacles_off": 2.25, "barrier": 0.0237, "leaves": 72.9}}
    gfcs_run = {"median_us": 4.0, "rollout_us_per_step": 3.5, "spheres": 81, "self_pairs": 1195, "obstacles": 10}
    runs = [{"gfcs": dict(gfcs_run, median_us=us), "fabrics": {"median_us": 1600.0, "casadi_median_us": 1400.0}}
            for us in (4.0, 5.0, 4.5)]
    solve = {"optimisation": 0.25, "first_batch": 0.05, "batches": 5, "solve": 0.32, "shell": 0.6, "cost": 2.9,
             "success": True}
    row = {"problem": "box/0001", "label": "Ours (5 b)", "success": True, "time": 0.3, "cost": 3.0,
           "ee_length": 1.0, "cspace_length": 5.0}
    stall = {k: [row, dict(row, label="Ours (5 b, retry)")] for k in (0, 1)}
    curves = {"obstacles": [{"obstacles": n, "rollout_us": 2.0 * n, "python_us": 2.5 * n} for n in (1, 10, 100, 1000)]}
    args = argparse.Namespace(measurement_time=3.0, stall_limit=1, scaling_repeat=1)
    page = speed.write(args, machine, crit, runs, [solve] * 3, [dict(solve, batches=2)] * 3, stall, curves)
    lines = {line.split("|")[1].strip(): line for line in page.splitlines() if line.startswith("| ")}
    assert "1.90 µs | met" in lines["fabric step, MBM Panda in free space (criterion, Rust)"]
    assert "7.50 µs | **not met**" in lines["fabric step, MBM Panda in the cage scene (criterion, Rust)"]
    assert "| 356 | met" in lines["ratio to `fabrics` `compute_action`, 10 obstacles"]  # 1600 / 4.5
    assert "0.600 s | **not met**" in lines["`gfcs solve` from the shell"]
    assert "0.050 s | met" in lines["built-in problem: first batch"]
    assert "Fitted exponent from 10 obstacles on: 1.00; from 100 on: 1.00" in page and "test CPU" in page
    # the cage step's budget: the obstacle part is the step less the step with the obstacle barrier off
    assert "take 2.25 µs" in page and "other 5.25 µs" in page and "72.9 leaves" in page and "23.7 ns" in page


def test_unseen_robots_disables_the_adjacent_pairs_setup_assistant_would(tmp_path):
    unseen = load_script("benches/unseen_robots.py")
    urdf = tmp_path / "r.urdf"
    geometry = '<collision><geometry><sphere radius="0.1"/></geometry></collision>'
    urdf.write_text(
        f'<robot name="r"><link name="base">{geometry}</link><link name="flange"/><link name="a">{geometry}</link>'
        f'<link name="b">{geometry}</link><link name="c">{geometry}</link>'
        '<joint name="j0" type="fixed"><parent link="base"/><child link="flange"/></joint>'
        '<joint name="j1" type="revolute"><parent link="flange"/><child link="a"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" velocity="1" effort="1"/></joint>'
        '<joint name="j2" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" velocity="1" effort="1"/></joint>'
        '<joint name="j3" type="revolute"><parent link="b"/><child link="c"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>')
    srdf = tmp_path / "r.srdf"
    srdf.write_text('<robot name="r"><group name="arm"><joint name="j1"/></group>'
                    '<disable_collisions link1="b" link2="a" reason="Never"/></robot>')
    import xml.etree.ElementTree as ET

    root = ET.fromstring(unseen.adjacent_srdf(urdf, srdf))
    pairs = {frozenset((e.get("link1"), e.get("link2"))) for e in root.iter("disable_collisions")}
    # base-a through the geometry-less flange; a-b kept once; b-c added; base-c and a-c stay checked
    assert pairs == {frozenset(p) for p in (("base", "a"), ("a", "b"), ("b", "c"))}
    assert root.find("group").get("name") == "arm"


def test_unseen_robots_adds_romeos_arm_groups():
    unseen = load_script("benches/unseen_robots.py")
    import xml.etree.ElementTree as ET

    root = ET.fromstring(unseen.romeo_srdf('<robot name="romeo"><group name="all"><joint name="waist"/></group>'
                                           '</robot>'))
    groups = {g.get("name"): [j.get("name") for j in g.iter("joint")] for g in root.iter("group")}
    assert groups["left_arm"][0] == "LShoulderPitch" and groups["right_arm"][-1] == "RWristPitch"
    assert len(groups["left_arm"]) == 7 and groups["both_arms"] == groups["left_arm"] + groups["right_arm"]
    assert groups["all"] == ["waist"]


def test_unseen_robots_tiago_pro_groups_resolve_to_both_arms_and_the_lift():
    """The TIAGo Pro SRDF's both_arms_torso group, resolved as MoveIt does (subgroups), is the lift then the
    fourteen arm joints, on a stand-in URDF with the TIAGo Pro's joint names."""
    unseen = load_script("benches/unseen_robots.py")
    from gfcs.srdf_groups import resolve_group

    def chain(side):
        parent, out = "torso", ""
        for i in range(1, 8):
            out += (f'<link name="{side}{i}"/><joint name="arm_{side}_{i}_joint" type="revolute"><parent '
                    f'link="{parent}"/><child link="{side}{i}"/><axis xyz="0 0 1"/>'
                    '<limit lower="-1" upper="1" velocity="1" effort="1"/></joint>')
            parent = f"{side}{i}"
        return out

    urdf = ('<robot name="tiago_pro"><link name="base"/><link name="torso"/><joint name="torso_lift_joint" '
            'type="prismatic"><parent link="base"/><child link="torso"/><axis xyz="0 0 1"/>'
            f'<limit lower="0" upper="0.35" velocity="0.035" effort="1"/></joint>{chain("left")}{chain("right")}'
            '</robot>')
    srdf = unseen.tiago_pro_srdf('<robot name="tiago_pro"></robot>')
    joints = list(resolve_group(urdf, srdf, "both_arms_torso").joints)
    assert joints[0] == "torso_lift_joint" and len(joints) == 15
    assert set(joints[1:]) == {f"arm_{s}_{i}_joint" for s in ("left", "right") for i in range(1, 8)}


def test_unseen_robots_two_arm_groups_of_centauro_and_the_g1():
    unseen = load_script("benches/unseen_robots.py")
    import xml.etree.ElementTree as ET

    def groups(text):
        return {g.get("name"): ([j.get("name") for j in g.findall("joint")],
                                [s.get("name") for s in g.findall("group")],
                                [(c.get("base_link"), c.get("tip_link")) for c in g.findall("chain")])
                for g in ET.fromstring(text).findall("group")}  # top-level groups, not subgroup references

    centauro = groups(unseen.centauro_srdf('<robot name="centauro"><group name="left_arm"><chain base_link="torso_2"'
                                           ' tip_link="arm1_8"/></group></robot>'))
    assert centauro["both_arms"] == ([], ["left_arm", "right_arm"], [])
    g1 = groups(unseen.g1_srdf('<robot name="g1"></robot>'))
    assert g1["left_arm"][2] == [("torso_link", "left_rubber_hand")]
    assert g1["right_arm"][2] == [("torso_link", "right_rubber_hand")]
    assert g1["arms_waist"][:2] == (["waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint"],
                                    ["left_arm", "right_arm"])


def test_sphere_fit_times_a_fresh_fit_and_writes_its_fragment(tmp_path):
    bench = load_script("benches/sphere_fit.py")
    urdf = tmp_path / "r.urdf"
    urdf.write_text('<robot name="r"><link name="base"><collision><geometry><box size="0.2 0.1 0.1"/></geometry>'
                    '</collision></link><link name="a"><collision><geometry><cylinder radius="0.05" length="0.3"/>'
                    '</geometry></collision></link><joint name="j" type="revolute"><parent link="base"/>'
                    '<child link="a"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1"/></joint></robot>')
    fit = bench.fit_once(urdf, tmp_path)
    assert fit["links"] == 2 and fit["spheres"] >= 2 and fit["seconds"] > 0
    text = bench.fragment([{"robot": "r", "links": 2, "spheres": fit["spheres"], "seconds": [0.5, 0.25, 1.0]}], 3)
    assert "--repeat 3" in text and "| r | 2 |" in text and "| 0.50 | 0.25-1.00 |" in text
