"""Mesh repair (gfcs.planning.repair): a path whose meshes touch an obstacle by millimetres is moved clear,
its ends kept, and a candidate repaired in the selection succeeds when judged in full."""

import dataclasses

import numpy as np
import pytest

import gfcs
from gfcs import generators, metrics, planning
from gfcs.planning import selection
from gfcs.planning.finish import FinishOptions
from gfcs.planning.repair import RepairOptions, path_constraint, repair_path
from gfcs.results import Trajectory

DEPTH = 0.002  # how far [m] the obstacle reaches into the mesh at the middle of the path


def _touching(problem, depth=DEPTH, samples=121, duration=3.0):
    """(problem with a one-sphere scene, t (T,), q (T, dof)): the straight joint path from the start to the
    goal, and a ball placed (by bisection along +z from the hand at the middle state) so that the meshes
    at the middle state reach ``depth`` into it."""
    t = np.linspace(0.0, duration, samples)
    q = problem.q0 + (t / duration)[:, None] * (problem.goal - problem.q0)
    mid = q[samples // 2]
    robot, checker = problem.robot, problem.mesh_checker
    hand = robot.link_poses(mid)[robot.link_index(robot.ee_link)][:3, 3]

    def scene_at(s):
        scene = gfcs.Scene()
        scene.add_sphere(hand + np.array([0.0, 0.0, s]), 0.03)
        return scene

    lo, hi = 0.0, 0.6
    assert float(checker.clearance(scene_at(lo), mid)) < -depth < float(checker.clearance(scene_at(hi), mid))
    for _ in range(60):
        s = 0.5 * (lo + hi)
        lo, hi = (s, hi) if float(checker.clearance(scene_at(s), mid)) < -depth else (lo, s)
    scene = scene_at(hi)
    assert float(checker.clearance(scene, q[0])) > 0.01 and float(checker.clearance(scene, q[-1])) > 0.01
    return dataclasses.replace(problem, scene=scene), t, q


@pytest.fixture(scope="module")
def touching():
    return _touching(generators.generate("box", 1, seed=0)[0])


def test_the_repair_clears_every_visited_state_and_keeps_the_ends(touching):
    problem, t, q = touching
    before = path_constraint(problem.robot, problem.scene, problem.mesh_checker, q, 1e-4, 0.002, 0.0)
    assert before.min() < -DEPTH + 1e-6  # the mesh term at the middle, at least
    options = RepairOptions()
    moved, record = repair_path(problem.robot, problem.scene, problem.mesh_checker, t, q, options)
    assert moved is not None and record["states_left"] == 0 and record["iterations"] >= 1
    after = path_constraint(problem.robot, problem.scene, problem.mesh_checker,
                            moved[metrics.checked_indices(moved)], 1e-4, options.clearance, 0.0)
    assert after.min(axis=1).min() >= 0.0
    np.testing.assert_array_equal(moved[0], q[0])
    np.testing.assert_array_equal(moved[-1], q[-1])
    # a local deformation: small, and nothing moves far (in time) from the contact
    assert 0.0 < record["max_displacement"] < 0.2
    touched = np.flatnonzero(np.any(moved != q, axis=1))
    assert touched.min() > 0 and touched.max() < len(q) - 1
    # the meshes now clear the ball along the whole path, between the states too
    assert metrics.mesh_verdict(problem.mesh_checker, problem.scene, moved)[2]


def test_a_clear_path_is_returned_unchanged(touching):
    problem, t, q = touching
    far = gfcs.Scene()
    far.add_sphere([3.0, 3.0, 3.0], 0.05)
    moved, record = repair_path(problem.robot, far, problem.mesh_checker, t, q, RepairOptions())
    np.testing.assert_array_equal(moved, q)
    assert record["iterations"] == 0 and record["states_left"] == 0


def test_a_contact_it_cannot_undo_in_its_iterations_is_reported(touching):
    problem, t, q = touching
    deep = _touching(problem, depth=0.015)[0]
    moved, record = repair_path(problem.robot, deep.scene, problem.mesh_checker, t, q,
                                RepairOptions(iterations=1, max_step=1e-3))
    assert moved is None and record["states_left"] > 0 and record["min_h"] < 0.0


def test_a_candidate_repaired_in_the_selection_succeeds_when_judged_in_full(touching):
    problem, t, q = touching
    qd = np.gradient(q, t, axis=0)
    qd[0] = qd[-1] = 0.0
    traj = Trajectory(t, q, qd)
    options = selection.SelectionOptions(repair=RepairOptions())
    judged = selection._judge(problem, traj, problem.mesh_checker, options, None)
    assert not judged["success"] and judged["mesh_clearance"] < 0.0
    candidate = selection.Candidate(0, np.zeros((1, problem.dof)), traj, 1.0, True, np.zeros(2), judged)
    repaired = selection._repair(problem, candidate, problem.mesh_checker, options, FinishOptions(), 0.01, None)
    assert repaired is not None and repaired.success
    assert repaired.metrics["mesh_repair"]["judged"] == "success"
    assert repaired.metrics["velocity_ratio"] <= 1.0 + 1e-6
    np.testing.assert_allclose(repaired.trajectory.q[-1], problem.goal, atol=1e-9)
    # the candidate that was repaired keeps its own trajectory and says what was tried
    assert candidate.trajectory is traj and "mesh_repair" in candidate.metrics


def test_only_mesh_contact_failures_are_repaired():
    assert selection.mesh_contact_only({"success": False, "sphere_success": True, "mesh_clearance": -0.001})
    assert not selection.mesh_contact_only({"success": False, "sphere_success": False, "mesh_clearance": 0.1})
    assert not selection.mesh_contact_only({"success": False, "sphere_success": True, "mesh_clearance": 0.0,
                                             "mesh_check_complete": False})
    assert not selection.mesh_contact_only({"success": True, "sphere_success": True, "mesh_clearance": 0.1})
    assert not selection.mesh_contact_only({"success": False, "sphere_success": True})  # no meshes judged


def test_the_presets_and_the_switch():
    assert planning.get_preset("default").repair is not None
    assert planning.get_preset("paper").repair is None
    problem = generators.generate("box", 1, seed=0)[0]
    for switch, expected in ((None, True), (False, False), (True, True)):
        result = planning.solve(problem, batches=1, population=4, policies=[], mesh_repair=switch)
        assert result.settings["mesh_repair"] is expected
    paper = planning.solve(problem, batches=1, population=4, preset="paper", mesh_repair=True)
    assert paper.settings["mesh_repair"] is True


@pytest.mark.parametrize("field,value", [("candidates", 0), ("iterations", 0), ("clearance", -1.0),
                                         ("smoothing", 0.0), ("max_step", float("nan")), ("fd_step", -1e-4)])
def test_bad_options_name_the_field(field, value):
    with pytest.raises(gfcs.InvalidValueError, match=field):
        RepairOptions(**{field: value})


def _per_part_agrees(checker, scene, qs):
    """shape_clearances / pair_clearances: the row minima are clearance / self_clearance, bit for bit, and
    under a cutoff every value below it is exact while the others are at or above it."""
    shapes = checker.shape_clearances(scene, qs)
    pairs = checker.pair_clearances(qs)
    assert shapes.shape == (len(qs), checker.num_shapes) and pairs.shape == (len(qs), checker.num_self_pairs)
    np.testing.assert_array_equal(shapes.min(axis=1), checker.clearance(scene, qs))
    np.testing.assert_array_equal(pairs.min(axis=1), checker.self_clearance(qs))
    np.testing.assert_array_equal(checker.shape_clearances(scene, qs[0]), shapes[0])
    assert len(checker.self_pair_links) == checker.num_self_pairs
    # depth=False (contact verdicts): the same distances apart; in contact ≤ 0 and no deeper than the depth
    flat = checker.pair_clearances(qs, depth=False)
    np.testing.assert_array_equal(flat[pairs > 0], pairs[pairs > 0])
    assert np.all((flat[pairs <= 0] <= 0) & (flat[pairs <= 0] >= pairs[pairs <= 0]))
    for cutoff in (0.005, 0.05):
        near_shapes = checker.shape_clearances(scene, qs, cutoff=cutoff)
        near_pairs = checker.pair_clearances(qs, cutoff=cutoff)
        for exact, near in ((shapes, near_shapes), (pairs, near_pairs)):
            below = exact < cutoff
            np.testing.assert_array_equal(near[below], exact[below])
            assert np.all(near[~below] >= cutoff)
        # the per-state minima under a cutoff agree with clearance(cutoff=...) below it
        c = checker.clearance(scene, qs, cutoff=cutoff)
        np.testing.assert_array_equal(np.minimum(near_shapes.min(axis=1), cutoff), np.minimum(c, cutoff))


def test_per_shape_and_per_pair_clearances_agree_with_the_minima(touching):
    problem, _, q = touching
    rng = np.random.default_rng(3)
    lo, up = np.asarray(problem.robot.lower), np.asarray(problem.robot.upper)
    qs = np.concatenate([q[::10], rng.uniform(lo, up, size=(40, problem.dof))])
    _per_part_agrees(problem.mesh_checker, problem.scene, qs)


def test_per_shape_clearances_on_detailed_meshes(mbm_dir):
    """The MotionBenchMaker Panda's meshes (hull bounds, mesh trees) in a MotionBenchMaker scene."""
    from gfcs.problems import load_mbm_dir

    problem = load_mbm_dir(mbm_dir, classes=["cage"], limit=1)[0]
    t = np.linspace(0.0, 1.0, 25)[:, None]
    qs = problem.q0 + t * (problem.goal - problem.q0)
    _per_part_agrees(problem.mesh_checker, problem.scene, qs)


def test_the_command_line_switch(tmp_path):
    from gfcs import cli

    out = tmp_path / "r.json"
    assert cli.main(["solve", "--batches", "1", "--no-mesh-repair", "--json", str(out), "--no-trajectory"]) == 0
    import json

    assert json.loads(out.read_text())["settings"]["mesh_repair"] is False


def test_a_sweep_past_its_own_time_is_a_final_mesh_failure(touching):
    """A path grazing the margin (its states 0.5 mm beyond it, within the interpolation allowance) needs the
    continuous check; given no time for it the verdict is a final failure (repairable), given a deadline
    that has passed it is an unfinished one."""
    import time

    problem, t, q = touching
    margin = metrics.DEFAULT_MESH_MARGIN
    checker, states = problem.mesh_checker, q[metrics.checked_indices(q)]
    hand = problem.robot.link_poses(q[len(q) // 2])[problem.robot.link_index(problem.robot.ee_link)][:3, 3]

    def scene_at(s):
        scene = gfcs.Scene()
        scene.add_sphere(hand + np.array([0.0, 0.0, s]), 0.03)
        return scene

    def path_clearance(s):
        return float(checker.clearance(scene_at(s), states).min())

    lo, hi = 0.0, 0.6
    want = margin + 0.0005
    for _ in range(60):  # the ball's height at which the path's closest state keeps `want`
        s = 0.5 * (lo + hi)
        lo, hi = (s, hi) if path_clearance(s) < want else (lo, s)
    scene = scene_at(hi)
    clear, _, ok, complete = metrics.mesh_check(checker, scene, q, margin)
    assert margin < clear < margin + metrics.INTERPOLATION_ALLOWANCE and ok and complete  # the sweep certifies it
    assert metrics.mesh_check(checker, scene, q, margin, sweep_time=1e-9)[2:] == (False, True)
    assert metrics.mesh_check(checker, scene, q, margin, deadline=time.perf_counter() - 1.0,
                              sweep_time=10.0)[2:] == (False, False)
    assert metrics.mesh_check(checker, scene, q, margin, sweep_time=60.0)[2:] == (True, True)


@pytest.mark.parametrize("length", [5, 61, 200])
def test_spread_keeps_the_path_length_and_centres_each_step(length):
    """A path shorter than the Gaussian kernel (3σ each side) gets a spread of its own length, as a long one."""
    from gfcs.planning.repair import _spread

    sigma, at = 10.0, np.array([length // 2])
    d = _spread(np.array([[1.0, -2.0]]), at, length, sigma)
    assert d.shape == (length, 2)
    s = np.arange(length)
    taper = np.clip(np.minimum(s, length - 1 - s) / sigma, 0.0, 1.0)
    # one step: the kernel (peak 1) centred on its sample, never divided by a weight below 1, then tapered
    expected = np.exp(-0.5 * ((s - at[0]) / sigma) ** 2) * (np.abs(s - at[0]) <= 30) * taper
    np.testing.assert_allclose(d[:, 0], expected, atol=1e-12)
    np.testing.assert_allclose(d[:, 1], -2.0 * expected, atol=1e-12)


def test_no_repair_iteration_starts_that_would_end_past_the_deadline(touching, monkeypatch):
    """On a clock that advances 1 s per constraint evaluation: with time for the first iteration and a bit
    more, the repair does not start a second one that would end past the deadline."""
    from types import SimpleNamespace

    from gfcs.planning import repair

    problem, t, q = touching
    clock = SimpleNamespace(now=0.0)
    plain = repair.path_constraint

    def counted(*args, **kwargs):
        clock.now += 1.0
        return plain(*args, **kwargs)

    monkeypatch.setattr(repair, "path_constraint", counted)
    monkeypatch.setattr(repair, "time", SimpleNamespace(perf_counter=lambda: clock.now))
    _, once = repair_path(problem.robot, problem.scene, problem.mesh_checker, t, q, RepairOptions(iterations=1))
    first = clock.now - 1.0  # the first iteration's evaluations (the second one's check costs one more)
    assert once["iterations"] == 1 and first >= 2.0
    clock.now = 0.0
    _, free = repair_path(problem.robot, problem.scene, problem.mesh_checker, t, q, RepairOptions(iterations=8))
    assert free["iterations"] >= 2  # without a deadline it runs more than one
    clock.now = 0.0
    moved, record = repair_path(problem.robot, problem.scene, problem.mesh_checker, t, q,
                                RepairOptions(iterations=8), deadline=first + 1.5)
    assert record["iterations"] == 1 and moved is None
