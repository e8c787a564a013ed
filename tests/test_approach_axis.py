"""gfcs.profile.derive_approach_axis on small generated arms: a gripper that extends from its wrist, a bare
flange whose frame sits on the flange face (its volume behind it, toward the arm), a tool frame rotated on
the last body, and the fallback without spheres."""

import numpy as np
import pytest

import gfcs
from gfcs.profile import derive_approach_axis, profile_for


def _arm(tool_spheres, ee_rpy="0 0 0", wrist_axis="0 0 1"):
    """A three-joint arm along +z whose last body ("tool", frame at the wrist joint, 0.3 m above the
    elbow) carries ``tool_spheres`` ((x, y, z, r) in its frame) and an end-effector frame "tcp" fixed on it
    with rotation ``ee_rpy``."""
    spheres = "".join(
        f'<collision><origin xyz="{x} {y} {z}"/><geometry><sphere radius="{r}"/></geometry></collision>'
        for x, y, z, r in tool_spheres)
    return f"""<robot name="arm">
  <link name="base"><collision><geometry><sphere radius="0.08"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="0 0 0.15"/><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="fore"><collision><origin xyz="0 0 0.1"/><geometry><sphere radius="0.045"/></geometry></collision>
    <collision><origin xyz="0 0 0.2"/><geometry><sphere radius="0.04"/></geometry></collision></link>
  <link name="tool">{spheres}</link>
  <link name="tcp"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <joint name="j3" type="revolute"><parent link="fore"/><child link="tool"/><origin xyz="0 0 0.3"/>
    <axis xyz="{wrist_axis}"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <joint name="tcp_joint" type="fixed"><parent link="tool"/><child link="tcp"/><origin rpy="{ee_rpy}"/></joint>
</robot>"""


def _axis(urdf):
    return derive_approach_axis(gfcs.Robot.from_urdf(urdf, ee_link="tcp"))


def test_a_gripper_extending_from_the_wrist_gives_its_direction():
    gripper = [(0.0, 0.0, 0.04, 0.03), (0.0, 0.0, 0.09, 0.025), (0.0, 0.02, 0.12, 0.01)]
    assert _axis(_arm(gripper)) == (0.0, 0.0, 1.0)


def test_a_gripper_pointing_down_its_frame_gives_minus_z():
    # the wrist joint's origin is the body's; the gripper hangs below it along -z of that frame
    gripper = [(0.0, 0.0, -0.05, 0.03), (0.0, 0.0, -0.1, 0.025)]
    urdf = _arm(gripper).replace('<origin xyz="0 0 0.3"/>\n    <axis xyz="0 0 1"/><limit lower="-2"',
                                 '<origin xyz="0 0 0.45" rpy="3.141592653589793 0 0"/>\n    <axis xyz="0 0 1"/>'
                                 '<limit lower="-2"')
    assert 'rpy="3.14' in urdf
    assert _axis(urdf) == (0.0, 0.0, -1.0)


def test_a_bare_flange_whose_frame_sits_on_its_face_points_away_from_the_arm():
    # the flange's volume lies behind its frame (toward the forearm): the tool extends along +z
    flange = [(0.0, 0.0, -0.03, 0.04), (0.01, 0.0, -0.05, 0.035)]
    assert _axis(_arm(flange)) == (0.0, 0.0, 1.0)


def test_the_axis_is_expressed_in_the_end_effector_frame():
    gripper = [(0.0, 0.0, 0.05, 0.03), (0.0, 0.0, 0.1, 0.025)]
    # tcp rotated +90 degrees about y: the tool's z is the tcp's -x
    got = _axis(_arm(gripper, ee_rpy="0 1.5707963267948966 0"))
    np.testing.assert_allclose(got, (-1.0, 0.0, 0.0), atol=1e-12)


def test_without_spheres_on_the_end_effector_the_z_axis_is_used():
    urdf = _arm([(0.0, 0.0, 0.05, 0.03)]).replace(
        '<link name="tool"><collision><origin xyz="0.0 0.0 0.05"/><geometry><sphere radius="0.03"/></geometry>'
        '</collision></link>', '<link name="tool"/>')
    assert 'name="tool"/>' in urdf
    assert _axis(urdf) == (0.0, 0.0, 1.0)


def test_the_profile_of_a_robot_without_a_data_file_derives_it():
    robot = gfcs.Robot.from_urdf(_arm([(0.0, 0.0, -0.03, 0.04)]), ee_link="tcp")
    assert profile_for(robot).approach_axis == (0.0, 0.0, 1.0)


@pytest.mark.parametrize("robot", [gfcs.Robot.panda()], ids=["shipped panda"])
def test_the_shipped_panda_hand_approaches_along_its_z(robot):
    assert derive_approach_axis(robot) == (0.0, 0.0, 1.0)
