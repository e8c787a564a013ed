"""gfcs.viz: rerun recordings read back with rerun's own RRD reader (entity paths, time steps, values
against independent computations), link meshes placed by the link poses, quaternions, the viewer command."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
from collections import defaultdict

import numpy as np
import pytest

rr = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

import gfcs  # noqa: E402
from gfcs import optimize, viz  # noqa: E402
from gfcs.problems import Problem  # noqa: E402

from conftest import require_shared  # noqa: E402

Q0 = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
GOAL = [0.4, -0.5, -0.3, -2.0, 0.2, 1.4, 0.9]


def pose(x, y, z):
    p = np.eye(4)
    p[:3, 3] = [x, y, z]
    return p


def small_scene():
    s = gfcs.Scene()
    s.add_sphere([0.5, 0.0, 0.4], 0.1, name="ball")
    s.add_box([0.3, 0.3, 0.05], pose(0.5, 0.4, 0.2), name="plate")
    s.add_cylinder(0.4, 0.05, pose(-0.4, 0.3, 0.3), name="post")
    s.add_capsule(0.3, 0.04, pose(-0.3, -0.3, 0.3), name="rod")
    s.add_halfspace([0.0, 0.0, 1.0], -0.3, name="floor")
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]) * 0.2 + [0.3, -0.6, 0.2]
    s.add_mesh((tet, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])), name="tet")
    s.add_point_cloud(np.random.default_rng(0).uniform(-0.05, 0.05, (20, 3)) + [-0.4, 0.5, 0.6], 0.01,
                      name="cloud")
    return s


@pytest.fixture(scope="module")
def solved():
    problem = Problem("toy/0001", gfcs.Robot.panda(), small_scene(), Q0, GOAL, cls="toy")
    gf = optimize.solve(problem, method="gf")
    ours = optimize.solve(problem, method="gfcs", batches=1, population=4, seed=0, threads=1)
    return problem, gf, ours


def read_rrd(path):
    """{entity: {"static": [record batches], "rows": [(time ns, {column: value})] sorted by time}}."""
    out = defaultdict(lambda: {"static": [], "rows": []})
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        entry = out[chunk.entity_path]
        if chunk.is_static:
            entry["static"].append(batch.to_pydict())
            continue
        times = batch.column("time").cast("int64").to_pylist()
        d = {name: batch.column(name).to_pylist() for name in batch.schema.names
             if name not in ("time", "log_time")}
        for i, t in enumerate(times):
            entry["rows"].append((t, {k: v[i] for k, v in d.items()}))
    for entry in out.values():
        entry["rows"].sort(key=lambda r: r[0])
    return out


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def test_recording_has_every_entity_and_one_time_step_per_sample(solved, tmp_path):
    problem, gf, ours = solved
    path = viz.record(problem, [gf, ours], tmp_path / "sub" / "toy.rrd")
    assert path == str(tmp_path / "sub" / "toy.rrd")
    data = read_rrd(path)
    reader = RrdReader(path)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) == 1  # the default layout

    for name in ("ball", "plate", "post", "rod", "floor", "tet", "cloud"):
        assert f"/world/obstacles/{name}" in data, name
    for fixed in ("/world/goal", "/world/start"):
        assert fixed in data

    for label, result in (("gf", gf), ("gfcs", ours)):
        traj = result.trajectory
        t_ns = [round(float(t) * 1e9) for t in traj.t]
        for entity in ("robot/spheres", "ee", "metrics/joint_speed", "metrics/clearance",
                       "metrics/self_clearance", "metrics/energy", "metrics/potential", "metrics/lyapunov"):
            rows = data[f"/methods/{label}/{entity}"]["rows"]
            times = [t for t, _ in rows]
            assert len(set(times)) == len(traj), (label, entity)
            assert np.allclose(times, t_ns, atol=2), (label, entity)
        for static in ("ee_path", "summary"):
            assert data[f"/methods/{label}/{static}"]["static"], (label, static)
    assert "/methods/gfcs/commands" in data and "/methods/gf/commands" not in data

    # the default layout: the 3D scene and one time-series view per quantity, holding both methods
    views = {}
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        for column in ("ViewBlueprint:display_name", "ViewContents:query"):
            if column in batch.schema.names:
                views.setdefault(chunk.entity_path.split("/")[2], {})[column] = batch.column(column).to_pylist()[0]
    by_name = {v.get("ViewBlueprint:display_name", [""])[0]: v for v in views.values()}
    assert "scene" in by_name
    speed_view = next(v for name, v in by_name.items() if name.startswith("joint speed"))
    assert sorted(speed_view["ViewContents:query"]) == ["/methods/gf/metrics/joint_speed",
                                                        "/methods/gfcs/metrics/joint_speed"]


def test_recorded_values_match_independent_computations(solved, tmp_path):
    problem, gf, ours = solved
    robot = problem.robot
    data = read_rrd(viz.record(problem, {"gf": gf, "gfcs": ours}, tmp_path / "v.rrd"))
    traj = ours.trajectory

    # collision spheres of step k are the sphere centres of q_k, with their radii
    rows = data["/methods/gfcs/robot/spheres"]["rows"]
    for k in (0, len(traj) // 2, len(traj) - 1):
        cols = rows[k][1]
        assert np.allclose(np.array(cols["Points3D:positions"]), robot.sphere_centers(traj.q[k]), atol=1e-5)
        assert np.allclose(np.array(cols["Points3D:radii"]), robot.sphere_radii, atol=1e-6)

    # joint speed = ‖q̇‖ per sample
    speed = np.array([r[1]["Scalars:scalars"][0] for r in data["/methods/gfcs/metrics/joint_speed"]["rows"]])
    assert np.allclose(speed, np.linalg.norm(traj.qd, axis=1), rtol=1e-9, atol=1e-12)

    # clearance = min over spheres of signed distance − radius (brute force over the spheres)
    k = len(traj) // 3
    d = problem.scene.signed_distance(robot.sphere_centers(traj.q[k])) - robot.sphere_radii
    clear_rows = data["/methods/gfcs/metrics/clearance"]["rows"]
    assert math.isclose(clear_rows[k][1]["Scalars:scalars"][0], float(d.min()), rel_tol=1e-9, abs_tol=1e-12)

    # fabric potential: samples before t_1* are steered by the first command, later ones by the goal
    # (GFCS eq. 5-7); the Lyapunov series is energy + potential
    fabric = gfcs.Fabric(robot, problem.scene, ours.fabric_config)
    potential = [r[1]["Scalars:scalars"][0] for r in data["/methods/gfcs/metrics/potential"]["rows"]]
    energy = [r[1]["Scalars:scalars"][0] for r in data["/methods/gfcs/metrics/energy"]["rows"]]
    lyapunov = [r[1]["Scalars:scalars"][0] for r in data["/methods/gfcs/metrics/lyapunov"]["rows"]]
    switch = int(round(ours.t_stars[0] / (traj.t[1] - traj.t[0])))
    assert 2 < switch < len(traj) - 2
    for k, command in ((0, ours.commands[0]), (switch - 1, ours.commands[0]), (switch + 1, ours.goal),
                       (len(traj) - 1, ours.goal)):
        fabric.acceleration(traj.q[k], traj.qd[k], command)
        diag = fabric.diagnostics()
        assert math.isclose(potential[k], diag["potential"], rel_tol=1e-9, abs_tol=1e-12), k
        assert math.isclose(energy[k], diag["energy"], rel_tol=1e-9, abs_tol=1e-12), k
        assert math.isclose(lyapunov[k], diag["energy"] + diag["potential"], rel_tol=1e-9, abs_tol=1e-12), k

    # commands in red at the EE of each command, goal in green at the EE of the goal, EE path
    cmd = data["/methods/gfcs/commands"]["static"][0]
    assert np.allclose(np.array(cmd["Points3D:positions"][0]), robot.ee_position(ours.commands), atol=1e-5)
    assert cmd["Points3D:colors"][0][0] >> 24 == 220  # 0xRRGGBBAA, red
    goal = data["/world/goal"]["static"][0]
    assert np.allclose(np.array(goal["Points3D:positions"][0]), robot.ee_position(problem.goal)[None], atol=1e-5)
    assert (goal["Points3D:colors"][0][0] >> 16) & 0xFF == 190  # green channel
    strip = data["/methods/gf/ee_path"]["static"][0]["LineStrips3D:strips"][0][0]
    assert np.allclose(np.array(strip), robot.ee_position(gf.trajectory.q), atol=1e-5)

    # obstacle poses and sizes
    ball = data["/world/obstacles/ball"]["static"]
    merged = {k: v for b in ball for k, v in b.items()}
    assert np.allclose(merged["Transform3D:translation"][0], [0.5, 0.0, 0.4])
    assert np.allclose(merged["Ellipsoids3D:half_sizes"][0], [[0.1, 0.1, 0.1]])
    cloud = data["/world/obstacles/cloud"]["static"][0]
    assert len(cloud["Points3D:positions"][0]) == 20


def test_link_meshes_follow_the_link_poses(tmp_path):
    mbm = require_shared("robots", "mbm_panda")
    from gfcs.problems import mbm_panda

    robot = mbm_panda(mbm)
    scene = gfcs.Scene()
    scene.add_sphere([0.5, 0.3, 0.5], 0.08)
    problem = Problem("mesh/0001", robot, scene, Q0, GOAL)
    result = optimize.solve(problem, method="gf")
    path = viz.record(problem, result, tmp_path / "m.rrd", urdf=mbm / "panda_spherized.urdf", energy=False)
    data = read_rrd(path)
    traj = result.trajectory
    assert "/methods/gf/robot/spheres" not in data  # meshes loaded: no sphere fallback
    links = sorted(e.split("/")[5] for e in data if e.startswith("/methods/gf/robot/links/") and e.count("/") == 5)
    assert {"panda_link0", "panda_link3", "panda_hand", "panda_leftfinger"} <= set(links)

    k = len(traj) // 2
    poses = robot.link_poses(traj.q[k])
    world_vertices = defaultdict(list)
    for link in links:
        rows = data[f"/methods/gf/robot/links/{link}"]["rows"]
        assert len(rows) == len(traj)
        cols = rows[k][1]
        t = np.array(cols["Transform3D:translation"]).reshape(3)
        r = quat_to_matrix(np.array(cols["Transform3D:quaternion"]).reshape(4))
        p = poses[robot.link_index(link)]
        assert np.allclose(t, p[:3, 3], atol=1e-5) and np.allclose(r, p[:3, :3], atol=1e-5), link
        v = np.array(data[f"/methods/gf/robot/links/{link}/visual_0"]["static"][0]["Mesh3D:vertex_positions"][0])
        world_vertices[link] = v @ r.T + t
    # every collision sphere (fitted to the link geometry) touches its link's mesh as drawn
    for c, rad, link in zip(robot.sphere_centers(traj.q[k]), robot.sphere_radii, robot.sphere_links):
        if link in world_vertices:
            gap = np.min(np.linalg.norm(world_vertices[link] - c, axis=1)) - rad
            assert gap < 0.02, (link, gap)


def test_meshes_required_but_absent_is_an_error(solved, tmp_path):
    problem, gf, _ = solved  # the shipped Panda has no collision meshes
    with pytest.raises(ValueError, match="no link mesh"):
        viz.record(problem, gf, tmp_path / "x.rrd", robot_geometry="meshes")


def test_rotation_to_quaternion_roundtrip():
    rng = np.random.default_rng(3)
    mats = []
    for _ in range(300):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = rng.uniform(-np.pi, np.pi)
        k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        mats.append(np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k)  # Rodrigues
    mats += [np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1]), np.eye(3)]
    mats = np.array(mats)
    q = viz.rotation_to_quaternion(mats)
    assert q.shape == (len(mats), 4)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.all(q[:, 3] >= 0.0)
    for m, qi in zip(mats, q):
        assert np.allclose(quat_to_matrix(qi), m, atol=1e-12)
    assert viz.rotation_to_quaternion(np.eye(3)).shape == (4,)
    with pytest.raises(ValueError):
        viz.rotation_to_quaternion(np.eye(4))


def test_method_labels(solved):
    _, gf, ours = solved
    learned = dataclasses.replace(ours, settings={**ours.settings, "sampler": "EBMSampler"})
    assert viz.method_labels([gf, ours, learned, ours]) == ["gf", "gfcs", "gfcs_learned", "gfcs_2"]


def test_record_rejects_bad_input(solved, tmp_path):
    problem, gf, _ = solved
    with pytest.raises(ValueError, match="path"):
        viz.record(problem, gf)
    with pytest.raises(ValueError, match="robot_geometry"):
        viz.record(problem, gf, tmp_path / "a.rrd", robot_geometry="wireframe")
    empty = dataclasses.replace(gf, trajectory=type(gf.trajectory)(np.zeros(0), np.zeros((0, 7)), np.zeros((0, 7))))
    with pytest.raises(ValueError, match="empty"):
        viz.record(problem, empty, tmp_path / "b.rrd")
    with pytest.raises(ValueError, match="at least one"):
        viz.record(problem, [], tmp_path / "c.rrd")


def test_view_without_display_prints_instructions(tmp_path, monkeypatch, capsys):
    rrd = tmp_path / "r.rrd"
    rrd.write_bytes(b"")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(viz.sys, "platform", "linux")
    assert viz.view(rrd) == 0
    out = capsys.readouterr().out
    assert "no display" in out and "r.rrd" in out and "--web-viewer" in out
    with pytest.raises(FileNotFoundError):
        viz.view(tmp_path / "missing.rrd")


def test_viewer_command_runs_the_shipped_rerun():
    cmd = viz.viewer_command() + ["--version"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "rerun" in (r.stdout + r.stderr).lower()


def test_cli_view(tmp_path):
    from gfcs import cli

    assert cli.main(["view", str(tmp_path / "missing.rrd")]) == 2
    r = subprocess.run([sys.executable, "-m", "gfcs.cli", "view", "--help"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and "REC.rrd" in r.stdout


def test_import_gfcs_does_not_import_rerun():
    code = "import sys, gfcs, gfcs.plots, gfcs.experiments; print('rerun' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.strip() == "False", r.stderr


ARM_URDF = """<robot name="arm">
  <link name="base"><visual><geometry><mesh filename="{mesh}"/></geometry></visual></link>
  <link name="link1">
    <visual><origin xyz="0 0 0.25"/><geometry><box size="0.05 0.05 0.5"/></geometry></visual>
    <collision><origin xyz="0 0 0.25"/><geometry><sphere radius="0.05"/></geometry></collision>
    <collision><origin xyz="0 0 0.5"/><geometry><sphere radius="0.05"/></geometry></collision>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="link1"/><origin xyz="0 0 0.1"/>
    <axis xyz="1 0 0"/><limit lower="-2" upper="2" velocity="2" effort="10"/></joint>
</robot>"""


def arm_problem(tmp_path, with_box=True):
    text = ARM_URDF.format(mesh=tmp_path / "missing.obj")
    if not with_box:
        text = text.replace('<geometry><box size="0.05 0.05 0.5"/></geometry>',
                            f'<geometry><mesh filename="{tmp_path / "missing2.obj"}"/></geometry>')
    urdf = tmp_path / ("arm.urdf" if with_box else "arm_nobox.urdf")
    urdf.write_text(text)
    robot = gfcs.Robot.from_urdf(str(urdf))
    return urdf, Problem("arm/0001", robot, gfcs.Scene(), [0.0], [1.0])


def test_unloadable_meshes_warn_and_fall_back(tmp_path):
    urdf, problem = arm_problem(tmp_path)
    result = optimize.solve(problem, method="gf")
    with pytest.warns(UserWarning, match="missing.obj"):
        data = read_rrd(viz.record(problem, result, tmp_path / "a.rrd", urdf=urdf))
    # the box visual is drawn along link1, placed by its URDF origin; the missing mesh is skipped
    box = np.array(data["/methods/gf/robot/links/link1/visual_0"]["static"][0]["Mesh3D:vertex_positions"][0])
    assert np.allclose(box.min(axis=0), [-0.025, -0.025, 0.0]) and np.allclose(box.max(axis=0), [0.025, 0.025, 0.5])
    assert "/methods/gf/robot/links/base" not in data and "/methods/gf/robot/spheres" not in data
    # an empty scene has no obstacle clearance to plot, the other series are there
    assert "/methods/gf/metrics/clearance" not in data and "/methods/gf/metrics/joint_speed" in data

    urdf2, problem2 = arm_problem(tmp_path, with_box=False)
    result2 = optimize.solve(problem2, method="gf")
    with pytest.warns(UserWarning):
        data = read_rrd(viz.record(problem2, result2, tmp_path / "b.rrd", urdf=urdf2))
    rows = data["/methods/gf/robot/spheres"]["rows"]  # no mesh at all: the collision spheres instead
    assert len(rows) == len(result2.trajectory) > 1
    assert np.allclose(np.array(rows[-1][1]["Points3D:positions"]),
                       problem2.robot.sphere_centers(result2.trajectory.q[-1]), atol=1e-6)


def test_a_thin_sphere_result_is_drawn_with_the_spheres_it_was_planned_on(solved, tmp_path):
    from gfcs import problems

    problem = dataclasses.replace(solved[0], mesh_checker=problems.shipped_panda_checker())
    thin = optimize.solve(problem, method="gfcs", batches=1, population=4, seed=0, threads=1)
    assert thin.settings["sphere_model"] == "thin"
    data = read_rrd(viz.record(problem, {"gfcs": thin}, tmp_path / "thin.rrd", robot_geometry="spheres"))
    k = len(thin.trajectory) // 2
    cols = data["/methods/gfcs/robot/spheres"]["rows"][k][1]
    assert np.allclose(np.array(cols["Points3D:positions"]), thin.robot.sphere_centers(thin.trajectory.q[k]),
                       atol=1e-5)
    assert np.allclose(np.array(cols["Points3D:radii"]), thin.robot.sphere_radii, atol=1e-6)
    assert len(thin.robot.sphere_radii) != len(problem.robot.sphere_radii)
