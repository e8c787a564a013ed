"""gfcs.Scene bindings: every obstacle type against closed-form distances, derivatives against finite
differences, poses, motion, MoveIt YAML (handwritten and MotionBenchMaker), and errors."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import gfcs

RNG = np.random.default_rng(3)


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def pose(r: np.ndarray, t) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = t
    return m


def box_sdf(p_local: np.ndarray, half: np.ndarray) -> float:
    """Exact signed distance to an axis-aligned box centred at the origin."""
    q = np.abs(p_local) - half
    return float(np.linalg.norm(np.maximum(q, 0.0)) + min(q.max(), 0.0))


def cylinder_sdf(p: np.ndarray, half_h: float, r: float) -> float:
    d = np.array([np.hypot(p[0], p[1]) - r, abs(p[2]) - half_h])
    return float(np.linalg.norm(np.maximum(d, 0.0)) + min(d.max(), 0.0))


def capsule_sdf(p: np.ndarray, half_h: float, r: float) -> float:
    z = np.clip(p[2], -half_h, half_h)
    return float(np.linalg.norm(p - np.array([0, 0, z])) - r)


CUBE_V = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
# 12 outward triangles of the unit cube (vertex index = 4x + 2y + z with x, y, z in {0, 1})
CUBE_F = np.array(
    [
        [0, 1, 3], [0, 3, 2],  # x = -0.5
        [4, 6, 7], [4, 7, 5],  # x = +0.5
        [0, 4, 5], [0, 5, 1],  # y = -0.5
        [2, 3, 7], [2, 7, 6],  # y = +0.5
        [0, 2, 6], [0, 6, 4],  # z = -0.5
        [1, 5, 7], [1, 7, 3],  # z = +0.5
    ]
)


def write_cube_obj(path, scale=1.0):
    lines = [f"v {x * scale} {y * scale} {z * scale}" for x, y, z in CUBE_V]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in CUBE_F]
    path.write_text("\n".join(lines) + "\n")


def sample_points(n=40, lo=-1.5, hi=1.5):
    return RNG.uniform(lo, hi, size=(n, 3))


# ------------------------------------------------------------------------------- closed-form distances


def test_sphere_distance_and_shapes():
    scene = gfcs.Scene()
    assert len(scene) == 0
    pts = sample_points()
    np.testing.assert_array_equal(scene.signed_distance(pts), np.full(len(pts), np.inf))
    sid = scene.add_sphere([0.1, -0.2, 0.3], 0.25, name="ball")
    assert isinstance(sid, int) and len(scene) == 1
    d = scene.signed_distance(pts)
    assert d.shape == (len(pts),) and d.dtype == np.float64
    np.testing.assert_allclose(d, np.linalg.norm(pts - [0.1, -0.2, 0.3], axis=1) - 0.25, atol=1e-12)
    one = scene.signed_distance([0.1, -0.2, 1.0])
    assert isinstance(one, float) and abs(one - 0.45) < 1e-12
    (info,) = scene.obstacles()
    assert info["id"] == sid and info["name"] == "ball" and info["type"] == "sphere"
    np.testing.assert_array_equal(info["size"], [0.25])
    np.testing.assert_array_equal(info["pose"][:3, 3], [0.1, -0.2, 0.3])
    np.testing.assert_array_equal(info["velocity"], np.zeros(3))
    assert scene.get(sid)["name"] == "ball"
    assert scene.ids() == [sid]


def test_box_full_sizes_with_matrix_and_quaternion_poses():
    size = np.array([0.4, 0.2, 0.6])
    r = rot_z(0.7)
    t = np.array([0.3, 0.1, -0.2])
    a = gfcs.Scene()
    a.add_box(size, pose(r, t))
    b = gfcs.Scene()
    quat = [0.0, 0.0, np.sin(0.35), np.cos(0.35)]  # xyzw for a rotation of 0.7 rad about z
    b.add_box(size, (t, quat))
    pts = sample_points(60, -1, 1)
    expect = [box_sdf(r.T @ (p - t), size / 2) for p in pts]
    np.testing.assert_allclose(a.signed_distance(pts), expect, atol=1e-9)
    np.testing.assert_allclose(b.signed_distance(pts), expect, atol=1e-9)
    np.testing.assert_allclose(a.obstacles()[0]["size"], size)
    np.testing.assert_allclose(b.obstacles()[0]["pose"], pose(r, t), atol=1e-12)


def test_cylinder_capsule_halfspace_pointcloud():
    pts = sample_points(60, -1, 1)
    s = gfcs.Scene()
    s.add_cylinder(0.8, 0.3)
    np.testing.assert_allclose(s.signed_distance(pts), [cylinder_sdf(p, 0.4, 0.3) for p in pts], atol=1e-9)
    s = gfcs.Scene()
    s.add_capsule(0.8, 0.3)
    np.testing.assert_allclose(s.signed_distance(pts), [capsule_sdf(p, 0.4, 0.3) for p in pts], atol=1e-9)
    s = gfcs.Scene()
    n = np.array([1.0, 2.0, 2.0])
    s.add_halfspace(normal=n, offset=0.3)
    np.testing.assert_allclose(s.signed_distance(pts), pts @ (n / 3) - 0.3, atol=1e-12)
    s2 = gfcs.Scene()
    s2.add_halfspace(pose=pose(np.eye(3), [0, 0, 0.2]))
    np.testing.assert_allclose(s2.signed_distance(pts), pts[:, 2] - 0.2, atol=1e-12)
    assert s2.obstacles()[0]["type"] == "half_space"
    cloud = RNG.uniform(-0.5, 0.5, size=(50, 3))
    s = gfcs.Scene()
    cid = s.add_point_cloud(cloud, radius=0.02, pose=pose(np.eye(3), [0.1, 0, 0]))
    brute = np.linalg.norm(pts[:, None, :] - (cloud + [0.1, 0, 0])[None], axis=2).min(axis=1) - 0.02
    np.testing.assert_allclose(s.signed_distance(pts), brute, atol=1e-12)
    np.testing.assert_array_equal(s.get(cid)["size"], [50, 0.02])


def test_mesh_from_arrays_and_file_matches_box(tmp_path):
    pts = sample_points(40, -1.2, 1.2)
    expect = [box_sdf(p, np.full(3, 0.5)) for p in pts]
    s = gfcs.Scene()
    mid = s.add_mesh((CUBE_V, CUBE_F))
    assert s.get(mid)["type"] == "mesh"
    np.testing.assert_allclose(s.signed_distance(pts), expect, atol=1e-9)
    obj = tmp_path / "cube.obj"
    write_cube_obj(obj, scale=0.5)
    s = gfcs.Scene()
    s.add_mesh(obj, scale=[2.0, 2.0, 2.0])
    np.testing.assert_allclose(s.signed_distance(pts), expect, atol=1e-9)
    s = gfcs.Scene()
    s.add_mesh(str(obj))  # a 0.5 m cube
    np.testing.assert_allclose(s.signed_distance(pts), [box_sdf(p, np.full(3, 0.25)) for p in pts], atol=1e-9)


# ------------------------------------------------------------------------------------------ derivatives


@pytest.mark.parametrize(
    "add",
    [
        lambda s: s.add_sphere([0.1, 0, 0], 0.2),
        lambda s: s.add_box([0.4, 0.3, 0.2], pose(rot_z(0.3), [0, 0.1, 0])),
        lambda s: s.add_cylinder(0.5, 0.2),
        lambda s: s.add_capsule(0.5, 0.2),
    ],
)
def test_distance_details_gradient_and_hessian_vs_finite_differences(add):
    s = gfcs.Scene()
    oid = add(s)
    h = 1e-5
    checked = 0
    for p in sample_points(30, -0.8, 0.8):
        (info,) = s.distance_details(p)
        assert info["obstacle"] == oid
        assert abs(info["distance"] - s.signed_distance(p)) < 1e-12
        fd = np.array([(s.signed_distance(p + h * e) - s.signed_distance(p - h * e)) / (2 * h) for e in np.eye(3)])
        if not np.allclose(np.linalg.norm(fd), 1.0, atol=1e-4):
            continue  # next to an edge or the medial axis: the distance is not differentiable there
        np.testing.assert_allclose(info["gradient"], fd, atol=1e-5)
        grad = lambda x: s.distance_details(x)[0]["gradient"]  # noqa: E731
        fdh = np.stack([(grad(p + h * e) - grad(p - h * e)) / (2 * h) for e in np.eye(3)], axis=1)
        if np.abs(fdh).max() < 1e3:
            np.testing.assert_allclose(info["hessian"], fdh, atol=1e-3 * max(1, np.abs(fdh).max()))
        checked += 1
    assert checked > 5


def test_distance_details_filters_by_max_distance_and_sorts():
    s = gfcs.Scene()
    far = s.add_sphere([2.0, 0, 0], 0.1)
    near = s.add_sphere([0.5, 0, 0], 0.1)
    infos = s.distance_details([0.0, 0, 0])
    assert [i["obstacle"] for i in infos] == [near, far]
    assert [i["obstacle"] for i in s.distance_details([0.0, 0, 0], max_distance=1.0)] == [near]


# ------------------------------------------------------------------------------------- moving, copying


def test_set_pose_velocity_advance_remove_copy():
    s = gfcs.Scene()
    a = s.add_sphere([0, 0, 0], 0.1)
    b = s.add_box([0.2, 0.2, 0.2], pose(np.eye(3), [1, 0, 0]))
    c = s.copy()
    s.set_pose(a, pose(np.eye(3), [0, 0, 1.0]))
    np.testing.assert_allclose(s.signed_distance([0, 0, 0]), 0.9, atol=1e-12)
    np.testing.assert_allclose(c.signed_distance([0, 0, 0]), -0.1, atol=1e-12)  # the copy did not move
    s.set_velocity(b, [0, 0.5, 0])
    s.advance(2.0)
    np.testing.assert_allclose(s.get(b)["pose"][:3, 3], [1, 1, 0], atol=1e-12)
    np.testing.assert_allclose(s.get(b)["velocity"], [0, 0.5, 0])
    removed = s.remove(a)
    assert removed["id"] == a and removed["type"] == "sphere" and len(s) == 1
    assert len(copy.copy(c)) == 2 and len(copy.deepcopy(c)) == 2
    with pytest.raises(gfcs.InvalidValueError, match=str(a)):
        s.remove(a)
    with pytest.raises(gfcs.InvalidValueError):
        s.set_pose(12345, np.eye(4))


def test_surface_points_lie_on_surfaces():
    s = gfcs.Scene()
    s.add_box([0.4, 0.4, 0.4], pose(np.eye(3), [0.5, 0, 0]))
    s.add_sphere([-0.5, 0, 0], 0.2)
    pts = s.surface_points(0.05)
    assert pts.ndim == 2 and pts.shape[1] == 3 and len(pts) > 50
    np.testing.assert_allclose(s.signed_distance(pts), 0.0, atol=1e-6)


# ------------------------------------------------------------------------------------------- MoveIt YAML

SCENE_YAML = """
name: test
world:
  collision_objects:
    - id: table
      primitives:
        - type: box
          dimensions: [1.0, 0.5, 0.2]
      primitive_poses:
        - position: [0.5, 0.0, -0.1]
          orientation: [0, 0, 0, 1]
    - id: can
      primitives:
        - type: cylinder
          dimensions: [0.14, 0.03]
        - type: sphere
          dimensions: [0.05]
      primitive_poses:
        - position: [0.4, 0.2, 0.07]
          orientation: [0, 0, 0.7071067811865476, 0.7071067811865476]
        - position: [0.4, -0.2, 0.3]
          orientation: [0, 0, 0, 1]
"""

REQUEST_YAML = """
group_name: panda_arm
start_state:
  joint_state:
    name: [panda_joint1, panda_joint2]
    position: [0.1, -0.2]
goal_constraints:
  - joint_constraints:
      - joint_name: panda_joint1
        position: 0.5
      - position: -0.5
        joint_name: panda_joint2
"""


def test_moveit_yaml_scene_sizes_and_poses(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_text(SCENE_YAML)
    for scene in (gfcs.Scene.from_moveit_yaml(path), gfcs.Scene.from_moveit_yaml_str(SCENE_YAML)):
        objs = {o["name"]: o for o in scene.obstacles()}
        assert set(objs) == {"table", "can/0", "can/1"}
        np.testing.assert_allclose(objs["table"]["size"], [1.0, 0.5, 0.2])  # full sizes
        np.testing.assert_allclose(objs["can/0"]["size"], [0.14, 0.03])  # [height, radius]
        np.testing.assert_allclose(objs["can/0"]["pose"][:3, :3], rot_z(np.pi / 2), atol=1e-12)
        # top face of the table at z = 0
        np.testing.assert_allclose(scene.signed_distance([0.5, 0.0, 0.1]), 0.1, atol=1e-12)


def test_bad_yaml_field_raises_format_error_naming_it(tmp_path):
    bad = SCENE_YAML.replace("dimensions: [1.0, 0.5, 0.2]", "dimensions: [1.0, 0.5]")
    path = tmp_path / "bad_scene.yaml"
    path.write_text(bad)
    with pytest.raises(gfcs.FormatError, match=r"bad_scene\.yaml.*primitives\[0\]\.dimensions"):
        gfcs.Scene.from_moveit_yaml(path)
    with pytest.raises(gfcs.FormatError, match="dimensions"):
        gfcs.Scene.from_moveit_yaml_str(SCENE_YAML.replace("[0.05]", "[zero]"))
    with pytest.raises(gfcs.IoError, match="absent.yaml"):
        gfcs.Scene.from_moveit_yaml(tmp_path / "absent.yaml")
    req = tmp_path / "bad_request.yaml"
    req.write_text(REQUEST_YAML.replace("group_name", "group"))
    with pytest.raises(gfcs.FormatError, match="group_name"):
        gfcs.load_motion_plan_request(req)


def test_objects_outside_the_planning_frame_or_attached_to_the_robot_are_refused():
    in_hand = SCENE_YAML.replace("    - id: table\n", "    - id: table\n      header: {frame_id: panda_hand}\n")
    with pytest.raises(gfcs.FormatError, match=r"collision_objects\[0\]\.header\.frame_id.*panda_hand"):
        gfcs.Scene.from_moveit_yaml_str(in_hand, root_frame="panda_link0")
    at_root = in_hand.replace("panda_hand", "panda_link0")
    with pytest.raises(gfcs.FormatError, match="frame_id"):
        gfcs.Scene.from_moveit_yaml_str(at_root)  # the root link is the planning frame only when named
    assert len(gfcs.Scene.from_moveit_yaml_str(at_root, root_frame="panda_link0").obstacles()) == 3
    held = "robot_state:\n  attached_collision_objects:\n    - link_name: panda_hand\n" + SCENE_YAML
    with pytest.raises(gfcs.FormatError, match="attached_collision_objects"):
        gfcs.Scene.from_moveit_yaml_str(held)


def test_load_motion_plan_request(tmp_path):
    path = tmp_path / "request.yaml"
    path.write_text(REQUEST_YAML)
    req = gfcs.load_motion_plan_request(path)
    assert req == {
        "group": "panda_arm",
        "start": {"panda_joint1": 0.1, "panda_joint2": -0.2},
        "goal": {"panda_joint1": 0.5, "panda_joint2": -0.5},
        "pose_goal": None,
        "ignored": [],
    }


def test_motionbenchmaker_scene_and_request(mbm_dir):
    import yaml

    scene_path = mbm_dir / "box" / "scene0001.yaml"
    scene = gfcs.Scene.from_moveit_yaml(scene_path)
    doc = yaml.safe_load(scene_path.read_text())
    n_prims = sum(len(o.get("primitives", [])) for o in doc["world"]["collision_objects"])
    assert len(scene) == n_prims
    # every primitive centre is inside its obstacle
    centres = np.array(
        [p["position"] for o in doc["world"]["collision_objects"] for p in o.get("primitive_poses", [])]
    )
    assert np.all(scene.signed_distance(centres) < 0)
    req = gfcs.load_motion_plan_request(mbm_dir / "box" / "request0001.yaml")
    robot = gfcs.Robot.panda()
    assert req["group"] == "panda_arm"
    assert all(j in req["start"] and j in req["goal"] for j in robot.joint_names)


# ------------------------------------------------------------------------------------------- bad input


def test_bad_sizes_poses_and_missing_mesh(tmp_path):
    s = gfcs.Scene()
    with pytest.raises(gfcs.InvalidValueError, match="radius"):
        s.add_sphere([0, 0, 0], -1.0)
    with pytest.raises(gfcs.InvalidValueError, match="size"):
        s.add_box([0.1, 0.0, 0.1])
    with pytest.raises(gfcs.ShapeError, match=r"center: expected shape \(3,\), got \(2,\)"):
        s.add_sphere([0, 0], 0.1)
    with pytest.raises(gfcs.NonFiniteError, match="center"):
        s.add_sphere([0, np.nan, 0], 0.1)
    with pytest.raises(gfcs.ShapeError, match=r"pose: expected shape \(4, 4\)"):
        s.add_box([1, 1, 1], np.eye(3))
    with pytest.raises(gfcs.InvalidValueError, match="pose"):
        s.add_box([1, 1, 1], np.diag([2.0, 1, 1, 1]))
    with pytest.raises(gfcs.InvalidValueError, match="quaternion"):
        s.add_box([1, 1, 1], ([0, 0, 0], [0, 0, 0, 0]))
    with pytest.raises(gfcs.ShapeError, match="quaternion"):
        s.add_box([1, 1, 1], ([0, 0, 0], [0, 0, 1]))
    with pytest.raises(gfcs.ShapeError, match=r"points: expected shape \(3,\) or \(N, 3\)"):
        s.signed_distance(np.zeros((4, 2)))
    with pytest.raises(gfcs.MeshError, match="no_such_mesh.obj") as info:
        s.add_mesh(tmp_path / "no_such_mesh.obj")
    assert isinstance(info.value, OSError)
    with pytest.raises(gfcs.InvalidValueError, match="mesh faces"):
        s.add_mesh((CUBE_V, CUBE_F + 10))
    with pytest.raises(gfcs.InvalidValueError, match="normal"):
        s.add_halfspace(normal=[0, 0, 0])
    assert len(s) == 0
