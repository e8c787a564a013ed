"""Energy model, InfoNCE loss (GFCS eq. 9) and SGLD (eq. 10-11) on synthetic contexts and targets."""

from __future__ import annotations

import math

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from gfcs.errors import ConfigError  # noqa: E402
from gfcs.learning.ebm import EnergyModel, info_nce_loss  # noqa: E402
from gfcs.learning.sgld import SGLDConfig, reflect_into_box, sgld, sigma2  # noqa: E402
from gfcs.learning.train import train_energy_model  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def one_thread():
    """Single-threaded torch: faster than two contending threads on a shared 2-core machine."""
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


def test_info_nce_matches_eq9_in_float64():
    rng = np.random.default_rng(0)
    e_pos, e_neg = rng.normal(size=5), rng.normal(size=(5, 7)) * 3.0
    per = [-math.log(math.exp(-e_pos[j]) / (math.exp(-e_pos[j]) + np.exp(-e_neg[j]).sum())) for j in range(5)]
    tp, tn = torch.tensor(e_pos), torch.tensor(e_neg)
    assert float(info_nce_loss(tp, tn, "sum")) == pytest.approx(sum(per), rel=1e-12)
    assert float(info_nce_loss(tp, tn)) == pytest.approx(np.mean(per), rel=1e-12)
    np.testing.assert_allclose(info_nce_loss(tp, tn, "none").numpy(), per, rtol=1e-12)
    with pytest.raises(ConfigError, match="reduction"):
        info_nce_loss(tp, tn, "max")
    with pytest.raises(ConfigError, match="e_neg"):
        info_nce_loss(tp, tn[:3])


def test_info_nce_is_stable_for_huge_energies():
    # exp(±1000) overflows; logsumexp must not. Positive far below negatives -> loss -> 0;
    # positive far above -> loss ≈ E+ - min E-.
    tp = torch.tensor([-1000.0, 1000.0], dtype=torch.float64, requires_grad=True)
    tn = torch.tensor([[0.0, 5.0], [0.0, 990.0]], dtype=torch.float64)
    per = info_nce_loss(tp, tn, "none")
    assert torch.all(torch.isfinite(per))
    vals = per.detach()
    assert float(vals[0]) == pytest.approx(0.0, abs=1e-12)
    assert float(vals[1]) == pytest.approx(1000.0, rel=1e-9)
    per.sum().backward()
    assert torch.all(torch.isfinite(tp.grad))
    # d loss / d E+ = 1 - softmax weight of the positive: 0 when it dominates, 1 when it is negligible
    np.testing.assert_allclose(tp.grad.numpy(), [0.0, 1.0], atol=1e-12)


def test_energy_model_split_first_layer_equals_concatenation():
    with torch.random.fork_rng():
        torch.manual_seed(0)
        m = EnergyModel(5, 3, (16, 8)).double()
    c, y = torch.randn(4, 5, dtype=torch.float64), torch.randn(4, 6, 3, dtype=torch.float64)
    w = torch.cat([m.context_layer.weight, m.target_layer.weight], dim=1)
    x = torch.cat([c[:, None, :].expand(4, 6, 5), y], dim=2)
    h = x @ w.T + m.context_layer.bias
    ref = m.trunk(h).squeeze(-1)
    torch.testing.assert_close(m(c, y), ref, rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(m(c, y[:, 2, :]), ref[:, 2], rtol=1e-12, atol=1e-12)
    assert m.meta() == {"context_dim": 5, "target_dim": 3, "hidden": [16, 8], "activation": "relu"}
    with pytest.raises(ConfigError, match="activation"):
        EnergyModel(5, 3, (8,), activation="sigmoidal")
    with pytest.raises(ConfigError, match="hidden"):
        EnergyModel(5, 3, ())
    with pytest.raises(ConfigError, match="context"):
        m(torch.zeros(4, 2, dtype=torch.float64), y)


def test_default_architecture_is_the_papers():
    m = EnergyModel(10, 7)
    assert m.hidden == [800, 800, 800] and m.activation == "relu"
    assert sum(isinstance(layer, torch.nn.ReLU) for layer in m.trunk) == 3


def test_sigma_schedule():
    assert sigma2(0) == 1.0
    assert sigma2(3) == pytest.approx(0.5)
    assert sigma2(99) == pytest.approx(0.1)


def test_sgld_config_with_noise_changes_only_the_noise():
    base = SGLDConfig(iters=40, step_scale=2.0, max_step=None)
    wide = base.with_noise(1.0)
    assert wide == SGLDConfig(iters=40, step_scale=2.0, noise_scale=1.0, max_step=None)
    assert base.noise_scale == SGLDConfig().noise_scale  # the original is not changed
    with pytest.raises(ConfigError, match="noise_scale"):
        base.with_noise(-0.5)


class Quadratic:
    """E(x, y) = ‖y − μ(x)‖² / (2 w²) with μ(x) = x: an energy with a known minimum (no training)."""

    def __init__(self, dim, width):
        self.target_dim = dim
        self.width = width

    def context_features(self, context):
        return context

    def energy_from_features(self, feats, y):
        return ((y - feats[:, None, :]) ** 2).sum(-1) / (2.0 * self.width ** 2)


def test_sgld_descends_a_known_energy_and_stays_in_the_box():
    mu = torch.tensor([[0.5, -0.3, 0.7], [-0.7, 0.0, 0.2]], dtype=torch.float64)
    gen = torch.Generator().manual_seed(0)
    y, e = sgld(Quadratic(3, 0.1), mu, 200, SGLDConfig(iters=100, noise_scale=0.3), gen)
    assert y.shape == (2, 200, 3) and e.shape == (2, 200)
    assert torch.all(y <= 1.0) and torch.all(y >= -1.0)
    # Stationary law ∝ exp(−E / T), T = τ² (step_scale 1): a Gaussian around μ with std w·τ per axis.
    spread = 0.1 * 0.3
    dist = (y - mu[:, None, :]).norm(dim=-1)
    assert float(dist.mean()) < 4.0 * spread * math.sqrt(3)
    torch.testing.assert_close(y.mean(dim=1), mu, atol=0.02, rtol=0)
    # energies returned are those of the returned particles
    torch.testing.assert_close(e, Quadratic(3, 0.1).energy_from_features(mu, y))


def test_reflect_into_box_mirrors_at_the_faces():
    y = torch.tensor([1.3, -1.25, 5.5, 0.2, -1.0, 3.0], dtype=torch.float64)
    torch.testing.assert_close(reflect_into_box(y),
                               torch.tensor([0.7, -0.75, 0.5, 0.2, -1.0, -1.0], dtype=torch.float64))


def test_sgld_sign_moves_toward_lower_energy_without_noise():
    mu = torch.tensor([[0.7, -0.7]], dtype=torch.float64)
    init = torch.zeros(1, 4, 2, dtype=torch.float64)
    y, _ = sgld(Quadratic(2, 1.0), mu, 4, SGLDConfig(iters=1, noise_scale=0.0, max_step=None), init=init)
    # one step from 0: y = 0 − (σ0²/2)·∇E = 0 − 0.5·(0 − μ)/1 = μ/2
    torch.testing.assert_close(y, (mu / 2.0)[:, None, :].expand(1, 4, 2))


def test_sgld_is_reproducible_and_reflects_under_huge_gradients():
    mu = torch.tensor([[5.0, -5.0]], dtype=torch.float64)  # minimum outside the box, gradients ~ 1e5
    run = lambda: sgld(Quadratic(2, 0.01), mu, 16, SGLDConfig(iters=20),  # noqa: E731
                       torch.Generator().manual_seed(7))[0]
    a, b = run(), run()
    torch.testing.assert_close(a, b, rtol=0, atol=0)
    assert torch.all(a.abs() <= 1.0)
    # one noiseless step from 0: the drift is clipped to max_step per coordinate
    zero = torch.zeros(1, 3, 2, dtype=torch.float64)
    y1, _ = sgld(Quadratic(2, 0.01), mu, 3, SGLDConfig(iters=1, noise_scale=0.0, max_step=0.1), init=zero)
    torch.testing.assert_close(y1, torch.tensor([0.1, -0.1], dtype=torch.float64).expand(1, 3, 2))
    # 20 noiseless clipped steps toward a minimum outside the box: reflected at the faces, the particles
    # end within one step of the limits, not stuck on them
    y20, _ = sgld(Quadratic(2, 0.01), mu, 3, SGLDConfig(iters=21, noise_scale=0.0, max_step=0.1), init=zero)
    torch.testing.assert_close(y20, torch.tensor([0.9, -0.9], dtype=torch.float64).expand(1, 3, 2))
    with pytest.raises(ConfigError, match="iters"):
        sgld(Quadratic(2, 1.0), mu, 4, SGLDConfig(iters=-1))
    with pytest.raises(ConfigError, match="init"):
        sgld(Quadratic(2, 1.0), mu, 4, init=torch.zeros(1, 3, 2, dtype=torch.float64))


# ---------------------------------------------------------------------------- trained EBM, synthetic data
C, D, N = 4, 7, 96


def synthetic_data():
    """Contexts in [-1, 1]^4 and one solution per context, a smooth map into the unit box of R^7."""
    rng = np.random.default_rng(0)
    a = rng.normal(size=(D, C))
    ctx = rng.uniform(-1.0, 1.0, (N, C))
    return ctx, 0.6 * np.tanh(ctx @ a.T)


@pytest.fixture(scope="module")
def trained():
    ctx, tgt = synthetic_data()
    with torch.random.fork_rng():
        torch.manual_seed(0)
        model = EnergyModel(C, D, (64, 64, 64))
    opt = torch.optim.Adam(model.parameters(), lr=1e-3)
    gen = torch.Generator().manual_seed(0)
    ct, tt = torch.tensor(ctx, dtype=torch.float32), torch.tensor(tgt, dtype=torch.float32)
    # fixed reference negatives (uniform) to measure the loss before and after on the same data
    neg = torch.rand(N, 16, D, generator=torch.Generator().manual_seed(1)) * 2 - 1
    with torch.no_grad():
        before = float(info_nce_loss(model(ct, tt), model(ct, neg)))
    losses = train_energy_model(model, opt, ct, tt, epochs=60, batch_size=48, n_neg=16,
                                sgld_config=SGLDConfig(iters=30), neg_refresh=5, generator=gen)
    with torch.no_grad():
        after = float(info_nce_loss(model(ct, tt), model(ct, neg)))
    return model, ct, tt, losses, before, after


def test_info_nce_falls_during_training(trained):
    _, _, _, losses, before, after = trained
    assert before == pytest.approx(math.log(17.0), abs=0.3)  # untrained: all energies alike
    assert after < 0.2 * before
    assert np.mean(losses[-5:]) < 0.6 * losses[0]


def test_sgld_concentrates_near_training_solutions(trained):
    model, ct, tt, _, _, _ = trained
    gen = torch.Generator().manual_seed(3)
    y, e = sgld(model, ct[:32], 64, SGLDConfig(iters=60, noise_scale=0.3), gen)
    assert torch.all(y.abs() <= 1.0)
    dist = (y - tt[:32, None, :]).norm(dim=-1)
    uniform = torch.rand(32, 64, D, generator=gen) * 2 - 1
    dist_uniform = (uniform - tt[:32, None, :]).norm(dim=-1)
    assert float(dist.mean()) < 0.4 * float(dist_uniform.mean())
    # the lowest-energy particle is closer still
    best = dist.gather(1, e.argmin(dim=1, keepdim=True))
    assert float(best.mean()) < 0.25 * float(dist_uniform.mean())
