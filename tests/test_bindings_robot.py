"""gfcs.Robot bindings: shapes, forward kinematics against yourdfpy, Jacobians against finite differences,
URDF options, sphere and SRDF inputs, and the exceptions raised for bad input."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

import gfcs

yourdfpy = pytest.importorskip("yourdfpy")

RNG = np.random.default_rng(7)
FK_TOL = 1e-9


def random_q(robot: gfcs.Robot, n: int) -> np.ndarray:
    """n configurations uniform within the joint limits, (n, dof)."""
    return RNG.uniform(robot.lower, robot.upper, size=(n, robot.dof))


def load_yourdfpy(path: Path) -> "yourdfpy.URDF":
    return yourdfpy.URDF.load(
        str(path),
        load_meshes=False,
        build_scene_graph=True,
        build_collision_scene_graph=False,
        load_collision_meshes=False,
    )


def yourdfpy_fk(urdf, robot: gfcs.Robot, q: np.ndarray, extra=None) -> np.ndarray:
    """Poses (L, 4, 4) of robot.link_names in the frame of robot.base_link, computed by yourdfpy."""
    cfg = dict(zip(robot.joint_names, q))
    cfg.update(extra or {})
    urdf.update_cfg(cfg)
    return np.stack([urdf.get_transform(link, robot.base_link) for link in robot.link_names])


@pytest.fixture(scope="module")
def panda() -> gfcs.Robot:
    return gfcs.Robot.panda()


@pytest.fixture(scope="module")
def panda_urdf_path(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("urdf") / "panda.urdf"
    path.write_text(gfcs.panda_urdf())
    return path


# ----------------------------------------------------------------------------------------------- shapes


def test_panda_properties(panda):
    assert panda.name == "panda"
    assert panda.dof == 7
    assert panda.joint_names == [f"panda_joint{i}" for i in range(1, 8)]
    assert panda.ee_link == "panda_hand"
    assert panda.base_link == "panda_link0"
    assert panda.link_names[0] == "panda_link0"
    for arr in (panda.lower, panda.upper, panda.velocity_limits):
        assert arr.shape == (7,) and arr.dtype == np.float64
    assert np.all(panda.lower < panda.upper)
    assert np.all(panda.velocity_limits > 0)
    s = len(panda.sphere_links)
    assert s > 0
    assert panda.sphere_radii.shape == (s,)
    assert np.all(panda.sphere_radii > 0)
    assert panda.sphere_centers_local.shape == (s, 3)
    assert set(panda.sphere_links) <= set(panda.link_names)
    pairs = panda.self_collision_pairs
    assert pairs.ndim == 2 and pairs.shape[1] == 2 and pairs.dtype == np.int64
    assert np.all(pairs[:, 0] < pairs[:, 1]) and np.all(pairs >= 0) and np.all(pairs < s)
    assert panda.link_index("panda_hand") == panda.link_names.index("panda_hand")
    assert "panda" in repr(panda)


def test_batch_shapes_match_single(panda):
    qs = random_q(panda, 4)
    n_links, n_spheres = len(panda.link_names), len(panda.sphere_radii)
    poses = panda.link_poses(qs)
    centers = panda.sphere_centers(qs)
    ee = panda.ee_position(qs)
    assert poses.shape == (4, n_links, 4, 4)
    assert centers.shape == (4, n_spheres, 3)
    assert ee.shape == (4, 3)
    for i, q in enumerate(qs):
        assert panda.link_poses(q).shape == (n_links, 4, 4)
        np.testing.assert_array_equal(panda.link_poses(q), poses[i])
        np.testing.assert_array_equal(panda.sphere_centers(list(q)), centers[i])
        np.testing.assert_array_equal(panda.ee_position(tuple(q)), ee[i])
    assert panda.link_poses(np.zeros((0, 7))).shape == (0, n_links, 4, 4)


def test_accepts_any_float_convertible(panda):
    q_int = np.zeros(7, dtype=np.int32)
    q32 = np.zeros(7, dtype=np.float32)
    q_strided = np.zeros((7, 2))[:, 0]
    ref = panda.link_poses(np.zeros(7))
    for q in (q_int, q32, q_strided, [0] * 7):
        np.testing.assert_array_equal(panda.link_poses(q), ref)


def test_ee_position_is_ee_link_translation(panda):
    qs = random_q(panda, 3)
    idx = panda.link_index(panda.ee_link)
    np.testing.assert_allclose(panda.ee_position(qs), panda.link_poses(qs)[:, idx, :3, 3], atol=1e-12)


# -------------------------------------------------------------------------------- FK against yourdfpy


def test_inverse_kinematics_reaches_fk_targets_single_and_batched(panda):
    rng = np.random.default_rng(5)
    lo, up = np.asarray(panda.lower), np.asarray(panda.upper)
    truth = rng.uniform(lo + 0.3, up - 0.3, size=(6, 7))
    start = np.clip(truth + rng.uniform(-0.2, 0.2, size=truth.shape), lo, up)
    poses = np.asarray(panda.link_poses(truth))[:, panda.link_index(panda.ee_link)]
    axes = np.stack([poses[:, :3, 0], poses[:, :3, 2]], axis=1)  # (6, 2, 3)
    q = panda.inverse_kinematics(start, poses[:, :3, 3], axes=axes, iterations=200)
    assert q.shape == (6, 7) and np.all(q >= lo) and np.all(q <= up)
    reached = np.asarray(panda.link_poses(q))[:, panda.link_index(panda.ee_link)]
    np.testing.assert_allclose(reached[:, :3, 3], poses[:, :3, 3], atol=1e-5)
    np.testing.assert_allclose(reached[:, :3, [0, 2]], poses[:, :3, [0, 2]], atol=1e-4)
    # one configuration, position only, another link by name: (dof,) out
    one = panda.inverse_kinematics(start[0], [0.4, 0.1, 0.5], link="panda_link7", iterations=100)
    assert one.shape == (7,)
    np.testing.assert_allclose(panda.link_poses(one)[panda.link_index("panda_link7")][:3, 3], [0.4, 0.1, 0.5],
                               atol=1e-4)


@pytest.mark.parametrize("kwargs, error, match", [
    ({"q_init": np.zeros((2, 7)), "positions": np.zeros(3)}, gfcs.ShapeError, "positions"),
    ({"q_init": np.zeros(7), "positions": np.zeros(3), "axes": np.zeros((3, 3))}, gfcs.ShapeError, "axes"),
    ({"q_init": np.zeros(7), "positions": [0.0, np.nan, 0.0]}, gfcs.NonFiniteError, "positions"),
    ({"q_init": np.zeros(7), "positions": np.zeros(3), "damping": 0.0}, gfcs.InvalidValueError, "damping"),
    ({"q_init": np.zeros(7), "positions": np.zeros(3), "link": "nope"}, gfcs.LinkError, "nope"),
])
def test_inverse_kinematics_rejects_bad_input(panda, kwargs, error, match):
    with pytest.raises(error, match=match):
        panda.inverse_kinematics(**kwargs)


def test_self_clearance_is_the_minimum_over_the_sphere_pairs(panda):
    """Robot.self_clearance against the formula over every self-collision pair, from the sphere centres."""
    q = random_q(panda, 40)
    pairs, radii = np.asarray(panda.self_collision_pairs), np.asarray(panda.sphere_radii)
    c = np.asarray(panda.sphere_centers(q))
    expect = (np.linalg.norm(c[:, pairs[:, 0]] - c[:, pairs[:, 1]], axis=2)
              - radii[pairs[:, 0]] - radii[pairs[:, 1]]).min(axis=1)
    got = panda.self_clearance(q)
    assert got.shape == (40,)
    np.testing.assert_allclose(got, expect, atol=1e-14, rtol=0)
    assert panda.self_clearance(q[0]).shape == () and float(panda.self_clearance(q[0])) == pytest.approx(expect[0])
    # a robot without pairs: +inf; a bad shape: the usual ShapeError
    bare = gfcs.Robot.from_urdf(gfcs.panda_urdf())
    assert np.all(np.isinf(bare.self_clearance(q[:3])))
    with pytest.raises(gfcs.ShapeError, match="q"):
        panda.self_clearance(np.zeros(6))


def numpy_point_ik(robot, q, xt, link, point, axis, approach, cone_deg, lo, up, iterations=150, tol=2e-3):
    """Reference of Robot.point_ik in numpy (the generators' former loop): DLS on [x* − x; 0.5 (a* − R·axis)]
    with λ² = 0.0025, steps ≤ 0.3 rad, clipped; converged tested before each step."""
    cos_cone, w = math.cos(math.radians(cone_deg)), 0.5
    q = np.clip(q, lo, up)
    for _ in range(iterations):
        pose = np.asarray(robot.link_poses(q))[link]
        err = xt - (pose[:3, :3] @ point + pose[:3, 3])
        rows, errs = [np.asarray(robot.point_jacobian(q, link, point))], [err]
        a = pose[:3, :3] @ axis
        if approach is not None:
            rows.append(w * np.asarray(robot.axis_jacobian(q, link, axis)))
            errs.append(w * (approach - a))
        if np.linalg.norm(err) < tol and (approach is None or float(a @ approach) >= cos_cone):
            return q, True
        jac, e = np.vstack(rows), np.concatenate(errs)
        dq = jac.T @ np.linalg.solve(jac @ jac.T + 0.05**2 * np.eye(jac.shape[0]), e)
        dq *= min(1.0, 0.3 / max(np.linalg.norm(dq), 1e-300))
        q = np.clip(q + dq, lo, up)
    return q, False


def test_point_ik_equals_its_numpy_reference(panda):
    """Random starts and targets, with and without an approach cone, converging or not: the core's descent
    is the numpy iteration to round-off, and a converged result meets the target."""
    rng = np.random.default_rng(0)
    link, tcp, z = panda.link_index(panda.ee_link), np.array([0.0, 0.0, 0.1034]), np.array([0.0, 0.0, 1.0])
    lo, up = np.asarray(panda.lower) + 0.05, np.asarray(panda.upper) - 0.05
    outcomes = set()
    for i in range(30):
        q, xt = rng.uniform(lo, up), rng.uniform([0.2, -0.5, 0.1], [0.7, 0.5, 0.8])
        approach = None if i % 2 else np.array([0.0, 0.0, -1.0])
        ref, ref_ok = numpy_point_ik(panda, q, xt, link, tcp, z, approach, 25.0, lo, up)
        got, ok = panda.point_ik(q, xt, link=link, point=tcp, approach=approach, cone_deg=25.0, lower=lo, upper=up)
        assert ok == ref_ok and got.shape == (7,)
        np.testing.assert_allclose(got, ref, atol=1e-10, rtol=0)
        assert np.all(got >= lo) and np.all(got <= up)
        if ok:
            pose = panda.link_poses(got)[link]
            assert np.linalg.norm(pose[:3, :3] @ tcp + pose[:3, 3] - xt) < 2e-3
            if approach is not None:
                assert pose[:3, 2] @ approach >= math.cos(math.radians(25.0))
        outcomes.add(ok)
    assert outcomes == {True, False}  # both branches exercised
    # defaults: the end-effector link's origin, the joint limits
    q, ok = panda.point_ik([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785], [0.4, 0.1, 0.5])
    assert ok and np.linalg.norm(panda.ee_position(q) - [0.4, 0.1, 0.5]) < 2e-3


@pytest.mark.parametrize("kwargs, error, match", [
    ({"position": np.zeros(2)}, gfcs.ShapeError, "position"),
    ({"position": [0.0, np.nan, 0.0]}, gfcs.NonFiniteError, "position"),
    ({"position": np.zeros(3), "approach": np.zeros(3)}, gfcs.InvalidValueError, "approach"),
    ({"position": np.zeros(3), "lower": np.ones(7), "upper": np.zeros(7)}, gfcs.InvalidValueError, "lower"),
    ({"position": np.zeros(3), "upper": np.zeros(6)}, gfcs.ShapeError, "upper"),
    ({"position": np.zeros(3), "max_step": 0.0}, gfcs.InvalidValueError, "max_step"),
    ({"position": np.zeros(3), "cone_deg": -1.0}, gfcs.InvalidValueError, "cone_deg"),
    ({"position": np.zeros(3), "cone_deg": float("nan")}, gfcs.InvalidValueError, "cone_deg"),
    ({"position": np.zeros(3), "link": "nope"}, gfcs.LinkError, "nope"),
])
def test_point_ik_rejects_bad_input(panda, kwargs, error, match):
    with pytest.raises(error, match=match):
        panda.point_ik(np.zeros(7), **kwargs)


def test_panda_fk_and_spheres_match_yourdfpy(panda, panda_urdf_path):
    urdf = load_yourdfpy(panda_urdf_path)
    # the shipped model locks the fingers open at 0.04 m (Robot.panda docs)
    fingers = {"panda_finger_joint1": 0.04}
    links = panda.link_names
    for q in random_q(panda, 6):
        ref = yourdfpy_fk(urdf, panda, q, fingers)
        np.testing.assert_allclose(panda.link_poses(q), ref, atol=FK_TOL, rtol=0)
        # sphere centres: T_link · c_local
        local = panda.sphere_centers_local
        expect = np.stack(
            [ref[links.index(l)][:3, :3] @ c + ref[links.index(l)][:3, 3] for l, c in zip(panda.sphere_links, local)]
        )
        np.testing.assert_allclose(panda.sphere_centers(q), expect, atol=FK_TOL, rtol=0)


def test_panda_from_urdf_file_matches_shipped(panda, panda_urdf_path):
    robot = gfcs.Robot.from_urdf(panda_urdf_path, ee_link="panda_hand")
    assert robot.joint_names == panda.joint_names
    q = random_q(panda, 1)[0]
    # no locked finger position given: fingers at 0 clamped into limits, which moves only the finger links
    arm = [panda.link_names.index(f"panda_link{i}") for i in range(8)]
    arm_r = [robot.link_names.index(f"panda_link{i}") for i in range(8)]
    np.testing.assert_allclose(robot.link_poses(q)[arm_r], panda.link_poses(q)[arm], atol=FK_TOL)
    # the same text, as a string and as os.PathLike / str
    r2 = gfcs.Robot.from_urdf(panda_urdf_path.read_text(), ee_link="panda_hand")
    r3 = gfcs.Robot.from_urdf(str(panda_urdf_path), ee_link="panda_hand")
    np.testing.assert_array_equal(r2.link_poses(q), robot.link_poses(q))
    np.testing.assert_array_equal(r3.link_poses(q), robot.link_poses(q))


def test_mbm_panda_fk_and_spheres_match_yourdfpy(mbm_panda_dir):
    path = mbm_panda_dir / "panda_spherized.urdf"
    robot = gfcs.Robot.from_urdf(path)
    assert robot.dof == 7
    urdf = load_yourdfpy(path)
    links = robot.link_names
    # reference spheres straight from the URDF <collision><sphere> elements, per link
    ref_spheres: dict[str, list] = {}
    for link in urdf.robot.links:
        for col in link.collisions:
            if col.geometry.sphere is not None:
                origin = col.origin if col.origin is not None else np.eye(4)
                ref_spheres.setdefault(link.name, []).append((col.geometry.sphere.radius, origin[:3, 3]))
    assert sum(len(v) for v in ref_spheres.values()) == len(robot.sphere_radii) == 59
    for q in random_q(robot, 5):
        ref = yourdfpy_fk(urdf, robot, q)
        np.testing.assert_allclose(robot.link_poses(q), ref, atol=FK_TOL, rtol=0)
        centers = robot.sphere_centers(q)
        for link, spheres in ref_spheres.items():
            t = ref[links.index(link)]
            expect = sorted((r, *(t[:3, :3] @ c + t[:3, 3])) for r, c in spheres)
            mine = sorted(
                (r, *c)
                for r, c, l in zip(robot.sphere_radii, centers, robot.sphere_links)
                if l == link
            )
            np.testing.assert_allclose(np.array(mine), np.array(expect), atol=FK_TOL, rtol=0)


def test_mbm_panda_srdf_prunes_pairs_and_meshes_resolve(mbm_panda_dir):
    plain = gfcs.Robot.from_urdf(mbm_panda_dir / "panda_spherized.urdf")
    pruned = gfcs.Robot.from_urdf(mbm_panda_dir / "panda_spherized.urdf", srdf=mbm_panda_dir / "panda.srdf")
    assert 0 < len(pruned.self_collision_pairs) < len(plain.self_collision_pairs)
    also = plain.with_srdf((mbm_panda_dir / "panda.srdf").read_text())
    np.testing.assert_array_equal(also.self_collision_pairs, pruned.self_collision_pairs)
    # mesh geometry of the mesh URDF resolves to existing files
    meshy = gfcs.Robot.from_urdf(mbm_panda_dir / "panda.urdf")
    geoms = meshy.collision_geometry()
    meshes = [g for g in geoms if g["type"] == "mesh"]
    assert meshes, "the MBM panda.urdf has collision meshes"
    for g in meshes:
        assert g["exists"] and os.path.isfile(g["path"])
        assert g["scale"].shape == (3,) and g["origin"].shape == (4, 4)
        assert g["link"] in meshy.link_names


# ------------------------------------------------------------------------ Jacobians vs finite differences


def fk_point(robot, q, link, p):
    t = robot.link_poses(q)[robot.link_index(link)]
    return t[:3, :3] @ p + t[:3, 3]


def fk_axis(robot, q, link, a):
    return robot.link_poses(q)[robot.link_index(link)][:3, :3] @ a


@pytest.mark.parametrize("link", ["panda_link3", "panda_hand", "panda_link7"])
def test_point_jacobian_and_jdot_qdot_vs_finite_differences(panda, link):
    p = np.array([0.03, -0.02, 0.05])
    h = 1e-6
    for q in random_q(panda, 3):
        jac = panda.point_jacobian(q, link, p)
        assert jac.shape == (3, 7)
        fd = np.stack(
            [(fk_point(panda, q + h * e, link, p) - fk_point(panda, q - h * e, link, p)) / (2 * h) for e in np.eye(7)],
            axis=1,
        )
        np.testing.assert_allclose(jac, fd, atol=1e-7)
        # J̇q̇ = d²/dt² x(q + t q̇) at t = 0 (second central difference along q̇)
        qd = RNG.normal(size=7)
        hh = 1e-4
        x = lambda s: fk_point(panda, q + s * qd, link, p)  # noqa: E731
        fd2 = (x(hh) - 2 * x(0.0) + x(-hh)) / hh**2
        jdq = panda.point_jdot_qdot(q, qd, link, p)
        assert jdq.shape == (3,)
        np.testing.assert_allclose(jdq, fd2, atol=1e-5 * max(1.0, np.abs(fd2).max()))
    # link given by index, point defaulting to the link origin
    q = random_q(panda, 1)[0]
    np.testing.assert_array_equal(
        panda.point_jacobian(q, panda.link_index(link)), panda.point_jacobian(q, link, np.zeros(3))
    )


def test_axis_jacobian_and_jdot_qdot_vs_finite_differences(panda):
    a = np.array([0.0, 0.0, 1.0])
    link = "panda_hand"
    h = 1e-6
    for q in random_q(panda, 3):
        jac = panda.axis_jacobian(q, link, a)
        fd = np.stack(
            [(fk_axis(panda, q + h * e, link, a) - fk_axis(panda, q - h * e, link, a)) / (2 * h) for e in np.eye(7)],
            axis=1,
        )
        np.testing.assert_allclose(jac, fd, atol=1e-7)
        qd = RNG.normal(size=7)
        hh = 1e-4
        x = lambda s: fk_axis(panda, q + s * qd, link, a)  # noqa: E731
        fd2 = (x(hh) - 2 * x(0.0) + x(-hh)) / hh**2
        np.testing.assert_allclose(panda.axis_jdot_qdot(q, qd, link, a), fd2, atol=1e-5 * max(1.0, np.abs(fd2).max()))


# ------------------------------------------------------------------------------------ options and inputs

TWO_LINK = """<robot name="two">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="2" effort="1"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="1 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.5" velocity="1" effort="1"/></joint>
  <joint name="jt" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.1 0 0"/></joint>
</robot>"""


def test_two_link_closed_form_and_options():
    robot = gfcs.Robot.from_urdf(TWO_LINK)
    assert robot.joint_names == ["j1", "j2"]
    assert robot.ee_link == "tip"
    np.testing.assert_array_equal(robot.lower, [-1, 0])
    np.testing.assert_array_equal(robot.upper, [1, 0.5])
    np.testing.assert_array_equal(robot.velocity_limits, [2, 1])
    th, s = 0.3, 0.2
    r = 1.0 + s + 0.1
    np.testing.assert_allclose(robot.ee_position([th, s]), [r * np.cos(th), r * np.sin(th), 0], atol=1e-12)
    # explicit options
    sub = gfcs.Robot.from_urdf(TWO_LINK, ee_link="l1", active_joints=["j1"])
    assert sub.dof == 1 and sub.ee_link == "l1"
    based = gfcs.Robot.from_urdf(TWO_LINK, base_link="base", ee_link="l2")
    assert based.base_link == "base" and based.ee_link == "l2"


def test_spheres_from_list_and_json_file(tmp_path):
    spheres = [("l1", [0.5, 0, 0], 0.1), (3, (0.0, 0.0, 0.0), 0.05)]
    robot = gfcs.Robot.from_urdf(TWO_LINK, spheres=spheres)
    assert robot.sphere_links == ["l1", "tip"]
    np.testing.assert_array_equal(robot.sphere_radii, [0.1, 0.05])
    centers = robot.sphere_centers([0.5, 0.1])
    np.testing.assert_allclose(centers[0], [0.5 * np.cos(0.5), 0.5 * np.sin(0.5), 0], atol=1e-12)
    np.testing.assert_allclose(centers[1], robot.ee_position([0.5, 0.1]), atol=1e-12)
    path = tmp_path / "spheres.json"
    path.write_text(json.dumps({"spheres": [{"link": "l1", "center": [0.5, 0, 0], "radius": 0.1},
                                            {"link": "tip", "center": [0, 0, 0], "radius": 0.05}]}))
    from_file = gfcs.Robot.from_urdf(TWO_LINK, spheres=path)
    np.testing.assert_array_equal(from_file.sphere_centers_local, robot.sphere_centers_local)
    again = gfcs.Robot.from_urdf(TWO_LINK).with_spheres(str(path))
    np.testing.assert_array_equal(again.sphere_radii, robot.sphere_radii)


# ------------------------------------------------------------------------------------------ bad input


def test_malformed_urdf_raises_urdf_error(tmp_path):
    with pytest.raises(gfcs.UrdfError, match="<string>"):
        gfcs.Robot.from_urdf("<robot name='x'><link name='a'></robot>")
    bad = tmp_path / "broken.urdf"
    bad.write_text("<robot name='x'><link name='a'>")
    with pytest.raises(gfcs.UrdfError, match="broken.urdf"):
        gfcs.Robot.from_urdf(bad)
    # a multi-DOF joint is held at its identity pose (MoveIt's default), and planning it is refused by name
    planar = TWO_LINK.replace('type="prismatic"', 'type="planar"')
    with pytest.raises(gfcs.InvalidValueError, match="'j2': is a planar joint"):
        gfcs.Robot.from_urdf(planar, active_joints=["j1", "j2"])


def test_missing_file_raises_io_error(tmp_path):
    missing = tmp_path / "nope.urdf"
    with pytest.raises(OSError, match="nope.urdf") as info:
        gfcs.Robot.from_urdf(missing)
    assert isinstance(info.value, gfcs.GfcsError)
    with pytest.raises(gfcs.IoError, match="nospheres.json"):
        gfcs.Robot.from_urdf(TWO_LINK, spheres=tmp_path / "nospheres.json")


def test_missing_link_and_joint_raise_link_error(panda):
    with pytest.raises(gfcs.LinkError, match="no_such_link"):
        gfcs.Robot.from_urdf(TWO_LINK, ee_link="no_such_link")
    with pytest.raises(KeyError):
        gfcs.Robot.from_urdf(TWO_LINK, active_joints=["j1", "no_such_joint"])
    with pytest.raises(gfcs.LinkError, match="no_such_link"):
        panda.point_jacobian(np.zeros(7), "no_such_link")
    with pytest.raises(gfcs.LinkError, match="#99"):
        panda.point_jacobian(np.zeros(7), 99)
    with pytest.raises(gfcs.LinkError, match="bogus"):
        panda.link_index("bogus")
    with pytest.raises(gfcs.LinkError, match="nolink"):
        gfcs.Robot.from_urdf(TWO_LINK, spheres=[("nolink", [0, 0, 0], 0.1)])


def test_wrong_shapes_name_the_argument(panda):
    with pytest.raises(gfcs.ShapeError, match=r"q: expected shape \(7,\) or \(N, 7\), got \(3,\)"):
        panda.link_poses([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"q: expected shape \(7,\) or \(N, 7\), got \(2, 3, 7\)"):
        panda.sphere_centers(np.zeros((2, 3, 7)))
    with pytest.raises(gfcs.ShapeError, match=r"qd: expected shape \(7,\), got \(6,\)"):
        panda.point_jdot_qdot(np.zeros(7), np.zeros(6), "panda_hand")
    with pytest.raises(gfcs.ShapeError, match=r"point: expected shape \(3,\)"):
        panda.point_jacobian(np.zeros(7), "panda_hand", [1.0, 2.0])
    with pytest.raises(gfcs.ShapeError, match="q: cannot convert"):
        panda.ee_position("not a number")
    with pytest.raises(gfcs.ShapeError, match="centre"):
        gfcs.Robot.from_urdf(TWO_LINK, spheres=[("l1", [0, 0], 0.1)])


def test_nan_inputs_raise_non_finite_error(panda):
    q = np.zeros(7)
    q[3] = np.nan
    with pytest.raises(gfcs.NonFiniteError, match="q contains NaN"):
        panda.link_poses(q)
    with pytest.raises(gfcs.NonFiniteError, match="q"):
        panda.ee_position(np.full((2, 7), np.inf))
    with pytest.raises(gfcs.NonFiniteError, match="qd"):
        panda.point_jdot_qdot(np.zeros(7), [np.inf] + [0] * 6, "panda_hand")


def test_bad_sphere_radius_raises(tmp_path):
    with pytest.raises(gfcs.InvalidValueError, match="sphere 0"):
        gfcs.Robot.from_urdf(TWO_LINK, spheres=[("l1", [0, 0, 0], -0.1)])
    bad = tmp_path / "bad.json"
    bad.write_text('{"spheres": [{"link": "l1", "center": [0, 0, 0]}]}')
    with pytest.raises(gfcs.FormatError, match="bad.json"):
        gfcs.Robot.from_urdf(TWO_LINK, spheres=bad)


def test_locked_positions_keep_one_order_in_every_process():
    """Requests and results written from ``locked_positions`` must not depend on a process's hash seed."""
    import subprocess
    import sys

    code = ("import gfcs\n"
            "names = gfcs.Robot.panda().joint_names\n"
            "locked = gfcs.Robot.from_urdf(gfcs.panda_urdf(), active_joints=names[:2]).locked_positions\n"
            "print(','.join(locked))")
    orders = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                             timeout=120).stdout.strip() for _ in range(4)}
    assert len(orders) == 1, orders
    assert orders.pop().split(",")[:5] == [f"panda_joint{k}" for k in range(3, 8)]
