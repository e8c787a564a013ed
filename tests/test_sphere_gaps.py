"""Inscribed gap spheres: ``tools/fill_sphere_gaps.py`` and the MBM Panda model that carries them.

References are independent of the tool: closed-form distances inside a box and an L-shaped prism, trimesh's
signed distance to the MotionBenchMaker collision meshes, and the MBM problems' own start and goal
configurations.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

import gfcs
from gfcs import problems

REPO_ROOT = Path(__file__).resolve().parent.parent
TOOL = REPO_ROOT / "tools" / "fill_sphere_gaps.py"

LIMIT = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'


def write_robot(tmp_path: Path, mesh_file: str = "box.obj") -> tuple[Path, Path]:
    """A slider whose link is a 0.2 × 0.1 × 0.1 m box mesh (offset by its URDF origin; or ``mesh_file``, written
    by the caller), and the same robot with one 0.03 m sphere at the box's +x end."""
    if mesh_file == "box.obj":
        trimesh.creation.box(extents=[0.2, 0.1, 0.1]).export(tmp_path / "box.obj")
    joint = f'<joint name="x" type="prismatic"><parent link="base"/><child link="link"/><axis xyz="1 0 0"/>{LIMIT}</joint>'
    mesh = tmp_path / "mesh.urdf"
    mesh.write_text(f"""<robot name="slider"><link name="base"/><link name="link"><collision>
      <origin xyz="0.5 0 0"/><geometry><mesh filename="{mesh_file}"/></geometry></collision></link>{joint}</robot>""")
    spheres = tmp_path / "spheres.urdf"
    spheres.write_text(f"""<robot name="slider"><link name="base"/><link name="link"><collision>
      <origin xyz="0.57 0 0"/><geometry><sphere radius="0.03"/></geometry></collision></link>{joint}</robot>""")
    return mesh, spheres


def test_tool_fills_a_box_from_inside(tmp_path):
    mesh, spheres = write_robot(tmp_path)
    out = tmp_path / "gaps.json"
    run = subprocess.run([sys.executable, str(TOOL), str(mesh), str(spheres), "--out", str(out), "--samples", "800",
                          "--target", "0.03", "--per-link", "3"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    added = json.loads(out.read_text())["spheres"]
    assert 1 <= len(added) <= 3 and all(s["link"] == "link" for s in added)
    lo, hi = np.array([0.4, -0.05, -0.05]), np.array([0.6, 0.05, 0.05])
    for s in added:
        c, r = np.asarray(s["center"]), s["radius"]
        # inscribed: the sphere stays inside the box by at least the 1 mm slack (closed form)
        assert np.min(np.concatenate([c - lo, hi - c])) >= r + 0.001 - 1e-6
    # the largest gap shrinks: the far (-x) end of the box is now within reach of a sphere
    centers = np.array([[0.57, 0, 0]] + [s["center"] for s in added])
    radii = np.array([0.03] + [s["radius"] for s in added])
    corner = np.array([0.4, 0.05, 0.05])
    assert np.min(np.linalg.norm(centers - corner, axis=1) - radii) < np.linalg.norm([0.57 - 0.4, 0.05, 0.05]) - 0.03
    assert "largest gap" in run.stderr
    # the file names the sphere model it was made for: only that model gets the spheres
    slider = gfcs.Robot.from_urdf(str(spheres))
    filled = problems.with_gap_spheres(slider, out)
    assert len(filled.sphere_radii) == 1 + len(added)
    np.testing.assert_allclose(filled.sphere_centers_local[1:], [s["center"] for s in added])
    other = slider.with_spheres([("link", [0.57, 0.0, 0.0], 0.031)])
    assert problems.with_gap_spheres(other, out) is other


def test_with_gap_spheres_rejects_a_file_of_another_kind(tmp_path):
    bad = tmp_path / "gaps.json"
    bad.write_text('{"spheres": []}')
    with pytest.raises(ValueError, match="gaps.json: not a gap-sphere file"):
        problems.with_gap_spheres(gfcs.Robot.panda(), bad)
    panda = gfcs.Robot.panda()
    assert problems.with_gap_spheres(panda) is panda  # not the model the shipped file was made for


#: The L-shaped cross-section (x, y) in m of the non-convex test link (counter-clockwise), extruded 0.05 m in z.
L_SHAPE = np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 0.05], [0.05, 0.05], [0.05, 0.2], [0.0, 0.2]])


def depth_in_l_prism(p: np.ndarray) -> float:
    """Closed-form distance from a point inside the L prism (its frame: cross-section ``L_SHAPE``, z in
    [0, 0.05]) to its surface: the nearest of the six side segments and the two end faces."""
    a, b = L_SHAPE, np.roll(L_SHAPE, -1, axis=0)
    t = np.clip(np.einsum("ij,ij->i", p[:2] - a, b - a) / np.einsum("ij,ij->i", b - a, b - a), 0.0, 1.0)
    side = np.linalg.norm(a + t[:, None] * (b - a) - p[:2], axis=1).min()
    return float(min(side, p[2], 0.05 - p[2]))


def test_tool_fills_a_non_convex_mesh_without_leaving_it(tmp_path):
    # the L prism's hull holds the notch x, y in (0.05, 0.2]: a hull-based filler would put spheres there
    triangles = np.array([[3, 4, 5], [3, 5, 0], [3, 0, 1], [3, 1, 2]])
    prism = trimesh.creation.extrude_triangulation(L_SHAPE, triangles, 0.05)
    assert prism.is_watertight and prism.volume < 0.7 * prism.convex_hull.volume
    # moved by the URDF origin (+0.5 m in x) like the box: the link frame is the prism's shifted by -0.07 m
    prism.apply_translation([-0.07, 0.0, 0.0])
    prism.export(tmp_path / "l.obj")
    mesh, spheres = write_robot(tmp_path, "l.obj")
    out = tmp_path / "gaps.json"
    run = subprocess.run([sys.executable, str(TOOL), str(mesh), str(spheres), "--out", str(out), "--samples", "800",
                          "--target", "0.02", "--per-link", "4"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    added = json.loads(out.read_text())["spheres"]
    assert len(added) >= 2
    for s in added:
        c = np.asarray(s["center"]) - [0.5 - 0.07, 0.0, 0.0]
        assert depth_in_l_prism(c) >= s["radius"] + 0.001 - 2e-6, s
    # both arms get spheres: the far ends of the L are no longer uncovered by 0.15 m
    centers = np.array([s["center"] for s in added]) - [0.5 - 0.07, 0.0, 0.0]
    assert centers[:, 1].max() > 0.1 and centers[:, 0].max() > 0.1


def test_mbm_panda_gap_spheres_lie_inside_the_meshes(mbm_panda_dir):
    robot = problems.mbm_panda(mbm_panda_dir)
    plain = problems.mbm_panda(mbm_panda_dir, fill_gaps=False)
    assert len(plain.sphere_radii) == 59 and len(robot.sphere_radii) == 81
    assert problems.mesh_checker_for(robot) is not None
    meshes = gfcs.Robot.from_urdf(str(mbm_panda_dir / "panda.urdf"), mesh_dir=str(mbm_panda_dir))
    geometry = {g["link"]: g for g in meshes.collision_geometry() if g["type"] == "mesh"}
    added = json.loads(problems.MBM_GAP_SPHERES.read_text())["spheres"]
    for s in added:
        g = geometry[s["link"]]
        m = trimesh.load(g["path"], force="mesh")
        origin = np.asarray(g["origin"])
        link = trimesh.Trimesh(np.asarray(m.vertices) @ origin[:3, :3].T + origin[:3, 3], m.faces)
        # the signed distance from the centre to the mesh surface (positive inside) exceeds the radius by
        # the tool's 1 mm slack, link6's non-convex mesh included
        depth = trimesh.proximity.signed_distance(link, np.asarray([s["center"]]))[0]
        assert depth >= s["radius"] + 0.001 - 2e-6, s
    assert {s["link"] for s in added} >= {"panda_link5", "panda_link6"}
    # the model's own spheres come first, the added ones after them, in the link frames
    np.testing.assert_allclose(robot.sphere_centers_local[59:], [s["center"] for s in added])


def test_mbm_gap_spheres_reach_the_spherized_urdf_however_it_is_loaded(mbm_panda_dir):
    # `gfcs solve --robot .../panda_spherized.urdf` loads it with Robot.from_urdf: same 81 spheres as `--robot mbm`
    from gfcs import cli

    args = cli.build_parser().parse_args(["solve", "--robot", str(mbm_panda_dir / "panda_spherized.urdf"),
                                          "--srdf", str(mbm_panda_dir / "panda.srdf")])
    loaded = cli._robot(args)
    reference = problems.mbm_panda(mbm_panda_dir)
    assert list(loaded.sphere_links) == list(reference.sphere_links)
    np.testing.assert_array_equal(loaded.sphere_centers_local, reference.sphere_centers_local)
    np.testing.assert_array_equal(loaded.sphere_radii, reference.sphere_radii)


def test_mbm_gap_spheres_keep_every_start_and_goal_as_clear_as_before(mbm_dir, mbm_panda_dir):
    from gfcs.metrics import obstacle_clearance

    robot = problems.mbm_panda(mbm_panda_dir)
    plain = problems.mbm_panda(mbm_panda_dir, fill_gaps=False)
    worse = []
    for p in problems.load_mbm_dir(mbm_dir, robot=robot, limit=10):
        q = np.stack([p.q0, p.goal])
        before = obstacle_clearance(plain, p.scene, q)
        after = obstacle_clearance(robot, p.scene, q)
        worse += [p.name for b, a in zip(before, after) if a < 0 <= b]
    assert worse == []
