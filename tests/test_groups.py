"""SRDF planning groups (gfcs.srdf_groups), the two-arm robot built from the shipped Panda, the hand paths of
several end effectors in the metrics, and the CLI's group taken from a request's group_name."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

import gfcs
from gfcs import bench, cli, generators, metrics, optimize, srdf_groups
from gfcs.errors import FormatError, GfcsWarning, IoError, LinkError

from conftest import require_shared

# world -fixed- base; base -a1 (revolute)- a1l -a2 (prismatic)- a2l -fixed- a_tool, a2l -a_mimic- a_m;
# base -b1 (continuous)- b1l -b2 (revolute)- b2l
URDF = """<robot name="forked">
  <link name="world"/><link name="base"/><link name="a1l"/><link name="a2l"/><link name="a_tool"/>
  <link name="a_m"/><link name="b1l"/><link name="b2l"/>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base"/></joint>
  <joint name="a1" type="revolute"><parent link="base"/><child link="a1l"/><origin xyz="0 0.2 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <joint name="a2" type="prismatic"><parent link="a1l"/><child link="a2l"/><origin xyz="0.3 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.2" velocity="0.1" effort="1"/></joint>
  <joint name="a_tip" type="fixed"><parent link="a2l"/><child link="a_tool"/><origin xyz="0.1 0 0"/></joint>
  <joint name="a_mimic" type="revolute"><parent link="a2l"/><child link="a_m"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" velocity="1" effort="1"/><mimic joint="a1" multiplier="1" offset="0"/></joint>
  <joint name="b1" type="continuous"><parent link="base"/><child link="b1l"/><origin xyz="0 -0.2 0.1"/>
    <axis xyz="0 0 1"/><limit velocity="1" effort="1"/></joint>
  <joint name="b2" type="revolute"><parent link="b1l"/><child link="b2l"/><origin xyz="0.3 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>"""

SRDF = """<robot name="forked">
  <group name="arm_a"><chain base_link="base" tip_link="a_tool"/></group>
  <group name="arm_b"><joint name="b2"/><joint name="b1"/><joint name="ghost_joint"/><link name="ghost_link"/></group>
  <group name="arm_b_links"><link name="b1l"/><link name="b2l"/></group>
  <group name="both"><group name="arm_a"/><group name="arm_b_links"/></group>
  <group name="with_mimic"><joint name="a1"/><joint name="a_mimic"/></group>
  <group name="tool_to_tool"><chain base_link="a_tool" tip_link="b2l"/></group>
  <group name="fixed_only"><joint name="a_tip"/></group>
  <disable_collisions link1="base" link2="a1l" reason="Adjacent"/>
</robot>"""


def resolve(group):
    with warnings.catch_warnings():
        warnings.simplefilter("error", GfcsWarning)  # groups without absent entries warn about nothing
        return srdf_groups.resolve_group(URDF, SRDF, group)


def test_urdf_tree_in_file_order_depth_first():
    tree = srdf_groups.read_urdf_tree(URDF)
    assert tree.root == "world"
    assert [j.name for j in tree.joints] == ["mount", "a1", "a2", "a_tip", "a_mimic", "b1", "b2"]
    assert tree.joint("a_mimic").mimic == "a1" and not tree.joint("a_mimic").active
    assert tree.ancestors("a_tool") == ["a2l", "a1l", "base", "world"]


def test_joint_of_zero_range_is_not_planned_by_a_group_nor_sampled_by_the_collision_matrix():
    # a wheel written as a revolute joint whose <limit> has no lower/upper (both 0): MoveIt moves it nowhere
    wheel = URDF.replace('<limit lower="-1" upper="1" velocity="1" effort="1"/>', '<limit velocity="1" effort="1"/>')
    tree = srdf_groups.read_urdf_tree(wheel)
    assert tree.joint("b2").zero_range and not tree.joint("b2").active
    assert not tree.joint("b1").zero_range  # continuous: unbounded
    from gfcs.collision_matrix import movable_joints
    assert movable_joints(wheel) == ["a1", "a2", "b1"]
    with pytest.warns(GfcsWarning):  # arm_b also names a ghost joint and link
        assert srdf_groups.resolve_group(wheel, SRDF, "arm_b").joints == ("b1",)
    robot = gfcs.Robot.from_urdf(wheel, ee_link="b2l")
    assert robot.joint_names == ["b1"] and robot.locked_positions["b2"] == 0.0


def test_chain_group_active_joints_and_tip():
    g = resolve("arm_a")
    assert g.joints == ("a1", "a2")  # the fixed a_tip is on the chain but does not move
    assert g.tips == ("a_tool",)


def test_joint_list_skips_absent_entries_with_one_warning():
    with pytest.warns(GfcsWarning) as record:
        g = srdf_groups.resolve_group(URDF, SRDF, "arm_b")
    assert len(record) == 1
    message = str(record[0].message)
    assert "ghost_joint" in message and "ghost_link" in message and "arm_b" in message
    assert g.joints == ("b1", "b2")  # tree order, not the SRDF's
    assert g.tips == ("b2l",)
    assert set(g.skipped) == {"joint ghost_joint (group arm_b)", "link ghost_link (group arm_b)"}


def test_link_list_and_subgroups():
    assert resolve("arm_b_links").joints == ("b1", "b2")
    g = resolve("both")
    assert g.joints == ("a1", "a2", "b1", "b2")
    assert g.tips == ("a_tool", "b2l")


def test_mimic_joint_is_not_active_and_the_deepest_link_is_the_tip():
    g = resolve("with_mimic")
    assert g.joints == ("a1",)
    assert g.tips == ("a_m",)  # a1l lies above a_m, so it is no tip


def test_chain_between_two_tips_goes_through_their_common_ancestor():
    assert resolve("tool_to_tool").joints == ("a1", "a2", "b1", "b2")


def test_group_states_in_document_order_and_malformed_ones_skipped_with_one_warning(tmp_path):
    from gfcs.srdf_groups import read_group_states

    srdf = ('<robot name="r"><group_state name="ready" group="arm"><joint name="j1" value="0.5"/>'
            '<joint name="j2" value="-1e-1"/></group_state><group_state name="home" group="arm"/></robot>')
    assert read_group_states(srdf) == [("arm", "ready", {"j1": 0.5, "j2": -0.1}), ("arm", "home", {})]
    # a multi-DOF (virtual floating) joint's pose is no URDF joint: left out, the state kept (TALOS' half_sitting)
    floating = ('<robot name="r"><group_state name="half_sitting" group="all"><joint name="root_joint" '
                'value="0. 0. 1.02 0. 0. 0. 1."/><joint name="j" value="0.25"/></group_state></robot>')
    assert read_group_states(floating) == [("all", "half_sitting", {"j": 0.25})]
    path = tmp_path / "bad.srdf"
    path.write_text('<robot name="r"><group_state name="standing"><joint name="j" value="1"/></group_state>'
                    '<group_state name="s" group="arm"><joint name="j" value="0 x"/></group_state>'
                    '<group_state name="t" group="arm"><joint value="1"/></group_state>'
                    '<group_state name="ok" group="arm"><joint name="j" value="1"/></group_state></robot>')
    with pytest.warns(gfcs.GfcsWarning, match=r"bad.srdf: 3 group_state\(s\) skipped: standing \(needs name and "
                      r"group\); s \(joint j: value '0 x' is not finite numbers\); t \(joint \(no name\)"):
        assert read_group_states(path) == [("arm", "ok", {"j": 1.0})]


def test_unknown_group_lists_the_groups():
    with pytest.raises(LinkError) as info:
        srdf_groups.resolve_group(URDF, SRDF, "arm_c")
    assert "arm_c" in str(info.value) and "arm_a" in str(info.value) and "both" in str(info.value)


def test_group_without_movable_joint_is_refused():
    with pytest.raises(gfcs.InvalidValueError, match="fixed_only"):
        srdf_groups.resolve_group(URDF, SRDF, "fixed_only")


def test_malformed_and_oversized_files_name_the_file(tmp_path, monkeypatch):
    bad = tmp_path / "bad.srdf"
    bad.write_text("<robot><group name='x'></robot>")
    with pytest.raises(FormatError, match="bad.srdf"):
        srdf_groups.read_srdf_groups(bad)
    big = tmp_path / "big.urdf"
    big.write_text(URDF)
    monkeypatch.setattr(srdf_groups, "MAX_XML_BYTES", 100)
    with pytest.raises(IoError, match="big.urdf"):
        srdf_groups.read_urdf_tree(big)
    with pytest.raises(IoError, match="missing.urdf"):
        srdf_groups.read_urdf_tree(tmp_path / "missing.urdf")


def test_robot_for_group_on_two_branches():
    robot, tips = srdf_groups.robot_for_group(URDF, SRDF, "both")
    assert list(robot.joint_names) == ["a1", "a2", "b1", "b2"]
    assert robot.ee_link == "a_tool" and tips == ["a_tool", "b2l"]
    single, tips = srdf_groups.robot_for_group(URDF, SRDF, "arm_a")
    assert list(single.joint_names) == ["a1", "a2"] and single.ee_link == "a_tool"
    assert "b1" in single.locked_positions and "b2" in single.locked_positions  # held, not planned
    with pytest.raises(gfcs.InvalidValueError, match="active_joints"):
        srdf_groups.robot_for_group(URDF, SRDF, "arm_a", active_joints=["a1"])


# ------------------------------------------------------------------------------------------ two arms
def test_two_arm_robot_has_both_arms_and_both_tips():
    urdf, srdf, spheres = generators.two_arm_panda()
    robot, tips = generators.two_arm_robot()
    assert robot.dof == 14
    assert list(robot.joint_names) == [f"{s}_panda_joint{i}" for s in ("left", "right") for i in range(1, 8)]
    assert tips == ["left_panda_hand", "right_panda_hand"] and robot.ee_link == "left_panda_hand"
    shipped = gfcs.Robot.panda()
    assert len(spheres) == 2 * len(shipped.sphere_radii) == len(robot.sphere_radii)
    assert robot.locked_positions == {"left_panda_finger_joint1": 0.04, "right_panda_finger_joint1": 0.04}
    # at the same joint values both hands sit where the shipped Panda's does, shifted by the mounts
    q = generators.READY
    hand = np.asarray(shipped.link_poses(q))[shipped.link_index("panda_hand")]
    poses = np.asarray(robot.link_poses(np.concatenate([q, q])))
    for link, y in (("left_panda_hand", 0.35), ("right_panda_hand", -0.35)):
        np.testing.assert_allclose(poses[robot.link_index(link), :3, 3], hand[:3, 3] + [0, y, 0], atol=1e-12)
    # each arm keeps the shipped Panda's disabled pairs: no more self pairs within one arm than it has
    left = {i for i, link in enumerate(robot.sphere_links) if link.startswith("left_")}
    within = sum(1 for a, b in np.asarray(robot.self_collision_pairs) if a in left and b in left)
    assert within == len(shipped.self_collision_pairs)


def test_two_arm_problems_are_collision_free_and_seeded():
    a = generators.two_arm_problems(2, seed=3)
    b = generators.two_arm_problems(1, seed=3)
    np.testing.assert_array_equal(a[0].q0, b[0].q0)
    for p in a:
        assert p.meta["ee_links"] == ["left_panda_hand", "right_panda_hand"]
        both = np.stack([p.q0, p.goal])
        assert np.all(metrics.obstacle_clearance(p.robot, p.scene, both) >= 0.02)
        assert np.all(np.asarray(p.robot.self_clearance(both)) >= generators.SELF_MARGIN)


@pytest.fixture(scope="module")
def two_arm_solve():
    problem = generators.two_arm_problems(1, seed=0)[0]
    return problem, optimize.solve(problem, batches=2, population=16, seed=0, threads=2)


def _hand_paths(robot, q, links):
    """Hand path lengths recomputed here from the link poses, independently of gfcs.metrics."""
    poses = np.asarray(robot.link_poses(q))
    return {link: float(np.linalg.norm(np.diff(poses[:, robot.link_index(link), :3, 3], axis=0), axis=1).sum())
            for link in links}


def test_two_arm_solve_succeeds_and_reports_both_hand_paths(two_arm_solve):
    problem, result = two_arm_solve
    assert result.success, result.metrics
    q = np.asarray(result.trajectory.q)
    expected = _hand_paths(problem.robot, q, problem.meta["ee_links"])
    assert min(expected.values()) > 0.05  # both arms move
    assert result.metrics["ee_length"] == pytest.approx(expected["left_panda_hand"], rel=1e-9)
    again = metrics.trajectory_metrics(problem.robot, problem.scene, result.trajectory.t, q, problem.goal,
                                       ee_links=problem.meta["ee_links"])
    assert again["ee_lengths"].keys() == expected.keys()
    for link, value in expected.items():
        assert again["ee_lengths"][link] == pytest.approx(value, rel=1e-9)
    row = gfcs.results.bench_row(problem.name, problem.cls, "x", "gfcs", 2, 0, 0.0, 0.0, again, 0.0)
    assert row["ee_lengths"] == pytest.approx(expected)


def test_two_arm_solve_metrics_carry_both_hands(two_arm_solve):
    problem, result = two_arm_solve
    expected = _hand_paths(problem.robot, np.asarray(result.trajectory.q), problem.meta["ee_links"])
    assert result.metrics["ee_lengths"] == pytest.approx(expected, rel=1e-9)


# ----------------------------------------------------------------------------------------------- CLI
def _two_arm_files(tmp_path: Path, group: str):
    """The two-arm robot's URDF, SRDF and sphere file, and one problem folder whose request names ``group``."""
    urdf, srdf, spheres = generators.two_arm_panda()
    (tmp_path / "two_arm.urdf").write_text(urdf)
    (tmp_path / "two_arm.srdf").write_text(srdf)
    (tmp_path / "spheres.json").write_text(json.dumps(
        {"spheres": [{"link": link, "center": centre, "radius": r} for link, centre, r in spheres]}))
    problem = generators.two_arm_problems(1, seed=0)[0]
    folder = tmp_path / "problems" / "two_arm"
    folder.mkdir(parents=True)
    (folder / "scene0001.yaml").write_text(generators.scene_yaml([generators.TWO_ARM_DIVIDER]))
    (folder / "request0001.yaml").write_text(generators.request_yaml(
        problem.robot.joint_names, problem.q0, problem.goal, group=group, locked=problem.robot.locked_positions))
    return problem, [("--robot", tmp_path / "two_arm.urdf"), ("--srdf", tmp_path / "two_arm.srdf"),
                     ("--spheres", tmp_path / "spheres.json")], folder


def _flags(pairs):
    return [str(x) for pair in pairs for x in pair]


def test_cli_bench_takes_the_group_of_the_first_request(tmp_path):
    problem, robot_flags, folder = _two_arm_files(tmp_path, "both_arms")
    args = cli.build_parser().parse_args(["bench", "--problems", str(folder.parent), *_flags(robot_flags)])
    robot = cli._robot(args)
    assert robot.dof == 14 and robot.ee_link == "left_panda_hand"
    suite = cli._with_mesh_checker(args, bench.load_problems(args, robot))
    assert suite[0].meta["ee_links"] == ["left_panda_hand", "right_panda_hand"]
    np.testing.assert_allclose(suite[0].goal, problem.goal)


def test_cli_holds_joints_outside_the_request_group_at_their_start(tmp_path, capsys):
    problem, robot_flags, folder = _two_arm_files(tmp_path, "both_arms")
    text = yaml.safe_load((folder / "request0001.yaml").read_text())
    text["group_name"] = "right_arm"
    (folder / "request0001.yaml").write_text(yaml.safe_dump(text))
    args = cli.build_parser().parse_args(["solve", "--scene", str(folder / "scene0001.yaml"), "--request",
                                          str(folder / "request0001.yaml"), *_flags(robot_flags)])
    p = cli._solve_problem(args)
    assert list(p.robot.joint_names) == [f"right_panda_joint{i}" for i in range(1, 8)]
    assert p.robot.ee_link == "right_panda_hand" and p.meta["ee_links"] == ["right_panda_hand"]
    held = p.robot.locked_positions
    for i in range(7):  # the left arm stays where the request's start state puts it
        assert held[f"left_panda_joint{i + 1}"] == pytest.approx(problem.q0[i])
    # --group overrides the request's group; without --srdf it is refused
    args = cli.build_parser().parse_args(["solve", *_flags(robot_flags), "--group", "left_arm"])
    assert cli._robot(args).ee_link == "left_panda_hand"
    assert cli.main(["solve", "--robot", str(tmp_path / "two_arm.urdf"), "--group", "left_arm"]) == 2
    assert "--group needs --srdf" in capsys.readouterr().err


def test_cli_solve_json_of_a_two_arm_request(tmp_path):
    _, robot_flags, folder = _two_arm_files(tmp_path, "both_arms")
    out = tmp_path / "result.json"
    code = cli.main(["solve", "--scene", str(folder / "scene0001.yaml"), "--request",
                     str(folder / "request0001.yaml"), *_flags(robot_flags), "--batches", "2", "--population",
                     "16", "--threads", "2", "--json", str(out), "--no-trajectory"])
    result = json.loads(out.read_text())
    assert code == 0 and len(result["joint_names"]) == 14
    assert "left_panda_hand" in result["metrics"]["ee_lengths"]


def test_cli_group_of_shared_fetch_requests():
    robots, problems = require_shared("robots", "mbm_fetch"), require_shared("mbm_fetch")
    args = cli.build_parser().parse_args([
        "bench", "--problems", str(problems), "--classes", "box", "--limit", "1",
        "--robot", str(robots / "fetch_spherized.urdf"), "--srdf", str(robots / "fetch.srdf")])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GfcsWarning)  # the SRDF names links this URDF lacks
        robot = cli._robot(args)
        suite = cli._with_mesh_checker(args, bench.load_problems(args, robot))
    # arm_with_torso: the prismatic torso and the seven arm joints, tree order; its deepest link the tip
    assert list(robot.joint_names) == ["torso_lift_joint", "shoulder_pan_joint", "shoulder_lift_joint",
                                       "upperarm_roll_joint", "elbow_flex_joint", "forearm_roll_joint",
                                       "wrist_flex_joint", "wrist_roll_joint"]
    assert robot.ee_link == "wrist_roll_link" and suite[0].meta["ee_links"] == ["wrist_roll_link"]
    assert list(suite[0].mesh_checker.joint_names) == list(robot.joint_names)


def test_ee_links_of_a_problem():
    problem = generators.two_arm_problems(1, seed=0)[0]
    assert srdf_groups.ee_links(problem) == ["left_panda_hand", "right_panda_hand"]
    problem.meta = {}
    assert srdf_groups.ee_links(problem) == ["left_panda_hand"]


def test_group_of_finds_the_srdf_group_of_a_robots_joints_and_generate_writes_it(tmp_path):
    from gfcs.srdf_groups import group_of

    robot = gfcs.Robot.panda()
    assert group_of(gfcs.panda_urdf(), gfcs.panda_srdf(), robot.joint_names) == "panda_arm"
    assert group_of(gfcs.panda_urdf(), gfcs.panda_srdf(), robot.joint_names[:3]) is None
    assert cli.main(["generate", "--n", "1", "--classes", "box", "--out", str(tmp_path)]) == 0
    request = yaml.safe_load((tmp_path / "box" / "request0001.yaml").read_text())
    assert request["group_name"] == "panda_arm"


def test_cli_bench_with_an_srdf_of_collision_pairs_only_plans_the_robots_joints(tmp_path):
    # an SRDF without <group> (written for a collision checker, not MoveIt's planning groups) cannot name
    # the request's group: the request is for the robot's default joints
    assert cli.main(["generate", "--n", "1", "--classes", "box", "--out", str(tmp_path / "p")]) == 0
    request = tmp_path / "p" / "box" / "request0001.yaml"
    request.write_text(request.read_text().replace("group_name: panda_arm", "group_name: panda"))
    pairs_only, urdf, srdf = tmp_path / "pairs.srdf", tmp_path / "panda.urdf", tmp_path / "panda.srdf"
    pairs_only.write_text('<robot name="panda"><disable_collisions link1="panda_link0" link2="panda_link1" '
                          'reason="Adjacent"/></robot>')
    urdf.write_text(gfcs.panda_urdf())
    srdf.write_text(gfcs.panda_srdf())
    args = cli.build_parser().parse_args(["bench", "--problems", str(tmp_path / "p"), "--robot", str(urdf),
                                          "--srdf", str(pairs_only)])
    assert cli._group_name(args) is None
    assert list(cli._robot(args).joint_names) == list(gfcs.Robot.panda().joint_names)
    # an SRDF with groups still refuses a request for a group it does not define, as MoveIt does
    args = cli.build_parser().parse_args(["bench", "--problems", str(tmp_path / "p"), "--robot", str(urdf),
                                          "--srdf", str(srdf)])
    assert cli._group_name(args) == "panda"
    with pytest.raises(gfcs.GfcsError, match="no group named 'panda'"):
        cli._robot(args)
