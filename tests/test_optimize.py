"""gfcs.optimize: Algorithm 1 on synthetic costs (pure numpy), then end-to-end solves with the bindings."""

import dataclasses
import math
import types

import numpy as np
import pytest

import gfcs
from gfcs import metrics
from gfcs import optimize as opt
from gfcs.planning import get_preset


def sphere_cost(center):
    def f(y):
        return np.sum((np.asarray(y) - center) ** 2, axis=1)

    return f


# ------------------------------------------------------------------------------ synthetic problems
def test_cma_import_skips_its_optional_modules_and_leaves_them_importable():
    import subprocess
    import sys

    code = ("import sys; from gfcs import optimize; cma = optimize._import_cma()\n"
            "print(cma.CMAEvolutionStrategy is not None, 'scipy.stats' in sys.modules, "
            "'matplotlib' in sys.modules, 'matplotlib.pyplot' in sys.modules)\n"
            "import scipy.stats, matplotlib.pyplot\n"
            "print(scipy.stats.kendalltau([1, 2, 3], [1, 3, 2])[0] > 0, matplotlib.pyplot.figure is not None)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "False", "False", "False", "True", "True"]


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


def test_warm_start_sampling_counts_in_the_first_batch_time():
    import time

    def slow_sampler(n, rng):
        time.sleep(0.05)
        return rng.uniform(-1, 1, size=(n, 2))

    res = opt.solve_gfcop(sphere_cost(np.zeros(2)), 2, -1, 1, sampler=slow_sampler, batches=3, population=4)
    assert res.batch_times[0] >= 0.05 and np.all(res.batch_times[1:] < 0.05)


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


def test_stalled_criterion():
    from gfcs.planning.gfcop import stalled

    assert not stalled([3.0, 3.0, 3.0], 0, 0.01)  # off
    assert not stalled([3.0], 1, 0.01)  # no batch followed the first yet
    assert stalled([3.0, 3.0], 1, 0.0)  # no improvement at all
    assert stalled([3.0, 2.98], 1, 0.01) and not stalled([3.0, 2.9], 1, 0.01)  # 0.7 % vs 3.3 %
    assert not stalled([3.0, 2.9, 2.9], 2, 0.01) and stalled([3.0, 2.9, 2.9], 1, 0.01)
    assert stalled([-1.0, -1.005], 1, 0.01)  # relative to the magnitude
    assert not stalled([math.inf, math.inf], 1, 0.01)  # nothing finite yet


def test_early_stop_after_stalled_batches():
    """A cost CMA-ES cannot improve (constant) stops after the first batch + K stalled ones; one that keeps
    improving (the shifted sphere, from a far warm start) runs until the criterion holds and no longer; K = 0
    runs every batch."""
    def flat(y):
        return np.ones(len(y))

    for k in (1, 2):
        res = opt.solve_gfcop(flat, 3, -1, 1, batches=6, population=6, stall_batches=k)
        assert res.batch_best_costs.shape == (1 + k,) and res.n_evaluations == 6 * (1 + k)
    assert opt.solve_gfcop(flat, 3, -1, 1, batches=6, population=6).batch_best_costs.shape == (6,)
    from gfcs.planning.gfcop import stalled

    far = np.full((6, 3), 0.9)
    for k, tol in ((1, 0.01), (2, 0.0), (1, 0.2)):
        res = opt.solve_gfcop(sphere_cost(np.full(3, -0.5)), 3, -1, 1, sampler=far, batches=8, population=6,
                              stall_batches=k, stall_tol=tol)
        best = list(res.batch_best_costs)
        # it stops at the first stalled batch, and only there (or after the last batch)
        assert not any(stalled(best[:j], k, tol) for j in range(1, len(best)))
        assert len(best) == 8 or stalled(best, k, tol)
        assert len(best) > 1 + k  # the far warm start improves at first
    for bad in ({"stall_batches": -1}, {"stall_tol": -0.1}, {"stall_tol": math.nan}):
        with pytest.raises(gfcs.InvalidValueError, match="stall"):
            opt.solve_gfcop(flat, 3, -1, 1, batches=2, population=4, **bad)


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


def test_approach_sampler_mixes_approach_and_uniform_commands():
    import gfcs
    from gfcs.approach import approach_configurations

    robot = gfcs.Robot.panda()
    goal = np.array([0.3, 0.4, -0.2, -1.9, 0.1, 2.2, 0.6])
    problem = types.SimpleNamespace(robot=robot, goal=goal)
    lo, up = np.asarray(robot.lower), np.asarray(robot.upper)
    # one command: the last (only) command of the first quarter at the two approach distances in turn
    one = opt.ApproachSampler(1, fraction=0.25, retract=0.0, distances=(0.05, 0.1), sigma=0.01)
    y = one.sample(problem, 400, np.random.default_rng(0))
    assert y.shape == (400, 7) and np.all(y >= lo) and np.all(y <= up)
    near = approach_configurations(robot, goal, (0.05, 0.1))
    for i in range(2):
        np.testing.assert_allclose(np.median(y[i:100:2], axis=0), near[i], atol=0.01 * (up - lo).max())
    assert np.all(np.abs(y[:100] - near[np.arange(100) % 2]) <= 5 * 0.01 * (up - lo))
    # the others are uniform
    assert np.all(np.abs(y[100:].mean(axis=0) - (lo + up) / 2) < 0.1 * (up - lo))
    assert np.mean(np.linalg.norm(y[100:] - goal, axis=1) < 0.5) < 0.05
    # two commands: the earlier one backs off one spacing (0.2 m) further along the corridor
    two = opt.ApproachSampler(2, fraction=0.25, retract=0.0, distances=(0.05, 0.1), spacings=(0.2,), sigma=0.01)
    y2 = two.sample(problem, 400, np.random.default_rng(0)).reshape(400, 2, 7)
    levels = approach_configurations(robot, goal, (0.05, 0.1, 0.25, 0.3))
    for i in range(2):
        np.testing.assert_allclose(np.median(y2[i:100:2, 1], axis=0), levels[i], atol=0.01 * (up - lo).max())
        np.testing.assert_allclose(np.median(y2[i:100:2, 0], axis=0), levels[i + 2],
                                   atol=0.01 * (up - lo).max())
    # no approach and no retract candidates: the uniform sampler, draw for draw
    u = opt.ApproachSampler(2, fraction=0.0, retract=0.0).sample(problem, 50, np.random.default_rng(3))
    np.testing.assert_array_equal(u, opt.UniformSampler(2).sample(problem, 50, np.random.default_rng(3)))


def test_approach_sampler_retract_candidates_follow_the_approach_ones():
    import types

    import gfcs
    from gfcs.approach import approach_configurations, retract_configurations

    robot = gfcs.Robot.panda()
    q0 = np.array([0.0, 0.6, 0.0, -1.2, 0.0, 1.8, 0.8])
    goal = np.array([0.3, 0.4, -0.2, -1.9, 0.1, 2.2, 0.6])
    problem = types.SimpleNamespace(robot=robot, q0=q0, goal=goal)
    lo, up = np.asarray(robot.lower), np.asarray(robot.upper)
    y = opt.ApproachSampler(1, fraction=0.25, retract=0.5, sigma=0.0).sample(problem, 40, np.random.default_rng(0))
    assert y.shape == (40, 7) and np.all(y >= lo) and np.all(y <= up)
    near = approach_configurations(robot, goal, (0.05, 0.1, 0.15, 0.2))
    np.testing.assert_allclose(y[:10], near[np.arange(10) % 4])
    # the next 20 are retract configurations: each one's hand nearer the base axis than both ends'
    ee = robot.link_index(robot.ee_link)
    radius = [np.linalg.norm(np.asarray(robot.link_poses(q))[ee][:2, 3]) for q in (q0, goal, *y[10:30])]
    assert max(radius[2:]) < min(radius[:2])
    # the last 10 are uniform: nowhere near either end
    assert np.all(np.linalg.norm(y[30:] - goal, axis=1) > 0.5)
    # with two commands the retract configuration comes first, then the approach corridor
    y2 = opt.ApproachSampler(2, fraction=0.0, retract=1.0, distances=(0.1,), spacings=(0.2,), sigma=0.0).sample(
        problem, 6, np.random.default_rng(1)).reshape(6, 2, 7)
    np.testing.assert_allclose(y2[:, 1], np.tile(approach_configurations(robot, goal, (0.1,)), (6, 1)))
    assert not np.allclose(y2[0, 0], y2[1, 0])
    # shares adding up to more than 1: the retract share is capped
    y3 = opt.ApproachSampler(1, fraction=0.75, retract=0.75, sigma=0.0).sample(problem, 8, np.random.default_rng(2))
    np.testing.assert_allclose(y3[:6], near[np.arange(6) % 4])
    assert not np.any(np.all(np.isclose(y3[6:, None, :], near[None]), axis=2))


@pytest.mark.parametrize("kwargs, match", [({"fraction": 1.5}, "fraction"), ({"fraction": -0.1}, "fraction"),
                                           ({"retract": 1.5}, "retract"), ({"retract": math.nan}, "retract"),
                                           ({"sigma": -0.1}, "sigma"), ({"sigma": math.nan}, "sigma"),
                                           ({"distances": ()}, "distances"), ({"distances": (0.1, -0.1)}, "distances"),
                                           ({"spacings": (math.inf,)}, "spacings"), ({"n_commands": 0}, "n_commands")])
def test_approach_sampler_rejects_bad_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        opt.ApproachSampler(**kwargs)


# ---------------------------------------------------------------------- robot level (needs _core)
@pytest.fixture(scope="module")
def shelf_problem():
    import gfcs
    from gfcs import generators

    return generators.generate("bookshelf_small", 1, seed=0, robot=gfcs.Robot.panda())[0]


@pytest.fixture(scope="module")
def solved(shelf_problem):
    # length_slack 0: the lowest-cost candidate (Alg. 1 as in the paper), so that cost and top-m line up
    return opt.solve(shelf_problem, batches=3, population=16, seed=0, length_slack=0)


def test_solve_end_to_end(shelf_problem, solved):
    r, p = solved, shelf_problem
    assert r.success and r.reached and r.method == "gfcs" and r.problem == p.name and r.cls == p.cls
    assert r.commands.shape == (1, 7) and r.t_stars.shape == (2,)
    np.testing.assert_array_equal(r.trajectory.q[0], p.q0)
    # the rollout stops within ε (0.05 rad) and the blend ends the trajectory exactly at the goal, at rest,
    # so success is judged at the tighter metrics tolerance (0.01 rad) on the returned trajectory
    np.testing.assert_array_equal(r.trajectory.q[-1], p.goal)
    np.testing.assert_array_equal(r.trajectory.qd[-1], np.zeros(7))
    assert r.metrics["final_error"] == 0.0 < metrics.DEFAULT_SUCCESS_TOL < r.settings["tol"]
    assert np.all(np.diff(r.trajectory.t) > 0)
    # the recorded rollout of the best candidate costs what the batch evaluation said (deterministic core)
    assert r.cost == pytest.approx(r.batch_best_costs[-1], abs=1e-12)
    assert r.cost == pytest.approx(r.t_stars.sum())
    assert np.all(np.diff(r.batch_best_costs) <= 0) and r.batch_times.shape == (3,)
    costs = [c for _, c in r.top]
    assert len(r.top) == 4 and costs == sorted(costs) and costs[0] == r.cost
    np.testing.assert_array_equal(r.top[0][0], r.commands.ravel())
    assert r.n_evaluations == 48 and r.solve_time == pytest.approx(r.batch_times.sum())
    assert r.wall_time > r.solve_time  # the whole call: the optimisation, then the returned motion's rollout
    lo, up = np.asarray(p.robot.lower), np.asarray(p.robot.upper)
    assert np.all(r.commands >= lo) and np.all(r.commands <= up)
    m = r.metrics
    assert m["success"] and m["ee_length"] > 0 and m["cspace_length"] >= np.linalg.norm(p.goal - p.q0) - 1e-9
    assert m["min_clearance"] >= 0 and np.isfinite(m["ee_ldj"]) and m["ee_ldj"] < 0


def test_solve_is_reproducible(shelf_problem, solved):
    again = opt.solve(shelf_problem, batches=3, population=16, seed=0, threads=1, length_slack=0)
    np.testing.assert_array_equal(again.commands, solved.commands)
    np.testing.assert_array_equal(again.batch_best_costs, solved.batch_best_costs)
    # Another seed draws other candidates (the goal-as-command candidate is in every first batch, so
    # the best may coincide: compare the whole top-m).
    first = opt.solve(shelf_problem, batches=1, population=16, seed=0)
    other = opt.solve(shelf_problem, batches=1, population=16, seed=1)
    assert any(not np.array_equal(a, b) for (a, _), (b, _) in zip(other.top, first.top))


@pytest.fixture(scope="module")
def free_problem():
    """The shipped Panda in an empty scene, moving joint 1 by 0.6 rad."""
    import gfcs
    from gfcs import generators
    from gfcs.problems import Problem

    goal = generators.READY + np.array([0.6, 0, 0, 0, 0, 0, 0])
    return Problem("free", gfcs.Robot.panda(), gfcs.Scene(), q0=generators.READY, goal=goal)


def test_length_slack_prefers_the_shorter_hand_path_among_near_optimal_candidates(free_problem, fake_optimum):
    p = free_problem
    fabric, settings = opt.make_fabric(p), get_preset("default").settings
    detour = p.goal + np.array([0, -0.8, 0, 0.6, 0, 0, 0])  # shoulder back, elbow out: a longer hand path
    direct = p.goal.copy()
    hand = {}
    for name, c in (("detour", detour), ("direct", direct)):
        traj, _, reached, _ = opt.rollout_commands(fabric, p.q0, p.qd0, p.goal, c[None], settings)
        assert reached
        hand[name] = metrics.path_length(p.robot.ee_position(traj.q))
    assert hand["direct"] < 0.8 * hand["detour"]
    # the detour is cheapest, the direct one 8 % dearer
    result = fake_optimum([detour, direct], [1.0, 1.08])

    def pick(slack, mesh_candidates=32, result=result):
        chosen = opt.select_candidate(fabric, p, result, 1, settings, None,
                                      opt.SelectionOptions(length_slack=slack, mesh_candidates=mesh_candidates))
        met = chosen.metrics
        assert "mesh_candidates_checked" not in met and met["ee_length"] == pytest.approx(
            hand["direct" if np.array_equal(chosen.commands[0], direct) else "detour"])
        return chosen.commands[0], met["selection_rank"]

    np.testing.assert_array_equal(pick(0.1)[0], direct)
    assert pick(0.1)[1] == 1
    for slack in (0.0, 0.05):  # 1.08 is outside a 5 % slack
        c, rank = pick(slack)
        np.testing.assert_array_equal(c, detour)
        assert rank == 0
    # a candidate whose cost says it missed the goal (above the penalty) stays out at any slack, however
    # short its hand path
    unreached = fake_optimum([detour, direct], [1.0, 150.0])
    np.testing.assert_array_equal(pick(1e6, result=unreached)[0], detour)
    np.testing.assert_array_equal(pick(0.1, mesh_candidates=1)[0], detour)  # only the lowest cost considered


def test_solve_records_the_slack_and_rejects_a_bad_one(shelf_problem):
    r = opt.solve(shelf_problem, batches=1, population=8, seed=0, length_slack=0.2)
    assert r.settings["length_slack"] == 0.2 and 0 <= r.metrics["selection_rank"] < 8
    # within the slack of the best cost, and no longer a hand path than the lowest-cost candidate's
    best = opt.solve(shelf_problem, batches=1, population=8, seed=0, length_slack=0)
    assert best.metrics["selection_rank"] == 0 and r.cost <= 1.2 * best.cost + 1e-12
    assert r.metrics["ee_length"] <= best.metrics["ee_length"] + 1e-12
    for bad in (-0.1, math.nan, math.inf):
        with pytest.raises(ValueError, match="length_slack"):
            opt.solve(shelf_problem, batches=1, population=8, length_slack=bad)


def test_gf_baseline(shelf_problem):
    r = opt.solve(shelf_problem, method="gf")
    assert r.method == "gf" and r.commands.shape == (0, 7) and r.t_stars.shape == (1,)
    assert r.n_evaluations == 1 and len(r.top) == 0
    np.testing.assert_array_equal(r.trajectory.q[0], shelf_problem.q0)
    expected = r.t_stars[0] + (0 if r.reached else r.settings["penalty"])
    expected += r.settings["collision_penalty"] if r.metrics["min_clearance"] < 0 else 0
    assert r.cost == pytest.approx(expected)
    with pytest.raises(ValueError, match="method"):
        opt.solve(shelf_problem, method="rrt")


def test_custom_sampler_warm_starts_the_first_batch(shelf_problem):
    class Fixed:
        def __init__(self):
            self.calls = 0

        def sample(self, problem, n, rng):
            self.calls += 1
            return np.tile(problem.goal, (n, 1)) + rng.normal(0, 0.05, (n, problem.dof))

    seen = []
    sampler = Fixed()
    r = opt.solve(shelf_problem, batches=2, population=8, sampler=sampler, callback=lambda i: seen.append(i))
    assert sampler.calls == 1 and len(seen) == 2
    assert np.all(np.abs(seen[0].candidates - shelf_problem.goal) < 0.3)  # the sampler's candidates
    assert r.settings["sampler"] == "Fixed"

    class Wrong:
        def sample(self, problem, n, rng):
            return np.zeros((n, 3))

    with pytest.raises(ValueError, match=r"sampler Wrong: expected shape \(8, 7\)"):
        opt.solve(shelf_problem, batches=1, population=8, sampler=Wrong())


def test_replay_is_exact_and_reacts_to_new_obstacles(shelf_problem, solved):
    from gfcs import metrics

    same = opt.replay(solved, shelf_problem.scene)
    np.testing.assert_array_equal(same.trajectory.q, solved.trajectory.q)
    assert same.cost == solved.cost
    # an obstacle on the end-effector path, which the optimisation never saw (GFCS Sec. V, Fig. 4)
    robot = shelf_problem.robot
    ee = robot.ee_position(solved.trajectory.q)
    scene = shelf_problem.scene.copy()
    scene.add_sphere(ee[len(ee) // 2], 0.05)
    assert metrics.obstacle_clearance(robot, scene, solved.trajectory.q).min() < 0  # old path collides
    new = opt.replay(solved, scene)
    assert new.metrics["min_clearance"] >= 0  # the fabric avoids it without re-optimising
    np.testing.assert_array_equal(new.commands, solved.commands)
    # first-batch commands replayed: the anytime solution after batch 1
    first = opt.replay(solved, shelf_problem.scene, commands=solved.batch_best_commands[0].reshape(1, 7))
    assert first.cost == pytest.approx(solved.batch_best_costs[0], abs=1e-12)


def test_result_json_round_trip(shelf_problem, solved):
    from gfcs.results import SolveResult

    text = solved.to_json()
    assert "NaN" not in text.replace('"NaN"', "") and "Infinity" not in text.replace('"Infinity"', "")
    back = SolveResult.from_json(text)
    for name in ("q0", "qd0", "goal", "commands", "t_stars", "batch_times", "batch_best_costs",
                 "batch_best_commands"):
        np.testing.assert_array_equal(getattr(back, name), getattr(solved, name), err_msg=name)
    for name in ("t", "q", "qd"):
        np.testing.assert_array_equal(getattr(back.trajectory, name), getattr(solved.trajectory, name))
    assert back.metrics == solved.metrics and back.settings == solved.settings
    assert back.fabric_config == solved.fabric_config
    # the joint order of every vector, for readers of the JSON that do not load the robot
    assert back.joint_names == solved.joint_names == list(shelf_problem.robot.joint_names)
    assert [(c.tolist(), v) for c, v in back.top] == [(c.tolist(), v) for c, v in solved.top]
    assert (back.problem, back.cls, back.method, back.seed, back.cost, back.success, back.wall_time) == (
        solved.problem, solved.cls, solved.method, solved.seed, solved.cost, solved.success, solved.wall_time)
    # non-finite values survive as strict JSON
    import dataclasses

    odd = dataclasses.replace(solved, cost=math.inf, metrics=dict(solved.metrics, ee_ldj=math.nan))
    back = SolveResult.from_json(odd.to_json(include_trajectory=False))
    assert back.cost == math.inf and math.isnan(back.metrics["ee_ldj"]) and len(back.trajectory) == 0
    with pytest.raises(ValueError, match="robot="):
        opt.replay(back, None)
    # a result loaded from JSON replays with an explicit robot (stored config and settings reused; the
    # shipped Panda's thin spheres, which the solve planned on, taken for it)
    loaded = SolveResult.from_json(text)
    assert loaded.settings["sphere_model"] == "thin"
    again = opt.replay(loaded, shelf_problem.scene, robot=shelf_problem.robot)
    np.testing.assert_array_equal(again.trajectory.q, solved.trajectory.q)


# ------------------------------------------------------------------------------ goals at a joint limit
@pytest.fixture(scope="module")
def limit_problem():
    """The shipped Panda in an empty scene, its goal with joint 5 at its upper limit (as MotionBenchMaker's
    cage goals put it, 2.8973 rad)."""
    import gfcs
    from gfcs import generators
    from gfcs.problems import Problem

    robot = gfcs.Robot.panda()
    goal = generators.READY.copy()
    goal[4] = robot.upper[4]
    return Problem("limit", robot, gfcs.Scene(), q0=generators.READY, goal=goal)


def test_fabric_goal_moves_only_joints_within_the_barrier_margin_plus_hold_off(limit_problem):
    fabric = opt.make_fabric(limit_problem)
    margin = fabric.config.to_dict()["joint_limits"]["margin"]
    lower, upper = np.asarray(limit_problem.robot.lower), np.asarray(limit_problem.robot.upper)
    goal = limit_problem.goal.copy()
    goal[0] = lower[0] + margin + 0.01  # within margin + 0.015 of the lower limit
    commanded = opt.fabric_goal(fabric, goal, 0.015)
    expected = goal.copy()
    expected[0] = lower[0] + margin + 0.015
    expected[4] = upper[4] - margin - 0.015
    np.testing.assert_array_equal(commanded, expected)
    assert goal[4] == upper[4]  # the input is not changed
    far = limit_problem.q0
    np.testing.assert_array_equal(opt.fabric_goal(fabric, far, 0.015), far)
    off = opt.make_fabric(limit_problem, {"joint_limits": {"enabled": False}})
    np.testing.assert_array_equal(opt.fabric_goal(off, goal, 0.015), goal)
    np.testing.assert_array_equal(opt.fabric_goal(fabric, goal, None), goal)  # None: the goal as it is
    for bad in (-0.01, math.nan, math.inf, "a lot"):
        with pytest.raises(gfcs.GfcsError, match="limit_hold_off"):
            opt.fabric_goal(fabric, goal, bad)


def test_a_goal_at_a_joint_limit_is_reached_within_the_limits(limit_problem):
    p = limit_problem
    fabric = opt.make_fabric(p)
    lower, upper = np.asarray(p.robot.lower), np.asarray(p.robot.upper)
    # commanded as it is, the limit barrier holds joint 5 about 0.018 rad off the goal: a tolerance below
    # that is never met (without the goal capture, which would take that rest point as arrival)
    tight = dataclasses.replace(get_preset("default").settings, tol=0.005, capture_tol=0.0)  # hold-off 0.015
    traj, _, reached, _ = opt.rollout_commands(fabric, p.q0, p.qd0, p.goal, np.zeros((0, 7)),
                                               dataclasses.replace(tight, limit_hold_off=0.0))
    assert not reached and np.linalg.norm(traj.q[-1] - p.goal) > 0.01
    traj, _, reached, _ = opt.rollout_commands(fabric, p.q0, p.qd0, p.goal, np.zeros((0, 7)), tight)
    assert reached
    np.testing.assert_array_equal(traj.q[-1], p.goal)
    assert np.all(traj.q >= lower) and np.all(traj.q <= upper)
    result = opt.solve(p, method="gf")
    assert result.success and result.metrics["within_limits"] and result.metrics["final_error"] == 0.0
