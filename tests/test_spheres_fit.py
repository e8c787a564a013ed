"""The shipped Panda collision spheres and the fitting tool ``tools/fit_spheres.py``.

References are independent of the fit: the MotionBenchMaker Panda collision meshes (coverage is re-measured on
a fresh sample and on every vertex), the URDF joint chain evaluated by yourdfpy (link frames), and synthetic
meshes built by trimesh whose placement in the link frame is recomputed here from the URDF origin.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yourdfpy

from conftest import load_script

REPO_ROOT = Path(__file__).resolve().parent.parent
ASSETS = REPO_ROOT / "crates" / "fabric-core" / "assets"
SPHERES_JSON = ASSETS / "panda_spheres.json"
PANDA_URDF = ASSETS / "panda.urdf"
TOOL = REPO_ROOT / "tools" / "fit_spheres.py"

ARM_LINKS = [f"panda_link{i}" for i in range(8)] + ["panda_hand"]
FINGERS = ["panda_leftfinger", "panda_rightfinger"]
SPHERE_LINKS = ARM_LINKS + FINGERS

#: Largest uncovered distance (m) tolerated on the reference meshes (the brief allows about 5 mm).
COVER_TOL = 0.005


def load_tool():
    """Import tools/fit_spheres.py as a module (it is a script, not part of the package)."""
    return load_script("tools/fit_spheres.py")


fs = load_tool()


def shipped_spheres() -> dict[str, list]:
    return fs.load_spheres_json(SPHERES_JSON)


@pytest.fixture(scope="module")
def mbm_urdf(mbm_panda_dir) -> Path:
    """The MotionBenchMaker Panda URDF (skip/fail rule of conftest's ``require_shared``)."""
    return mbm_panda_dir / "panda.urdf"


# ------------------------------------------------------------------------------------- shipped sphere file


def test_shipped_json_is_well_formed():
    data = json.loads(SPHERES_JSON.read_text())
    entries = data["spheres"]
    assert 0 < len(entries) <= 70
    for i, entry in enumerate(entries):
        assert set(entry) >= {"link", "center", "radius"}, i
        assert isinstance(entry["link"], str), i
        center = entry["center"]
        assert len(center) == 3 and all(isinstance(v, (int, float)) and math.isfinite(v) for v in center), i
        radius = entry["radius"]
        assert isinstance(radius, (int, float)) and math.isfinite(radius) and 0 < radius < 0.5, i
    by_link = shipped_spheres()
    assert set(by_link) == set(SPHERE_LINKS)


def test_shipped_links_exist_in_shipped_urdf():
    root = ET.fromstring(PANDA_URDF.read_text())
    urdf_links = {link.get("name") for link in root.iter("link")}
    missing = set(shipped_spheres()) - urdf_links
    assert not missing, f"sphere links not in {PANDA_URDF}: {missing}"


# ------------------------------------------------------------------------------ against the MBM Panda meshes


@pytest.fixture(scope="module")
def mbm_meshes(mbm_urdf):
    return fs.load_link_meshes(mbm_urdf, links=SPHERE_LINKS)


@pytest.mark.parametrize("link", SPHERE_LINKS)
def test_shipped_spheres_cover_mbm_collision_mesh(mbm_meshes, link):
    mesh = mbm_meshes[link]
    spheres = shipped_spheres()[link]
    # every vertex exactly (up to float rounding), and a fresh sample of surface and interior
    assert fs.excess(np.asarray(mesh.vertices), spheres).max() <= 1e-9
    assert fs.coverage(mesh, spheres, surface_points=30000, grid_points=20000, seed=12345) <= COVER_TOL
    # "not wildly larger than the mesh"
    ratio = fs.union_volume(spheres, 200_000) / fs.mesh_volume(mesh, 40_000)
    assert 1.0 <= ratio < 3.5, ratio  # fitted: 1.4-1.8 on arm links, 2.2 link7, 2.9 fingers


def test_mbm_collision_meshes_are_placed_in_link_frames(mbm_meshes):
    # the right finger's collision origin (rpy 0 0 pi) must be applied: its mesh is the left one turned
    meshes = mbm_meshes
    left, right = (np.asarray(meshes[name].vertices) for name in FINGERS)
    assert left[:, 1].min() > -0.001 and left[:, 1].max() > 0.02  # pad towards +y of the link frame
    assert right[:, 1].max() < 0.001 and right[:, 1].min() < -0.02
    turned = left * np.array([-1.0, -1.0, 1.0])
    assert np.allclose(np.sort(turned, axis=0), np.sort(right, axis=0), atol=1e-9)


def test_shipped_link_frames_equal_mbm_link_frames(mbm_urdf):
    """The fit is done in MBM link frames; the shipped URDF must put those frames at the same places.

    Arm links and hand: same pose relative to panda_link0 at several joint configurations. Fingers: MBM fixes
    them 0.065 m off the hand axis, the shipped model opens them by a joint value; in both the finger frame is
    the hand frame translated along +y (left) / -y (right) by the opening and 0.0584 m along z.
    """
    mbm = yourdfpy.URDF.load(str(mbm_urdf), load_meshes=False, build_collision_scene_graph=False)
    ours = yourdfpy.URDF.load(str(PANDA_URDF), load_meshes=False, build_collision_scene_graph=False)
    arm_joints = [f"panda_joint{i}" for i in range(1, 8)]
    rng = np.random.default_rng(7)
    for q in [np.zeros(7), *rng.uniform(-1.5, 1.5, (3, 7))]:
        cfg = dict(zip(arm_joints, q))
        mbm.update_cfg({name: cfg[name] for name in mbm.actuated_joint_names})
        ours.update_cfg({name: cfg.get(name, 0.04) for name in ours.actuated_joint_names})
        for link in ARM_LINKS:
            a = mbm.get_transform(link, "panda_link0")
            b = ours.get_transform(link, "panda_link0")
            assert np.allclose(a, b, atol=1e-9), (link, q)
    for model, opening in ((mbm, 0.065), (ours, 0.04)):
        model.update_cfg({name: 0.04 for name in model.actuated_joint_names if "finger" in name})
        for link, side in zip(FINGERS, (1.0, -1.0)):
            expected = np.eye(4)
            expected[:3, 3] = [0.0, side * opening, 0.0584]
            assert np.allclose(model.get_transform(link, "panda_hand"), expected, atol=1e-9), link


# ----------------------------------------------------------------------------------- the tool on toy meshes

QUICK = ["--fit-surface-points", "800", "--fit-grid-points", "800", "--outside-grid-points", "3000",
         "--check-surface-points", "6000", "--check-grid-points", "4000", "--iterations", "60",
         "--restarts", "1", "--quiet"]

BOX_EXTENTS = (0.20, 0.10, 0.06)
CAPSULE = dict(height=0.15, radius=0.04)
CAPSULE_ORIGIN = dict(xyz=(0.05, -0.02, 0.3), rpy=(0.3, -0.4, 1.1))
CYLINDER = dict(radius=0.05, length=0.12)


def origin_matrix(xyz, rpy) -> np.ndarray:
    """URDF origin: fixed-axis roll-pitch-yaw, R = Rz(yaw) Ry(pitch) Rx(roll), then translation."""
    roll, pitch, yaw = rpy
    cx, sx, cy, sy, cz, sz = (math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch),
                              math.cos(yaw), math.sin(yaw))
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    out = np.eye(4)
    out[:3, :3] = rz @ ry @ rx
    out[:3, 3] = xyz
    return out


@pytest.fixture(scope="module")
def toy_robot(tmp_path_factory):
    """A URDF with a box mesh (OBJ), a capsule mesh (STL) under a rotated, shifted origin, and a primitive
    cylinder; returns (urdf path, {link: reference mesh in the link frame})."""
    root = tmp_path_factory.mktemp("toy")
    (root / "meshes").mkdir()
    box = trimesh.creation.box(extents=BOX_EXTENTS)
    capsule = trimesh.creation.capsule(**CAPSULE, count=[24, 24])
    box.export(root / "meshes" / "box.obj")
    capsule.export(root / "meshes" / "capsule.stl")
    xyz = " ".join(map(str, CAPSULE_ORIGIN["xyz"]))
    rpy = " ".join(map(str, CAPSULE_ORIGIN["rpy"]))
    urdf = f"""<?xml version="1.0"?>
<robot name="toy">
  <link name="base">
    <collision><geometry><mesh filename="package://toy/meshes/box.obj"/></geometry></collision>
  </link>
  <link name="arm">
    <collision>
      <origin xyz="{xyz}" rpy="{rpy}"/>
      <geometry><mesh filename="meshes/capsule.stl"/></geometry>
    </collision>
  </link>
  <link name="drum">
    <collision><geometry><cylinder radius="{CYLINDER['radius']}" length="{CYLINDER['length']}"/></geometry>
    </collision>
  </link>
  <link name="empty"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="fixed"><parent link="arm"/><child link="drum"/></joint>
  <joint name="j3" type="fixed"><parent link="drum"/><child link="empty"/></joint>
</robot>
"""
    path = root / "toy.urdf"
    path.write_text(urdf)
    placed = capsule.copy()
    placed.apply_transform(origin_matrix(CAPSULE_ORIGIN["xyz"], CAPSULE_ORIGIN["rpy"]))
    return path, {"base": box, "arm": placed}


def run_tool(args: list) -> int:
    """Run the tool as a program (as users do: its BLAS thread setting then takes effect); exit status."""
    done = subprocess.run([sys.executable, str(TOOL), *map(str, args)], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0 or "fit_spheres: error:" in done.stderr, done.stderr
    return done.returncode


def test_tool_covers_box_and_capsule(toy_robot, tmp_path):
    urdf, reference = toy_robot
    out = tmp_path / "spheres.json"
    report = tmp_path / "report.json"
    status = run_tool([urdf, "--out", out, "--report", report, "--max-per-link", "5", "--max-total", "12",
                       "--links", "base", "arm", *QUICK])
    assert status == 0
    spheres = fs.load_spheres_json(out)
    assert set(spheres) == {"base", "arm"}
    assert all(1 <= len(s) <= 5 for s in spheres.values())
    assert sum(len(s) for s in spheres.values()) <= 12
    rng = np.random.default_rng(99)
    for link, mesh in reference.items():
        vertices = np.asarray(mesh.vertices)
        assert fs.excess(vertices, spheres[link]).max() <= 1e-9, link
        surface, _ = trimesh.sample.sample_surface(mesh, 20000, seed=5)
        assert fs.excess(np.asarray(surface), spheres[link]).max() <= 0.002, link
        lo, hi = mesh.bounds
        cloud = rng.uniform(lo, hi, (20000, 3))
        interior = cloud[mesh.contains(cloud)]
        assert len(interior) > 1000
        assert fs.excess(interior, spheres[link]).max() <= 1e-9, link
        # the union is a cover, not a blob: bounded by a few times the solid's volume
        assert fs.union_volume(spheres[link], 100_000) < 3.0 * mesh.volume, link
    rows = {row["link"]: row for row in json.loads(report.read_text())}
    assert set(rows) == {"base", "arm"}
    for link, row in rows.items():
        assert row["spheres"] == len(spheres[link])
        assert row["max_uncovered"] <= 0.002 and row["max_uncovered_vertices"] == 0.0
        assert row["volume_ratio"] >= 1.0


def test_tool_gap_fits_thinner_spheres_within_the_gap(toy_robot, tmp_path):
    urdf, reference = toy_robot
    box = reference["base"]
    covers = {}
    for gap in (0.0, 0.01):
        out = tmp_path / f"gap{gap}.json"
        assert run_tool([urdf, "--out", out, "--links", "base", "--max-per-link", "4", "--gap", gap, *QUICK]) == 0
        covers[gap] = fs.load_spheres_json(out)["base"]
        assert (f"within {gap * 1000:g} mm" in out.read_text()) == (gap > 0)
    surface, _ = trimesh.sample.sample_surface(box, 20000, seed=6)
    points = np.vstack([np.asarray(surface), box.vertices])
    miss = fs.excess(points, covers[0.01])
    # the spheres may miss the mesh, but by no more than the gap (plus the fit's sampling slack) ...
    assert 0.002 < miss.max() <= 0.01 + 0.002
    assert fs.excess(points, covers[0.0]).max() <= 0.002
    # ... and reach beyond it less: a smaller union, and a smaller protrusion
    assert fs.union_volume(covers[0.01], 100_000) < 0.8 * fs.union_volume(covers[0.0], 100_000)
    assert fs.max_protrusion(box, covers[0.01]) < fs.max_protrusion(box, covers[0.0])


def test_union_objective_volume_term_sees_the_shrunk_spheres():
    rng = np.random.default_rng(2)
    targets, outside = rng.normal(size=(50, 3)) * 0.2, rng.normal(size=(300, 3)) * 0.5
    x = np.concatenate([rng.normal(size=6) * 0.2, [0.3, 0.35]])
    plain = fs.UnionObjective(targets, outside, 1e-3, 0.05)
    shrunk = fs.UnionObjective(targets, outside, 1e-3, 0.05, gap=0.1)
    for objective in (plain, shrunk):
        objective.mu = 0.0  # the volume term only
    moved = x.copy()
    moved[6:] -= 0.1
    assert shrunk(x)[0] == pytest.approx(plain(moved)[0], rel=1e-12)
    assert np.allclose(shrunk(x)[1], plain(moved)[1], rtol=1e-12)


def test_tool_covers_primitive_cylinder_and_skips_empty_links(toy_robot, tmp_path):
    urdf, _ = toy_robot
    out = tmp_path / "spheres.json"
    assert run_tool([urdf, "--out", out, "--max-per-link", "4", *QUICK]) == 0
    spheres = fs.load_spheres_json(out)
    assert set(spheres) == {"base", "arm", "drum"}  # "empty" has no collision geometry
    # points on the true (round) cylinder, not its polygonal mesh
    rng = np.random.default_rng(4)
    theta = rng.uniform(0, 2 * np.pi, 5000)
    z = rng.uniform(-CYLINDER["length"] / 2, CYLINDER["length"] / 2, 5000)
    side = np.stack([CYLINDER["radius"] * np.cos(theta), CYLINDER["radius"] * np.sin(theta), z], axis=1)
    rim = side.copy()
    rim[:, 2] = np.where(z > 0, 1.0, -1.0) * CYLINDER["length"] / 2
    assert fs.excess(np.vstack([side, rim]), spheres["drum"]).max() <= 0.001


def test_tool_is_deterministic(toy_robot, tmp_path):
    urdf, _ = toy_robot
    texts = []
    for name in ("a.json", "b.json"):
        assert run_tool([urdf, "--out", tmp_path / name, "--links", "arm", "--max-per-link", "3", *QUICK]) == 0
        texts.append((tmp_path / name).read_text())
    assert texts[0] == texts[1]


def test_tool_reports_bad_input(toy_robot, tmp_path, capsys):
    urdf, _ = toy_robot
    assert fs.main([str(urdf), "--links", "nope", *QUICK]) == 2
    assert "nope" in capsys.readouterr().err
    broken = tmp_path / "broken.urdf"
    broken.write_text(urdf.read_text().replace("box.obj", "missing.obj"))
    assert fs.main([str(broken), "--links", "base", *QUICK]) == 2
    assert "missing.obj" in capsys.readouterr().err
    assert fs.main([str(urdf), "--max-total", "1", *QUICK]) == 2  # three links cannot share one sphere
    assert "--max-total" in capsys.readouterr().err
    assert fs.main([str(urdf), "--gap", "-0.001", *QUICK]) == 2
    assert "--gap" in capsys.readouterr().err
    assert fs.main([str(tmp_path / "absent.urdf"), *QUICK]) == 2
    assert "absent.urdf" in capsys.readouterr().err


def test_winding_number_matches_containment():
    # closed mesh: generalised winding number is 1 inside and 0 outside (trimesh's ray test as reference)
    mesh = trimesh.creation.capsule(height=0.1, radius=0.03, count=[16, 16])
    points = np.random.default_rng(0).uniform(-0.06, 0.06, (3000, 3))
    w = fs.winding_numbers(mesh, points)
    assert np.array_equal(w >= 0.5, mesh.contains(points))
    assert np.allclose(w[w >= 0.5], 1.0, atol=1e-6) and np.allclose(w[w < 0.5], 0.0, atol=1e-6)
    flipped = mesh.copy()
    flipped.invert()
    assert np.array_equal(fs.inside(flipped, points), mesh.contains(points))


def test_union_objective_gradient_matches_finite_differences():
    rng = np.random.default_rng(1)
    objective = fs.UnionObjective(rng.normal(size=(150, 3)) * 0.3, rng.normal(size=(250, 3)) * 0.5, 1e-3, 0.05)
    objective.mu = 10.0
    x = np.concatenate([rng.normal(size=9) * 0.2, [0.3, 0.25, 0.4]])
    _, grad = objective(x)
    h = 1e-6
    numeric = np.array([(objective(x + e)[0] - objective(x - e)[0]) / (2 * h) for e in np.eye(len(x)) * h])
    assert np.allclose(grad, numeric, rtol=1e-5, atol=1e-6 * np.abs(grad).max())
