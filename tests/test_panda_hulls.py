"""The shipped Panda's collision polytopes (``python/gfcs/data/panda_hulls``, ``tools/fit_hulls.py``) and the mesh
checker built from them (``gfcs.problems.shipped_panda_checker``).

References are independent of the checker: the polytopes' own face planes (convexity, containment of the
Franka collision meshes' vertices, which the tool never writes out), the support function of those vertices
(how far a polytope exceeds the meshes' convex hull), and the closed-form clearance of a convex body above a
plane (its lowest vertex).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import ConvexHull

import gfcs
from conftest import load_script
from gfcs import generators, optimize, problems

LINKS = [f"panda_link{i}" for i in range(8)] + ["panda_hand", "panda_leftfinger", "panda_rightfinger"]
#: The largest distance (m) a polytope may exceed its link's collision meshes' convex hull by.
EXCESS_TOL = 0.003


def load_tool():
    return load_script("tools/fit_hulls.py")


def read_obj(path: Path):
    verts, faces = [], []
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            faces.append([int(x.split("/")[0]) - 1 for x in line.split()[1:4]])
    return np.array(verts), np.array(faces)


def face_planes(verts, faces, min_height=1e-5):
    """(F, 3) unit outward normals and (F,) offsets of the triangles (counter-clockwise from outside) at
    least ``min_height`` m high: qhull's triangulation of a flat face leaves slivers whose normals are
    numerical noise (their orientation is checked by the edge pairing and the volume instead)."""
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    n = np.cross(b - a, c - a)
    area2 = np.linalg.norm(n, axis=1)
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                      np.linalg.norm(a - c, axis=1)], axis=0)
    keep = area2 / longest >= min_height
    n = n[keep] / area2[keep, None]
    return n, np.einsum("ij,ij->i", n, a[keep])


@pytest.mark.parametrize("link", LINKS)
def test_each_polytope_is_closed_convex_and_outward(link):
    verts, faces = read_obj(problems.PANDA_HULLS / f"{link}.obj")
    edges = {}
    for f in faces:
        for i in range(3):
            e = (f[i], f[(i + 1) % 3])
            edges[e] = edges.get(e, 0) + 1
    assert all(k == 1 and edges.get((b, a)) == 1 for (a, b), k in edges.items()), "not a closed oriented surface"
    n, d = face_planes(verts, faces)
    assert np.all(verts @ n.T <= d + 1e-8), "a vertex lies outside a face plane: not convex"
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
    assert volume == pytest.approx(ConvexHull(verts).volume, rel=1e-9), "inward faces or a hole"


@pytest.fixture(scope="module")
def mesh_points(mbm_panda_dir):
    """{link: the MBM Panda collision meshes' vertices in its link frame} (skip/fail rule of conftest)."""
    return load_tool().link_points(mbm_panda_dir / "panda.urdf")


@pytest.mark.parametrize("link", LINKS)
def test_each_polytope_contains_its_franka_mesh_and_hugs_its_hull(link, mesh_points):
    verts, faces = read_obj(problems.PANDA_HULLS / f"{link}.obj")
    n, d = face_planes(verts, faces)
    pts = mesh_points[link]
    assert np.all(pts @ n.T <= d + 1e-8)
    u = np.random.default_rng(7).normal(size=(5000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    excess = ((verts @ u.T).max(axis=0) - (pts @ u.T).max(axis=0)).max()
    assert 0 <= excess <= EXCESS_TOL


def test_the_tool_rebuilds_the_shipped_files(tmp_path, mbm_panda_dir):
    tool = load_tool()
    assert tool.main([str(mbm_panda_dir / "panda.urdf"), "--out-dir", str(tmp_path)]) == 0
    for link in LINKS:
        made, _ = read_obj(tmp_path / f"{link}.obj")
        shipped, _ = read_obj(problems.PANDA_HULLS / f"{link}.obj")
        assert made.shape == shipped.shape
        assert np.allclose(np.sort(made, axis=0), np.sort(shipped, axis=0), atol=1e-9)


def test_polytope_of_a_cube_is_the_cube():
    tool = load_tool()
    cube = np.array([[x, y, z] for x in (-0.1, 0.2) for y in (0.0, 0.05) for z in (-0.3, 0.3)])
    verts, faces = tool.polytope(cube, tool.directions(cube, 40))
    assert len(verts) == 8 and len(faces) == 12
    assert np.allclose(np.sort(verts, axis=0), np.sort(cube, axis=0), atol=1e-9)


def test_checker_clearance_below_a_ceiling_is_the_highest_polytope_vertex():
    checker = problems.shipped_panda_checker()
    robot = gfcs.Robot.panda()
    assert checker.joint_names == robot.joint_names and checker.num_shapes == len(LINKS)
    bottom = 0.9
    scene = gfcs.Scene()
    scene.add_box([3.0, 3.0, 1.0], ([0.0, 0.0, bottom + 0.5], [0.0, 0.0, 0.0, 1.0]), name="ceiling")
    q = np.random.default_rng(3).uniform(robot.lower, robot.upper, size=(12, robot.dof))
    poses = checker.robot.link_poses(q)  # (N, L, 4, 4)
    shapes = {link: read_obj(problems.PANDA_HULLS / f"{link}.obj")[0] for link in LINKS}
    expected = np.array([bottom - max(float((v @ T[:3, :3].T + T[:3, 3])[:, 2].max())
                                      for link, v in shapes.items()
                                      for T in [poses[k, checker.robot.link_index(link)]])
                         for k in range(len(q))])
    got = checker.clearance(scene, q)
    assert (expected > 0).sum() >= 3 and (expected < 0).sum() >= 3  # both cases met
    for e, g in zip(expected, got):
        if e > 0:
            assert g == pytest.approx(e, abs=1e-9)
        else:
            assert g <= 1e-9


def test_the_shipped_panda_gets_the_polytope_checker_with_its_fingers():
    robot = gfcs.Robot.panda()
    assert problems.mesh_checker_for(robot) is problems.shipped_panda_checker()
    wider = robot.with_locked_positions({"panda_finger_joint1": 0.03})
    held = problems.mesh_checker_for(wider)
    assert held is not problems.shipped_panda_checker()
    assert held.robot.locked_positions == pytest.approx(wider.locked_positions)
    other = robot.with_spheres([("panda_hand", [0.0, 0.0, 0.05], 0.1)])
    assert problems.mesh_checker_for(other) is None


def test_moveit_problems_of_the_shipped_panda_are_validated_on_its_polytopes(tmp_path):
    made = generators.generate("box", 1, seed=2)
    generators.write_problems(made, tmp_path)
    loaded = problems.load_mbm_dir(tmp_path)
    assert len(loaded) == 1 and loaded[0].mesh_checker is problems.shipped_panda_checker()
    result = optimize.solve(loaded[0], batches=1, population=8, seed=0, threads=1)
    assert "mesh_clearance" in result.metrics
    assert result.success == (result.metrics["sphere_success"] and result.metrics["mesh_clearance"] > 0.001)


def test_missing_polytope_files_are_named(tmp_path, monkeypatch):
    monkeypatch.setattr(problems, "PANDA_HULLS", tmp_path)
    problems.shipped_panda_checker.cache_clear()
    try:
        with pytest.raises(FileNotFoundError, match="collision polytopes are missing.*reinstall"):
            problems.shipped_panda_checker()
    finally:
        problems.shipped_panda_checker.cache_clear()


def test_the_fitted_planes_do_not_depend_on_the_order_of_the_points():
    """A mesh-like point set (a faceted cylinder with flat caps, whose hull has coplanar points): qhull lists
    its facets in an order that depends on the input's, which the k-means seeding must not see."""
    tool = load_tool()
    rng = np.random.default_rng(3)
    ang = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    rings = [np.column_stack([0.06 * np.cos(ang), 0.06 * np.sin(ang), np.full(48, z)]) for z in (-0.1, 0.0, 0.1)]
    caps = [np.column_stack([0.03 * np.cos(ang[::3]), 0.03 * np.sin(ang[::3]), np.full(16, z)]) for z in (-0.1, 0.1)]
    points = np.vstack(rings + caps)
    dirs = tool.directions(points, 60)
    assert len(dirs) > 26 + 20
    for _ in range(3):
        np.testing.assert_allclose(tool.directions(points[rng.permutation(len(points))], 60), dirs, atol=1e-12)


#: A folded wrist (joint 6 at its lower limit): link7's Franka mesh reaches into link5's by 5.6 mm.
FOLDED_WRIST = np.array([0.0, 0.0, 0.0, -1.5, 0.0, -0.0175, 0.785])


def _pairs_between(robot, a, b):
    links = np.asarray(robot.sphere_links)
    return [(i, j) for i, j in np.asarray(robot.self_collision_pairs) if {links[i], links[j]} == {a, b}]


def test_the_checker_and_the_thin_spheres_check_the_wrist_pair():
    checker = problems.shipped_panda_checker()
    assert float(np.asarray(checker.self_clearance(FOLDED_WRIST[None]))[0]) < -0.004
    opened = FOLDED_WRIST.copy()
    opened[5] = 0.4
    assert float(np.asarray(checker.self_clearance(opened[None]))[0]) > 0.01
    # the covering spheres leave the pair out (they overlap at goals the meshes keep apart); the thin ones don't
    a, b = problems.PANDA_WRIST_PAIR
    assert not _pairs_between(gfcs.Robot.panda(), a, b)
    assert _pairs_between(problems.thin_sphere_model(gfcs.Robot.panda()), a, b)
    shipped, checked = disabled_pairs(gfcs.panda_srdf()), disabled_pairs(problems.panda_srdf_with_wrist_pair())
    assert checked == shipped - {frozenset((a, b))} and len(checked) == len(shipped) - 1


def disabled_pairs(srdf):
    import xml.etree.ElementTree as ET

    return {frozenset((e.get("link1"), e.get("link2"))) for e in ET.fromstring(srdf).iter("disable_collisions")}


def test_the_franka_meshes_touch_at_the_folded_wrist(mbm_panda_dir):
    # independent of the polytopes: MotionBenchMaker's Franka meshes and SRDF, which checks the pair
    franka = problems.mbm_mesh_checker(mbm_panda_dir)
    assert float(np.asarray(franka.self_clearance(FOLDED_WRIST[None]))[0]) < -0.004
