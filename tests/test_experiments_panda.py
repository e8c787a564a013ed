"""The GF Sec. VII Panda experiments (gfcs.experiments.panda): reaching with the goal switch on the hand,
the wall, rings and dynamic tasks, the figure, the JSON and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

import gfcs
from gfcs import cli
from gfcs.experiments import panda as px


def test_reaching_fabric_converges_in_free_space():
    """With the goal switch on the hand's distance, the hand settles on its target (GF VII-A3); RMPflow's
    posture leaf leaves it within a millimetre after 5 s."""
    for variant in px.VARIANTS:
        r = px.Reacher(variant, gfcs.Scene())
        target = np.array([0.5, 0.2, 0.4])
        hands = np.asarray([r.step(target) for _ in range(500)])
        error = np.linalg.norm(hands - target, axis=1)
        assert error[-1] < (1e-3 if variant == "rmpflow" else 1e-4) and error[0] > 0.1
        np.testing.assert_allclose(hands[-1], r.robot.ee_position(r.q), atol=1e-12)
    with pytest.raises(ValueError, match="variant"):
        px.Reacher("rmp", gfcs.Scene())


def test_wall_errors_grow_toward_the_wall_and_the_spheres_stay_out():
    for variant in px.VARIANTS:
        w = px.wall(variant, distances=(0.20, 0.10, 0.0))
        assert len(w["errors"]) == 3 and w["errors"][0] < 2e-3 < 1e-2 < w["errors"][2]
        assert w["errors"][0] < w["errors"][1] < w["errors"][2]
        assert w["min_clearance"] > 0.0  # the barrier keeps every collision sphere off the wall
        # the hand origin stops short of the face by about the hand's own spheres
        assert 0.02 < w["min_approach"] < 0.15
        assert w["degrades_below"] in (0.20, 0.10, 0.0)


def test_rings_are_laid_out_as_in_the_paper_and_never_hit():
    g = px.rings("bent")
    assert len(g["rings_passed"]) == len(px.RING_RADII) == 5
    assert g["rings_passed"][0] and g["n_passed"] >= 1
    assert g["min_clearance"] > 0.0
    # passing is monotone: a ring behind one not passed is not passed either
    assert g["rings_passed"] == sorted(g["rings_passed"], reverse=True)


def test_dynamic_task_is_seeded_and_measured():
    a = px.dynamic("bent", seed=3, n_targets=2)
    b = px.dynamic("bent", seed=3, n_targets=2)
    assert a["targets"] == b["targets"] and a["closest"] == b["closest"]
    assert a["targets"] != px.dynamic("bent", seed=4, n_targets=2)["targets"]
    assert len(a["reached"]) == 2 and a["n_reached"] == sum(a["reached"])
    assert all(r == (c < px.REACHED) for r, c in zip(a["reached"], a["closest"]))
    assert 0.0 <= a["collision_rate"] <= 1.0
    assert a["hand"].shape == (2 * int(px.HOLD / px.DT), 3)


def test_dynamic_seeds_aggregate_with_intervals():
    runs = [px.dynamic("bent", seed=s, n_targets=1) for s in (5, 6)]
    px_dynamic = px.dynamic
    try:  # two short seeds: patch the task length
        px.dynamic = lambda v, s, model="thin": px_dynamic(v, s, n_targets=1, model=model)
        d = px.dynamic_seeds("bent", [5, 6])
    finally:
        px.dynamic = px_dynamic
    assert d["seeds"] == [5, 6] and d["targets"] == runs[0]["targets"]
    assert d["n_reached_per_seed"] == [r["n_reached"] for r in runs]
    assert d["collision_rate_mean"] == pytest.approx(np.mean([r["collision_rate"] for r in runs]))
    lo, hi = d["collision_rate_ci95"]
    assert lo <= d["collision_rate_mean"] <= hi


def test_ring_readings_and_models():
    assert px.ring_radii("centre") == px.RING_RADII
    np.testing.assert_allclose(np.asarray(px.ring_radii("opening")) - px.RING_RADII, px.RING_BALL)
    with pytest.raises(ValueError, match="reading"):
        px.ring_radii("inner")
    with pytest.raises(ValueError, match="model"):
        px.Reacher("bent", gfcs.Scene(), model="fat")
    thin, shipped = (px.Reacher("bent", gfcs.Scene(), m).robot for m in ("thin", "shipped"))
    assert len(thin.sphere_radii) != len(shipped.sphere_radii)
    assert isinstance(px.Reacher("rmpflow", gfcs.Scene()).fabric, gfcs.Rmpflow)


def test_run_rejects_unknown_experiments():
    with pytest.raises(ValueError, match="unknown experiment"):
        px.run(["cubby"])


def test_cli_experiment_panda(tmp_path, capsys):
    out, js = tmp_path / "panda.png", tmp_path / "panda.json"
    assert cli.main(["experiment", "panda", "--only", "wall", "--out", str(out), "--json", str(js)]) == 0
    text = capsys.readouterr().out
    assert "wall     bent" in text and "wall     unbent" in text and "wall     rmpflow" in text
    assert out.stat().st_size > 10_000
    claims = json.loads(js.read_text())
    assert set(claims["wall"]) == set(px.VARIANTS)
    assert len(claims["wall"]["bent"]["errors"]) == 21


def test_recordings_hold_both_variants_the_targets_and_the_moving_spheres(tmp_path):
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    exp = px.PandaExperiments(results={"dynamic": {v: px.dynamic(v, seed=1, n_targets=1) for v in px.VARIANTS}})
    (path,) = px.record(exp, tmp_path / "rrd", every=5)
    assert path == tmp_path / "rrd" / "dynamic.rrd"
    rows, static = {}, set()
    for chunk in RrdReader(str(path)).stream():
        batch = chunk.to_record_batch()
        if chunk.is_static:
            static.add(chunk.entity_path)
            continue
        columns = {n: batch.column(n).to_pylist() for n in batch.schema.names if n not in ("time", "log_time")}
        times = batch.column("time").cast("int64").to_pylist()
        positions = next(v for n, v in columns.items() if n.endswith("positions"))
        rows.setdefault(chunk.entity_path, []).extend(zip(times, positions))
    steps = int(px.HOLD / px.DT)
    for v in px.VARIANTS:
        assert f"/{v}/hand_path" in static
        spheres = sorted(rows[f"/{v}/spheres"], key=lambda r: r[0])
        assert len(spheres) == steps // 5
        q = exp.results["dynamic"][v]["q"][10]  # the third row is step 10
        np.testing.assert_allclose(np.asarray(spheres[2][1]), px.Reacher(v, gfcs.Scene()).robot.sphere_centers(q),
                                   atol=1e-6)
    moving = sorted(rows["/world/moving"], key=lambda r: r[0])
    assert len(moving) == steps // 5 and np.asarray(moving[0][1]).shape == (3, 3)
    np.testing.assert_allclose(np.asarray(moving[0][1]), exp.results["dynamic"]["bent"]["moving"][0], atol=1e-6)
    assert "/world/obstacles/static0" in static and "/world/obstacles/moving0" not in static
    target = sorted(rows["/world/target"], key=lambda r: r[0])
    np.testing.assert_allclose(np.asarray(target[0][1])[0], exp.results["dynamic"]["bent"]["targets"][0], atol=1e-6)


def test_settings_override_the_systems_and_divergence_is_reported():
    saved = (px.SETTINGS.fabric, px.SETTINGS.rmpflow, px.SETTINGS.rmp_substeps)
    try:
        px.SETTINGS.rmpflow = {"obstacles": {"metric_scalar": 0.25}}
        px.SETTINGS.fabric = {"ee_position": {"potential": {"gain": 2.0}}}
        px.SETTINGS.rmp_substeps = 3
        r = px.Reacher("rmpflow", gfcs.Scene())
        assert r.fabric.config["obstacles"]["metric_scalar"] == 0.25 and r.substeps == 3
        f = px.Reacher("bent", gfcs.Scene())
        assert f.fabric.config.to_dict()["ee_position"]["potential"]["gain"] == 2.0
        assert f.substeps == 1
        # a policy whose state blows up ends the dynamic run: the remaining targets count as missed
        px.SETTINGS.rmpflow = {"target": {"accel_p_gain": 1e6, "accel_d_gain": 0.0}, "damping": {"accel_d_gain": 0.0}}
        px.SETTINGS.rmp_substeps = 1
        d = px.dynamic("rmpflow", seed=0, n_targets=2)
        assert d["diverged"] and d["n_reached"] <= 1 and len(d["reached"]) == 2
    finally:
        px.SETTINGS.fabric, px.SETTINGS.rmpflow, px.SETTINGS.rmp_substeps = saved
