"""tools/check_trajectories.py, the validator that shares no code with gfcs (yourdfpy, trimesh, FCL, PyYAML):
closed-form distances on a one-joint robot, its failure modes, its exact branch-and-bound minimum, MoveIt pose
goals on a three-joint arm (poses from yourdfpy), and its agreement with what gfcs reports on MotionBenchMaker
problems (skip without ../shared, fail under CI=true)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("fcl", reason="python-fcl (the 'test' extra) is the validator's distance library")
trimesh = pytest.importorskip("trimesh")
yourdfpy = pytest.importorskip("yourdfpy")

from conftest import load_script  # noqa: E402

ct = load_script("tools/check_trajectories.py")

# One prismatic joint x moves `link` (a 0.2 m cube centred at (x, 0, 0)); `post` (a 0.1 m cube) is fixed at
# (-0.5, 0, 0); the scene holds a 0.2 m cube at (1, 0, 0). Closed forms for x in (-0.35, 0.8):
# clearance to the obstacle 0.8 - x, between the links x + 0.35.
URDF = """<robot name="slider"><link name="base"/>
  <link name="link"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="post"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="link"/><axis xyz="1 0 0"/>
    <limit lower="-0.3" upper="0.9" velocity="1" effort="1"/></joint>
  <joint name="fix" type="fixed"><parent link="base"/><child link="post"/><origin xyz="-0.5 0 0"/></joint>
</robot>"""
SCENE = """world:
  collision_objects:
    - id: wall
      primitive_poses: [{position: [1.0, 0, 0], orientation: [0, 0, 0.3826834, 0.9238795]}]
      primitives: [{type: box, dimensions: [0.2, 0.2, 0.2]}]
"""


def request(start: float, goal: float) -> str:
    return (f"start_state: {{joint_state: {{name: [x], position: [{start}]}}}}\n"
            f"goal_constraints: [{{joint_constraints: [{{joint_name: x, position: {goal}}}]}}]\n")


def write_result(tmp_path: Path, problem: str, method: str, q: np.ndarray, success: bool) -> Path:
    """A result file as ``gfcs bench --results-dir`` writes it: states ``q`` (T, dof) 0.1 s apart."""
    result = {"problem": problem, "method": method, "success": success,
              "trajectory": {"t": (0.1 * np.arange(len(q))).tolist(), "q": q.tolist()}}
    out = tmp_path / "results" / f"{problem.replace('/', '_')}.{method}.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(result))
    return out


@pytest.fixture
def slider(tmp_path):
    """(problems folder, URDF path, write(result name, q path, start, goal, success) -> result file)."""
    (tmp_path / "robot.urdf").write_text(URDF)
    folder = tmp_path / "problems" / "slide"
    folder.mkdir(parents=True)

    def write(number: str, q, start: float, goal: float, success: bool = True) -> Path:
        (folder / f"scene{number}.yaml").write_text(SCENE)
        (folder / f"request{number}.yaml").write_text(request(start, goal))
        return write_result(tmp_path, f"slide/{number}", "gf", np.asarray(q, dtype=float).reshape(-1, 1), success)

    return tmp_path / "problems", tmp_path / "robot.urdf", write


def run(slider, files, *extra, ee="link"):
    problems, urdf, _ = slider
    out = Path(files[0]).parent / "checked.jsonl"
    code = ct.main(["--problems", str(problems), "--urdf", str(urdf), "--ee-link", ee, "--jobs", "1",
                    "--json", str(out), *map(str, files), *extra])
    return code, [json.loads(line) for line in out.read_text().splitlines()]


def test_closed_form_clearances_lengths_and_verdict(slider):
    # the obstacle is turned 45 degrees about z: its nearest point to the link is a vertical edge at
    # x = 1 - 0.1*sqrt(2), so the clearance is 0.9 - 0.1*sqrt(2) - x
    f = slider[2]("0001", np.linspace(0.0, 0.5, 51), 0.0, 0.5)
    code, [r] = run(slider, [f])
    assert code == 0 and r["valid"] and r["claimed_success"]
    assert r["clearance"] == pytest.approx(0.9 - 0.1 * math.sqrt(2) - 0.5, abs=1e-9)
    assert r["closest_state"] == 50 and r["closest_obstacle"] == "link / wall"
    assert r["self_clearance"] == pytest.approx(0.35, abs=1e-9) and r["closest_links"] == ["link", "post"]
    assert r["ee_length"] == pytest.approx(0.5) and r["cspace_length"] == pytest.approx(0.5)
    assert r["goal_error"] == 0.0 and r["start_error"] == 0.0
    assert r["limit_margin"] == pytest.approx(0.3) and r["speed_ratio"] == pytest.approx(0.1)
    assert r["fk_error"] < 1e-12


def test_contact_start_goal_and_limits_make_a_claim_invalid(slider):
    write = slider[2]
    files = [
        write("0001", np.linspace(0.0, 0.8, 9), 0.0, 0.8),  # reaches the obstacle's edge region: contact
        write("0002", np.linspace(0.1, 0.4, 4), 0.0, 0.4),  # does not start at the start
        write("0003", np.linspace(0.0, 0.4, 4), 0.0, 0.45),  # stops 0.05 rad short
        write("0004", np.linspace(0.0, -0.31, 4), 0.0, -0.31),  # leaves the lower limit
        write("0005", np.linspace(0.0, 0.8, 9), 0.0, 0.8, success=False),  # contact, not claimed
    ]
    code, rows = run(slider, files)
    assert code == 1
    assert [r["valid"] for r in rows] == [False] * 5
    assert rows[0]["clearance"] == 0.0
    assert rows[1]["start_error"] == pytest.approx(0.1)
    assert rows[2]["goal_error"] == pytest.approx(0.05)
    assert rows[3]["limit_margin"] == pytest.approx(-0.01)
    # only the unclaimed failure: nothing claimed is wrong, the run passes
    assert run(slider, files[4:])[0] == 0


def test_unreadable_results_are_reported_not_raised(slider, tmp_path):
    bad = tmp_path / "results" / "bad.json"
    bad.parent.mkdir(exist_ok=True)
    bad.write_text(json.dumps({"problem": "slide/0009", "success": True, "trajectory": {"t": [0], "q": [[0]]}}))
    code, [r] = run(slider, [bad])
    assert code == 2 and "no " in r["error"] and "scene0009.yaml" in r["error"]


def test_a_robot_without_the_end_effector_link_is_one_clear_error(slider, capsys):
    """The model is loaded before the worker pool: a pool whose initializer raises respawns its workers
    forever."""
    _, _, write = slider
    with pytest.raises(SystemExit) as e:
        run(slider, [write("0001", [0.0, 0.1], 0.0, 0.1)], ee="panda_hand")
    assert e.value.code == 2
    assert "no link 'panda_hand' (--ee-link); its links: base, link, post" in capsys.readouterr().err


def test_branch_and_bound_finds_the_exact_minimum():
    rng = np.random.default_rng(3)
    for _ in range(20):
        bounds = rng.normal(size=(7, 5, 3))
        exact_values = bounds + rng.exponential(0.5, size=bounds.shape)
        calls = []

        def exact(*i):
            calls.append(i)
            return float(exact_values[i])

        best, where = ct.smallest(bounds, exact)
        assert best == exact_values.min() and exact_values[where] == best
        assert len(calls) < bounds.size


def test_agrees_with_gfcs_on_motionbenchmaker(mbm_dir, mbm_panda_dir, tmp_path, monkeypatch):
    """The returned motions of both methods on two MBM problems: the validator's verdict equals the claimed
    success, and its mesh clearance, path lengths and kinematics equal gfcs's own to round-off."""
    # `--robot mbm` finds the shared folder through GFCS_SHARED when gfcs is installed outside the checkout (CI).
    monkeypatch.setenv("GFCS_SHARED", str(mbm_panda_dir.parent.parent))
    from gfcs import cli

    out = tmp_path / "res"
    cli.main(["bench", "--problems", str(mbm_dir), "--robot", "mbm", "--classes", "table_under_pick", "box",
              "--limit", "1", "--batches", "1", "--method", "gf", "gfcs", "--results-dir", str(out),
              "--no-progress"])
    files = sorted(out.glob("*.json"))
    assert [f.name for f in files] == ["box_0001.gf.json", "box_0001.gfcs.json", "table_under_pick_0001.gf.json",
                                       "table_under_pick_0001.gfcs.json"]
    code = ct.main(["--problems", str(mbm_dir), "--urdf", str(mbm_panda_dir / "panda.urdf"),
                    "--srdf", str(mbm_panda_dir / "panda.srdf"), "--json", str(tmp_path / "c.jsonl"),
                    "--jobs", "1", str(out)])
    rows = [json.loads(line) for line in (tmp_path / "c.jsonl").read_text().splitlines()]
    assert code == 0 and len(rows) == 4
    assert sum(r["valid"] for r in rows) >= 3  # GF fails table under (the paper's pattern); GFCS solves it
    for r in rows:
        result = json.loads(Path(r["file"]).read_text())
        m = result["metrics"]
        assert r["valid"] == result["success"], r
        assert r["fk_error"] < 1e-9 and r["start_error"] == 0.0
        assert r["ee_length"] == pytest.approx(m["ee_length"], abs=1e-9)
        assert r["cspace_length"] == pytest.approx(m["cspace_length"], abs=1e-9)
        # FCL reports contact as 0, gfcs the penetration depth; GJK on cylinders differs by up to 11 µm
        # (all 700 motions of Table I)
        # gfcs measures mesh clearances exactly up to metrics.mesh_report_cutoff, and reports inf beyond
        from gfcs.metrics import DEFAULT_MESH_MARGIN, mesh_report_cutoff

        for mine, theirs in ((m["mesh_clearance"], r["clearance"]), (m["mesh_self_clearance"], r["self_clearance"])):
            mine = float(mine)
            if math.isinf(mine):
                assert theirs > mesh_report_cutoff(DEFAULT_MESH_MARGIN) - 2e-5
            else:
                assert theirs == pytest.approx(max(mine, 0.0), abs=2e-5)


# ------------------------------------------------------------------------------------------ pose goals
# Three revolute joints (z, y, x) and a fixed, tilted `tool`; small spheres keep the links apart, the scene
# is empty. Goal poses come from yourdfpy's forward kinematics, not from the validator's.
ARM = """<robot name="arm"><link name="base"/>
  <link name="l1"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
  <link name="l2"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
  <link name="l3"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
  <link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="10" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3" rpy="0.1 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" velocity="10" effort="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.3 0 0"/>
    <axis xyz="1 0 0"/><limit lower="-3" upper="3" velocity="10" effort="1"/></joint>
  <joint name="mount" type="fixed"><parent link="l3"/><child link="tool"/><origin xyz="0.1 0 0" rpy="0 0.3 0.2"/></joint>
</robot>"""
ARM_JOINTS = ["j1", "j2", "j3"]
Q_GOAL = np.array([0.4, -0.3, 0.7])
OFFSET = np.array([0.05, -0.02, 0.03])  # the constrained point in the tool frame


@pytest.fixture
def arm(tmp_path):
    """(problems folder, URDF path, write(number, final q, goal constraints, success) -> result file); the
    motion goes in 10 states from 0 (the request's start) to the final q."""
    (tmp_path / "arm.urdf").write_text(ARM)
    folder = tmp_path / "problems" / "reach"
    folder.mkdir(parents=True)

    def write(number: str, q_final, goal: dict, success: bool = True) -> Path:
        (folder / f"scene{number}.yaml").write_text("world:\n  collision_objects: []\n")
        req = {"start_state": {"joint_state": {"name": ARM_JOINTS, "position": [0.0, 0.0, 0.0]}},
               "goal_constraints": [goal]}
        (folder / f"request{number}.yaml").write_text(yaml.safe_dump(req))
        q = np.linspace(np.zeros(3), np.asarray(q_final, dtype=float), 10)
        return write_result(tmp_path, f"reach/{number}", "gfcs", q, success)

    return tmp_path / "problems", tmp_path / "arm.urdf", write


def tool_pose(urdf: Path, q) -> np.ndarray:
    """The tool's world pose by yourdfpy."""
    robot = yourdfpy.URDF.load(str(urdf), load_meshes=False, build_collision_scene_graph=False,
                               load_collision_meshes=False)
    robot.update_cfg(dict(zip(ARM_JOINTS, map(float, q))))
    return robot.get_transform("tool", robot.base_link)


def xyzw(R: np.ndarray) -> list:
    w, x, y, z = trimesh.transformations.quaternion_from_matrix(R)
    return [float(x), float(y), float(z), float(w)]


def rotation(axis, angle: float) -> np.ndarray:
    return trimesh.transformations.rotation_matrix(angle, np.asarray(axis, dtype=float))[:3, :3]


def position_constraint(primitives, poses, offset=OFFSET, frame="world") -> dict:
    return {"link_name": "tool", "header": {"frame_id": frame}, "weight": 1.0,
            "target_point_offset": dict(zip("xyz", map(float, offset))),
            "constraint_region": {"primitives": primitives, "primitive_poses": poses}}


def orientation_constraint(R: np.ndarray, tol=(0.01, 0.01, 0.01), parameterization=None, frame="world") -> dict:
    c = {"link_name": "tool", "header": {"frame_id": frame}, "orientation": xyzw(R), "weight": 1.0,
         **{f"absolute_{a}_axis_tolerance": float(t) for a, t in zip("xyz", tol)}}
    if parameterization is not None:
        c["parameterization"] = parameterization
    return c


BOX_TURN = rotation([0, 0, 1], math.radians(30))  # the box region is turned 30 degrees about z


def full_pose_goal(urdf: Path) -> dict:
    """Position (a 1 cm box about the offset point of the tool at Q_GOAL, or a far sphere) and orientation
    (the tool's, 0.01 rad per axis)."""
    T = tool_pose(urdf, Q_GOAL)
    centre = T[:3, :3] @ OFFSET + T[:3, 3] + [0.002, 0, 0]
    box = {"position": dict(zip("xyz", map(float, centre))), "orientation": dict(zip("xyzw", xyzw(BOX_TURN)))}
    far = {"position": [1.0, 1.0, 1.0], "orientation": [0, 0, 0, 1]}
    return {"position_constraints": [position_constraint([{"type": "box", "dimensions": [0.01] * 3},
                                                          {"type": 2, "dimensions": [0.1]}], [box, far])],
            "orientation_constraints": [orientation_constraint(T[:3, :3])], "joint_constraints": []}


def test_pose_goal_with_offset_and_orientation_is_reached(arm):
    f = arm[2]("0001", Q_GOAL, full_pose_goal(arm[1]))
    code, [r] = run(arm, [f], ee="tool")
    assert code == 0 and r["valid"] and r["goal_reached"], r
    assert r["goal_kind"] == "pose" and r["goal_link"] == "tool" and r["goal_error"] is None
    assert r["goal_position_error"] == 0.0 and r["goal_orientation_error"] == 0.0
    assert np.abs(r["goal_orientation_components"]).max() < 1e-9
    assert r["fk_error"] < 1e-12 and r["start_error"] == 0.0 and r["clearance"] == math.inf


def test_perturbed_final_state_misses_the_pose_goal(arm, capsys):
    q = Q_GOAL + [0.05, 0.0, 0.0]
    f = arm[2]("0002", q, full_pose_goal(arm[1]))
    code, [r] = run(arm, [f], ee="tool")
    assert code == 1 and not r["valid"] and not r["goal_reached"] and r["claimed_success"]
    # expected miss from yourdfpy: the offset point against the turned box (the far sphere is farther)
    T, T_goal = tool_pose(arm[1], q), tool_pose(arm[1], Q_GOAL)
    p = T[:3, :3] @ OFFSET + T[:3, 3]
    centre = T_goal[:3, :3] @ OFFSET + T_goal[:3, 3] + [0.002, 0, 0]
    outside = np.maximum(np.abs(BOX_TURN.T @ (p - centre)) - 0.005, 0)
    assert r["goal_position_error"] == pytest.approx(np.linalg.norm(outside), abs=1e-9)
    assert r["goal_position_error"] > 0.005
    # 0.05 rad about the world z: at least 0.05/sqrt(3) about one of the target's axes
    assert 0.015 < r["goal_orientation_error"] < 0.05
    err = capsys.readouterr().err
    assert "1 claim success, 0 of them valid here, 1 not" in err and "max pose goal error" in err
    assert f"NOT VALID: {f}: start_error=0, goal_position_error=" in err
    # not claimed: no fault of the run
    assert run(arm, [arm[2]("0003", q, full_pose_goal(arm[1]), success=False)], ee="tool")[0] == 0


@pytest.mark.parametrize("primitive, pose, shift, expected", [
    ({"type": "SPHERE", "dimensions": [0.004]}, [0, 0, 0, 1], [0, 0, 0.003], 0.0),
    ({"type": "sphere", "dimensions": [0.004]}, [0, 0, 0, 1], [0, 0, 0.007], 0.003),
    # a cylinder (height 2 cm, radius 4 mm) whose axis is turned from z to x
    ({"type": 3, "dimensions": [0.02, 0.004]}, xyzw(rotation([0, 1, 0], math.pi / 2)), [0.009, 0, 0], 0.0),
    ({"type": "Cylinder", "dimensions": [0.02, 0.004]}, xyzw(rotation([0, 1, 0], math.pi / 2)), [0.012, 0, 0], 0.002),
    ({"type": 3, "dimensions": [0.02, 0.004]}, xyzw(rotation([0, 1, 0], math.pi / 2)), [0, 0.006, 0], 0.002),
    ({"type": 1, "dimensions": [0.01, 0.02, 0.04]}, [0, 0, 0, 1], [0.004, -0.009, 0.019], 0.0),
])
def test_position_only_goal(arm, primitive, pose, shift, expected):
    T = tool_pose(arm[1], Q_GOAL)
    offset = [0.0, 0.1, 0.0]
    centre = T[:3, :3] @ offset + T[:3, 3] - np.asarray(shift)  # the point is `shift` from the centre
    goal = {"position_constraints": [position_constraint([primitive], [{"position": centre.tolist(),
                                                                        "orientation": pose}], offset, frame="")]}
    code, [r] = run(arm, [arm[2]("0004", Q_GOAL, goal)], ee="tool")
    assert r["goal_kind"] == "pose" and r["goal_orientation_error"] == 0.0
    assert r["goal_orientation_components"] is None
    assert r["goal_position_error"] == pytest.approx(expected, abs=1e-9)
    assert r["goal_reached"] == r["valid"] == (expected == 0.0) and code == (0 if expected == 0.0 else 1)


@pytest.mark.parametrize("tol, reached, error", [((0.065, 0.001, 0.085), True, 0.0),
                                                 ((0.055, 0.001, 0.085), False, 0.005)])
def test_rotation_vector_parameterization(arm, tol, reached, error):
    # target R* = R · Rot(a, 0.1)ᵀ, so D = R*ᵀ R = Rot(a, 0.1), whose rotation vector is 0.1 · a
    T = tool_pose(arm[1], Q_GOAL)
    axis = np.array([0.6, 0.0, 0.8])
    target = T[:3, :3] @ rotation(axis, 0.1).T
    point = T[:3, :3] @ OFFSET + T[:3, 3]
    goal = {"position_constraints": [position_constraint([{"type": "sphere", "dimensions": [0.001]}],
                                                         [{"position": point.tolist(), "orientation": [0, 0, 0, 1]}])],
            "orientation_constraints": [orientation_constraint(target, tol, parameterization=1, frame="base")]}
    code, [r] = run(arm, [arm[2]("0005", Q_GOAL, goal)], ee="tool")
    assert r["goal_orientation_components"] == pytest.approx([0.06, 0.0, 0.08], abs=1e-9)
    assert r["goal_position_error"] == 0.0
    assert r["goal_orientation_error"] == pytest.approx(error, abs=1e-9)
    assert r["goal_reached"] == r["valid"] == reached and code == (0 if reached else 1)


def test_unsupported_pose_goals_are_errors_for_their_result(arm):
    write, good = arm[2], full_pose_goal(arm[1])
    frame = json.loads(json.dumps(good))
    frame["orientation_constraints"][0]["header"]["frame_id"] = "panda_link0"
    two = json.loads(json.dumps(good))
    two["position_constraints"] *= 2
    link = json.loads(json.dumps(good))
    for c in link["position_constraints"] + link["orientation_constraints"]:
        c["link_name"] = "gripper"
    both = {**good, "joint_constraints": [{"joint_name": "j1", "position": 0.4}]}
    files = [write("0006", Q_GOAL, frame), write("0007", Q_GOAL, two), write("0008", Q_GOAL, link),
             write("0009", Q_GOAL, both), write("0010", Q_GOAL, good)]
    code, rows = run(arm, files, ee="tool")
    assert code == 2
    assert "frame 'panda_link0' is not supported" in rows[0]["error"]
    assert "orientation_constraints[0].header.frame_id" in rows[0]["error"]
    assert "one position constraint is supported, got 2" in rows[1]["error"]
    assert "goal link 'gripper' is not a link" in rows[2]["error"]
    assert "joint constraints together with position or orientation constraints" in rows[3]["error"]
    assert "error" not in rows[4] and rows[4]["valid"]


def rx(a):
    return rotation([1, 0, 0], a)


def ry(a):
    return rotation([0, 1, 0], a)


def rz(a):
    return rotation([0, 0, 1], a)


def test_xyz_euler_angles_of_known_rotations():
    # a small rotation: its own angles
    assert ct.xyz_euler(rx(0.03) @ ry(-0.02) @ rz(0.05)) == pytest.approx([0.03, -0.02, 0.05], abs=1e-12)
    # |b| > pi/2: (a + pi, pi - b, c + pi) is the other representation, larger here
    assert ct.xyz_euler(rx(0.1) @ ry(2.0) @ rz(-0.2)) == pytest.approx([0.1, 2.0, -0.2], abs=1e-12)
    # (2.5, 0.3, -2.9) is the larger of the two: the smaller one is returned, and gives the same rotation
    D = rx(2.5) @ ry(0.3) @ rz(-2.9)
    a, b, c = ct.xyz_euler(D)
    assert [a, b, c] == pytest.approx([2.5 - math.pi, math.pi - 0.3, -2.9 + math.pi], abs=1e-12)
    assert rx(a) @ ry(b) @ rz(c) == pytest.approx(D, abs=1e-12)


def test_rotation_vector_of_known_rotations():
    axis = np.array([2.0, -1.0, 0.5]) / np.linalg.norm([2.0, -1.0, 0.5])
    for angle in (0.0, 1e-8, 0.1, 3.0):
        assert ct.rotation_vector(rotation(axis, angle)) == pytest.approx(angle * axis, abs=1e-12)
    v = ct.rotation_vector(rotation(axis, math.pi))  # either sign at pi
    assert np.abs(v) == pytest.approx(math.pi * np.abs(axis), abs=1e-9)


def test_speed_beyond_the_velocity_limit_is_invalid_and_a_rounded_start_on_a_bound_matches(slider):
    write = slider[2]
    fast = write("0001", np.linspace(0.0, 0.5, 3), 0.0, 0.5)  # 0.25 rad per 0.1 s: 2.5 x the 1 rad/s limit
    rounded = write("0002", np.linspace(-0.3, 0.0, 31), -0.3004, 0.0)  # request 0.4 mrad below the bound
    outside = write("0003", np.linspace(-0.3, 0.0, 31), -0.31, 0.0)  # 10 mrad below: no match
    code, rows = run(slider, [fast, rounded, outside])
    assert code == 1
    assert rows[0]["speed_ratio"] == pytest.approx(2.5) and not rows[0]["valid"]
    assert rows[1]["start_error"] == 0.0 and rows[1]["valid"]
    assert rows[2]["start_error"] == pytest.approx(0.01) and not rows[2]["valid"]


def test_the_verdict_without_speeds_judges_the_path_alone():
    row = {"start_error": 0.0, "goal_reached": True, "limit_margin": 0.01, "speed_ratio": 3.5,
           "clearance": 0.004, "self_clearance": 0.01}
    assert not ct.is_valid(row) and ct.is_valid(row, speed=False)
    assert ct.is_valid(dict(row, speed_ratio=1.0))
    for key, bad in (("clearance", 0.0), ("self_clearance", -1e-4), ("goal_reached", False),
                     ("limit_margin", -1e-3), ("start_error", 1e-3)):
        assert not ct.is_valid(dict(row, **{key: bad}), speed=False), key


def test_links_of_one_rigid_body_are_not_checked_against_each_other(tmp_path):
    # the post split into two touching boxes joined by a fixed joint (as some URDFs split a part's meshes)
    split = URDF.replace("</robot>", """<link name="post_2"><collision><origin xyz="0 0 0.1"/>
      <geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
      <joint name="fix2" type="fixed"><parent link="post"/><child link="post_2"/></joint></robot>""")
    (tmp_path / "split.urdf").write_text(split)
    robot = yourdfpy.URDF.load(str(tmp_path / "split.urdf"), load_meshes=False).robot
    assert ct.rigid_link_pairs(robot.joints) == {frozenset(p) for p in
                                                 (("base", "post"), ("base", "post_2"), ("post", "post_2"))}
    default = ct.RobotModel(tmp_path / "split.urdf", None, "link")
    assert frozenset(("post", "post_2")) in default.disabled and frozenset(("link", "post")) not in default.disabled
    strict = ct.RobotModel(tmp_path / "split.urdf", None, "link", rigid_pairs=True)
    assert frozenset(("post", "post_2")) not in strict.disabled


def test_joints_the_trajectory_does_not_move_stay_at_the_request_start(slider, tmp_path):
    """A second slider y carries a 0.2 m cube `holder` along z; the result's trajectory moves x alone. Held at
    y = 0 (the request names no y, or names 0) the holder's cube sits on the link's; the request's start at
    y = 0.5 lifts it 0.3 m clear, as MoveIt keeps a joint outside the group where the start state holds it."""
    problems, _, _ = slider
    held = URDF.replace("</robot>", """<link name="holder"><collision><geometry><box size="0.2 0.2 0.2"/></geometry>
      </collision></link>
      <joint name="y" type="prismatic"><parent link="base"/><child link="holder"/><axis xyz="0 0 1"/>
        <limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>""")
    urdf = tmp_path / "held.urdf"
    urdf.write_text(held)
    folder = problems / "slide"
    folder.mkdir(parents=True, exist_ok=True)
    verdicts = {}
    for number, y in (("0001", 0.5), ("0002", 0.0)):
        (folder / f"scene{number}.yaml").write_text(SCENE)
        (folder / f"request{number}.yaml").write_text(
            f"start_state: {{joint_state: {{name: [x, y], position: [0.0, {y}]}}}}\n"
            "goal_constraints: [{joint_constraints: [{joint_name: x, position: 0.1}]}]\n")
        out = write_result(tmp_path, f"slide/{number}", "gf", np.linspace(0.0, 0.1, 5).reshape(-1, 1), True)
        doc = json.loads(out.read_text())
        doc["trajectory"]["joint_names"] = ["x"]
        out.write_text(json.dumps(doc))
        checked = out.parent / f"checked{number}.jsonl"
        ct.main(["--problems", str(problems), "--urdf", str(urdf), "--ee-link", "link", "--jobs", "1",
                 "--json", str(checked), str(out)])
        verdicts[y] = json.loads(checked.read_text().splitlines()[0])
    assert verdicts[0.5]["valid"] and verdicts[0.5]["self_clearance"] == pytest.approx(0.3, abs=1e-6)
    assert not verdicts[0.0]["valid"] and verdicts[0.0]["self_clearance"] <= 0.0


def test_ros_package_finds_a_package_by_its_package_xml_name(tmp_path, monkeypatch):
    """The validator finds package://pkg/... as ROS does (independently of the core's resolution): the folder of
    the package.xml naming pkg below the mesh directory or a ROS_PACKAGE_PATH root, hidden folders skipped."""
    pkg = tmp_path / "ws" / "src" / "arm"
    pkg.mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name> moveit_resources_arm </name></package>")
    hidden = tmp_path / "ws" / ".git" / "other"
    hidden.mkdir(parents=True)
    (hidden / "package.xml").write_text("<package><name>other</name></package>")
    assert ct.ros_package("moveit_resources_arm", tmp_path / "ws") == pkg
    assert ct.ros_package("other", tmp_path / "ws") is None
    assert ct.ros_package("moveit_resources_arm", tmp_path / "nowhere") is None
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path / "ws"))
    assert ct.ros_package("moveit_resources_arm", tmp_path / "nowhere") == pkg
