"""sphere_deficits and the self-collision cover margins against closed forms, and the MeshCover policy's place
among the default policies."""

import math

import numpy as np
import pytest

import gfcs
from gfcs.coverage import sphere_deficits
from gfcs.planning.policies import MeshCover, cover_self_margins, default_policies

BOX = """<robot name="b"><link name="base"/><link name="arm">{collision}</link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
  <limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>"""


def test_a_box_sticks_out_of_a_centred_sphere_by_its_half_diagonal_less_the_radius():
    meshes = gfcs.Robot.from_urdf(BOX.format(collision='<collision><origin xyz="0.3 0 0"/>'
                                                       '<geometry><box size="0.2 0.1 0.1"/></geometry></collision>'))
    spheres = gfcs.Robot.from_urdf(BOX.format(collision=""), spheres=[("arm", [0.3, 0.0, 0.0], 0.05),
                                                                      ("arm", [0.9, 0.0, 0.0], 0.01)])
    d = sphere_deficits(spheres, meshes)
    assert d[0] == pytest.approx(math.sqrt(0.1**2 + 0.05**2 + 0.05**2) - 0.05, abs=1e-9)  # a corner vertex
    assert d[1] == 0.0  # no mesh point is nearer to it than to the first sphere
    covering = gfcs.Robot.from_urdf(BOX.format(collision=""), spheres=[("arm", [0.3, 0.0, 0.0], 0.2)])
    assert sphere_deficits(covering, meshes).tolist() == [0.0]


def test_mesh_cover_is_a_named_policy_off_by_default():
    assert not any(isinstance(p, MeshCover) for p in default_policies())
    chosen = default_policies(mesh_cover=0.03)
    cover = [p for p in chosen if isinstance(p, MeshCover)]
    assert len(cover) == 1 and cover[0].max_extra == 0.03 and cover[0].name == "mesh cover"
    names = [p.name for p in chosen]
    assert names.index("mesh cover") == names.index("goal contact") + 1  # after the other mesh retries
    with pytest.raises(gfcs.GfcsError):
        MeshCover(max_extra=-1.0)


TWO = """<robot name="two"><link name="base"/><link name="a"/><link name="c"/><link name="b"/>
  <joint name="ja" type="prismatic"><parent link="base"/><child link="a"/><axis xyz="1 0 0"/>
  <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <joint name="jc" type="revolute"><parent link="base"/><child link="c"/><axis xyz="0 0 1"/>
  <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <joint name="jb" type="revolute"><parent link="c"/><child link="b"/><origin xyz="1 0 0"/><axis xyz="0 0 1"/>
  <limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>"""


def test_cover_self_margins_add_both_deficits_and_stay_feasible_at_the_start_and_goal():
    # a sphere on a slider (x = q) and one on a two-link arm at x = 1 for jc = jb = 0, radii 0.1: their gap is
    # 0.8 - q
    robot = gfcs.Robot.from_urdf(TWO, ee_link="b", active_joints=["ja", "jc", "jb"],
                                 spheres=[("a", [0.0, 0.0, 0.0], 0.1), ("b", [0.0, 0.0, 0.0], 0.1)])
    assert np.asarray(robot.self_collision_pairs).tolist() == [[0, 1]]
    deficits = np.array([0.01, 0.02])
    far = cover_self_margins(robot, deficits, 0.002, 0.05, [[0.0, 0, 0], [0.1, 0, 0]])
    assert far.tolist() == pytest.approx([0.002 + 0.03])  # e_a + e_b
    assert cover_self_margins(robot, deficits, 0.002, 0.02, [[0.0, 0, 0]]).tolist() == pytest.approx([0.022])  # capped
    # a goal at q = 0.78 leaves a gap of 0.02: the margin drops to the gap less the slack
    assert cover_self_margins(robot, deficits, 0.002, 0.05, [[0.0, 0, 0], [0.78, 0, 0]], slack=0.002).tolist() == \
        pytest.approx([0.018])
    # ... but never below the configured margin
    assert cover_self_margins(robot, deficits, 0.002, 0.05, [[0.799, 0, 0]]).tolist() == pytest.approx([0.002])
