"""gfcs.sphere_fit: spheres fitted to collision geometry contain every point of it, on the links without
spheres only, with the SRDF's disabled pairs honoured; a mesh robot with no spheres plans from the CLI."""

import numpy as np
import pytest

import gfcs
from gfcs.coverage import sphere_deficits
from gfcs.sphere_fit import fit_link_spheres, fitted_spheres, with_fitted_spheres


def _box_points(size, n=4000, seed=0):
    """Corners and seeded surface points of a box of ``size`` (3,) centred at the origin."""
    rng = np.random.default_rng(seed)
    half = np.asarray(size) / 2
    pts = rng.uniform(-half, half, (n, 3))
    face = rng.integers(0, 3, n)
    pts[np.arange(n), face] = np.where(rng.random(n) < 0.5, -half[face], half[face])
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    return np.vstack([pts, corners])


def _covered(points, spheres, margin=0.0):
    centres = np.array([c for c, _ in spheres])
    radii = np.array([r for _, r in spheres])
    gap = np.linalg.norm(points[:, None] - centres[None], axis=2) - radii[None]
    return np.min(gap, axis=1)


@pytest.mark.parametrize("size", [(0.1, 0.1, 0.1), (0.6, 0.08, 0.08), (0.3, 0.2, 0.02)])
def test_every_point_lies_inside_a_sphere_with_the_margin_to_spare(size):
    pts = _box_points(size)
    spheres = fit_link_spheres(pts, margin=0.002)
    assert np.max(_covered(pts, spheres)) <= -0.002 + 1e-12
    # a cover hugs the shape: no sphere much larger than the box's half-diagonal
    assert max(r for _, r in spheres) <= np.linalg.norm(size) / 2 + 0.002 + 1e-9


def test_a_long_link_takes_several_spheres_and_a_cube_one():
    assert len(fit_link_spheres(_box_points((0.1, 0.1, 0.1)))) == 1
    long = fit_link_spheres(_box_points((0.6, 0.08, 0.08)))
    assert len(long) >= 4
    volume = sum(r**3 for _, r in long) * 4 / 3 * np.pi
    assert volume < 4 / 3 * np.pi * (np.linalg.norm((0.6, 0.08, 0.08)) / 2) ** 3 / 10  # far below one sphere


def test_an_l_shaped_link_is_covered_by_spheres_along_both_arms():
    pts = np.vstack([_box_points((0.4, 0.05, 0.05)) + [0.2, 0, 0], _box_points((0.05, 0.4, 0.05)) + [0, 0.2, 0]])
    spheres = fit_link_spheres(pts)
    assert np.max(_covered(pts, spheres)) < 0
    centres = np.array([c for c, _ in spheres])
    assert np.any(centres[:, 0] > 0.25) and np.any(centres[:, 1] > 0.25)


#: A thin cylinder on an offset, turned origin (a gripper finger tip of a ROS description): the SLSQP refinement
#: of one of its clusters steps off to a centre ~1e25 m away.
THIN_CYLINDER = """<robot name="finger"><link name="base"/>
  <link name="tip"><collision><origin rpy="0 0 3.14159265359" xyz="0 -0.0045 -0.015"/>
    <geometry><cylinder length="0.037" radius="0.008"/></geometry></collision></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="tip"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="1"/></joint></robot>"""


def test_a_refinement_that_diverges_keeps_the_iterations_sphere(tmp_path):
    urdf = tmp_path / "finger.urdf"
    urdf.write_text(THIN_CYLINDER)
    spheres = fitted_spheres(gfcs.Robot.from_urdf(str(urdf)))
    assert spheres
    # every sphere hugs the 37 mm x 16 mm cylinder: within its half-diagonal of its axis' middle
    for _, centre, radius in spheres:
        assert radius <= np.hypot(0.037, 0.016) / 2 + 0.002
        assert np.linalg.norm(np.asarray(centre) - [0.0, -0.0045, -0.015]) <= 0.037


def test_the_fit_is_reproducible_and_a_subsample_still_covers_every_point():
    pts = _box_points((0.5, 0.1, 0.05), n=20000, seed=3)  # more points than the fit iterates over
    a, b = fit_link_spheres(pts), fit_link_spheres(pts)
    assert [(c.tolist(), r) for c, r in a] == [(c.tolist(), r) for c, r in b]
    assert np.max(_covered(pts, a)) < 0


@pytest.mark.parametrize("points, kwargs", [
    (np.zeros((5, 2)), {}), (np.array([[0.0, np.nan, 0.0]]), {}), (np.zeros((5, 3)), {"max_per_link": 0}),
    (np.zeros((5, 3)), {"margin": -0.1})])
def test_bad_input_names_the_problem(points, kwargs):
    with pytest.raises(gfcs.InvalidValueError):
        fit_link_spheres(points, **kwargs)
    assert fit_link_spheres(np.zeros((0, 3))) == []


ARM = """<robot name="arm">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="0.2 0 0"/><geometry><box size="0.4 0.06 0.06"/></geometry></collision></link>
  <link name="fore"><collision><origin xyz="0.15 0 0" rpy="0 1.5708 0"/>
    <geometry><cylinder radius="0.03" length="0.3"/></geometry></collision>{fore_sphere}</link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.4 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" velocity="1" effort="1"/></joint>
</robot>"""


def test_a_mesh_robot_gets_spheres_covering_its_geometry_and_keeps_its_srdf():
    robot = gfcs.Robot.from_urdf(ARM.format(fore_sphere=""), ee_link="fore")
    assert len(robot.sphere_radii) == 0
    fitted = with_fitted_spheres(robot)
    assert set(fitted.sphere_links) == {"base", "upper", "fore"}
    assert np.all(sphere_deficits(fitted, robot) == 0.0)
    srdf = '<robot name="arm"><disable_collisions link1="base" link2="fore" reason="Never"/></robot>'
    pruned = with_fitted_spheres(robot.with_srdf(srdf))
    links = np.asarray(pruned.sphere_links)
    pairs = {tuple(sorted((links[a], links[b]))) for a, b in np.asarray(pruned.self_collision_pairs)}
    assert ("base", "fore") not in pairs
    assert fitted_spheres(robot, ["upper"]) and {s[0] for s in fitted_spheres(robot, ["upper"])} == {"upper"}


def test_only_the_links_without_spheres_are_fitted():
    sphere = ('<collision><origin xyz="0.15 0 0"/><geometry><sphere radius="0.04"/></geometry></collision>')
    robot = gfcs.Robot.from_urdf(ARM.format(fore_sphere=""), ee_link="fore",
                                 spheres=[("fore", [0.15, 0.0, 0.0], 0.2)])
    fitted = with_fitted_spheres(robot)
    assert list(fitted.sphere_links).count("fore") == 1 and {"base", "upper"} <= set(fitted.sphere_links)
    covered = gfcs.Robot.from_urdf(ARM.format(fore_sphere=sphere), ee_link="fore",
                                   spheres=[(k, [0.0, 0.0, 0.0], 0.5) for k in ("base", "upper", "fore")])
    assert with_fitted_spheres(covered) is covered


STACK = """<robot name="stack">
  <link name="base"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="middle"><collision><geometry><box size="0.05 0.05 0.05"/></geometry></collision></link>
  <link name="top"><collision><origin xyz="0.1 0 0"/><geometry><box size="0.3 0.05 0.05"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="middle"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="middle"/><child link="top"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
</robot>"""


def test_link_pairs_whose_fitted_spheres_always_overlap_are_left_out_as_moveit_setup_assistant_does():
    """base and top turn about the same point, two joints apart: their fitted spheres overlap whatever the
    joints do (a pair MoveIt Setup Assistant disables as "always in collision")."""
    robot = gfcs.Robot.from_urdf(STACK, ee_link="top")
    left_out = []
    fitted = with_fitted_spheres(robot, left_out=left_out)
    assert left_out == [("base", "top")]
    links = np.asarray(fitted.sphere_links)
    pairs = {tuple(sorted((links[a], links[b]))) for a, b in np.asarray(fitted.self_collision_pairs)}
    assert ("base", "top") not in pairs
    with pytest.raises(gfcs.LinkError):
        fitted.with_disabled_pairs([("base", "nowhere")])


#: base; a link ``b`` on a joint 0.3 m out along x, turning about z, its sphere 0.15 m out on it; between
#: them a lift of 1 mm (links one joint apart are not self pairs)
SWING = """<robot name="swing"><link name="base"/><link name="lift"/><link name="b"/>
  <joint name="up" type="prismatic"><parent link="base"/><child link="lift"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.001" velocity="1"/></joint>
  <joint name="j" type="revolute"><parent link="lift"/><child link="b"/><origin xyz="0.3 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3.14159" upper="3.14159" velocity="1"/></joint></robot>"""


class _SwingMeshes:
    """A mesh checker stand-in for :data:`SWING`: the pair (base, b) is apart by |c_b| − 0.18 m, c_b the
    centre of b's sphere (in contact within ~15 % of the turn, near θ = π)."""

    self_pair_links = [("base", "b")]

    def __init__(self):
        self.calls = 0

    def pair_clearances(self, q, cutoff=None, depth=True):
        self.calls += 1
        theta = np.atleast_2d(q)[:, 1]
        return (np.sqrt(0.1125 + 0.09 * np.cos(theta)) - 0.18)[:, None]


def test_pairs_whose_spheres_overlap_where_the_meshes_are_apart_are_left_out(tmp_path, monkeypatch):
    """Spheres of 0.25 and 0.15 m overlap over ~68 % of b's turn, the meshes touch over ~15 %: the spheres
    forbid most of what the meshes allow (a forearm's spheres round a torso's), which always_touching's 95 %
    does not catch; a smaller sphere on b (overlap ~31 %) keeps the pair checked."""
    from gfcs.sphere_fit import always_touching, sphere_artefacts

    monkeypatch.setenv("GFCS_CACHE_DIR", str(tmp_path))
    for radius, artefact in ((0.15, True), (0.05, False)):
        robot = gfcs.Robot.from_urdf(SWING, ee_link="b").with_spheres([("base", [0, 0, 0], 0.25),
                                                                       ("b", [0.15, 0, 0], radius)])
        assert always_touching(robot, ["base", "b"]) == []
        meshes = _SwingMeshes()
        assert sphere_artefacts(robot, ["base", "b"], meshes) == ([("b", "base")] if artefact else [])
        # the cache answers the second call; a factory is called only on a miss
        assert sphere_artefacts(robot, ["base", "b"], lambda: pytest.fail("built on a hit")) == (
            [("b", "base")] if artefact else [])
        assert sphere_artefacts(robot, ["base", "b"], meshes, cache=False) == ([("b", "base")] if artefact else [])
        assert meshes.calls == 2
    # no meshes found by the factory: nothing is judged
    assert sphere_artefacts(robot, ["base", "b"], lambda: None, cache=False) == []


def test_the_cli_judges_fitted_sphere_pairs_by_the_robots_own_meshes(tmp_path, monkeypatch):
    """`gfcs solve/bench/generate --robot X.urdf` (cli._robot) hands sphere_artefacts a factory of the robot's
    mesh checker, built from the same URDF."""
    from gfcs import cli, sphere_fit

    monkeypatch.setenv("GFCS_CACHE_DIR", str(tmp_path / "cache"))
    urdf = tmp_path / "stack.urdf"
    urdf.write_text(STACK)
    seen = []

    def recording(robot, links, mesh_checker, **kwargs):
        checker = mesh_checker()
        seen.append((sorted(links), type(checker).__name__, sorted(map(tuple, checker.self_pair_links))))
        return []

    monkeypatch.setattr(sphere_fit, "sphere_artefacts", recording)
    args = cli.build_parser().parse_args(["solve", "--robot", str(urdf), "--ee-link", "top"])
    cli._robot(args)
    assert seen == [(["base", "middle", "top"], "MeshChecker", [("base", "top")])]


def test_a_covering_model_replaces_spheres_that_leave_the_meshes_uncovered(tmp_path, monkeypatch):
    """Spheres made for another checker (here one small sphere per link) leave centimetres of the meshes
    outside; the covering model's spheres, fitted to the meshes the checker judges, leave none, on every link
    that has geometry, and the robot given keeps its own spheres."""
    from gfcs.sphere_fit import covering_model

    monkeypatch.setenv("GFCS_CACHE_DIR", str(tmp_path))
    meshes = gfcs.Robot.from_urdf(ARM.format(fore_sphere=""), ee_link="fore")
    small = meshes.with_spheres([("base", [0, 0, 0], 0.05), ("upper", [0.2, 0, 0], 0.03),
                                 ("fore", [0.15, 0, 0], 0.03)])
    assert sphere_deficits(small, meshes).max() > 0.05
    covering = covering_model(small, gfcs.MeshChecker(meshes))
    assert np.all(sphere_deficits(covering, meshes) == 0.0)
    assert set(covering.sphere_links) == {"base", "upper", "fore"}
    assert len(small.sphere_radii) == 3 and list(small.sphere_radii) == [0.05, 0.03, 0.03]
    # a link the description models by a <sphere> alone carries that sphere, not spheres fitted around it
    ball = ARM.replace('<geometry><cylinder radius="0.03" length="0.3"/></geometry>',
                       '<geometry><sphere radius="0.07"/></geometry>').format(fore_sphere="")
    balled = gfcs.Robot.from_urdf(ball, ee_link="fore")
    covering = covering_model(small, gfcs.MeshChecker(balled))
    fore = [(list(c), r) for link, c, r in zip(covering.sphere_links, covering.sphere_centers_local,
                                                covering.sphere_radii) if link == "fore"]
    assert len(fore) == 1 and fore[0][1] == pytest.approx(0.07) and np.allclose(fore[0][0], [0.15, 0, 0])


def _arm_with_short_spheres():
    """The ARM's mesh model and the same arm on one sphere per link, 10 cm short of the upper link's box."""
    meshes = gfcs.Robot.from_urdf(ARM.format(fore_sphere=""), ee_link="fore")
    return meshes, meshes.with_spheres([("base", [0, 0, 0], 0.15), ("upper", [0.2, 0, 0], 0.03),
                                        ("fore", [0.15, 0, 0], 0.03)])


def test_a_solve_plans_on_covering_spheres_first_where_its_own_leave_the_meshes_uncovered(tmp_path, monkeypatch):
    """models_for: the covering model comes first for spheres 10 cm short of a moving link's mesh, not for
    spheres that cover it, nor unless asked; a result's settings rebuild it (model_named)."""
    from types import SimpleNamespace

    from gfcs.planning.models import model_named, models_for

    monkeypatch.setenv("GFCS_CACHE_DIR", str(tmp_path))
    meshes, small = _arm_with_short_spheres()
    checker = gfcs.MeshChecker(meshes)
    models = models_for(SimpleNamespace(robot=small, mesh_checker=checker), covering=True)
    assert [m.name for m in models.planning] == ["covering", "spheres"]
    covering = models.planning[0]
    assert np.all(sphere_deficits(covering.robot, meshes) == 0.0)
    rebuilt = model_named(small, covering.settings())
    assert np.allclose(rebuilt.sphere_radii, covering.robot.sphere_radii)
    assert [m.name for m in models_for(SimpleNamespace(robot=small, mesh_checker=checker)).planning] == ["spheres"]
    fitted = with_fitted_spheres(meshes)
    assert [m.name for m in models_for(SimpleNamespace(robot=fitted, mesh_checker=checker),
                                       covering=True).planning] == ["spheres"]


def test_a_solve_on_covering_spheres_records_and_names_them(tmp_path, monkeypatch):
    """The default preset plans the two-link arm on covering spheres (its own are 10 cm short); the result
    records the model, the CLI summary names it, and the paper preset keeps the robot's own spheres."""
    from gfcs import cli, planning
    from gfcs.problems import Problem

    monkeypatch.setenv("GFCS_CACHE_DIR", str(tmp_path))
    meshes, small = _arm_with_short_spheres()
    problem = Problem("arm/1", small, gfcs.Scene(), np.array([0.0, 0.0]), np.array([1.0, -1.0]),
                      mesh_checker=gfcs.MeshChecker(meshes))
    result = planning.solve(problem, seed=0, batches=1, population=8, threads=1, time_limit=5)
    assert result.success and result.settings["sphere_model"] == "covering"
    assert len(result.settings["spheres"]) == len(result.robot.sphere_radii)
    assert "covering spheres fitted to the collision meshes" in cli.summary_text(result, problem)
    paper = planning.solve(problem, seed=0, batches=1, population=8, threads=1, time_limit=5, preset="paper")
    assert "sphere_model" not in paper.settings
