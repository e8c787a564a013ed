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


HELD_ARMS = """<robot name="held">
  <link name="base"/>
  <link name="a"><collision><origin xyz="0.5 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="b"><collision><origin xyz="0.5 0 0"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <link name="s"><collision><geometry><sphere radius="0.05"/></geometry></collision></link>
  <joint name="ja" type="revolute"><parent link="base"/><child link="a"/><origin xyz="0 0.15 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
  <joint name="jb" type="revolute"><parent link="base"/><child link="b"/><origin xyz="0 -0.15 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
  <joint name="js" type="prismatic"><parent link="base"/><child link="s"/><origin xyz="0 0 5"/>
    <axis xyz="1 0 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>"""


def test_links_held_in_contact_by_the_joints_outside_the_group_refuse_every_problem():
    """Two arms locked at the base (joints outside the planned slider) whose boxes face each other 0.1 m
    apart; held at −0.3 rad, arm a's box crosses the gap. No motion of the slider moves them, and MoveIt checks
    the pair: the problem is refused naming the two links, for any start."""
    from gfcs.planning.endpoints import check_held_links

    robot = gfcs.Robot.from_urdf(HELD_ARMS, active_joints=["js"])
    apart = gfcs.MeshChecker(robot)
    assert apart.self_contacts(np.zeros(1), 1.0) == []  # the fabric's and the trajectory's pairs: none
    (a, b, gap), = apart.held_contacts(np.zeros(1), 0.2)
    assert (a, b) == ("a", "b") and gap == pytest.approx(0.1, abs=1e-9)
    check_held_links(apart, np.zeros(1), "apart")  # 0.1 m apart: nothing raised
    touching = gfcs.MeshChecker(robot.with_locked_positions({"ja": -0.3}))
    scene = gfcs.Scene()
    problem = gfcs.problems.Problem(name="held/1", robot=touching.robot, scene=scene, q0=np.array([-0.5]),
                               goal=np.array([0.5]), mesh_checker=touching)
    with pytest.raises(gfcs.CollisionError, match=r"held/1.*links 'a' and 'b' touch.*ja"):
        check_endpoints(problem)
    with pytest.raises(gfcs.CollisionError, match="held/1"):
        planning.solve(problem, batches=1, population=4, policies=[])


ELBOW = """<robot name="elbow">
  <link name="base"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.1 0.1"/></geometry></collision></link>
  <link name="arm"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.1 0.1"/></geometry></collision></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0.21 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
</robot>"""


def test_adjacent_links_the_srdf_leaves_enabled_are_checked_at_the_endpoints():
    """Two boxes joined end to end, 1 cm apart, by a revolute joint: turned by 2.5 rad the arm's box folds
    back into the base's. The planner never measures adjacent links; MoveIt checks them unless the SRDF disables them."""
    folded = np.array([2.5])
    enabled = gfcs.MeshChecker(gfcs.Robot.from_urdf(ELBOW, srdf='<robot name="elbow"/>'))
    (a, b, depth), = enabled.adjacent_contacts(folded, 0.0)
    assert (a, b) == ("base", "arm") and depth <= 0.0
    (a, b, flat), = enabled.adjacent_contacts(folded, 0.0, depth=False)  # the verdict without the depth
    assert (a, b) == ("base", "arm") and depth <= flat <= 0.0
    assert enabled.adjacent_contacts(np.zeros(1), 0.0) == []  # stretched out: 1 cm apart
    assert enabled.self_contacts(folded, 1.0) == []  # the pair the planner checks: none
    problem = gfcs.problems.Problem(name="elbow/1", robot=enabled.robot, scene=gfcs.Scene(), q0=folded,
                                    goal=np.zeros(1), mesh_checker=enabled)
    with pytest.raises(gfcs.CollisionError, match=r"elbow/1.*start state.*adjacent links 'base' and 'arm'.*Adjacent.*gfcs collision-matrix"):
        check_endpoints(problem)
    srdf = '<robot name="elbow"><disable_collisions link1="base" link2="arm" reason="Adjacent"/></robot>'
    for robot in (gfcs.Robot.from_urdf(ELBOW, srdf=srdf), gfcs.Robot.from_urdf(ELBOW)):  # disabled, or no SRDF
        checker = gfcs.MeshChecker(robot)
        assert checker.adjacent_contacts(folded, 0.0) == []
        check_endpoints(dataclasses.replace(problem, robot=robot, mesh_checker=checker))


def test_generate_hold_parses_joints_outside_the_group_and_names_bad_items():
    from gfcs.cli import _held_positions

    robot = gfcs.Robot.from_urdf(HELD_ARMS, active_joints=["js"])
    assert _held_positions(["ja=0.4", "jb=-1"], robot) == {"ja": 0.4, "jb": -1.0}
    for item, why in (("js=0.1", "is planned"), ("nope=1", "not a movable joint"), ("ja", "JOINT=VALUE"),
                      ("ja=x", "JOINT=VALUE"), ("ja=nan", "JOINT=VALUE")):
        with pytest.raises(gfcs.InvalidValueError, match=why):
            _held_positions([item], robot)
    moved = robot.with_locked_positions(_held_positions(["ja=-0.3"], robot))
    assert gfcs.MeshChecker(moved).held_contacts(np.zeros(1), 0.0)[0][:2] == ("a", "b")


def test_generate_holds_joints_at_the_srdfs_named_states_unless_given():
    """Held joints take the first SRDF group_state naming them (MoveIt's "ready" of a second arm); a --hold
    value wins, a planned joint is never taken, and states naming no held joint are not reported."""
    from gfcs.cli import _named_holds

    robot = gfcs.Robot.from_urdf(HELD_ARMS, active_joints=["js"])
    srdf = ('<robot name="held"><group name="slider"><joint name="js"/></group>'
            '<group_state name="out" group="slider"><joint name="js" value="0.5"/></group_state>'
            '<group_state name="ready" group="arms"><joint name="ja" value="0.4"/><joint name="jb" value="-1"/>'
            '</group_state><group_state name="home" group="arms"><joint name="ja" value="0.1"/></group_state>'
            '</robot>')
    assert _named_holds(srdf, robot, {}) == ({"ja": 0.4, "jb": -1.0}, ["arms/ready"])
    assert _named_holds(srdf, robot, {"ja": 0.2}) == ({"jb": -1.0}, ["arms/ready"])
    assert _named_holds(None, robot, {}) == ({}, [])


def test_generate_uses_a_named_state_that_puts_held_links_in_contact_and_says_so(tmp_path, capsys):
    """The named state is what `gfcs generate` holds: one that crosses the arms is refused like --hold; the
    same problem with --hold overriding it is drawn past that check."""
    from gfcs import cli

    urdf, srdf = tmp_path / "held.urdf", tmp_path / "held.srdf"
    urdf.write_text(HELD_ARMS)
    srdf.write_text('<robot name="held"><group name="slider"><joint name="js"/></group>'
                    '<group_state name="crossed" group="arms"><joint name="ja" value="-0.3"/></group_state></robot>')
    args = ["generate", "--robot", str(urdf), "--srdf", str(srdf), "--group", "slider", "--out",
            str(tmp_path / "out"), "--n", "1", "--classes", "box"]
    assert cli.main(args) == 2
    err = capsys.readouterr().err
    assert "named states arms/crossed" in err and "links 'a' and 'b' touch" in err
    # gfcs solve's built-in problem holds them alike
    assert cli.main(["solve", "--robot", str(urdf), "--srdf", str(srdf), "--group", "slider"]) == 2
    assert "named states arms/crossed" in capsys.readouterr().err
    cli.main(args + ["--hold", "ja=0"])
    assert "touch" not in capsys.readouterr().err


def test_generate_refuses_a_hold_that_puts_held_links_in_contact(tmp_path, capsys):
    """`gfcs generate --hold` with the held arm crossing the gap: one refusal naming the links and --hold,
    before any class is drawn (the generator checks the robot's meshes, which the CLI hands it)."""
    from gfcs import cli

    urdf, srdf = tmp_path / "held.urdf", tmp_path / "held.srdf"
    urdf.write_text(HELD_ARMS)
    srdf.write_text('<robot name="held"><group name="slider"><joint name="js"/></group></robot>')
    code = cli.main(["generate", "--robot", str(urdf), "--srdf", str(srdf), "--group", "slider",
                     "--hold", "ja=-0.3", "--out", str(tmp_path / "out"), "--n", "1"])
    err = capsys.readouterr().err
    assert code == 2
    assert "links 'a' and 'b' touch" in err and "--hold" in err
    assert not (tmp_path / "out").exists()
