"""gfcs.experiments.particles (GF Sec. VI): the path comparisons against closed forms and brute force, the
fan layout, the measured claims of GF Sec. VI-C, the figure and the `gfcs experiment particles` command."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gfcs import cli
from gfcs.experiments import particles as px


# ------------------------------------------------------------------------------------ path measures
def test_arc_length_resampling_is_uniform_along_the_polyline():
    path = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 1.0]])  # length 4
    r = px.resample_by_arc_length(path, 9)  # spacing 0.5
    assert np.allclose(np.linalg.norm(np.diff(r, axis=0), axis=1), 0.5)
    assert np.allclose(r[0], path[0]) and np.allclose(r[-1], path[-1]) and np.allclose(r[6], [3.0, 0.0])
    # sample density does not matter: a densely sampled copy resamples to the same points
    dense = np.vstack([np.linspace(path[i], path[i + 1], 50, endpoint=False) for i in range(2)] + [path[-1:]])
    assert np.allclose(px.resample_by_arc_length(dense, 9), r)
    assert np.allclose(px.resample_by_arc_length(np.array([[1.0, 2.0]]), 4), [[1.0, 2.0]] * 4)
    with pytest.raises(ValueError):
        px.resample_by_arc_length(np.zeros((0, 2)), 4)


def test_path_distances_closed_forms_and_brute_force():
    a = np.column_stack([np.linspace(0.0, 2.0, 30), np.zeros(30)])
    b = a + [0.0, 0.3]
    assert math.isclose(px.mean_pointwise_distance(a, b), 0.3, rel_tol=1e-12)
    assert math.isclose(px.hausdorff_distance(a, b), 0.3, rel_tol=1e-12)
    assert px.mean_pointwise_distance(a, a[[0, 5, 17, 29]]) < 1e-12  # same shape, other sampling
    # Hausdorff against a brute force over the resampled point sets
    rng = np.random.default_rng(0)
    p, q = np.cumsum(rng.normal(size=(40, 2)), axis=0), np.cumsum(rng.normal(size=(25, 2)), axis=0)
    rp, rq = px.resample_by_arc_length(p, 200), px.resample_by_arc_length(q, 200)
    brute = max(max(min(np.linalg.norm(x - y) for y in rq) for x in rp),
                max(min(np.linalg.norm(x - y) for x in rp) for y in rq))
    assert math.isclose(px.hausdorff_distance(p, q), brute, rel_tol=1e-12)


def test_lateral_deviation_closed_form():
    start, target = np.array([3.0, 1.0]), np.array([-3.0, 1.0])
    path = np.array([[3.0, 1.0], [0.0, 2.5], [-1.0, 0.2], [-3.0, 1.0]])
    assert math.isclose(px.lateral_deviation(path, start, target), 1.5)
    diag = np.array([[0.0, 0.0], [1.0, 0.0]])
    assert math.isclose(px.lateral_deviation(diag, [0.0, 0.0], [1.0, 1.0]), math.sqrt(0.5))


def test_fan_layout():
    target, centre = [-3.0, 0.0], [0.0, 0.0]
    s = px.fan_starts(7, 6.0, 30.0, target, centre)
    assert s.shape == (7, 2)
    assert np.allclose(np.linalg.norm(s - target, axis=1), 6.0)
    assert np.allclose(s[3], [3.0, 0.0])  # the middle one aims straight at the obstacle
    ang = np.degrees(np.arctan2(s[:, 1], s[:, 0] + 3.0))
    assert np.allclose(ang, np.linspace(-30.0, 30.0, 7))
    assert np.all(s[:, 0] > 1.0)  # all to the right of the unit circle
    with pytest.raises(ValueError):
        px.fan_starts(5, 6.0, 30.0, [0.0, 0.0], [0.0, 0.0])


@pytest.mark.parametrize("bad", [dict(n_particles=4), dict(n_particles=1), dict(half_angle=95.0),
                                 dict(dt=0.0), dict(t_max=math.nan), dict(resample=1)])
def test_invalid_setup(bad):
    with pytest.raises(ValueError):
        px.run(px.ParticleSetup(**bad))


def test_invalid_speeds_and_variants():
    with pytest.raises(ValueError, match="speeds"):
        px.run(px.ParticleSetup(n_particles=3), speeds=[2.0])
    with pytest.raises(ValueError, match="variants"):
        px.run(px.ParticleSetup(n_particles=3), variants=["bent_lagrangian"])


# ------------------------------------------------------------------------------------ the experiment
@pytest.fixture(scope="module")
def experiment():
    return px.run(px.ParticleSetup(n_particles=7, t_max=12.0))


def test_runs_cover_every_variant_and_speed(experiment):
    exp = experiment
    assert set(exp.runs) == {(v, s) for v in px.VARIANTS for s in px.SPEEDS}
    target = np.asarray(exp.params["target"])
    for run in exp.runs.values():
        assert len(run.paths) == 7
        for i, path in enumerate(run.paths):
            assert np.allclose(path[0], exp.starts[i])  # starts at rest where laid out
            assert np.all(np.isfinite(path))
            # the reached flag agrees with the final distance to the target
            assert run.reached[i] == (np.linalg.norm(path[-1] - target) <= exp.setup.tol + 1e-9)


def test_claims_are_finite_and_match_gf_section_vi(experiment):
    claims = experiment.claims
    json.dumps(claims, allow_nan=False)  # JSON-ready
    for v, e in claims["variants"].items():
        for key in ("path_change", "path_change_hausdorff"):
            assert math.isfinite(e[key]) and e[key] >= 0.0, (v, key)
        for key in ("centre_standoff", "max_lateral_deviation", "mean_path_length", "min_clearance"):
            assert all(math.isfinite(x) for x in e[key].values()), (v, key)
        # every particle reaches the target except the one shot at the obstacle's local minimum
        assert e["all_but_centre_reach"], v
        assert not any(e["centre_reached"].values()), v
    checks = claims["checks"]
    # GF Sec. VI-C: bent systems keep their paths across speeds; unbent ones push the centre out farther
    for metric in ("riemannian", "finsler"):
        u, b = claims["variants"][f"unbent_{metric}"], claims["variants"][f"bent_{metric}"]
        assert b["path_change"] < u["path_change"]
        assert b["path_change_hausdorff"] < u["path_change_hausdorff"]
        assert checks[f"bent_{metric}_changes_less"] and checks[f"unbent_{metric}_pushes_centre_farther"]


def test_claims_recomputed_by_hand(experiment):
    exp = experiment
    e = exp.claims["variants"]["unbent_finsler"]
    a, b = exp.runs[("unbent_finsler", 2.0)], exp.runs[("unbent_finsler", 4.0)]
    by_hand = np.mean([np.mean(np.linalg.norm(px.resample_by_arc_length(p, 200) - px.resample_by_arc_length(q, 200),
                                              axis=1)) for p, q in zip(a.paths, b.paths)])
    assert math.isclose(e["path_change"], by_hand, rel_tol=1e-12)
    final = b.paths[exp.centre][-1]
    assert math.isclose(e["centre_standoff"]["4"], float(np.hypot(*final)) - 1.0, rel_tol=1e-12)


def test_figure_and_summary(experiment, tmp_path):
    import matplotlib.image as mpimg

    out = px.plot(experiment, tmp_path / "f" / "particles.png")
    img = mpimg.imread(out)
    assert img.shape[0] > img.shape[1] > 300  # 4 rows x 2 columns: taller than wide
    assert img[..., :3].std() > 0.05
    text = px.summary_text(experiment.claims)
    for v in px.VARIANTS:
        assert v in text
    assert "checks:" in text


def test_cli_experiment_particles(tmp_path, capsys):
    fig, js = tmp_path / "p.png", tmp_path / "p.json"
    code = cli.main(["experiment", "particles", "--out", str(fig), "--json", str(js), "--n-particles", "5"])
    assert code == 0
    assert fig.stat().st_size > 1000
    claims = json.loads(js.read_text())
    assert claims["setup"]["n_particles"] == 5 and set(claims["variants"]) == set(px.VARIANTS)
    assert "bent_finsler" in capsys.readouterr().out
    assert cli.main(["experiment", "particles", "--out", str(fig), "--n-particles", "4"]) == 2
