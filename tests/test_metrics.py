"""gfcs.metrics against closed forms (pure numpy; no compiled extension needed)."""

import math

import numpy as np
import pytest

import gfcs
from gfcs import metrics as m


def min_jerk(tau):
    """Minimum-jerk profile s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ on τ ∈ [0, 1]."""
    return 10 * tau**3 - 15 * tau**4 + 6 * tau**5


# --------------------------------------------------------------------------------------------- lengths
def test_straight_line_length_with_uneven_samples():
    rng = np.random.default_rng(1)
    a, b = np.array([0.1, -0.4, 0.3]), np.array([0.9, 0.5, -0.2])
    s = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0, 1, 200)]))
    pts = a + s[:, None] * (b - a)
    assert m.path_length(pts) == pytest.approx(np.linalg.norm(b - a), rel=1e-12)


def test_back_and_forth_length_counts_both_ways():
    x = np.array([0.0, 1.0, 0.5, 2.0])
    assert m.path_length(x) == pytest.approx(1.0 + 0.5 + 1.5)


def test_circle_arc_length_polygon_and_limit():
    r, theta = 0.7, 2.1
    for n in (3, 17, 1000):
        ang = np.linspace(0.0, theta, n + 1)
        pts = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros_like(ang)])
        chords = 2 * n * r * math.sin(theta / (2 * n))  # exact polygon length
        assert m.path_length(pts) == pytest.approx(chords, rel=1e-12)
    # converges to the arc length r·θ with error r θ³ / (24 n²)
    n = 1000
    assert abs(m.path_length(pts) - r * theta) < 1.1 * r * theta**3 / (24 * n * n)


def test_degenerate_lengths():
    assert m.path_length(np.zeros((1, 3))) == 0.0
    assert m.path_length(np.zeros((0, 3))) == 0.0
    with pytest.raises(ValueError, match="x"):
        m.path_length(np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="NaN"):
        m.path_length([[0.0], [math.nan]])


# ------------------------------------------------------------------------------------------------ LDJ
def test_min_jerk_ldj_matches_closed_form():
    # DJ = T³/v_peak² ∫ x⃛² dt with v_peak = 1.875 A/T and ∫ x⃛² = 720 A²/T⁵  ->  DJ = 720/1.875² = 204.8
    T, n = 1.5, 2001
    t = np.linspace(0.0, T, n)
    x = 0.8 * min_jerk(t / T)
    expected = -math.log(720.0 / 1.875**2)
    assert m.log_dimensionless_jerk(x, t[1] - t[0]) == pytest.approx(expected, abs=1e-4)
    # second-order estimator: halving dt divides the error by about 4
    e1 = abs(m.log_dimensionless_jerk(x[::2], 2 * (t[1] - t[0])) - expected)
    e2 = abs(m.log_dimensionless_jerk(x, t[1] - t[0]) - expected)
    assert 3.0 < e1 / e2 < 5.0


def test_cosine_profile_ldj_matches_closed_form():
    # x = A(1 − cos(πt/T))/2: v_peak = Aπ/(2T), ∫ x⃛² = A²π⁶/(8T⁵)  ->  DJ = π⁴/2
    T, n = 2.0, 1001
    t = np.linspace(0.0, T, n)
    x = 0.3 * (1 - np.cos(np.pi * t / T)) / 2
    assert m.dimensionless_jerk(x, t[1] - t[0]) == pytest.approx(np.pi**4 / 2, rel=1e-5)


def test_ldj_is_dimensionless_and_direction_free():
    n = 800
    tau = np.linspace(0, 1, n)
    base = m.log_dimensionless_jerk(min_jerk(tau), 1.0 / (n - 1))
    direction = np.array([0.3, -0.5, 0.81])
    direction /= np.linalg.norm(direction)
    pts = 2.5 * min_jerk(tau)[:, None] * direction + np.array([1.0, 2.0, 3.0])
    # amplitude x2.5, offset, a 3-D direction and duration x7 (same samples, dt x7): identical value
    assert m.log_dimensionless_jerk(pts, 7.0 / (n - 1)) == pytest.approx(base, rel=1e-10)


def test_two_submovements_are_less_smooth_than_one():
    n = 2001
    tau = np.linspace(0, 1, n)
    one = min_jerk(tau)
    two = np.where(tau < 0.5, 0.5 * min_jerk(2 * tau), 0.5 + 0.5 * min_jerk(np.clip(2 * tau - 1, 0, 1)))
    dt = 1.0 / (n - 1)
    assert m.log_dimensionless_jerk(two, dt) < m.log_dimensionless_jerk(one, dt) - 0.5


def test_ldj_degenerate_cases():
    assert math.isnan(m.log_dimensionless_jerk(np.zeros((10, 3)), 0.01))  # no motion
    assert math.isnan(m.log_dimensionless_jerk(np.arange(3.0), 0.01))  # too short
    assert m.log_dimensionless_jerk(np.arange(10.0), 0.01) == math.inf  # zero jerk
    with pytest.raises(ValueError, match="dt"):
        m.log_dimensionless_jerk(np.arange(10.0), 0.0)


def test_uniform_resample():
    t = np.array([0.0, 0.1, 0.35, 0.5, 1.0])
    x = np.column_stack([2 * t + 1, -t])
    xu, dt = m.uniform_resample(t, x)
    assert dt == pytest.approx(0.25)
    grid = np.arange(5) * 0.25
    np.testing.assert_allclose(xu, np.column_stack([2 * grid + 1, -grid]), atol=1e-15)
    # already uniform: returned unchanged
    xu2, dt2 = m.uniform_resample(grid, x)
    assert xu2 is not None and dt2 == pytest.approx(0.25)
    np.testing.assert_array_equal(xu2, x)
    with pytest.raises(ValueError, match="increasing"):
        m.uniform_resample([0.0, 0.0, 1.0], np.zeros((3, 1)))


# --------------------------------------------------------------------- clearance and success (fakes)
class FakeRobot:
    """Two spheres on a prismatic 'robot': sphere i sits at (q0, 0, q1 + 0.5·i), radius 0.1."""

    lower = np.array([-1.0, 0.0])
    upper = np.array([1.0, 2.0])
    velocity_limits = np.array([5.0, np.inf])
    sphere_radii = np.array([0.1, 0.1])
    self_collision_pairs = np.array([[0, 1]])

    def sphere_centers(self, q):
        q = np.atleast_2d(q)
        c = np.zeros((q.shape[0], 2, 3))
        c[:, :, 0] = q[:, :1]
        c[:, 0, 2] = q[:, 1]
        c[:, 1, 2] = q[:, 1] + 0.5
        return c

    def self_clearance(self, q):
        c = self.sphere_centers(q)
        return np.linalg.norm(c[:, 0] - c[:, 1], axis=1) - 0.2

    def ee_position(self, q):
        return self.sphere_centers(q)[:, 1]


class FakeFloor:
    """Half-space z ≥ 0."""

    def __len__(self):
        return 1

    def signed_distance(self, p):
        return np.asarray(p)[:, 2]


def test_clearances_and_success_flags():
    robot, floor = FakeRobot(), FakeFloor()
    t = np.linspace(0.0, 1.0, 101)
    q = np.column_stack([t, 1.0 - 0.8 * t])  # lowest sphere ends at z = 0.2
    clear = m.obstacle_clearance(robot, floor, q)
    np.testing.assert_allclose(clear, 1.0 - 0.8 * t - 0.1)
    np.testing.assert_allclose(m.self_clearance(robot, q), np.full(101, 0.3))
    out = m.trajectory_metrics(robot, floor, t, q, goal=q[-1])
    assert out["success"] and out["within_limits"]
    assert out["min_clearance"] == pytest.approx(0.1)
    assert out["ee_length"] == pytest.approx(math.hypot(1.0, 0.8))
    assert out["cspace_length"] == pytest.approx(math.hypot(1.0, 0.8))
    assert out["duration"] == pytest.approx(1.0)
    # penetrating the floor, missing the goal, leaving the limits: each alone fails
    q_low = np.column_stack([t, 1.0 - 1.0 * t])
    assert not m.trajectory_metrics(robot, floor, t, q_low, goal=q_low[-1])["success"]
    assert not m.trajectory_metrics(robot, floor, t, q, goal=q[-1] + 0.1)["success"]
    q_out = q.copy()
    q_out[50, 0] = 1.5
    res = m.trajectory_metrics(robot, floor, t, q_out, goal=q_out[-1])
    assert not res["within_limits"] and not res["success"]


def test_empty_scene_has_infinite_clearance():
    class Empty:
        def __len__(self):
            return 0

    c = m.obstacle_clearance(FakeRobot(), Empty(), np.zeros((4, 2)))
    assert c.shape == (4,) and np.all(np.isinf(c))


def test_within_limits_shapes():
    assert m.within_limits([[0.0, 1.0]], [-1, 0], [1, 2])
    assert not m.within_limits([[0.0, 2.1]], [-1, 0], [1, 2])
    with pytest.raises(ValueError, match="lower/upper"):
        m.within_limits([[0.0, 1.0]], [-1], [1])


def test_velocity_ratio_is_the_fastest_finite_difference_over_the_limit_and_fails_success():
    from gfcs.metrics import velocity_ratio

    t = np.linspace(0.0, 1.0, 11)
    q = np.stack([np.linspace(0.0, 0.6, 11), np.linspace(0.5, 1.5, 11)], axis=1)  # 0.6 and 1.0 units/s
    assert velocity_ratio(t, q, [1.2, np.inf]) == pytest.approx(0.5)
    assert velocity_ratio(t, q, [0.3, 0.5]) == pytest.approx(2.0)
    fast = FakeRobot()
    fast.velocity_limits = np.array([0.3, np.inf])
    slow = m.trajectory_metrics(FakeRobot(), FakeFloor(), t, q, q[-1])
    quick = m.trajectory_metrics(fast, FakeFloor(), t, q, q[-1])
    assert slow["success"] and slow["velocity_ratio"] == pytest.approx(0.12)
    assert not quick["success"] and quick["velocity_ratio"] == pytest.approx(2.0)


def test_continuous_joints_wrap_the_goal_error_and_have_no_position_limits():
    import math

    robot = FakeRobot()
    robot.lower = np.array([-1.0, -math.tau])  # the core's range of a continuous joint
    robot.upper = np.array([1.0, math.tau])
    t = np.linspace(0.0, 10.0, 11)
    q = np.stack([np.zeros(11), np.linspace(0.5, 7.0, 11)], axis=1)  # past 2π: allowed
    met = m.trajectory_metrics(robot, FakeFloor(), t, q, [0.0, 7.0 - math.tau])
    assert met["final_error"] == pytest.approx(0.0, abs=1e-12) and met["within_limits"] and met["success"]


def test_checked_states_visit_a_slow_path_at_the_check_resolution_and_keep_a_fast_one():
    slow = np.stack([np.linspace(0.0, 0.1, 101), np.zeros(101)], axis=1)  # 1 mrad steps
    fast = np.stack([np.linspace(0.0, 1.0, 51), np.zeros(51)], axis=1)  # 20 mrad steps
    kept = m.checked_states(slow, step=0.0045)
    assert kept.shape == (21, 2) and np.all(np.diff(kept[:, 0]) <= 0.005 + 1e-12)
    np.testing.assert_array_equal(kept[[0, -1]], slow[[0, -1]])
    np.testing.assert_array_equal(m.checked_states(fast, step=0.005), fast)


def _visited_by_definition(q, step):
    """The rows :func:`checked_indices` visits, by its definition: the first, every next row at least
    ``step`` (max over joints) from the last one visited, and the last."""
    keep = [0]
    for k in range(1, len(q) - 1):
        if np.max(np.abs(q[k] - q[keep[-1]])) >= step:
            keep.append(k)
    return keep + ([len(q) - 1] if len(q) > 1 else [])


def test_checked_indices_follow_their_definition_on_generated_paths():
    """Slow, fast, mixed and standing paths of 1-8 joints (steps from 10⁻⁴ to 3·10⁻² rad, some rows
    standing still): the rows skipped by the summed-steps bound are exactly those the definition skips."""
    rng = np.random.default_rng(7)
    for trial in range(600):
        n = int(rng.integers(1, 40)) if trial % 3 else int(rng.integers(100, 800))
        steps = rng.normal(size=(n, int(rng.integers(1, 9)))) * 10 ** rng.uniform(-4.0, -1.5)
        steps *= rng.uniform(size=(n, 1)) < rng.uniform(0.2, 1.0)  # standing rows
        q = np.cumsum(steps, axis=0)
        step = (0.001, 0.005, 0.01)[trial % 3]
        assert m.checked_indices(q, step).tolist() == _visited_by_definition(q, step), trial


class _CountingChecker:
    """Mesh checker double: obstacle clearance 0.2 m everywhere except at the configurations whose first
    joint is in ``contact`` (clearance 0 there), counting the states it is asked about."""

    def __init__(self, contact=()):
        self.states = self.calls = 0
        self.contact = {round(float(c), 9) for c in contact}

    def min_clearance(self, scene, q, threads=None, cutoff=None):
        self.states += len(q)
        self.calls += 1
        return 0.0 if any(round(float(r[0]), 9) in self.contact for r in q) else 0.2

    def min_self_clearance(self, q, threads=None, cutoff=None):
        return 0.2


def test_a_contact_first_mesh_check_rejects_after_the_first_call_with_the_same_verdicts():
    """With ``likely_contact`` the states are checked lowest value first: a path touching where that value
    is lowest fails after one call of MESH_CHECK_CHUNK states instead of after every state before the
    contact; a clear path is checked on all of its states in calls of 8, 16, 32, ...; verdicts do not
    depend on the order."""
    q = np.stack([np.linspace(0.0, 6.0, 601), np.zeros(601)], axis=1)  # 10 mrad steps: every state checked
    likely = np.abs(np.arange(601) - 500.0)  # the spheres come nearest at sample 500
    plain, first = _CountingChecker(contact=[q[500, 0]]), _CountingChecker(contact=[q[500, 0]])
    assert not m.mesh_check(plain, None, q)[2] and plain.states == 601
    clear, _, ok, complete = m.mesh_check(first, None, q, likely_contact=likely)
    assert (clear, ok, complete) == (0.0, False, True) and first.states == m.MESH_CHECK_CHUNK
    free = _CountingChecker()
    assert m.mesh_check(free, None, q, likely_contact=likely)[2:] == (True, True)
    assert free.states == 601 and free.calls == 7  # 8, 16, 32, 64, 128, 256, then the 97 left
    with pytest.raises(gfcs.ShapeError, match="likely_contact"):
        m.mesh_check(_CountingChecker(), None, q, likely_contact=likely[:-1])


def test_a_mesh_check_past_its_deadline_stops_with_a_negative_verdict():
    q = np.stack([np.linspace(0.0, 6.0, 601), np.zeros(601)], axis=1)  # 10 mrad steps: every state checked
    full = _CountingChecker()
    assert m.mesh_verdict(full, None, q)[2] and full.states == 601
    late = _CountingChecker()
    clear, _, ok = m.mesh_verdict(late, None, q, deadline=0.0)  # already past
    assert not ok and late.states == m.MESH_CHECK_CHUNK and clear == 0.2
    assert m.mesh_check(_CountingChecker(), None, q, deadline=0.0)[3] is False
    assert m.mesh_check(_CountingChecker(), None, q)[3] is True


def test_a_mesh_check_with_time_left_doubles_its_calls():
    import time

    q = np.stack([np.linspace(0.0, 6.0, 601), np.zeros(601)], axis=1)
    checker = _CountingChecker()
    assert m.mesh_verdict(checker, None, q, deadline=time.perf_counter() + 60.0)[2]
    # 8, 16, 32, 64, 128, 256 states, then the 97 left: 7 calls, not 76 of 8
    assert checker.states == 601 and checker.calls == 7


def test_ldj_closed_forms_of_single_movements():
    """Minimum jerk is not the largest LDJ of one movement: DJ divides by the peak speed too. Closed forms:
    minimum jerk DJ = 720/1.875², a sin² speed profile 2π⁴, a half-sine speed profile π⁴/2."""
    T, n = 1.0, 20001
    t = np.linspace(0.0, T, n)
    dt = t[1] - t[0]
    s = t / T
    minimum_jerk = 10 * s**3 - 15 * s**4 + 6 * s**5
    sin2 = s - np.sin(2 * np.pi * s) / (2 * np.pi)  # speed ∝ sin²(πs)
    half_sine = (1 - np.cos(np.pi * s)) / 2  # speed ∝ sin(πs): nonzero acceleration at both ends
    assert m.log_dimensionless_jerk(minimum_jerk, dt) == pytest.approx(-math.log(720 / 1.875**2), abs=2e-3)
    assert m.log_dimensionless_jerk(sin2, dt) == pytest.approx(-math.log(2 * np.pi**4), abs=2e-3)
    assert m.log_dimensionless_jerk(half_sine, dt) == pytest.approx(-math.log(np.pi**4 / 2), abs=2e-3)
    assert m.log_dimensionless_jerk(half_sine, dt) > m.log_dimensionless_jerk(minimum_jerk, dt)


def test_raw_rollout_ldj_is_reported_beside_the_returned_trajectorys():
    """Without finishing (the paper preset) the returned motion is the fabric's own, so both LDJs agree; the
    default preset's finishing changes the returned one only."""
    import gfcs
    from gfcs import generators
    from gfcs.planning import solve

    problem = generators.generate("box", 1, seed=0, robot=gfcs.Robot.panda())[0]
    paper = solve(problem, method="gf", preset="paper")
    assert paper.metrics["raw_cspace_ldj"] == pytest.approx(paper.metrics["cspace_ldj"], abs=1e-12)
    assert paper.metrics["raw_ee_ldj"] == pytest.approx(paper.metrics["ee_ldj"], abs=1e-12)
    default = solve(problem, method="gf")
    assert math.isfinite(default.metrics["raw_cspace_ldj"])
    assert default.metrics["raw_cspace_ldj"] != pytest.approx(default.metrics["cspace_ldj"], abs=1e-6)
