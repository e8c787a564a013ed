"""sphere_deficits against closed forms, and the MeshCover policy's place among the default policies."""

import math

import numpy as np
import pytest

import gfcs
from gfcs.coverage import sphere_deficits
from gfcs.planning.policies import MeshCover, default_policies

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
