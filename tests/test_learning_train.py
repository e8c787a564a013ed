"""Algorithm 2 (GFCS Sec. IV-C) end to end on synthetic problems, EBMSampler, checkpoints and resume.

The problems here need no robot model: a stand-in robot (limits, dof, joint names) and a stand-in scene
(a point cloud returned by ``surface_points``), and a stand-in ``solve_fn`` whose solutions are a known
function of the problem. That isolates the learning loop; the real solver is exercised in
``test_learning_cli.py``.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from gfcs.errors import ConfigError, FormatError, IoError  # noqa: E402
from gfcs.learning.encoding import EncoderConfig  # noqa: E402
from gfcs.learning.sampler import EBMSampler  # noqa: E402
from gfcs.learning.sgld import SGLDConfig  # noqa: E402
from gfcs.learning.train import TrainConfig, load_checkpoint, train  # noqa: E402

LOWER = np.array([-2.0, -1.0, -3.0])
UPPER = np.array([2.0, 1.0, 3.0])


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


class CloudScene:
    def __init__(self, points):
        self.points = points

    def surface_points(self, spacing):
        return self.points


def make_problems(n, seed=0):
    rng = np.random.default_rng(seed)
    robot = SimpleNamespace(dof=3, lower=LOWER, upper=UPPER, velocity_limits=np.full(3, 2.0),
                            joint_names=["j1", "j2", "j3"], name="toy")
    problems = []
    for i in range(n):
        centre = rng.uniform(-0.5, 0.5, 3)
        problems.append(SimpleNamespace(
            name=f"toy{i:02d}", cls="toy", robot=robot, scene=CloudScene(centre + 0.1 * rng.normal(size=(30, 3))),
            q0=rng.uniform(LOWER, UPPER) * 0.5, qd0=np.zeros(3), goal=rng.uniform(LOWER, UPPER) * 0.5))
    return problems


def solution_of(problem):
    """The 'optimal' command of a toy problem: midway between start and goal (in the limits)."""
    return 0.5 * (problem.q0 + problem.goal)


class ToySolver:
    """solve_fn stand-in: top-6 candidates around the solution, seeded; records its calls."""

    def __init__(self):
        self.calls = []

    def __call__(self, problem, sampler, seed):
        self.calls.append((problem.name, sampler, seed))
        rng = np.random.default_rng(seed)
        cands = np.clip(solution_of(problem) + 0.05 * rng.normal(size=(6, 3)), LOWER, UPPER)
        costs = np.sort(rng.uniform(1.0, 3.0, 6))
        return SimpleNamespace(top=[(c, float(v)) for c, v in zip(cands, costs)])


def small_config(**kw):
    base = TrainConfig(passes=2, n_train=4, buffer_size=40, top_m=4, n_neg=8, hidden=(32, 32), epochs=6,
                       batch_size=16, neg_refresh=2, sgld=SGLDConfig(iters=15),
                       encoder=EncoderConfig(spacing=0.5, box_lower=(-1, -1, -1), box_upper=(1, 1, 1)),
                       seed=3, checkpoint_every=1, device="cpu")
    return replace(base, **kw)


def weights(sampler):
    return {k: v.detach().clone() for k, v in sampler.model.state_dict().items()}


def assert_same_weights(a, b):
    assert a.keys() == b.keys()
    for k in a:
        torch.testing.assert_close(a[k], b[k], rtol=0, atol=0)


def test_algorithm2_loop_buffer_trainings_and_sampler_switch(tmp_path):
    problems = make_problems(6)
    solver = ToySolver()
    out = tmp_path / "model.pt"
    res = train(problems, out=out, config=small_config(), solve_fn=solver, progress=False)
    # 2 passes x 6 problems, training after every 4 solves -> 3 trainings
    assert res.steps_done == 12 and res.trainings == 3
    # 2 x 5: after solves 4 and 8, and after the last (10) so that solves 9-10 are learned too
    five = train(make_problems(5), config=small_config(), solve_fn=ToySolver(), progress=False)
    assert five.steps_done == 10 and five.trainings == 3
    assert [c[0] for c in solver.calls] == [p.name for p in problems] * 2
    # uniform sampler (None) until the first training, then the EBM sampler
    assert all(c[1] is None for c in solver.calls[:4])
    assert all(isinstance(c[1], EBMSampler) for c in solver.calls[4:])
    # seeds differ per step and fit a 31-bit int
    seeds = [c[2] for c in solver.calls]
    assert len(set(seeds)) == 12 and all(0 <= s < 2**31 for s in seeds)
    # buffer: top-4 of each of the 12 solves, capped at 40 (FIFO)
    assert len(res.buffer) == 40
    assert res.buffer.problems()[-4:] == ["toy05"] * 4
    trains = [h for h in res.history if h["event"] == "train"]
    assert [h["step"] for h in trains] == [3, 7, 11] and all(len(h["losses"]) == 6 for h in trains)
    assert out.exists() and (tmp_path / "model.ckpt.pt").exists()


def test_run_is_reproducible_and_resume_matches_uninterrupted(tmp_path):
    problems = make_problems(6)
    full = train(problems, config=small_config(), solve_fn=ToySolver(), checkpoint=tmp_path / "a.pt",
                 progress=False)
    again = train(problems, config=small_config(), solve_fn=ToySolver(), progress=False)
    assert_same_weights(weights(full.sampler), weights(again.sampler))

    ck = tmp_path / "b.pt"
    first = train(problems, config=small_config(), solve_fn=ToySolver(), checkpoint=ck, progress=False,
                  stop_after=6)
    assert first.steps_done == 6 and first.trainings == 1
    state = load_checkpoint(ck)
    assert state["step"] == 6 and len(state["buffer"]["problems"]) == 24
    solver = ToySolver()
    resumed = train(problems, config=None, solve_fn=solver, resume=ck, checkpoint=ck, progress=False)
    assert [c[0] for c in solver.calls] == [p.name for p in problems]  # only the second pass ran
    assert resumed.steps_done == 12 and resumed.trainings == 3
    assert_same_weights(weights(full.sampler), weights(resumed.sampler))
    np.testing.assert_array_equal(full.buffer.targets(), resumed.buffer.targets())
    strip = lambda hs: [{k: v for k, v in h.items() if k != "seconds"} for h in hs]  # noqa: E731
    assert strip(full.history) == strip(resumed.history)


def test_resume_rejects_changed_config_and_problem_set(tmp_path):
    problems = make_problems(6)
    ck = tmp_path / "c.pt"
    train(problems, config=small_config(), solve_fn=ToySolver(), checkpoint=ck, progress=False, stop_after=2)
    with pytest.raises(ConfigError, match="n_neg"):
        train(problems, config=small_config(n_neg=4), solve_fn=ToySolver(), resume=ck, progress=False)
    with pytest.raises(ConfigError, match="problem set"):
        train(problems[:5], solve_fn=ToySolver(), resume=ck, progress=False)
    # passes may change: extend to three passes
    res = train(problems, config=small_config(passes=3), solve_fn=ToySolver(), resume=ck, progress=False)
    assert res.steps_done == 18
    with pytest.raises(IoError):
        load_checkpoint(tmp_path / "missing.pt")
    with pytest.raises(FormatError, match="format"):
        EBMSampler(ck)  # a checkpoint is not a model file


def test_learned_sampler_beats_uniform_and_reloads_identically(tmp_path):
    problems = make_problems(24, seed=1)
    # the sampler at the negatives' noise (τ = 0.3) shows the concentration; the default τ = 1 below
    cfg = small_config(passes=2, n_train=8, buffer_size=96, epochs=20, neg_refresh=5, hidden=(64, 64),
                       sgld=SGLDConfig(iters=40, noise_scale=0.3), sample_noise=0.3)
    out = tmp_path / "m.pt"
    res = train(problems, out=out, config=cfg, solve_fn=ToySolver(), progress=False)
    sampler = res.sampler
    rng_u = np.random.default_rng(0)
    d_ebm, d_uni = [], []
    for p in problems[:8]:
        y = sampler.sample(p, 16, np.random.default_rng(1))
        assert y.shape == (16, 3)
        assert np.all(y >= LOWER) and np.all(y <= UPPER)
        # sorted by energy, lowest first
        e = sampler.energy(sampler.context_of(p), y)
        assert np.all(np.diff(e) >= -1e-4)
        d_ebm.append(np.linalg.norm((y - solution_of(p)) / (UPPER - LOWER), axis=1).mean())
        u = rng_u.uniform(LOWER, UPPER, (16, 3))
        d_uni.append(np.linalg.norm((u - solution_of(p)) / (UPPER - LOWER), axis=1).mean())
    assert np.mean(d_ebm) < 0.35 * np.mean(d_uni)  # measured: 0.12 against 0.53 (seeds 3, 4)
    # at the paper's τ = 1 (the default sample_noise) the batch is wider but still nearer than uniform
    wide = EBMSampler(out, device="cpu", sgld_config=SGLDConfig(iters=40, noise_scale=1.0))
    d_wide = [np.linalg.norm((wide.sample(p, 16, np.random.default_rng(1)) - solution_of(p)) / (UPPER - LOWER),
                             axis=1).mean() for p in problems[:8]]
    assert np.mean(d_wide) < 0.9 * np.mean(d_uni)  # measured: 0.43 against 0.53
    assert np.mean(d_wide) > np.mean(d_ebm)
    best = sampler.best(problems[0], rng=0)
    assert best.shape == (3,)

    loaded = EBMSampler(out, device="cpu")
    assert loaded.sgld_config == cfg.sampler_sgld() and loaded.dof == 3 and loaded.n_free == 1
    assert loaded.sgld_config.noise_scale == 0.3 and cfg.sgld.noise_scale == 0.3
    for p in problems[:3]:
        np.testing.assert_array_equal(loaded.sample(p, 8, np.random.default_rng(5)),
                                      sampler.sample(p, 8, np.random.default_rng(5)))
    np.testing.assert_array_equal(loaded.best(problems[0], rng=0), best)


def test_sampler_checks_robot_and_inputs(tmp_path):
    problems = make_problems(4)
    res = train(problems, config=small_config(passes=1, n_train=4, epochs=1), solve_fn=ToySolver(),
                progress=False)
    other = SimpleNamespace(**vars(problems[0]))
    other.robot = SimpleNamespace(dof=2, lower=LOWER[:2], upper=UPPER[:2], joint_names=["a", "b"])
    with pytest.raises(ConfigError, match="dof"):
        res.sampler.sample(other, 4, np.random.default_rng(0))
    renamed = SimpleNamespace(**vars(problems[0]))
    renamed.robot = SimpleNamespace(**vars(problems[0].robot))
    renamed.robot.joint_names = ["x", "y", "z"]
    with pytest.raises(ConfigError, match="joints"):
        res.sampler.sample(renamed, 4, np.random.default_rng(0))
    with pytest.raises(ConfigError, match="n"):
        res.sampler.sample(problems[0], 0, np.random.default_rng(0))
    with pytest.raises(ConfigError, match="no problems"):
        train([], solve_fn=ToySolver(), progress=False)
    bad = make_problems(2)
    bad[1] = SimpleNamespace(**vars(bad[1]))
    bad[1].robot = SimpleNamespace(dof=3, lower=LOWER - 1, upper=UPPER, joint_names=["j1", "j2", "j3"])
    with pytest.raises(ConfigError, match="joint limits"):
        train(bad, config=small_config(), solve_fn=ToySolver(), progress=False)
    with pytest.raises(ConfigError, match="epochs"):
        train(problems, config=small_config(epochs=0), solve_fn=ToySolver(), progress=False)


def test_config_round_trip():
    cfg = small_config(latent_dim=8, max_cost=50.0, solve={"batches": 2})
    again = TrainConfig.from_dict(cfg.to_dict())
    assert again == cfg
    with pytest.raises(ConfigError, match="unknown"):
        TrainConfig.from_dict({"nope": 1})


def test_autoencoder_context_path(tmp_path):
    problems = make_problems(4)
    cfg = small_config(passes=1, n_train=4, epochs=2, latent_dim=5, ae_hidden=(16,), ae_epochs=20)
    res = train(problems, out=tmp_path / "ae.pt", config=cfg, solve_fn=ToySolver(), progress=False)
    assert res.sampler.encoder.env_dim == 5
    assert res.sampler.model.context_dim == 3 * 3 + 5
    loaded = EBMSampler(tmp_path / "ae.pt", device="cpu")
    np.testing.assert_allclose(loaded.context_of(problems[1]), res.sampler.context_of(problems[1]), atol=1e-6)


class ScriptedValidator:
    """validate_fn stand-in: every validation round costs ``round_costs[k]`` on every problem (round 0 is
    the uniform sampler); records (problem, sampler, seed)."""

    def __init__(self, round_costs, n_problems):
        self.round_costs, self.n, self.calls = round_costs, n_problems, []

    def __call__(self, problem, sampler, seed):
        cost = self.round_costs[len(self.calls) // self.n]
        self.calls.append((problem.name, sampler, seed))
        return SimpleNamespace(top=[(solution_of(problem), cost)], success=cost < 4.5)


def test_validation_keeps_the_best_trained_model_and_resumes(tmp_path):
    problems, held = make_problems(6), make_problems(2, seed=9)
    for i, p in enumerate(held):
        p.name = f"held{i}"
    costs = [1.0, 3.0, 2.0, 4.0]  # uniform (not selectable), then trainings 1-3: training 2 is best
    val = ScriptedValidator(costs, 2)
    out = tmp_path / "v.pt"
    res = train(problems, out=out, config=small_config(), solve_fn=ToySolver(), progress=False,
                validation=held, validate_fn=val)
    events = [h for h in res.history if h["event"] == "validate"]
    assert [e["trainings"] for e in events] == [0, 1, 2, 3]
    assert [e["step"] for e in events] == [0, 4, 8, 12]
    assert [e["mean_cost"] for e in events] == costs and [e["solved"] for e in events] == [2, 2, 2, 2]
    assert val.calls[0][1] is None and all(isinstance(c[1], EBMSampler) for c in val.calls[2:])
    seeds = [c[2] for c in val.calls]  # the same seed per problem in every round (paired comparison)
    assert seeds[0::2] == [seeds[0]] * 4 and seeds[1::2] == [seeds[1]] * 4 and seeds[0] != seeds[1]
    assert res.best["trainings"] == 2 and res.best["mean_cost"] == 2.0
    # the best sampler is the model right after training 2 (8 solves)
    upto8 = train(problems, config=small_config(), solve_fn=ToySolver(), progress=False, stop_after=8)
    assert_same_weights(weights(res.best_sampler), weights(upto8.sampler))
    assert_same_weights(weights(EBMSampler(tmp_path / "v.best.pt", device="cpu")), weights(upto8.sampler))
    assert_same_weights(weights(EBMSampler(out, device="cpu")), weights(res.sampler))  # --out: the final model

    # interrupted after training 1, resumed: same best, same history
    ck = tmp_path / "vc.pt"
    train(problems, config=small_config(), solve_fn=ToySolver(), progress=False, checkpoint=ck, stop_after=6,
          validation=held, validate_fn=ScriptedValidator(costs, 2))
    with pytest.raises(ConfigError, match="validation"):
        train(problems, solve_fn=ToySolver(), resume=ck, progress=False, validation=held[:1])
    resumed = train(problems, solve_fn=ToySolver(), resume=ck, progress=False, validation=held,
                    validate_fn=ScriptedValidator(costs[2:], 2))
    assert resumed.best["trainings"] == 2
    assert_same_weights(weights(resumed.best_sampler), weights(res.best_sampler))
    strip = lambda hs: [{k: v for k, v in h.items() if k != "seconds"} for h in hs]  # noqa: E731
    assert strip(resumed.history) == strip(res.history)
    # without validation problems nothing is selected
    plain = train(problems, config=small_config(passes=1), solve_fn=ToySolver(), progress=False)
    assert plain.best is None and plain.best_sampler is None
