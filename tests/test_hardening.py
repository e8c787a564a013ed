"""Hostile and unusual input through the Python API and the command line: nesting limits, locked and goal
joints, MoveIt fields that are not applied, integer arguments, thread pools, a bench that survives one bad
problem, and Hypothesis property tests (any array, dict or path gives a result or a gfcs error)."""

import math
import os
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import gfcs
from gfcs import bench, cli, problems
from gfcs.errors import GfcsWarning
from gfcs.results import read_rows

from conftest import require_shared

PROPERTY = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def run(*args, timeout=600):
    return subprocess.run([sys.executable, "-m", "gfcs.cli", *args], capture_output=True, text=True,
                          timeout=timeout)


def deep_urdf(depth):
    return ("<robot name='r'><link name='a'><visual><geometry><box size='1 1 1'/></geometry>"
            + "<g>" * depth + "</g>" * depth + "</visual></link><link name='b'/>"
            "<joint name='j' type='revolute'><parent link='a'/><child link='b'/>"
            "<limit lower='-1' upper='1' velocity='1'/></joint></robot>")


@pytest.fixture(scope="module")
def panda():
    return gfcs.Robot.panda()


@pytest.fixture(scope="module")
def fabric(panda):
    scene = gfcs.Scene()
    scene.add_sphere([0.5, 0.0, 0.5], 0.1)
    return gfcs.Fabric(panda, scene)


# ------------------------------------------------------------------------------------------ input limits
def test_deeply_nested_xml_is_an_error_not_a_crash(tmp_path):
    path = tmp_path / "deep.urdf"
    path.write_text(deep_urdf(25_000))
    # in a child process: on a stack overflow the process dies (exit 139) instead of raising
    code = ("import gfcs\n"
            f"try:\n    gfcs.Robot.from_urdf({str(path)!r})\n"
            "except gfcs.UrdfError as e:\n    print('UrdfError', e)\n"
            "try:\n    gfcs.Robot.panda().with_srdf('<robot>' + '<g>' * 25000 + '</g>' * 25000 + '</robot>')\n"
            "except gfcs.FormatError as e:\n    print('FormatError', e)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert "UrdfError" in r.stdout and "nested more than 64 deep" in r.stdout and "deep.urdf" in r.stdout
    assert "FormatError" in r.stdout and "(xml)" in r.stdout
    r = run("solve", "--robot", str(path), timeout=120)
    assert r.returncode == 2, (r.returncode, r.stderr[-2000:])
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert "nested more than 64 deep" in r.stderr


def test_deeply_nested_yaml_is_refused_at_once():
    text = "world: " + "[" * 100_000 + "]" * 100_000 + "\n"
    start = time.perf_counter()
    with pytest.raises(gfcs.FormatError, match=r"<string>: field '<root>': nested more than 64 levels"):
        gfcs.Scene.from_moveit_yaml_str(text)
    assert time.perf_counter() - start < 5.0


def test_truncated_urdf_and_mimic_cycle_say_what_is_wrong():
    text = gfcs.panda_urdf()
    with pytest.raises(gfcs.UrdfError, match=r"URDF <string>: the text ends .*\(line \d+\).*the file looks truncated"):
        gfcs.Robot.from_urdf(text[: len(text) // 2])
    cycle = ("<robot name='m'><link name='a'/><link name='b'/><link name='c'/><link name='d'/>"
             "<joint name='j0' type='revolute'><parent link='a'/><child link='b'/>"
             "<limit lower='-1' upper='1' velocity='1'/></joint>"
             "<joint name='j1' type='revolute'><parent link='b'/><child link='c'/>"
             "<limit lower='-1' upper='1' velocity='1'/><mimic joint='j2'/></joint>"
             "<joint name='j2' type='revolute'><parent link='c'/><child link='d'/>"
             "<limit lower='-1' upper='1' velocity='1'/><mimic joint='j1'/></joint></robot>")
    with pytest.raises(gfcs.UrdfError, match="mimic joints form a cycle: j1 -> j2 -> j1"):
        gfcs.Robot.from_urdf(cycle, active_joints=["j0"])


# ------------------------------------------------------------------------- locked and requested joints
def test_locked_joint_outside_its_limits_is_refused(panda):
    with pytest.raises(gfcs.InvalidValueError, match=r"locked joint 'panda_finger_joint1'.*\[0, 0\.04\]"):
        panda.with_locked_positions({"panda_finger_joint1": -0.5})
    # MotionBenchMaker's open fingers (0.065 m) lie within MoveIt's bounds tolerance: held there
    assert panda.with_locked_positions({"panda_finger_joint1": 0.065}).locked_positions == {
        "panda_finger_joint1": 0.065}


def _request(tmp_path, start_fingers=0.04, extra_goal=()):
    """A generated box problem's files, the request rewritten with the fingers and extra goal joints."""
    assert cli.main(["generate", "--out", str(tmp_path), "--classes", "box", "--n", "1"]) == 0
    scene, request = tmp_path / "box" / "scene0001.yaml", tmp_path / "box" / "request0001.yaml"
    doc = yaml.safe_load(request.read_text())
    js = doc["start_state"]["joint_state"]
    names, positions = list(js["name"]), list(js["position"])
    for finger in ("panda_finger_joint1", "panda_finger_joint2"):
        if finger in names:
            positions[names.index(finger)] = start_fingers
        else:
            names.append(finger)
            positions.append(start_fingers)
    js["name"], js["position"] = names, positions
    for name, value in extra_goal:
        doc["goal_constraints"][0]["joint_constraints"].append({"joint_name": name, "position": value})
    request.write_text(yaml.safe_dump(doc))
    return scene, request


def test_request_with_fingers_outside_their_limits_is_refused(tmp_path, panda):
    scene, request = _request(tmp_path, start_fingers=-0.5)
    with pytest.raises(gfcs.InvalidValueError, match=r"request0001\.yaml: start_state: .*panda_finger_joint1"):
        problems.load_mbm(scene, request, robot=panda)


def test_goal_on_an_unknown_joint_is_refused(tmp_path, panda):
    scene, request = _request(tmp_path, extra_goal=[("panda_joint8", 0.3)])
    with pytest.raises(gfcs.LinkError, match=r"request0001\.yaml: goal_constraints name joint\(s\) 'panda_joint8'"):
        problems.load_mbm(scene, request, robot=panda)


# ------------------------------------------------------------------------------------ MoveIt fields
SCENE = """
world:
  collision_objects:
    - id: box
      primitives: [{type: box, dimensions: [1, 1, 1]}]
      primitive_poses: [{position: [2, 0, 0], orientation: [0, 0, 0, 1]}]
    - id: box
      primitives: [{type: box, dimensions: [0.2, 0.2, 0.2]}]
      primitive_poses: [{position: [3, 0, 0], orientation: [0, 0, 0, 1]}]
  octomap:
    octomap: {binary: true, id: OcTree, resolution: 0.02, data: [1, 2, 3]}
"""


def test_scene_fields_not_applied_warn_and_duplicate_ids_replace():
    with pytest.warns(GfcsWarning) as record:
        scene = gfcs.Scene.from_moveit_yaml_str(SCENE, source="s.yaml")
    messages = [str(w.message) for w in record]
    assert any(m.startswith("s.yaml: world.octomap: ") for m in messages), messages
    assert any("world.collision_objects[0]: id 'box' is added again" in m for m in messages), messages
    assert len(scene) == 1
    assert scene.signed_distance([3.0, 0.0, 0.5]) == pytest.approx(0.4)


def test_srdf_links_the_urdf_lacks_give_one_warning():
    fetch = require_shared("robots", "mbm_fetch")
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        robot = gfcs.Robot.from_urdf(str(fetch / "fetch.urdf"), srdf=str(fetch / "fetch.srdf"))
    ours = [w for w in record if issubclass(w.category, GfcsWarning)]
    assert len(ours) == 1, [str(w.message) for w in record]
    assert "bellows_link2" in str(ours[0].message) and "fetch.srdf" in str(ours[0].message)
    assert robot.dof > 0
    # a solve loads the SRDF with its planning and its mesh model: the same words are said once per process
    urdfs = (str(fetch / "fetch_spherized.urdf"), str(fetch / "fetch.urdf"))
    script = f"import gfcs\nfor u in {urdfs!r}: gfcs.Robot.from_urdf(u, srdf={str(fetch / 'fetch.srdf')!r})"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, check=True)
    assert run.stderr.count("bellows_link2") == 1, run.stderr


# -------------------------------------------------------------------------------- integer arguments
def test_integer_arguments_are_checked_with_their_name(panda, fabric):
    q = np.zeros(panda.dof)
    cands = np.tile(q, (2, 1))
    with pytest.raises(gfcs.InvalidValueError, match=r"invalid threads: must be an integer >= 1, got -1"):
        fabric.evaluate(q, q, q, cands, threads=-1)
    with pytest.raises(gfcs.InvalidValueError, match="invalid threads"):
        fabric.evaluate(q, q, q, cands, threads=2.5)
    with pytest.raises(gfcs.InvalidValueError, match=r"invalid iterations: .* got -1"):
        panda.inverse_kinematics(q, [0.4, 0.0, 0.4], iterations=-1)
    with pytest.raises(gfcs.InvalidValueError, match=r"invalid link: .* got -1"):
        panda.point_jacobian(q, link=-1)
    with pytest.raises(gfcs.InvalidValueError, match=r"invalid link: .* got 1e\+30|invalid link"):
        panda.point_jacobian(q, link=10**30)
    scene = gfcs.Scene()
    with pytest.raises(gfcs.InvalidValueError, match=r"invalid id: .* got -1"):
        scene.remove(-1)
    with pytest.raises(gfcs.InvalidValueError, match=r"invalid id: .* got True"):
        scene.get(True)
    with pytest.raises(gfcs.InvalidValueError, match="invalid id"):
        fabric.update_obstacle(-3, velocity=[0, 0, 0])


@pytest.mark.parametrize("args", [["bench", "--limit", "-1"], ["bench", "--skip", "-1"],
                                  ["solve", "--threads", "-1"], ["solve", "--batches", "0"],
                                  ["generate", "--out", "x", "--n", "-2"]])
def test_cli_integer_options_are_checked(args):
    r = run(*args, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    option = next(a for a in args if a.startswith("--") and a != "--out" or a == "--n")
    assert f"argument {option}" in r.stderr and "must be >=" in r.stderr


def test_threads_above_the_cap_warn_and_give_the_same_costs(panda, fabric):
    rng = np.random.default_rng(0)
    q = np.zeros(panda.dof)
    cands = rng.uniform(panda.lower, panda.upper, size=(3, panda.dof))
    base = fabric.evaluate(q, q, q, cands, t_max=0.5, threads=1)
    start = time.perf_counter()
    with pytest.warns(GfcsWarning, match=r"threads=100000 exceeds 4 x the \d+ cores"):
        capped = fabric.evaluate(q, q, q, cands, t_max=0.5, threads=100_000)
    with pytest.warns(GfcsWarning, match="threads=100000"):  # every call warns; the pool is built once
        for _ in range(5):
            fabric.evaluate(q, q, q, cands, t_max=0.5, threads=100_000)
    assert time.perf_counter() - start < 30.0
    np.testing.assert_array_equal(np.asarray(base[0]), np.asarray(capped[0]))


def test_a_solve_above_the_thread_cap_warns_once():
    import warnings

    from gfcs import _core, generators
    from gfcs.planning import solve

    problem = generators.generate("box", 1, seed=0, robot=gfcs.Robot.panda())[0]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        solve(problem, batches=1, population=4, threads=10 * _core.max_threads())
    assert sum("exceeds 4 x" in str(w.message) for w in caught) == 1


@pytest.mark.parametrize("seed", [None, -1, 1.5, "7"])
def test_a_solve_names_a_seed_that_is_not_a_non_negative_integer(seed):
    from gfcs import generators
    from gfcs.planning import solve

    problem = generators.generate("box", 1, seed=0, robot=gfcs.Robot.panda())[0]
    with pytest.raises(gfcs.InvalidValueError, match=r"seed must be an integer ≥ 0, got"):
        solve(problem, batches=1, population=4, seed=seed)


# ----------------------------------------------------------------------------------- bench survival
def test_bench_records_a_malformed_problem_and_goes_on(tmp_path, capsys):
    assert cli.main(["generate", "--out", str(tmp_path / "suite"), "--classes", "box", "--n", "2"]) == 0
    (tmp_path / "suite" / "box" / "scene0002.yaml").write_text("world:\n  collision_objects: [{id: 3}]\n")
    rows_file = tmp_path / "rows.jsonl"
    code = cli.main(["bench", "--problems", str(tmp_path / "suite"), "--method", "gf", "--json", str(rows_file),
                     "--no-progress"])
    assert code == 0
    rows = read_rows(rows_file.read_text().splitlines())
    assert rows[0]["problem"] == "box/0002" and "scene0002.yaml" in rows[0]["left_out"]
    assert [(r["problem"], r["label"]) for r in rows[1:]] == [("box/0001", "GF")]
    assert "scene0002.yaml: field 'world.collision_objects[0].id'" in capsys.readouterr().err


def test_bench_records_a_problem_whose_solve_fails_and_goes_on(tmp_path, monkeypatch, capsys):
    from gfcs import generators, planning

    suite = generators.generate("box", 2, seed=0)
    real = planning.solve

    def solve(problem, *args, **kwargs):
        if problem.name == suite[0].name:
            raise gfcs.InvalidValueError("qd0: deliberately unreachable start")
        return real(problem, *args, **kwargs)

    monkeypatch.setattr(planning, "solve", solve)
    rows = bench.run_bench(suite, ["gf"], batches=1, population=4, progress=False,
                         jsonl=str(tmp_path / "rows.jsonl"))
    assert [r["problem"] for r in rows] == [suite[0].name, suite[1].name]
    assert rows[0]["success"] is False and "deliberately unreachable" in rows[0]["error"]
    assert math.isnan(rows[0]["time"]) and "error" not in rows[1]
    assert f"gfcs: bench: {suite[0].name}: InvalidValueError" in capsys.readouterr().err
    assert len(read_rows((tmp_path / "rows.jsonl").read_text().splitlines())) == 2


@pytest.mark.parametrize("option", ["--json", "--rrd"])
def test_solve_checks_output_paths_before_solving(tmp_path, option):
    target = tmp_path / "no" / "such" / "dir" / "out.x"
    start = time.perf_counter()
    r = run("solve", option, str(target), "--batches", "50", timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert f"{option} {target}: directory" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert time.perf_counter() - start < 60.0


def test_config_refuses_mass_min_above_mass_max():
    with pytest.raises(gfcs.GfcsError, match=r"ee_position\.mass_min.*mass_max"):
        gfcs.FabricConfig({"ee_position": {"mass_min": 3.0, "mass_max": 2.0}})


# ------------------------------------------------------------------------------- property tests
finite = st.floats(allow_nan=True, allow_infinity=True, width=64)
arrays = hnp.arrays(np.float64, hnp.array_shapes(min_dims=0, max_dims=3, max_side=9), elements=finite)


@PROPERTY
@given(q=arrays)
def test_any_array_gives_poses_or_a_gfcs_error(panda, q):
    try:
        out = panda.link_poses(q)
    except gfcs.GfcsError:
        return
    assert np.all(np.isfinite(out))


@PROPERTY
@given(q=arrays, qd=arrays, command=arrays)
def test_any_arrays_give_an_acceleration_or_a_gfcs_error(fabric, q, qd, command):
    try:
        qdd = fabric.acceleration(q, qd, command)
    except gfcs.GfcsError:
        return
    assert qdd.shape == (7,)


@PROPERTY
@given(points=arrays)
def test_any_points_give_distances_or_a_gfcs_error(points):
    scene = gfcs.Scene()
    scene.add_box([0.2, 0.2, 0.2])
    try:
        scene.signed_distance(points)
    except gfcs.GfcsError:
        pass


@PROPERTY
@given(positions=st.dictionaries(st.sampled_from(["panda_finger_joint1", "panda_finger_joint2", "panda_joint1",
                                                  "nope", ""]) | st.text(max_size=8), finite, max_size=3))
def test_any_locked_positions_give_a_robot_or_a_gfcs_error(panda, positions):
    try:
        robot = panda.with_locked_positions(positions)
    except gfcs.GfcsError:
        return
    for name, value in robot.locked_positions.items():
        assert math.isfinite(value)


config_values = st.recursive(st.none() | st.booleans() | st.integers() | finite | st.text(max_size=5),
                             lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8),
                                                                                        inner, max_size=3),
                             max_leaves=10)


@PROPERTY
@given(values=st.dictionaries(st.sampled_from(["speed", "ee_position", "obstacles", "joint_attraction", "x"]),
                              config_values, max_size=3))
def test_any_config_dict_gives_a_config_or_a_gfcs_error(values):
    try:
        gfcs.FabricConfig(values)
    except gfcs.GfcsError:
        pass


@PROPERTY
@given(name=st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"),
                    min_size=1, max_size=30))
def test_any_path_gives_a_gfcs_error_naming_it(tmp_path_factory, name):
    path = str(tmp_path_factory.getbasetemp() / "missing" / name)
    for load in (gfcs.Robot.from_urdf, gfcs.Scene.from_moveit_yaml, gfcs.load_motion_plan_request):
        with pytest.raises(gfcs.GfcsError):
            load(path)


@PROPERTY
@given(value=st.integers(min_value=-2**70, max_value=2**70) | st.booleans() | st.floats() | st.text(max_size=3))
def test_any_integer_argument_gives_a_result_or_a_named_error(panda, value):
    scene = gfcs.Scene()
    scene.add_sphere([0, 0, 0], 0.1)
    for call, name in ((lambda: scene.get(value), "id"),
                       (lambda: panda.point_jacobian(np.zeros(7), link=value), "link")):
        try:
            call()
        except gfcs.InvalidValueError as e:  # a bad argument, or an id the scene does not have
            assert f"invalid {name}" in str(e) or f"invalid obstacle {name}" in str(e)
        except gfcs.LinkError:
            assert isinstance(value, (int, str)) and not isinstance(value, bool)
