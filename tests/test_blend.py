import numpy as np

from gfcs.blend import append_goal_blend, quintic_to_rest


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
