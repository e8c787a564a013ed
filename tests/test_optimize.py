"""gfcs.optimize: Algorithm 1 on synthetic costs (pure numpy), then end-to-end solves with the bindings."""

import math
import types

import numpy as np
import pytest

from gfcs import optimize as opt


def sphere_cost(center):
    def f(y):
        return np.sum((np.asarray(y) - center) ** 2, axis=1)

    return f


# ------------------------------------------------------------------------------ synthetic problems
def test_finds_known_minimum_of_shifted_sphere():
    center = np.array([0.3, -1.2, 2.0, 0.7, -0.4])
    res = opt.solve_gfcop(sphere_cost(center), 5, -3.0, 3.0, batches=80, population=16, seed=3)
    np.testing.assert_allclose(res.best_x, center, atol=1e-3)
    assert res.best_cost < 1e-5
    assert res.n_evaluations == 80 * 16


def test_finds_global_minimum_of_multimodal_cost():
    # Rastrigin in 2-D, shifted: global minimum 0 at `center`, many local minima on the unit grid
    center = np.array([1.3, -0.6])

    def rastrigin(y):
        z = np.asarray(y) - center
        return 20 + np.sum(z**2 - 10 * np.cos(2 * np.pi * z), axis=1)

    res = opt.solve_gfcop(rastrigin, 2, -5.0, 5.0, batches=60, population=64, sigma0=0.3, seed=0)
    np.testing.assert_allclose(res.best_x, center, atol=1e-2)


def test_top_m_sorted_and_anytime_best_non_increasing():
    res = opt.solve_gfcop(sphere_cost(np.zeros(3)), 3, -1, 1, batches=6, population=8, top_m=5, seed=1)
    assert res.top_x.shape == (5, 3) and res.top_costs.shape == (5,)
    np.testing.assert_array_equal(res.top_costs, np.sort(res.all_costs)[:5])
    np.testing.assert_allclose(sphere_cost(np.zeros(3))(res.top_x), res.top_costs)
    assert np.all(np.diff(res.batch_best_costs) <= 0)
    # the anytime best after batch j is the minimum over batches 0..j
    for j in range(6):
        assert res.batch_best_costs[j] == res.all_costs[res.all_batches <= j].min()
        assert sphere_cost(np.zeros(3))(res.batch_best_x[j : j + 1])[0] == res.batch_best_costs[j]
    assert res.batch_times.shape == (6,) and np.all(res.batch_times > 0)
    assert res.best_cost == res.top_costs[0]


def test_reproducible_with_seed_and_isolated_from_global_rng():
    f = sphere_cost(np.full(4, 0.5))
    np.random.seed(123)
    state = np.random.get_state()[1].copy()
    a = opt.solve_gfcop(f, 4, 0, 1, batches=4, population=6, seed=7)
    # the global generator was neither reseeded nor advanced
    assert np.array_equal(np.random.get_state()[1], state) and np.random.get_state()[2] == 624

    def noisy_user_cost(y):  # a cost that uses (and reseeds) the global generator must not matter
        np.random.seed(np.random.randint(1000))
        return f(y)

    b = opt.solve_gfcop(noisy_user_cost, 4, 0, 1, batches=4, population=6, seed=7)
    np.testing.assert_array_equal(a.all_x, b.all_x)
    c = opt.solve_gfcop(f, 4, 0, 1, batches=4, population=6, seed=8)
    assert not np.array_equal(a.all_x, c.all_x)


def test_first_batch_is_the_warm_start_and_stays_in_bounds():
    lo, up = np.array([-1.0, 0.0, 2.0]), np.array([1.0, 0.5, 4.0])
    warm = np.array([[0.2, 0.1, 3.0], [-1.0, 0.5, 2.0], [1.0, 0.0, 4.0]])  # includes corners
    res = opt.solve_gfcop(sphere_cost(np.array([0.5, 0.25, 3.0])), 3, lo, up, sampler=warm,
                          batches=5, population=6, seed=2)
    first = res.all_x[res.all_batches == 0]
    np.testing.assert_array_equal(first[:3], warm)  # exactly the sampler's candidates
    assert first.shape == (6, 3)  # topped up to the population
    assert np.all(res.all_x >= lo) and np.all(res.all_x <= up)

    calls = []

    def sampler(n, rng):
        calls.append(n)
        return rng.uniform(lo, up, size=(n, 3))

    res2 = opt.solve_gfcop(sphere_cost(np.zeros(3)), 3, lo, up, sampler=sampler, batches=2, population=5)
    assert calls == [5] and res2.all_x.shape == (10, 3)


def test_callback_sees_every_batch_and_can_stop():
    seen = []

    def cb(info):
        seen.append((info.index, info.best_cost, info.candidates.shape, info.elapsed))
        return info.index == 2

    res = opt.solve_gfcop(sphere_cost(np.zeros(2)), 2, -1, 1, batches=10, population=4, callback=cb)
    assert [s[0] for s in seen] == [0, 1, 2]
    assert res.batch_best_costs.shape == (3,) and res.n_evaluations == 12
    assert all(s[2] == (4, 2) for s in seen)
    assert seen[-1][3] == pytest.approx(res.batch_times.sum())


def test_nan_costs_rank_last():
    def f(y):
        c = np.sum(np.asarray(y) ** 2, axis=1)
        c[::2] = np.nan
        return c

    res = opt.solve_gfcop(f, 2, -1, 1, batches=3, population=6, seed=0)
    assert np.isfinite(res.best_cost)
    assert np.isinf(res.all_costs[::2]).all()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(dim=0), "dim"),
        (dict(batches=0), "batches"),
        (dict(population=1), "population"),
        (dict(top_m=0), "top_m"),
        (dict(sigma0=-1.0), "sigma0"),
        (dict(seed=-1), "seed"),
        (dict(lower=[0, 0], upper=[1, 1, 1]), "lower/upper"),
        (dict(lower=[0, 1], upper=[1, 1]), "coordinate 1"),
        (dict(sampler=np.zeros((3, 5))), "sampler"),
    ],
)
def test_bad_arguments(kwargs, match):
    args = dict(cost_fn=sphere_cost(np.zeros(2)), dim=2, lower=[-1, -1], upper=[1, 1], batches=1, population=4)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        opt.solve_gfcop(**args)


def test_bad_cost_shape():
    with pytest.raises(ValueError, match="cost_fn"):
        opt.solve_gfcop(lambda y: np.zeros(2), 2, -1, 1, batches=1, population=4)


def test_uniform_sampler_within_limits():
    robot = types.SimpleNamespace(lower=np.array([-1.0, 0.0]), upper=np.array([1.0, 3.0]))
    problem = types.SimpleNamespace(robot=robot)
    y = opt.UniformSampler(n_commands=3).sample(problem, 500, np.random.default_rng(0))
    assert y.shape == (500, 6)
    lo, up = np.tile(robot.lower, 3), np.tile(robot.upper, 3)
    assert np.all(y >= lo) and np.all(y <= up)
    np.testing.assert_allclose(y.mean(axis=0), (lo + up) / 2, atol=0.15)
