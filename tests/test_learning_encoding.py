"""Environment encoding and context (GFCS Sec. IV-B): lattice, d_E against brute force, normalisation."""

from __future__ import annotations

import numpy as np
import pytest

from gfcs.errors import ConfigError, NonFiniteError, ShapeError
from gfcs.learning.encoding import (
    EncoderConfig,
    SceneEncoder,
    distance_encoding,
    from_unit,
    normalise_distances,
    normalise_velocity,
    reference_lattice,
    to_unit,
)


class PointScene:
    """Stand-in for gfcs.Scene: records the spacing asked for and returns a fixed point set."""

    def __init__(self, points):
        self.points = np.asarray(points, dtype=np.float64)
        self.spacings = []

    def surface_points(self, spacing):
        self.spacings.append(spacing)
        return self.points


def test_default_lattice_is_paper_spacing_centred_in_box():
    ref = reference_lattice()
    assert ref.shape == (14 ** 3, 3)
    for axis, (lo, hi) in enumerate([(-1.0, 1.0), (-1.0, 1.0), (-0.5, 1.5)]):
        values = np.unique(np.round(ref[:, axis], 12))
        assert values.size == 14
        np.testing.assert_allclose(np.diff(values), 0.15, atol=1e-12)
        # centred: equal margins on both sides
        np.testing.assert_allclose(values[0] - lo, hi - values[-1], atol=1e-12)
        assert lo <= values[0] and values[-1] <= hi


def test_lattice_exact_fit_keeps_end_points_and_order():
    ref = reference_lattice(0.5, (0.0, 0.0, 0.0), (1.0, 1.0, 2.0))
    assert ref.shape == (3 * 3 * 5, 3)
    np.testing.assert_allclose(ref[0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(ref[1], [0.0, 0.0, 0.5])  # z varies fastest (x-major order)
    np.testing.assert_allclose(ref[-1], [1.0, 1.0, 2.0])
    # floating-point division 2.0 / 0.1 = 19.999...: the last point must not be lost
    assert reference_lattice(0.1, (0, 0, 0), (2.0, 0.0, 0.0)).shape == (21, 3)


def test_distance_encoding_equals_brute_force():
    rng = np.random.default_rng(1)
    points = rng.uniform(-1.0, 1.0, (300, 3))
    ref = reference_lattice(0.4, (-1, -1, -1), (1, 1, 1))
    brute = np.linalg.norm(ref[:, None, :] - points[None, :, :], axis=2).min(axis=1)
    np.testing.assert_allclose(distance_encoding(points, ref), brute, rtol=0, atol=1e-12)


def test_distance_encoding_of_single_point_is_closed_form():
    ref = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0], [1.0, 2.0, 2.0]])
    np.testing.assert_allclose(distance_encoding([[0.0, 0.0, 0.0]], ref), [0.0, 5.0, 3.0])


def test_empty_point_set_encodes_as_free_space():
    ref = reference_lattice(0.5, (0, 0, 0), (1, 1, 1))
    d = distance_encoding(np.zeros((0, 3)), ref)
    assert np.all(np.isinf(d))
    np.testing.assert_array_equal(normalise_distances(d, 1.0), np.ones(ref.shape[0]))


def test_normalisation_saturates_at_max_distance():
    np.testing.assert_allclose(normalise_distances([0.0, 0.25, 0.5, 2.0], 0.5), [0.0, 0.5, 1.0, 1.0])
    with pytest.raises(ConfigError, match="max_distance"):
        normalise_distances([0.1], 0.0)


def test_bad_points_are_named():
    ref = reference_lattice(0.5, (0, 0, 0), (1, 1, 1))
    with pytest.raises(ShapeError, match=r"points: expected shape \(N, 3\), got \(4, 2\)"):
        distance_encoding(np.zeros((4, 2)), ref)
    with pytest.raises(NonFiniteError, match="points"):
        distance_encoding([[0.0, np.nan, 0.0]], ref)
    with pytest.raises(ConfigError, match="spacing"):
        reference_lattice(-0.1)
    with pytest.raises(ConfigError, match="lattice box"):
        reference_lattice(0.1, (0, 0, 0), (1, -1, 1))


def test_unit_box_round_trip_and_limits():
    lo, hi = np.array([-2.0, 0.0, -1.0]), np.array([2.0, 1.0, 3.0])
    np.testing.assert_allclose(to_unit(lo, lo, hi), -1.0)
    np.testing.assert_allclose(to_unit(hi, lo, hi), 1.0)
    np.testing.assert_allclose(to_unit([0.0, 0.5, 1.0], lo, hi), [0.0, 0.0, 0.0])
    q = np.random.default_rng(2).uniform(lo, hi, (10, 3))
    np.testing.assert_allclose(from_unit(to_unit(q, lo, hi), lo, hi), q, atol=1e-14)
    with pytest.raises(ConfigError, match="joint limits"):
        to_unit(q, hi, lo)


def test_velocity_normalisation_skips_missing_limits():
    np.testing.assert_allclose(normalise_velocity([1.0, 2.0, 3.0], [2.0, np.inf, 0.0]), [0.5, 2.0, 3.0])
    np.testing.assert_allclose(normalise_velocity([1.0, 2.0], None), [1.0, 2.0])


def test_context_layout_and_scene_encoding():
    cfg = EncoderConfig(spacing=0.5, box_lower=(0, 0, 0), box_upper=(1, 1, 1), max_distance=2.0,
                        surface_spacing=0.07)
    enc = SceneEncoder(cfg)
    assert enc.n_reference == 27 and enc.env_dim == 27
    points = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    scene = PointScene(points)
    code = enc.encode_scene(scene)
    assert scene.spacings == [0.07]
    brute = np.linalg.norm(enc.reference[:, None] - points[None], axis=2).min(axis=1) / 2.0
    np.testing.assert_allclose(code, brute, atol=1e-12)
    lo, hi = np.array([-1.0, -2.0]), np.array([1.0, 2.0])
    ctx = enc.context([0.5, 1.0], [0.2, -0.4], [-1.0, 2.0], code, lo, hi, velocity_limits=[2.0, 2.0])
    assert ctx.shape == (2 + 2 + 2 + 27,)
    np.testing.assert_allclose(ctx[:6], [0.5, 0.5, 0.1, -0.2, -1.0, 1.0])
    np.testing.assert_allclose(ctx[6:], code)
    with pytest.raises(ShapeError, match="goal"):
        enc.context([0.5, 1.0], [0.0, 0.0], [0.0], code, lo, hi)
    with pytest.raises(ShapeError, match="env_code"):
        enc.context([0.5, 1.0], [0.0, 0.0], [0.0, 0.0], code[:5], lo, hi)


def test_encoder_state_round_trip_without_torch_objects():
    enc = SceneEncoder(EncoderConfig(spacing=0.3))
    again = SceneEncoder.from_state_dict(enc.state_dict())
    assert again.config == enc.config
    np.testing.assert_array_equal(again.reference, enc.reference)
    with pytest.raises(ConfigError, match="unknown fields"):
        EncoderConfig.from_dict({"spacing": 0.1, "bogus": 1})


def test_autoencoder_reduces_code_and_reconstructs():
    torch = pytest.importorskip("torch")
    from gfcs.learning.ebm import DistanceAutoencoder

    torch.set_num_threads(1)
    cfg = EncoderConfig(spacing=0.25, box_lower=(-1, -1, -1), box_upper=(1, 1, 1))
    base = SceneEncoder(cfg)
    rng = np.random.default_rng(3)
    # environments: one sphere of surface points each, at random centres
    dirs = rng.normal(size=(200, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    codes = np.stack([base.distances(rng.uniform(-0.6, 0.6, 3) + 0.2 * dirs) for _ in range(40)])
    with torch.random.fork_rng():
        torch.manual_seed(0)
        ae = DistanceAutoencoder(base.n_reference, latent_dim=8, hidden=(64,))
    history = ae.fit(codes, epochs=150, lr=3e-3, batch_size=16, seed=0)
    # reference: the error of predicting the mean code (what a collapsed autoencoder achieves)
    mean_error = float(np.mean((codes - codes.mean(axis=0)) ** 2))
    assert history[-1] < 0.1 * mean_error
    recon = ae(torch.as_tensor(codes, dtype=torch.float32)).detach().double().numpy()
    np.testing.assert_allclose(np.mean((recon - codes) ** 2), history[-1], rtol=0.5)
    enc = SceneEncoder(cfg, ae)
    assert enc.env_dim == 8
    z = enc.encode_points(rng.normal(size=(50, 3)))
    assert z.shape == (8,) and np.all(np.abs(z) < 1.0)
    again = SceneEncoder.from_state_dict(enc.state_dict())
    np.testing.assert_allclose(again.encode_points(dirs), enc.encode_points(dirs), atol=1e-12)
