import numpy as np
import pytest

from gfcs.profile import acceleration_limits
from gfcs.blend import append_goal_blend, limit_dynamics, quintic_to_rest
from gfcs.metrics import velocity_ratio

#: Franka Control Interface documentation, "Limits for Panda", joints 1-7 [rad/s²].
PANDA_ACCELERATION_LIMITS = (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)


def test_quintic_meets_its_boundary_conditions():
    rng = np.random.default_rng(0)
    q0, v0, a0, q1 = (rng.normal(size=7) for _ in range(4))
    T = 0.4
    s = np.linspace(0.0, T, 4001)
    pos, vel = quintic_to_rest(q0, v0, a0, q1, T, s)
    assert np.allclose(pos[0], q0) and np.allclose(vel[0], v0)
    assert np.allclose(pos[-1], q1, atol=1e-12) and np.allclose(vel[-1], 0.0, atol=1e-12)
    h = s[1] - s[0]
    e = 1e-7
    _, v_start = quintic_to_rest(q0, v0, a0, q1, T, np.array([0.0, e]))
    _, v_end = quintic_to_rest(q0, v0, a0, q1, T, np.array([T - e, T]))
    assert np.allclose((v_start[1] - v_start[0]) / e, a0, atol=1e-3)
    assert np.allclose((v_end[1] - v_end[0]) / e, 0.0, atol=1e-3)
    assert np.allclose(np.gradient(pos, h, axis=0)[1:-1], vel[1:-1], atol=1e-4)


def test_blend_ends_exactly_at_the_goal_at_rest_and_moves_little():
    dt = 0.01
    t = np.arange(5) * dt
    q = np.zeros((5, 7)); qd = np.zeros((5, 7)); qd[-1] = 0.2 / np.sqrt(7)
    goal = np.full(7, 0.009 / np.sqrt(7))
    t2, q2, qd2 = append_goal_blend(t, q, qd, np.zeros(7), goal, dt)
    assert np.array_equal(q2[-1], goal) and np.array_equal(qd2[-1], np.zeros(7))
    assert np.allclose(np.diff(t2), dt)
    step = np.linalg.norm(np.diff(q2[4:], axis=0), axis=1)
    assert step.sum() < 0.05


def _abrupt_start(dt=0.01, n=120):
    """A start from rest with the fabric's defects: the acceleration jumps to 15 rad/s² at t = 0 and drops to
    0 in one step at 1.5 rad/s, along a planar arc of radius 2 (so the path bends), then cruises."""
    t = dt * np.arange(n)
    qd = np.zeros((n, 3)); q = np.zeros((n, 3)); qdd = np.zeros((n, 3))
    s = v = 0.0
    for k in range(n):
        a = 15.0 if v < 1.5 else 0.0
        th = s / 2.0
        u = np.array([np.cos(th), np.sin(th), 0.0])
        q[k] = 2.0 * np.array([np.sin(th), 1.0 - np.cos(th), 0.0])
        qd[k] = v * u
        qdd[k] = a * u + v * v / 2.0 * np.array([-np.sin(th), np.cos(th), 0.0])
        v = min(v + a * dt, 1.5)
        s += v * dt
    return t, q, qd, qdd


def test_retime_start_keeps_the_path_and_joins_the_rollout():
    from gfcs.blend import START_WINDOW, retime_start
    dt = 0.01
    t, q, qd, qdd = _abrupt_start(dt)
    t2, q2, qd2 = retime_start(t, q, qd, qdd, dt)
    J = int(round(START_WINDOW / dt))
    n_new = len(t2) - (len(t) - J - 1)
    assert np.allclose(np.diff(t2), dt) and t2[0] == 0.0
    # the same path: every re-timed state lies on the arc (radius 2 about (0, 2, 0))
    r = np.linalg.norm(q2[:n_new] - np.array([0.0, 2.0, 0.0]), axis=1)
    assert np.abs(r - 2.0).max() < 1e-6 and np.all(np.diff(np.arctan2(q2[:n_new, 0], 2.0 - q2[:n_new, 1])) >= 0)
    # starts at rest, joins the rollout exactly, then the rollout's own samples follow
    assert np.array_equal(q2[0], q[0]) and np.array_equal(qd2[0], np.zeros(3))
    assert np.array_equal(q2[n_new - 1], q[J]) and np.array_equal(qd2[n_new - 1], qd[J])
    assert np.array_equal(q2[n_new:], q[J + 1:]) and np.array_equal(qd2[n_new:], qd[J + 1:])
    # velocities are the derivative of the positions, the start leaves rest gently, and the jerk falls
    assert np.allclose(np.gradient(q2, dt, axis=0)[1:n_new - 1], qd2[1:n_new - 1], atol=5e-3)
    assert np.linalg.norm(q2[1] - q2[0]) < 0.1 * np.linalg.norm(q[1] - q[0])
    jerk = lambda x: np.sum(np.diff(x, 3, axis=0) ** 2)
    assert jerk(q2) < 0.05 * jerk(q)


def test_retime_start_leaves_other_trajectories_alone():
    from gfcs.blend import retime_start
    dt = 0.01
    t, q, qd, qdd = _abrupt_start(dt)
    moving = qd.copy(); moving[0] = 0.1
    assert retime_start(t, q, moving, qdd, dt)[1] is q  # does not start at rest
    q_short = q[:20]
    assert retime_start(t[:20], q_short, qd[:20], qdd[:20], dt)[1] is q_short  # shorter than the window
    still = np.zeros_like(q)
    out = retime_start(t, still, np.zeros_like(qd), np.zeros_like(qdd), dt)  # no motion
    assert out[0] is t and out[1] is still


def _fd_acceleration(t, q):
    """Plain three-point second difference (no smoothing), interior samples: what a validator computes."""
    h0, h1 = (t[1:-1] - t[:-2])[:, None], (t[2:] - t[1:-1])[:, None]
    return 2.0 * (h0 * q[2:] - (h0 + h1) * q[1:-1] + h1 * q[:-2]) / (h0 * h1 * (h0 + h1))


def test_second_difference_is_exact_for_quadratics_on_any_grid():
    from gfcs.blend import second_difference

    t = np.cumsum(np.r_[0.0, np.random.default_rng(0).uniform(0.005, 0.015, 40)])
    q = np.stack([3.0 * t**2 - t, -0.5 * t**2 + 2.0], axis=1)
    np.testing.assert_allclose(second_difference(t, q), np.tile([6.0, -1.0], (t.size, 1)), atol=1e-9)
    np.testing.assert_allclose(second_difference(t, q)[1:-1], _fd_acceleration(t, q), atol=1e-9)


def test_limit_dynamics_slows_a_fast_circle_down_along_the_same_path():
    """A unit circle in a 2-joint space at ω = 4 rad/s: centripetal 16 rad/s² against limits of 4 and 8.
    Entered from rest and left to rest over 0.5 s ramps, so both ends are at rest."""
    dt = 0.01
    t = np.arange(0.0, 3.0 + dt / 2, dt)
    phase = 4.0 * np.where(t < 0.5, t**2, np.where(t > 2.5, 2.25 + (t - 2.5) - (t - 2.5)**2, t - 0.25))
    q = np.stack([np.cos(phase), np.sin(phase)], axis=1)
    qd = np.gradient(q, t, axis=0)
    limits = np.array([4.0, 8.0])
    assert np.max(np.abs(_fd_acceleration(t, q)) / limits) > 3.5
    t2, q2, qd2 = limit_dynamics(t, q, qd, dt, acceleration=limits)
    assert np.max(np.abs(_fd_acceleration(t2, q2)) / limits) <= 1.0
    assert t2[0] == t[0] and t2[-1] > 4.0  # the 2 s at full speed take at least sqrt(16 / 4) = 2 times longer
    assert np.allclose(np.diff(t2), dt, rtol=0.01)
    np.testing.assert_array_equal(q2[[0, -1]], q[[0, -1]])
    np.testing.assert_allclose(np.linalg.norm(q2, axis=1), 1.0, atol=2e-4)  # still on the circle
    angle = np.unwrap(np.arctan2(q2[:, 1], q2[:, 0]))
    assert np.all(np.diff(angle) >= -1e-9) and angle[-1] == pytest.approx(phase[-1], abs=1e-9)  # same order
    np.testing.assert_allclose(qd2[1:-1], np.gradient(q2, t2, axis=0)[1:-1], atol=0.02)


def test_limit_dynamics_leaves_a_slow_trajectory_alone_and_checks_its_limits():
    t = np.linspace(0.0, 1.0, 101)
    q = np.stack([0.1 * t**2, -0.2 * t], axis=1)
    qd = np.gradient(q, t, axis=0)
    out = limit_dynamics(t, q, qd, 0.01, acceleration=[1.0, 1.0])
    assert out[0] is t and out[1] is q and out[2] is qd
    for bad in ([1.0], [1.0, 0.0], [1.0, np.nan]):
        with pytest.raises(ValueError, match="acceleration limits"):
            limit_dynamics(t, q, qd, 0.01, acceleration=bad)


def test_panda_limits_are_known_for_panda_joints_only():
    import gfcs

    np.testing.assert_array_equal(acceleration_limits(gfcs.Robot.panda()), PANDA_ACCELERATION_LIMITS)
    assert acceleration_limits(gfcs.Robot.panda()).shape == (7,)
    other = gfcs.Robot.from_urdf("""<robot name="r"><link name="a"/><link name="b"/>
      <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
      <limit lower="-1" upper="1" velocity="1" effort="1"/></joint></robot>""")
    assert acceleration_limits(other) is None


def test_solve_returns_trajectories_within_the_panda_limits():
    """Generated table-under problem 0 (shipped Panda) turns at 1.38 times the limits when not re-timed
    with this warm start (approach and uniform candidates)."""
    import gfcs
    from gfcs import generators, optimize

    p = generators.generate("table_under_pick", 1, seed=0, robot=gfcs.Robot.panda())[0]
    limits = acceleration_limits(gfcs.Robot.panda())
    sampler = optimize.ApproachSampler(retract=0.0)
    raw = optimize.solve(p, batches=1, population=8, seed=0, sampler=sampler,
                         finish=optimize.FinishOptions(limit_acceleration=False))
    r = optimize.solve(p, batches=1, population=8, seed=0, sampler=sampler)
    assert r.success and raw.success and np.array_equal(r.commands, raw.commands)
    assert np.max(np.abs(_fd_acceleration(raw.trajectory.t, raw.trajectory.q)) / limits) > 1.2
    assert np.max(np.abs(_fd_acceleration(r.trajectory.t, r.trajectory.q)) / limits) <= 1.0
    assert raw.trajectory.t[-1] < r.trajectory.t[-1] < 1.1 * raw.trajectory.t[-1]
    np.testing.assert_array_equal(r.trajectory.q[[0, -1]], raw.trajectory.q[[0, -1]])
    assert r.metrics["ee_length"] == pytest.approx(raw.metrics["ee_length"], rel=2e-3)


def test_a_blend_toward_a_goal_at_a_limit_is_shortened_until_it_keeps_the_limit():
    dt, upper = 0.01, np.full(7, 1.0)
    goal = np.full(7, 0.5)
    goal[1] = 1.0  # joint 2 at its upper limit
    t = np.array([0.0])
    q = goal[None] - 0.02
    qd = np.zeros((1, 7))
    qd[0, 1] = 0.9  # still moving toward the limit, as a fabric reaching its tolerance does
    _, free, _ = append_goal_blend(t, q, qd, np.zeros(7), goal, dt)
    assert free[:, 1].max() > upper[1] + 1e-3  # the quintic passes the limit and comes back
    t2, kept, qd2 = append_goal_blend(t, q, qd, np.zeros(7), goal, dt, lower=-upper, upper=upper)
    assert kept[:, 1].max() <= upper[1]
    assert len(t2) < len(free)  # a shorter blend
    np.testing.assert_array_equal(kept[-1], goal)
    np.testing.assert_array_equal(qd2[-1], 0.0)
    # limits the quintic keeps anyway change nothing
    _, wide, _ = append_goal_blend(t, q, qd, np.zeros(7), goal, dt, lower=-upper - 1, upper=upper + 1)
    np.testing.assert_array_equal(wide, free)


def _fast_line(speed: float = 2.0, dt: float = 0.01):
    """Two joints moving at ``speed`` and -speed/2 rad/s with smooth 0.3 s ramps from and to rest."""
    t = np.arange(0.0, 2.0 + dt / 2, dt)
    ramp = np.clip(t / 0.3, 0, 1) * np.clip((2.0 - t) / 0.3, 0, 1)
    s = np.concatenate([[0.0], np.cumsum(0.5 * (ramp[1:] + ramp[:-1]) * dt)]) * speed
    q = np.stack([s, -0.5 * s], axis=1)
    return t, q, np.gradient(q, t, axis=0)


def test_limit_dynamics_keeps_velocity_limits_along_the_same_path():
    t, q, qd = _fast_line()
    limits = np.array([0.5, np.inf])  # joint 2 has no limit (a continuous joint without one)
    assert velocity_ratio(t, q, limits) > 3.5
    t2, q2, qd2 = limit_dynamics(t, q, qd, 0.01, velocity=limits)
    assert velocity_ratio(t2, q2, limits) <= 1.0
    assert t2[-1] > 3.5 * t[-1] * 0.9
    np.testing.assert_array_equal(q2[[0, -1]], q[[0, -1]])
    np.testing.assert_allclose(q2[:, 1], -0.5 * q2[:, 0], atol=1e-9)  # still on the line
    assert np.all(np.diff(q2[:, 0]) >= -1e-12)  # same order


def test_limit_dynamics_keeps_a_moving_start_state_and_rejects_an_impossible_one():
    t, q, qd = _fast_line()
    k = 20  # start mid-ramp, moving
    t, q, qd = t[k:] - t[k], q[k:], qd[k:]
    assert np.all(qd[0] != 0)
    limits = np.array([1.5, 1.5])
    t2, q2, qd2 = limit_dynamics(t, q, qd, 0.01, velocity=limits)
    np.testing.assert_array_equal(qd2[0], qd[0])
    np.testing.assert_array_equal(q2[0], q[0])
    assert velocity_ratio(t2[15:], q2[15:], limits) <= 1.0
    with pytest.raises(ValueError, match="start velocity .* exceeds its velocity limit"):
        limit_dynamics(t, q, qd, 0.01, velocity=np.abs(qd[0]) / 2)


@pytest.mark.parametrize("speed", [0.05, 0.5, 1.5])
@pytest.mark.parametrize("seed", range(4))
def test_the_blend_stays_within_the_ball_around_the_goal_through_its_first_state(speed, seed):
    """A rollout that reaches its tolerance at speed, in any direction: the blend moves no state farther from
    the goal than the state it starts from (a quintic of the unshortened duration coasts past it)."""
    rng = np.random.default_rng(seed)
    dt, dof = 0.01, 7
    goal = rng.normal(size=dof)
    gap = rng.normal(size=dof)
    q_end = goal + 0.04 * gap / np.linalg.norm(gap)
    v = rng.normal(size=dof)
    qd = np.vstack([np.zeros(dof), speed * v / np.linalg.norm(v)])
    q = np.vstack([q_end - dt * qd[1], q_end])
    t2, q2, qd2 = append_goal_blend(np.array([0.0, dt]), q, qd, np.zeros(dof), goal, dt)
    assert np.linalg.norm(q2[2:] - goal, axis=1).max() <= 0.04 * (1 + 1e-9)
    np.testing.assert_array_equal(q2[-1], goal)
    np.testing.assert_array_equal(qd2[-1], 0.0)
    if speed >= 0.5:  # the quintic of the first duration leaves the ball: the blend was shortened
        from gfcs.blend import blend_duration

        T = blend_duration(q_end, qd[1], goal, dt)
        free, _ = quintic_to_rest(q_end, qd[1], np.zeros(dof), goal, T, dt * np.arange(1, int(round(T / dt)) + 1))
        assert np.linalg.norm(free - goal, axis=1).max() > 0.05
        assert t2[-1] - t2[1] < T
