"""gfcs.generators for robots other than the Panda: layouts scaled by the robot's reach, and `gfcs generate`
on a robot whose SRDF has no group moving exactly its joints."""

import re
import subprocess
import sys

import numpy as np
import pytest

import gfcs
from gfcs import generators
from gfcs.generators import workspace_scale

SCALE = 0.6


def _small_arm():
    """The shipped Panda with every joint offset and sphere scaled by SCALE and its joints renamed (not a
    Panda to the generator): (URDF text, spheres)."""
    text = gfcs.panda_urdf().replace("panda_joint", "arm_joint")

    def shrink(m):
        return 'xyz="' + " ".join(repr(float(v) * SCALE) for v in m.group(1).split()) + '"'

    text = re.sub(r'xyz="([^"]*)"', shrink, text)
    panda = gfcs.Robot.panda()
    spheres = [(link, (np.asarray(c) * SCALE).tolist(), float(r) * SCALE)
               for link, c, r in zip(panda.sphere_links, panda.sphere_centers_local, panda.sphere_radii)]
    return text, spheres


@pytest.fixture(scope="module")
def small_arm():
    text, spheres = _small_arm()
    return gfcs.Robot.from_urdf(text, spheres=spheres, srdf=gfcs.panda_srdf())


def test_the_workspace_scale_is_the_reach_over_the_pandas(small_arm):
    assert workspace_scale(gfcs.Robot.panda()) == 1.0
    assert workspace_scale(small_arm) == pytest.approx(SCALE, rel=1e-9)  # every length scaled: the reach too


def test_a_placed_layout_scales_about_the_shoulder_and_moves_positions_sizes_and_targets_only():
    rng = np.random.default_rng(3)
    layout = generators._LAYOUTS["box"](rng)
    mount = np.array([0.3, -0.2, 1.0])
    placed = generators._placed(layout, 0.5, mount)
    shoulder = np.asarray(generators.PANDA_MOUNT)
    for a, b in zip(layout.primitives, placed.primitives):
        assert np.allclose(np.asarray(b.position) - mount, 0.5 * (np.asarray(a.position) - shoulder))
        assert np.allclose(b.dims, 0.5 * np.asarray(a.dims)) and b.quaternion == a.quaternion
    t, u = layout.goal(np.random.default_rng(1)), placed.goal(np.random.default_rng(1))
    assert np.allclose(u.position - mount, 0.5 * (t.position - shoulder))
    assert np.array_equal(u.approach, t.approach)
    assert generators._placed(layout, 1.0, shoulder) is layout


MOUNT = (0.3, 0.2, 0.5)
#: Where the layouts move with the shoulder: the column, and the lift in the middle of its range.
SHIFT = np.add(MOUNT, (0.0, 0.0, 0.15))


@pytest.fixture(scope="module")
def mounted_arm():
    """The shipped Panda (joints renamed: not a Panda to the generator) on a column 0.5 m high and off the
    base origin, behind a prismatic lift of 0.3 m, as a mobile manipulator's arm sits on its torso."""
    text = gfcs.panda_urdf().replace("panda_joint", "arm_joint")
    x, y, z = MOUNT
    column = (f'<link name="base"/><link name="torso"/>'
              f'<joint name="lift" type="prismatic"><parent link="base"/><child link="torso"/>'
              f'<origin xyz="{x} {y} {z}"/><axis xyz="0 0 1"/>'
              f'<limit lower="0" upper="0.3" velocity="0.1" effort="1"/></joint>'
              f'<joint name="mount" type="fixed"><parent link="torso"/><child link="panda_link0"/></joint>')
    text = text.replace('<link name="panda_link0"/>', column + '<link name="panda_link0"/>')
    panda = gfcs.Robot.panda()
    spheres = list(zip(panda.sphere_links, panda.sphere_centers_local, panda.sphere_radii))
    return gfcs.Robot.from_urdf(text, spheres=spheres, srdf=gfcs.panda_srdf())


def test_the_arm_mount_is_the_shoulder_wherever_the_arm_sits(mounted_arm):
    np.testing.assert_allclose(generators.arm_mount(gfcs.Robot.panda()), generators.PANDA_MOUNT, atol=1e-12)
    assert mounted_arm.joint_names[0] == "lift"
    np.testing.assert_allclose(generators.arm_mount(mounted_arm), SHIFT + generators.PANDA_MOUNT, atol=1e-12)
    assert 1.0 <= workspace_scale(mounted_arm) < 1.2  # the same arm, and a lift


def test_a_mounted_arm_gets_every_class_in_front_of_its_shoulder(mounted_arm):
    for cls in gfcs.problems.CLASSES:
        problem = generators.generate(cls, 1, seed=0, robot=mounted_arm)[0]
        panda = generators.generate(cls, 1, seed=0)[0]
        # the Panda's structures, moved with its shoulder: at its height, within its reach (the draws of the
        # two robots' scenes may differ where a scene is redrawn: the orientation of a table, a shelf)
        lifted = np.mean([p["position"] for p in problem.meta["primitives"]], axis=0) - SHIFT
        height = np.mean([p["position"] for p in panda.meta["primitives"]], axis=0)[2]
        assert abs(lifted[2] - height) < 0.1 and np.linalg.norm(lifted[:2]) < 1.5, cls
        assert generators.is_collision_free(mounted_arm, problem.scene, problem.q0, 0.01)
        assert generators.is_collision_free(mounted_arm, problem.scene, problem.goal, 0.01)


def test_a_small_arm_gets_problems_in_its_own_reach(small_arm):
    problems = generators.generate("bookshelf_tall", 1, seed=0, robot=small_arm)
    panda = generators.generate("bookshelf_tall", 1, seed=0)
    far = lambda p: max(np.linalg.norm(np.asarray(q["position"])[:2]) for q in p.meta["primitives"])
    assert far(problems[0]) < 0.8 * far(panda[0])  # structures nearer the base
    for p in problems:
        assert generators.is_collision_free(small_arm, p.scene, p.q0, 0.01)
        assert generators.is_collision_free(small_arm, p.scene, p.goal, 0.01)
    with pytest.raises(gfcs.InvalidValueError, match="scale"):
        generators.generate("box", 1, robot=small_arm, scale=0.0)


def test_generate_plans_for_the_first_srdf_group_when_none_moves_exactly_the_robots_joints(tmp_path):
    """The arm's seven joints move by default; the SRDF's only group holds six of them. A request must name
    a group of the SRDF: the problems are for that group (its joints), not for the robot's name."""
    import json

    text, spheres = _small_arm()
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(text)
    (tmp_path / "spheres.json").write_text(json.dumps({"spheres": [{"link": l, "center": c, "radius": r}
                                                                    for l, c, r in spheres]}))
    srdf = tmp_path / "arm.srdf"
    joints = "".join(f'<joint name="arm_joint{k}"/>' for k in range(1, 7))
    srdf.write_text(f'<robot name="arm"><group name="six">{joints}</group></robot>')
    out = tmp_path / "problems"
    r = subprocess.run([sys.executable, "-m", "gfcs", "generate", "--out", str(out), "--n", "1", "--classes",
                        "bookshelf_tall", "--robot", str(urdf), "--srdf", str(srdf), "--spheres",
                        str(tmp_path / "spheres.json")], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "the problems are for its first group, 'six'" in r.stderr
    request = (out / "bookshelf_tall" / "request0001.yaml").read_text()
    goal = request[request.index("goal_constraints"):]
    assert "group_name: six" in request and "arm_joint6" in goal and "arm_joint7" not in goal


def _backward_tool_arm():
    """The shipped Panda (joints renamed: not a Panda to the generator) with its end effector a frame on the
    hand turned half a turn about x: its z axis points back up the arm, and the gripper approaches along −z."""
    text = gfcs.panda_urdf().replace("panda_joint", "arm_joint")
    tool = ('<link name="tool"/><joint name="tool_joint" type="fixed"><parent link="panda_hand"/>'
            '<child link="tool"/><origin xyz="0 0 0" rpy="3.141592653589793 0 0"/></joint></robot>')
    text = text[: text.rindex("</robot>")] + tool
    panda = gfcs.Robot.panda()
    spheres = list(zip(panda.sphere_links, panda.sphere_centers_local, panda.sphere_radii))
    return gfcs.Robot.from_urdf(text, ee_link="tool", spheres=spheres, srdf=gfcs.panda_srdf())


def test_targets_are_reached_along_the_robots_own_approach_axis():
    panda = generators.tcp_along_approach(gfcs.Robot.panda())
    np.testing.assert_array_equal(panda["point"], generators.PANDA_TCP)  # the Panda's problems unchanged
    assert panda["axis"] == (0.0, 0.0, 1.0)
    robot = _backward_tool_arm()
    hand = generators.tcp_along_approach(robot)
    assert hand["axis"] == (0.0, 0.0, -1.0)
    np.testing.assert_allclose(hand["point"], -generators.PANDA_TCP, atol=1e-15)
    problem = generators.generate("table_pick", 1, seed=0, robot=robot)[0]
    # the target approaches from above: the gripper (the hand's z axis, the tool's −z) points down
    poses = np.asarray(robot.link_poses(problem.goal))
    gripper = poses[robot.link_index("panda_hand"), :3, 2]
    assert gripper[2] < -np.cos(np.radians(30.0)), gripper


def test_a_layout_without_a_start_starts_beside_a_ready_configuration_it_touches():
    ready, near, far = np.zeros(2), np.ones(2), 2 * np.ones(2)
    arm = _backward_tool_arm()

    def free(q):
        return q[0] > 1.5

    assert generators._layout_start(arm, ready, lambda q: True, [near, far]) is ready
    np.testing.assert_array_equal(generators._layout_start(arm, ready, free, [near, far]), far)
    assert generators._layout_start(arm, ready, free, [near]) is None
    # the Panda's layouts are drawn around its ready configuration: a scene it touches is redrawn
    assert generators._layout_start(gfcs.Robot.panda(), ready, free, [near, far]) is None
