"""gfcs.MeshChecker (collision-mesh validation) against closed forms, and its use by problems, metrics and
optimize. Tests that read the MotionBenchMaker data skip without ``../shared`` (fail under CI=true)."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

import gfcs
from gfcs import generators, metrics, problems
from gfcs import optimize as opt
from gfcs.problems import Problem

LIMIT = '<limit lower="-3.2" upper="3.2" velocity="1" effort="1"/>'


def slider_urdf(collision: str) -> str:
    """One prismatic joint along x moving ``link``, whose ``<collision>`` holds ``collision``."""
    return f"""<robot name="slider"><link name="base"/>
      <link name="link"><collision>{collision}</collision></link>
      <joint name="x" type="prismatic"><parent link="base"/><child link="link"/><axis xyz="1 0 0"/>{LIMIT}</joint>
    </robot>"""


def write_cube_obj(path: Path) -> Path:
    """A unit cube centred on the origin (OBJ, outward quads)."""
    lines = [f"v {x} {y} {z}" for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    faces = [(1, 2, 4, 3), (5, 7, 8, 6), (1, 5, 6, 2), (3, 4, 8, 7), (1, 3, 7, 5), (2, 6, 8, 4)]
    lines += ["f " + " ".join(map(str, f)) for f in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def box_sdf(p: np.ndarray, half: np.ndarray) -> float:
    """Closed-form signed distance from p to the origin-centred box of half extents ``half``."""
    q = np.abs(p) - half
    return float(np.linalg.norm(np.maximum(q, 0.0)) + min(q.max(), 0.0))


@pytest.fixture(scope="module")
def cube_checker(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cube")
    write_cube_obj(folder / "cube.obj")
    urdf = folder / "slider.urdf"
    urdf.write_text(slider_urdf('<geometry><mesh filename="cube.obj" scale="0.4 0.4 0.4"/></geometry>'))
    robot = gfcs.Robot.from_urdf(urdf)
    return gfcs.MeshChecker(robot, max_distance=math.inf)


# --------------------------------------------------------------------------------------- the binding
def test_properties_and_repr(cube_checker):
    c = cube_checker
    assert c.num_shapes == 1 and c.shape_links == ["link"] and c.dof == 1 and c.joint_names == ["x"]
    assert c.max_distance == math.inf and c.num_self_pairs == 0 and c.robot.name == "slider"
    assert "MeshChecker(robot='slider', shapes=1" in repr(c)


def test_cube_mesh_against_sphere_closed_form(cube_checker):
    half = np.full(3, 0.2)  # unit cube scaled by 0.4
    rng = np.random.default_rng(0)
    qs, expected = [], []
    while len(qs) < 60:
        c, q = rng.uniform(-0.8, 0.8, 3), rng.uniform(-0.3, 0.3)
        sdf = box_sdf(c - [q, 0.0, 0.0], half)
        if sdf < 1e-3:
            continue
        scene = gfcs.Scene()
        scene.add_sphere(c, 0.05)
        d = cube_checker.clearance(scene, [q])
        assert isinstance(d, float)
        assert d == pytest.approx(sdf - 0.05, abs=1e-7)
        qs.append(q)
        expected.append(sdf - 0.05)
    # one scene, a trajectory: (T,) array equal to the per-state values, whatever the thread count
    scene = gfcs.Scene()
    scene.add_sphere([0.6, 0.1, 0.0], 0.05)
    traj = np.linspace(-0.3, 0.38, 35)[:, None]  # the ball centre stays outside the cube
    along = cube_checker.clearance(scene, traj, threads=2)
    assert along.shape == (35,) and along.dtype == np.float64
    np.testing.assert_array_equal(along, cube_checker.clearance(scene, traj, threads=1))
    for q, d in zip(traj, along):
        assert d == cube_checker.clearance(scene, q)
    want = [box_sdf(np.array([0.6 - q[0], 0.1, 0.0]), half) - 0.05 for q in traj]
    np.testing.assert_allclose(along, want, atol=1e-7)
    assert along.min() < 0.0 < along.max()  # the cube pushes into the ball at the end
    # the trajectory minimum (culled) is the minimum of the states, and the single-state value
    assert cube_checker.min_clearance(scene, traj) == along.min()
    assert cube_checker.min_clearance(scene, traj[:17], threads=1) == along[:17].min()
    assert cube_checker.min_clearance(scene, traj[3]) == along[3]
    assert cube_checker.min_clearance(scene, np.zeros((0, 1))) == math.inf
    # Deeper, with the centre inside the cube, a mesh penetration depth is measured from the triangles,
    # not the solid: only its sign is reliable.
    assert np.all(cube_checker.clearance(scene, np.linspace(0.4, 0.6, 9)[:, None]) <= 0.0)


def write_cube_dae(path: Path) -> Path:
    """The unit cube of :func:`write_cube_obj` as COLLADA: positions of [0, 1]³, placed by a node that
    translates them by −0.5 (in a library node, scaled by 1), with unit and up-axis tags that MoveIt's
    loader and trimesh leave unapplied."""
    corners = " ".join(f"{x} {y} {z}" for z in (0, 1) for y in (0, 1) for x in (0, 1))
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    path.write_text(f"""<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit meter="0.001"/><up_axis>Y_UP</up_axis></asset>
  <library_geometries><geometry id="cube"><mesh>
    <source id="p"><float_array id="pa" count="24">{corners}</float_array>
      <technique_common><accessor source="#pa" count="8" stride="3"/></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <polylist count="6"><input semantic="VERTEX" source="#v" offset="0"/><vcount>4 4 4 4 4 4</vcount>
      <p>{" ".join(str(i) for quad in quads for i in quad)}</p></polylist>
  </mesh></geometry></library_geometries>
  <library_nodes><node id="shifted"><translate>-0.5 -0.5 -0.5</translate><instance_geometry url="#cube"/></node>
  </library_nodes>
  <library_visual_scenes><visual_scene id="s"><node><scale>1 1 1</scale><instance_node url="#shifted"/></node>
  </visual_scene></library_visual_scenes><scene><instance_visual_scene url="#s"/></scene>
</COLLADA>""")
    return path


def test_a_collada_mesh_measures_as_the_same_cube_in_obj(tmp_path):
    write_cube_dae(tmp_path / "cube.dae")
    urdf = tmp_path / "slider.urdf"
    urdf.write_text(slider_urdf('<geometry><mesh filename="cube.dae" scale="0.4 0.4 0.4"/></geometry>'))
    checker = gfcs.MeshChecker(gfcs.Robot.from_urdf(urdf), max_distance=math.inf)
    rng = np.random.default_rng(1)
    for _ in range(30):
        c, q = rng.uniform(-0.8, 0.8, 3), rng.uniform(-0.3, 0.3)
        sdf = box_sdf(c - [q, 0.0, 0.0], np.full(3, 0.2))
        if sdf < 1e-3:
            continue
        scene = gfcs.Scene()
        scene.add_sphere(c, 0.05)
        assert checker.clearance(scene, [q]) == pytest.approx(sdf - 0.05, abs=1e-7)
    (tmp_path / "broken.dae").write_text("<COLLADA><library_geometries/></COLLADA>")
    urdf.write_text(slider_urdf('<geometry><mesh filename="broken.dae"/></geometry>'))
    with pytest.raises(gfcs.GfcsError, match="broken.dae.*no triangles"):
        gfcs.MeshChecker(gfcs.Robot.from_urdf(urdf))


def test_cutoff_reports_inf_and_empty_trajectory():
    urdf = slider_urdf('<geometry><box size="0.2 0.2 0.2"/></geometry>')
    checker = gfcs.MeshChecker(gfcs.Robot.from_urdf(urdf))
    assert checker.max_distance == 0.5
    scene = gfcs.Scene()
    scene.add_box([0.4, 0.4, 0.4], ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]))  # face at x = 0.8
    assert checker.clearance(scene, [0.0]) == math.inf  # 0.7 m > cutoff
    assert checker.clearance(scene, [0.3]) == pytest.approx(0.4, abs=1e-9)
    assert checker.clearance(scene, np.zeros((0, 1))).shape == (0,)


def test_self_clearance_closed_form():
    # base cube 0.2 m; hand ball r = 0.05 at x = 0.3 of a link on an elbow at x = 0.42: for θ1 = 0 the
    # ball centre is (0.42 + 0.3 cos θ2, 0.3 sin θ2, 0), and the clearance sdf_box(c) − 0.05.
    urdf = f"""<robot name="folding">
      <link name="base"><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
      <link name="arm"/>
      <link name="hand"><collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.05"/></geometry></collision></link>
      <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>{LIMIT}</joint>
      <joint name="j2" type="revolute"><parent link="arm"/><child link="hand"/><origin xyz="0.42 0 0"/>
        <axis xyz="0 0 1"/>{LIMIT}</joint></robot>"""
    checker = gfcs.MeshChecker(gfcs.Robot.from_urdf(urdf), max_distance=math.inf)
    assert checker.num_self_pairs == 1
    t2 = np.linspace(-3.1, 3.1, 25)
    qs = np.column_stack([np.zeros_like(t2), t2])
    got = checker.self_clearance(qs)
    want = [box_sdf(np.array([0.42 + 0.3 * math.cos(a), 0.3 * math.sin(a), 0.0]), np.full(3, 0.1)) - 0.05
            for a in t2]
    np.testing.assert_allclose(got, want, atol=1e-7)
    assert checker.self_clearance([0.0, math.pi]) == pytest.approx(-0.03, abs=1e-7)
    assert checker.min_self_clearance(qs) == got.min()
    assert checker.min_self_clearance(qs[:10], threads=1) == got[:10].min()


def test_errors(tmp_path, cube_checker):
    scene = gfcs.Scene()
    with pytest.raises(gfcs.ShapeError, match=r"q: expected shape \(1,\) or \(N, 1\)"):
        cube_checker.clearance(scene, [0.0, 1.0])
    with pytest.raises(gfcs.NonFiniteError, match="q"):
        cube_checker.clearance(scene, [math.nan])
    with pytest.raises(gfcs.InvalidValueError, match="threads"):
        cube_checker.clearance(scene, np.zeros((3, 1)), threads=0)
    with pytest.raises(gfcs.InvalidValueError, match="no URDF <collision> geometry"):
        gfcs.MeshChecker(gfcs.Robot.panda())
    robot = gfcs.Robot.from_urdf(slider_urdf('<geometry><box size="0.2 0.2 0.2"/></geometry>'))
    with pytest.raises(gfcs.InvalidValueError, match="max_distance"):
        gfcs.MeshChecker(robot, max_distance=-1.0)
    urdf = tmp_path / "missing.urdf"
    urdf.write_text(slider_urdf('<geometry><mesh filename="meshes/nothing_here.obj"/></geometry>'))
    with pytest.raises(gfcs.MeshError, match=r"nothing_here\.obj.*link 'link'") as info:
        gfcs.MeshChecker(gfcs.Robot.from_urdf(urdf))
    assert isinstance(info.value, OSError)


# --------------------------------------------------------------------------------- metrics, problems
@pytest.fixture(scope="module")
def sphere_and_mesh_sliders():
    """The same slider twice: a 0.05 m collision sphere (the fabric's model) and a 0.4 m box (its mesh)."""
    spheres = gfcs.Robot.from_urdf(slider_urdf('<geometry><sphere radius="0.05"/></geometry>'))
    boxes = gfcs.Robot.from_urdf(slider_urdf('<geometry><box size="0.4 0.4 0.4"/></geometry>'))
    scene = gfcs.Scene()
    scene.add_sphere([0.5, 0.0, 0.0], 0.1)
    return spheres, gfcs.MeshChecker(boxes), scene


def test_trajectory_metrics_report_mesh_contact(sphere_and_mesh_sliders):
    spheres, checker, scene = sphere_and_mesh_sliders
    t = np.linspace(0.0, 1.0, 51)
    q = (0.25 * t)[:, None]  # slides to x = 0.25: sphere gap 0.1, box face at 0.45 inside the ball
    plain = metrics.trajectory_metrics(spheres, scene, t, q, [0.25])
    assert plain["success"] and "mesh_clearance" not in plain
    assert plain["min_clearance"] == pytest.approx(0.1, abs=1e-9)
    meshed = metrics.trajectory_metrics(spheres, scene, t, q, [0.25], mesh_checker=checker)
    assert not meshed["success"]
    assert meshed["mesh_clearance"] == pytest.approx(0.4 - 0.45, abs=1e-7)
    assert meshed["mesh_self_clearance"] == math.inf  # one link: no pair
    np.testing.assert_allclose(metrics.mesh_clearance(checker, scene, q), 0.4 - (0.2 + 0.25 * t), atol=1e-7)
    short = metrics.trajectory_metrics(spheres, scene, t[:21], q[:21], q[20], mesh_checker=checker)
    # 0.1 m clear: beyond the exactly measured range (metrics.mesh_report_cutoff), reported as inf
    assert short["success"] and short["mesh_clearance"] == math.inf
    assert metrics.mesh_clearance(checker, scene, q[:21]).min() == pytest.approx(0.1, abs=1e-7)


def test_mesh_margin_is_the_clearance_a_success_keeps(sphere_and_mesh_sliders):
    spheres, checker, scene = sphere_and_mesh_sliders
    t = np.linspace(0.0, 1.0, 51)
    q = (0.1 * t)[:, None]  # box face from 0.2 to 0.3: 0.1 m from the ball at the end (closed form)
    assert metrics.DEFAULT_MESH_MARGIN == 0.0001
    assert metrics.trajectory_metrics(spheres, scene, t, q, [0.1], mesh_checker=checker)["success"]
    for margin, ok in ((0.0, True), (0.0999, True), (0.1001, False)):
        m = metrics.trajectory_metrics(spheres, scene, t, q, [0.1], mesh_checker=checker, mesh_margin=margin)
        assert m["success"] is ok and m["sphere_success"], margin
    # without a checker the margin has nothing to judge
    assert metrics.trajectory_metrics(spheres, scene, t, q, [0.1], mesh_margin=1.0)["success"]
    for bad in (-0.001, math.nan, math.inf):
        with pytest.raises(ValueError, match="mesh_margin"):
            metrics.trajectory_metrics(spheres, scene, t, q, [0.1], mesh_checker=checker, mesh_margin=bad)


def test_sweep_finds_contact_between_states_and_certifies_near_misses(sphere_and_mesh_sliders):
    """The slider's box (faces at x ± 0.2) against a 0.1 m ball at x = 0.5. Two states at x = -0.5 and 1.5
    leave the ball outside the box at both ends, the straight path between them runs through it: the
    sweep refuses it. A path whose states come 0.5 mm from the ball (margin 0.1 mm, within the allowance)
    is certified by the sweep and passes mesh_check; at a 0.6 mm margin it does not."""
    _, checker, scene = sphere_and_mesh_sliders
    jump = np.array([[-0.5], [1.5]])
    assert np.all(checker.clearance(scene, jump) > 0.5)
    swept = checker.sweep(scene, jump, margin=1e-4)
    assert set(swept) == {"ok", "complete", "clearance", "self_clearance", "measured"}
    assert not swept["ok"] and swept["complete"] and swept["clearance"] <= 1e-4
    near = np.linspace(0.0, 0.2 - 0.0005, 40)[:, None]  # face reaches 0.3995, ball surface at 0.4
    ok = checker.sweep(scene, near, margin=1e-4)
    assert ok["ok"] and ok["clearance"] == pytest.approx(0.0005, abs=1e-7)
    assert metrics.mesh_check(checker, scene, near, margin=1e-4)[2]
    assert not metrics.mesh_check(checker, scene, near, margin=6e-4)[2]
    for bad in ({"margin": -1.0}, {"time_limit": -1.0}, {"time_limit": math.nan}):
        with pytest.raises(ValueError):
            checker.sweep(scene, near, **bad)
    with pytest.raises(ValueError, match="q"):
        checker.sweep(scene, np.zeros((3, 2)))


def test_problem_carries_a_matching_checker(sphere_and_mesh_sliders):
    spheres, checker, scene = sphere_and_mesh_sliders
    p = Problem("slide", spheres, scene, q0=[0.0], goal=[0.2], mesh_checker=checker)
    assert p.with_scene(gfcs.Scene()).mesh_checker is checker
    assert dataclasses.replace(p, name="other").mesh_checker is checker
    panda_meshless = Problem("p", gfcs.Robot.panda(), gfcs.Scene(), generators.READY, generators.READY)
    assert panda_meshless.mesh_checker is None
    with pytest.raises(ValueError, match="mesh_checker: joints"):
        Problem("p", gfcs.Robot.panda(), gfcs.Scene(), generators.READY, generators.READY, mesh_checker=checker)


def test_mesh_urdf_for_finds_the_solid_model(tmp_path):
    spherized = tmp_path / "slider_spherized.urdf"
    spherized.write_text(slider_urdf('<geometry><sphere radius="0.05"/></geometry>'))
    assert problems.mesh_urdf_for(spherized) is None  # no neighbour yet
    plain = tmp_path / "slider.urdf"
    plain.write_text(slider_urdf('<geometry><sphere radius="0.05"/></geometry>'))
    assert problems.mesh_urdf_for(spherized) is None  # the neighbour has spheres only
    plain.write_text(slider_urdf('<geometry><box size="0.4 0.4 0.4"/></geometry>'))
    assert problems.mesh_urdf_for(spherized) == plain
    assert problems.mesh_urdf_for(plain) == plain  # a solid model validates itself
    other = tmp_path / "other.urdf"  # sphere-only, no _spherized suffix: nothing to guess
    other.write_text(slider_urdf('<geometry><sphere radius="0.05"/></geometry>'))
    assert problems.mesh_urdf_for(other) is None
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot><link")
    with pytest.raises(ValueError, match="broken.urdf"):
        problems.mesh_urdf_for(broken)


def test_urdf_mesh_checker_matches_joints(tmp_path):
    plain = tmp_path / "slider.urdf"
    plain.write_text(slider_urdf('<geometry><box size="0.4 0.4 0.4"/></geometry>'))
    spheres = gfcs.Robot.from_urdf(slider_urdf('<geometry><sphere radius="0.05"/></geometry>'))
    checker = problems.urdf_mesh_checker(plain, spheres)
    scene = gfcs.Scene()
    scene.add_sphere([0.5, 0.0, 0.0], 0.1)
    assert checker.clearance(scene, [0.0]) == pytest.approx(0.5 - 0.1 - 0.2, abs=1e-7)
    with pytest.raises(gfcs.LinkError, match="no joint named 'panda_joint1' in robot 'slider'"):
        problems.urdf_mesh_checker(plain, gfcs.Robot.panda())


def test_solve_refuses_a_robot_without_spheres_among_obstacles(sphere_and_mesh_sliders):
    spheres, checker, scene = sphere_and_mesh_sliders
    boxes = checker.robot  # box collision geometry only: no spheres for the fabric
    assert len(boxes.sphere_radii) == 0
    with pytest.raises(ValueError, match="no collision spheres.*1 obstacles"):
        opt.solve(Problem("blind", boxes, scene, q0=[0.0], goal=[0.2]), batches=1, population=4)
    free = opt.solve(Problem("free", boxes, gfcs.Scene(), q0=[0.0], goal=[0.2]), method="gf")
    assert free.reached  # nothing to avoid: fine
    # the check sits in the fabric itself, so replay, set_scene and user code get it too
    with pytest.raises(ValueError, match="robot 'slider' has no collision spheres"):
        opt.replay(free, scene, robot=boxes)
    fabric = gfcs.Fabric(boxes)
    with pytest.raises(ValueError, match="no collision spheres"):
        fabric.set_scene(scene)
    assert len(fabric.scene) == 0  # the refused scene was not taken
    blind = gfcs.Fabric(boxes, scene, {"obstacles": {"enabled": False}})  # avoidance off: allowed
    assert len(blind.scene) == 1


def test_mbm_mesh_checker_is_none_without_panda_urdf(tmp_path):
    assert problems.mbm_mesh_checker(tmp_path) is None
    assert problems.mesh_checker_for(gfcs.Robot.panda()) is problems.shipped_panda_checker()  # its polytopes


# ------------------------------------------------------------------------------------------ optimize
class FlaggingChecker:
    """Duck-typed mesh checker that reports contact for the first ``bad`` trajectories it sees."""

    def __init__(self, robot, bad):
        self.joint_names = list(robot.joint_names)
        self.bad, self.seen = bad, 0

    def clearance(self, scene, q):
        self.seen += 1
        return np.full(np.atleast_2d(q).shape[0], -0.01 if self.seen <= self.bad else 0.2)

    def self_clearance(self, q):
        return np.full(np.atleast_2d(q).shape[0], 0.1)

    def min_clearance(self, scene, q, threads=None, cutoff=None):
        return float(np.min(self.clearance(scene, q)))

    def min_self_clearance(self, q, threads=None, cutoff=None):
        return float(np.min(self.self_clearance(q)))


@pytest.fixture(scope="module")
def shelf():
    return generators.generate("bookshelf_small", 1, seed=0, robot=gfcs.Robot.panda())[0]


def test_solve_returns_the_best_mesh_free_candidate(shelf):
    # length_slack 0: candidates in cost order (the slack's own order is tested in test_optimize.py)
    plain = opt.solve(shelf, batches=1, population=8, seed=0, top_m=3, length_slack=0)
    flagged = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=1))
    r = opt.solve(flagged, batches=1, population=8, seed=0, top_m=3, length_slack=0)
    assert r.metrics["selection_rank"] == 1 and r.metrics["mesh_candidates_checked"] == 2 and r.success
    np.testing.assert_array_equal(r.commands.ravel(), plain.top[1][0])
    assert r.cost == pytest.approx(plain.top[1][1], abs=1e-12)
    assert [c for _, c in r.top] == [c for _, c in plain.top]  # the optimiser's top-m is unchanged
    # every candidate in contact: the lowest-cost one comes back, reported as failed
    hopeless = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=99))
    r = opt.solve(hopeless, batches=1, population=8, seed=0, top_m=3, mesh_candidates=3, length_slack=0,
                  mesh_retry_margin=0)
    np.testing.assert_array_equal(r.commands, plain.commands)
    assert not r.success and r.metrics["selection_rank"] == 0
    assert r.metrics["mesh_candidates_checked"] == 3 and r.metrics["mesh_clearance"] < 0
    assert r.metrics["sphere_success"]  # the spheres alone would have passed it
    gf = opt.solve(hopeless, method="gf")
    assert "mesh_clearance" in gf.metrics and not gf.success


def test_solve_holds_candidates_to_the_mesh_margin(shelf):
    clear = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=0))  # 0.2 m, self 0.1 m
    once = dict(batches=1, population=8, seed=0, mesh_candidates=2, mesh_retry_margin=0, max_commands=1)
    ok = opt.solve(clear, **once)
    assert ok.success and ok.settings["mesh_margin"] == metrics.DEFAULT_MESH_MARGIN and ok.metrics["mesh_candidates_checked"] == 1
    strict = opt.solve(clear, mesh_margin=0.15, **once)  # the links' 0.1 m from each other is too close
    assert not strict.success and strict.metrics["sphere_success"] and strict.metrics["mesh_candidates_checked"] == 2


def test_failed_solve_retries_with_one_more_command(shelf):
    # the checker flags the first two trajectories it sees: the one-command attempt (two candidates
    # checked) fails, the two-command retry succeeds
    flagged = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=2))
    r = opt.solve(flagged, batches=1, population=8, seed=0, mesh_candidates=2)
    assert r.success and r.commands.shape == (2, 7)
    assert r.settings["commands_tried"] == [1, 2] and r.settings["n_commands"] == 2
    assert r.n_evaluations == 16
    # without a retry the one-command attempt is returned, failed
    once = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=2))
    r1 = opt.solve(once, batches=1, population=8, seed=0, mesh_candidates=2, max_commands=1, mesh_retry_margin=0,
                   restarts=0, thin_spheres=False)
    assert not r1.success and r1.commands.shape == (1, 7) and "commands_tried" not in r1.settings
    # a sampler of your own proposes a fixed width: no retry by default, an error when asked for one
    mine = opt.UniformSampler(1)
    again = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=2))
    r2 = opt.solve(again, batches=1, population=8, seed=0, mesh_candidates=2, sampler=mine, mesh_retry_margin=0,
                   restarts=0, thin_spheres=False)
    assert not r2.success and r2.commands.shape == (1, 7)
    with pytest.raises(ValueError, match="max_commands"):
        opt.solve(shelf, batches=1, population=8, sampler=mine, max_commands=2)
    with pytest.raises(ValueError, match="max_commands"):
        opt.solve(shelf, batches=1, population=8, n_commands=2, max_commands=1)


def test_mesh_only_failure_retries_with_a_wider_obstacle_margin(shelf):
    mine = opt.UniformSampler(1)
    # the first two trajectories touch a mesh: the one-command attempt fails on meshes alone, and the
    # same solve with the obstacle margin 2 mm wider comes back, succeeded, with that margin
    flagged = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=2))
    r = opt.solve(flagged, batches=1, population=8, seed=0, mesh_candidates=2, sampler=mine, thin_spheres=False)
    base = gfcs.FabricConfig.defaults().to_dict()["obstacles"]["margin"]
    assert r.success and r.commands.shape == (1, 7) and r.settings["commands_tried"] == [1, 1]
    assert r.settings["obstacle_margins_tried"] == pytest.approx([base, base + 0.002])
    assert r.fabric_config["obstacles"]["margin"] == pytest.approx(base + 0.002)
    assert r.n_evaluations == 16
    # a failure of the sphere model itself (no time to reach the goal) is not retried that way
    short = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=0))
    r = opt.solve(short, batches=1, population=8, seed=0, sampler=mine, settings=opt.RolloutSettings(t_max=0.05),
                  restarts=0, thin_spheres=False)
    assert not r.success and "commands_tried" not in r.settings and r.n_evaluations == 8
    with pytest.raises(ValueError, match="mesh_retry_margin"):
        opt.solve(shelf, batches=1, population=8, mesh_retry_margin=-0.001)


def test_mesh_retry_tries_one_and_two_commands(shelf):
    base = gfcs.FabricConfig.defaults().to_dict()["obstacles"]["margin"]
    # six trajectories touch (two checked per attempt): one and two commands at the plain margin and one
    # command 2 mm wider fail; two commands 2 mm wider succeed
    flagged = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=6))
    r = opt.solve(flagged, batches=1, population=8, seed=0, mesh_candidates=2, thin_spheres=False, max_commands=2)
    assert r.success and r.commands.shape == (2, 7) and r.settings["commands_tried"] == [1, 2, 1, 2]
    assert r.settings["obstacle_margins_tried"] == pytest.approx([base, base, base + 0.002, base + 0.002])


def test_mesh_retries_widen_the_margin_step_by_step(shelf):
    base = gfcs.FabricConfig.defaults().to_dict()["obstacles"]["margin"]
    # ten trajectories touch: five attempts fail (two checked each); a single mesh retry stops after four,
    # the default second one, 4 mm wider, succeeds with two commands
    kw = dict(batches=1, population=8, seed=0, mesh_candidates=2, thin_spheres=False, restarts=0, max_commands=2)
    once = opt.solve(dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=10)),
                     mesh_retries=1, **kw)
    assert not once.success and once.settings["commands_tried"] == [1, 2, 1, 2]
    twice = opt.solve(dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=10)), **kw)
    assert twice.success and twice.settings["commands_tried"] == [1, 2, 1, 2, 1, 2]
    assert twice.settings["obstacle_margins_tried"] == pytest.approx([base] * 2 + [base + 0.002] * 2
                                                                     + [base + 0.004] * 2)
    none = opt.solve(dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=10)),
                     mesh_retries=0, **kw)
    assert not none.success and none.settings["commands_tried"] == [1, 2]
    for bad in (-1, 1.5, True, "2"):
        with pytest.raises(ValueError, match="mesh_retries"):
            opt.solve(shelf, batches=1, population=8, mesh_retries=bad)


# ------------------------------------------------------------------------------ MotionBenchMaker Panda
def test_mbm_panda_attaches_its_mesh_checker(shared_dir):
    folder = shared_dir / "robots" / "mbm_panda"
    robot = problems.mbm_panda(folder)
    assert problems.mbm_panda(folder) is robot
    checker = problems.mesh_checker_for(robot)
    assert checker is not None and checker.num_shapes == 11 and checker.joint_names == robot.joint_names
    assert checker.shape_links[-3:] == ["panda_hand", "panda_leftfinger", "panda_rightfinger"]
    suite = problems.load_mbm_dir(shared_dir / "mbm", classes=["table_pick"], limit=2, robot=robot)
    assert all(p.mesh_checker is checker for p in suite)
    plain = problems.load_mbm_dir(shared_dir / "mbm", classes=["table_pick"], limit=1,
                                  robot=gfcs.Robot.panda())
    shipped = plain[0].mesh_checker  # the shipped Panda's polytopes, fingers opened as the request says
    assert shipped is not checker and shipped.robot.locked_positions == pytest.approx({"panda_finger_joint1": 0.065})


@pytest.mark.parametrize("cls", problems.CLASSES)
def test_mbm_starts_and_goals_are_mesh_free(shared_dir, cls):
    robot = problems.mbm_panda(shared_dir / "robots" / "mbm_panda")
    for p in problems.load_mbm_dir(shared_dir / "mbm", classes=[cls], limit=3, robot=robot):
        states = np.vstack([p.q0, p.goal])
        assert np.all(p.mesh_checker.clearance(p.scene, states) > 0.0), p.name
        assert np.all(p.mesh_checker.self_clearance(states) > 0.0), p.name


def test_mbm_arm_pushed_into_the_table_is_in_contact(shared_dir):
    checker = problems.mesh_checker_for(problems.mbm_panda(shared_dir / "robots" / "mbm_panda"))
    scene = gfcs.Scene.from_moveit_yaml(shared_dir / "mbm" / "table_pick" / "scene0001.yaml")
    for o in scene.obstacles():
        if o["name"] != "table_top":
            scene.remove(o["id"])
    bend = np.array([[1.17, q2, 0.0, -1.5, 0.0, 1.6, 0.785] for q2 in np.linspace(0.3, 0.7, 21)])
    d = checker.clearance(scene, bend)
    assert d[0] > 0.05 and d[-1] <= 0.0
    first = int(np.argmax(d <= 0.0))
    assert np.all(d[:first] > 0.0)


def test_mbm_clearance_matches_dense_surface_samples(shared_dir):
    """Independent reference: the scene's signed distance at dense samples of every collision mesh surface
    (trimesh) is never below the mesh clearance and approaches it (sample spacing ~2 mm)."""
    trimesh = pytest.importorskip("trimesh")
    checker = problems.mesh_checker_for(problems.mbm_panda(shared_dir / "robots" / "mbm_panda"))
    robot = checker.robot
    local = []
    for g in robot.collision_geometry():
        mesh = trimesh.load(g["path"], force="mesh")
        pts, _ = trimesh.sample.sample_surface_even(mesh, 4000, seed=0)
        pts = np.vstack([pts, mesh.vertices]) * g["scale"]
        local.append((robot.link_index(g["link"]), pts @ g["origin"][:3, :3].T + g["origin"][:3, 3]))
    mbm = problems.mbm_panda(shared_dir / "robots" / "mbm_panda")
    for cls in ("cage", "table_under_pick", "bookshelf_thin"):
        for p in problems.load_mbm_dir(shared_dir / "mbm", classes=[cls], limit=2, robot=mbm):
            for q in (p.q0, p.goal):
                poses = robot.link_poses(q)
                ref = min(float(np.min(p.scene.signed_distance(pts @ poses[k][:3, :3].T + poses[k][:3, 3])))
                          for k, pts in local)
                got = checker.clearance(p.scene, q)
                if ref > checker.max_distance:
                    assert got == math.inf or got > checker.max_distance - 2e-3
                    continue
                assert got <= ref + 1e-9 and ref - got < 2e-3, (p.name, got, ref)


def test_selection_skips_candidates_whose_meshes_collide(sphere_and_mesh_sliders, fake_optimum):
    """The cheapest command (x = 0.25) keeps the 0.05 m sphere clear of the ball at x = 0.5 but drives the
    0.4 m box into it; the dearer one (x = −0.3) stays clear. An unreached candidate is never tried."""
    spheres, checker, scene = sphere_and_mesh_sliders
    p = Problem("slide", spheres, scene, q0=[-0.2], goal=[-0.1], mesh_checker=checker)
    # joint-space speed control at 1.2 rad/s, no hand attractor: the slider overshoots the command's
    # waypoint tolerance (0.1 rad here; at the default 0.3 it turns back before the box reaches the ball)
    fabric = opt.make_fabric(p, {"speed": {"ee_weight": 0.0, "desired_speed": 1.2},
                                 "ee_position": {"enabled": False}})
    settings = opt.RolloutSettings(waypoint_tol=0.1)
    result = fake_optimum([[0.25], [-0.9], [-0.3]], [1.0, 150.0, 2.0])
    chosen = opt.select_candidate(fabric, p, result, 1, settings, checker,
                                  opt.SelectionOptions(length_slack=0.0, mesh_candidates=8))
    met = chosen.metrics
    assert chosen.reached and met["success"] and met["mesh_clearance"] > 0
    assert chosen.commands[0, 0] == -0.3 and met["selection_rank"] == 1 and met["mesh_candidates_checked"] == 2
    chosen = opt.select_candidate(fabric, p, result, 1, settings, checker,
                                  opt.SelectionOptions(length_slack=0.0, mesh_candidates=1))
    met = chosen.metrics
    assert chosen.commands[0, 0] == 0.25 and not met["success"] and met["mesh_clearance"] < 0
    assert met["mesh_candidates_checked"] == 1


def test_bench_rows_carry_the_mesh_clearances_and_stay_strict_json(sphere_and_mesh_sliders):
    from gfcs.results import _enc, bench_row

    spheres, checker, scene = sphere_and_mesh_sliders
    t = np.linspace(0.0, 1.0, 51)
    q = (0.25 * t)[:, None]
    plain = bench_row("p", "c", "GF", "gf", 0, 0, 0.1, 1.0, metrics.trajectory_metrics(spheres, scene, t, q, [0.25]),
                      0.2)
    assert "mesh_clearance" not in plain and "mesh_self_clearance" not in plain
    met = metrics.trajectory_metrics(spheres, scene, t, q, [0.25], mesh_checker=checker)
    row = bench_row("p", "c", "GF", "gf", 0, 0, 0.1, 1.0, met, 0.2)
    assert row["mesh_clearance"] == pytest.approx(0.4 - 0.45, abs=1e-7) and not row["success"]
    # one link: no self pair, clearance inf, written as the string "Infinity" in strict JSON
    assert json.loads(json.dumps(_enc(row), allow_nan=False))["mesh_self_clearance"] == "Infinity"


def test_the_cli_no_retry_options_turn_every_retry_off(shelf):
    from gfcs import cli

    # every candidate of every attempt touches a mesh: each retry would run and be listed
    hopeless = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=10**6))
    retried = opt.solve(hopeless, batches=1, population=8, seed=0, mesh_candidates=2)
    # thin spheres: 1-4 commands, 1-4 with the margin 2 mm wider, 1-4 4 mm wider; then the same on the
    # covering spheres; then all of it again in each of the two restarts
    assert not retried.success and retried.settings["commands_tried"] == [1, 2, 3, 4] * 3 * 2 * 3
    base = gfcs.FabricConfig.defaults().to_dict()["obstacles"]["margin"]
    thin = base + opt.THIN_SPHERE_MARGIN
    assert retried.settings["obstacle_margins_tried"] == pytest.approx(
        [m + k * 0.002 for m in (thin, base) for k in (0,) * 4 + (1,) * 4 + (2,) * 4] * 3)
    assert [a["settings"]["restart"] for a in retried.attempts] == [0] * 24 + [1] * 24 + [2] * 24
    once = opt.solve(hopeless, batches=1, population=8, seed=0, mesh_candidates=2, **cli._no_retry())
    assert not once.success and "commands_tried" not in once.settings and once.n_evaluations == 8
    assert once.settings["sphere_model"] == "thin"  # the thin spheres are the first model, not a retry


def test_a_failed_thin_sphere_solve_falls_back_to_the_covering_spheres(shelf):
    base = gfcs.FabricConfig.defaults().to_dict()["obstacles"]["margin"]
    single = dict(batches=1, population=8, seed=0, mesh_candidates=2, max_commands=1, mesh_retry_margin=0,
                  goal_contact_slack=0, restarts=0)
    # the two trajectories checked on the thin spheres touch: the covering spheres' solve comes back
    flagged = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=2))
    r = opt.solve(flagged, **single)
    assert r.success and "sphere_model" not in r.settings and r.robot is shelf.robot
    assert r.settings["commands_tried"] == [1, 1]
    assert r.settings["obstacle_margins_tried"] == pytest.approx([base + opt.THIN_SPHERE_MARGIN, base])
    assert r.n_evaluations == 16
    covering = opt.solve(shelf, thin_spheres=False, **single)
    np.testing.assert_array_equal(r.trajectory.q, covering.trajectory.q)
    # without the fallback the thin spheres' failure is returned
    flagged = dataclasses.replace(shelf, mesh_checker=FlaggingChecker(shelf.robot, bad=2))
    r = opt.solve(flagged, sphere_fallback=False, **single)
    assert not r.success and r.settings["sphere_model"] == "thin" and r.n_evaluations == 8
    assert r.fabric_config["obstacles"]["margin"] == pytest.approx(base + opt.THIN_SPHERE_MARGIN)


def test_an_endpoint_grazing_the_meshes_gets_the_longer_sweep(sphere_and_mesh_sliders):
    """The box face is at 0.2 + q and the ball's surface at 0.4: a goal at 0.1995 keeps 0.5 mm, within the
    margin (0.1 mm) + 1 mm that the continuous check must certify; one at 0.15 keeps 50 mm."""
    from gfcs.planning.endpoints import endpoint_grazes

    spheres, checker, scene = sphere_and_mesh_sliders
    near = Problem("near", spheres, scene, q0=[0.0], goal=[0.1995], mesh_checker=checker)
    far = dataclasses.replace(near, goal=[0.15])
    assert endpoint_grazes(near, metrics.DEFAULT_MESH_MARGIN)
    assert not endpoint_grazes(far, metrics.DEFAULT_MESH_MARGIN)
    assert endpoint_grazes(dataclasses.replace(far, q0=[0.1995]), metrics.DEFAULT_MESH_MARGIN)  # the start too
    assert not endpoint_grazes(dataclasses.replace(near, goal=[0.1985]), metrics.DEFAULT_MESH_MARGIN)  # 1.5 mm
    assert not endpoint_grazes(dataclasses.replace(near, mesh_checker=None), metrics.DEFAULT_MESH_MARGIN)
    preset = gfcs.planning.get_preset("default")
    for problem, cap in ((near, preset.grazing_sweep_time), (far, preset.sweep_time)):
        r = opt.solve(problem, batches=1, population=4, threads=1, policies=[])
        assert r.settings["sweep_time"] == cap
