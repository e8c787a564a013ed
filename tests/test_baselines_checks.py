"""The OMPL-free parts of the sampling-based baselines: batched sphere checks (against gfcs.metrics, the
independent reference), the motion-check resolution, the time parameterisation, and Bi-EST on a toy."""

import math

import numpy as np
import pytest

import gfcs
from gfcs import metrics
from gfcs.baselines.biest import BiEST
from gfcs.baselines.timing import time_path
from gfcs.baselines.validity import SphereValidity, segment_states
from gfcs.blend import first_difference_speed, second_difference


def _panda_validity(scene, margin=0.0, step=0.05):
    robot = gfcs.Robot.panda()
    return SphereValidity(robot, scene, margin, np.asarray(robot.lower), np.asarray(robot.upper), step)


def test_segment_states_match_omplsubdivision():
    a, b = np.zeros(3), np.array([0.3, 0.0, 0.4])  # length 0.5
    s = segment_states(a, b, 0.1)
    assert s.shape == (5, 3)
    np.testing.assert_allclose(s[-1], b)
    np.testing.assert_allclose(np.linalg.norm(np.diff(np.vstack([a, s]), axis=0), axis=1), 0.1)
    assert segment_states(a, a, 0.1).shape == (1, 3)  # a zero-length motion still checks its end


def test_sphere_validity_agrees_with_the_metrics():
    scene = gfcs.Scene()
    scene.add_box([0.3, 0.3, 0.3], ([0.45, 0.0, 0.4], [0.0, 0.0, 0.0, 1.0]))
    v = _panda_validity(scene, margin=0.002)
    rng = np.random.default_rng(0)
    q = v.lower + rng.random((200, 7)) * (v.upper - v.lower)
    robot = v.robot
    clear = metrics.obstacle_clearance(robot, scene, q)
    self_clear = metrics.self_clearance(robot, q)
    np.testing.assert_allclose(v.clearances(q), clear, atol=1e-12)
    expected = (clear >= 0.002) & (self_clear >= 0.0)
    np.testing.assert_array_equal(v.valid(q), expected)
    assert 0 < expected.sum() < 200  # both kinds occur
    bad = q[~expected][0]
    assert "collision" in v.why_invalid(bad, "goal")
    assert v.why_invalid(q[expected][0], "goal") == ""


def test_coarse_resolution_misses_a_thin_obstacle_that_a_fine_one_sees():
    robot = gfcs.Robot.panda()
    a = np.array([0.9, 0.3, 0.0, -1.8, 0.0, 2.0, 0.8])
    b = a.copy()
    b[0] = -0.9
    mid = robot.sphere_centers(0.5 * (a + b))
    hand = mid[np.argmax(mid[:, 0])]  # the sphere farthest out in front at mid-swing
    scene = gfcs.Scene()
    scene.add_box([0.01, 0.01, 0.01], (hand, [0.0, 0.0, 0.0, 1.0]))
    fine = _panda_validity(scene, step=0.01)
    coarse = _panda_validity(scene, step=2.0)  # checks b only
    assert fine.valid(np.vstack([a, b])).all()
    assert not fine.segment_valid(a, b)
    assert coarse.segment_valid(a, b)


def _distance_to_polyline(p, w):
    d = math.inf
    for a, b in zip(w[:-1], w[1:]):
        u = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        d = min(d, float(np.linalg.norm(p - (a + u * (b - a)))))
    return d


def test_time_path_rest_to_rest_within_the_limits_on_the_path():
    w = np.array([[0.0, 0.0], [1.0, 0.2], [1.2, 1.5], [0.5, 1.5]])
    v, acc = np.array([1.0, 2.0]), np.array([5.0, 5.0])
    traj = time_path(w, v, acc, dt=0.01)
    np.testing.assert_allclose(traj.q[0], w[0])
    np.testing.assert_allclose(traj.q[-1], w[-1])
    assert np.all(traj.qd[0] == 0) and np.all(traj.qd[-1] == 0)
    assert np.all(np.diff(traj.t) > 0)
    assert metrics.velocity_ratio(traj.t, traj.q, v) <= 1.0 + 1e-9
    # the path is kept: every sample lies on the polyline, up to the chord of one sample step
    step = np.max(np.linalg.norm(np.diff(traj.q, axis=0), axis=1))
    assert max(_distance_to_polyline(p, w) for p in traj.q) <= step
    # the corners are slowed down toward the acceleration limits (a piecewise-linear path at full speed
    # would turn with |Δq̇| / dt ≈ 100 rad/s² there)
    assert np.max(np.abs(second_difference(traj.t, traj.q)) / acc) < 3.0
    # nominal speed: the straight middle of the first segment runs near the slower joint's limit
    assert np.max(first_difference_speed(traj.t, traj.q)[:, 0]) > 0.5


def test_time_path_of_a_point_is_a_single_sample():
    traj = time_path(np.array([[0.1, 0.2], [0.1, 0.2]]), [1.0, 1.0])
    assert len(traj) == 1
    with pytest.raises(ValueError, match="velocity limits"):
        time_path(np.zeros((2, 2)), [1.0, 0.0])


class _Walls:
    """A 2-D point in [0, 1]² with a wall at x ∈ [0.45, 0.55] except a gap at y ∈ [0.8, 0.9]."""

    lower, upper = np.zeros(2), np.ones(2)
    step = 0.005

    def valid(self, q):
        q = np.atleast_2d(q)
        in_wall = (np.abs(q[:, 0] - 0.5) <= 0.05) & ~((q[:, 1] >= 0.8) & (q[:, 1] <= 0.9))
        return np.all((q >= 0) & (q <= 1), axis=1) & ~in_wall

    def segment_valid(self, a, b):
        return bool(np.all(self.valid(segment_states(a, b, self.step))))


def test_biest_finds_the_gap_and_is_reproducible():
    world = _Walls()
    start, goal = np.array([0.1, 0.1]), np.array([0.9, 0.1])
    paths = []
    for _ in range(2):
        planner = BiEST(world, extent=math.sqrt(2.0))
        path = planner.solve(start, goal, np.random.default_rng(7), deadline=math.inf)
        assert path is not None and planner.nodes > 2
        paths.append(np.array(path))
    p = paths[0]
    np.testing.assert_array_equal(p, paths[1])
    np.testing.assert_allclose(p[0], start)
    np.testing.assert_allclose(p[-1], goal)
    assert all(world.segment_valid(a, b) for a, b in zip(p[:-1], p[1:]))
    crossing = p[np.abs(p[:, 0] - 0.5) <= 0.05]
    assert np.all((crossing[:, 1] >= 0.8) & (crossing[:, 1] <= 0.9))  # through the gap only
    assert np.max(np.linalg.norm(np.diff(p, axis=0), axis=1)) <= 0.2 * math.sqrt(2.0) * math.sqrt(2.0) + 1e-12


def test_missing_ompl_names_the_extra(monkeypatch):
    import sys

    from gfcs import generators
    from gfcs.baselines import plan_ompl

    problem = generators.generate("box", 1, seed=0)[0]
    monkeypatch.setitem(sys.modules, "ompl", None)  # import ompl then raises ImportError
    with pytest.raises(ImportError, match=r"gfcs\[baselines\]"):
        plan_ompl(problem, "rrtconnect", planner_time=0.1)


def test_two_stage_segment_check_gives_the_verdict_of_all_states():
    scene = gfcs.Scene()
    scene.add_box([0.3, 0.3, 0.3], ([0.45, 0.0, 0.4], [0.0, 0.0, 0.0, 1.0]))
    v = _panda_validity(scene, margin=0.002, step=0.03)
    rng = np.random.default_rng(3)
    verdicts = []
    for _ in range(60):
        a, b = (v.lower + rng.random((2, 7)) * (v.upper - v.lower)) * 0.5
        full = bool(np.all(v.valid(segment_states(a, b, v.step))))
        assert v.segment_valid(a, b) == full
        verdicts.append(full)
    assert 0 < sum(verdicts) < len(verdicts)
