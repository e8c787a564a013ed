"""gfcs.plots: the bench summary figure draws the success rates and EE lengths of the rows (checked
against counts made here), and the PNG files are real, non-blank images."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest

pytest.importorskip("matplotlib")
import matplotlib.image as mpimg  # noqa: E402

from gfcs import plots  # noqa: E402
from gfcs.results import _enc, bench_row  # noqa: E402

LABELS = [("GF", "gf", 0), ("Ours (1 b)", "gfcs", 1), ("Ours (5 b)", "gfcs", 5)]


def make_rows(seed=0):
    rng = np.random.default_rng(seed)
    rows = []
    for cls in ("box", "cage", "table_under_pick"):
        for i in range(6):
            for label, method, batches in LABELS:
                ok = bool(rng.random() < (0.3 if method == "gf" else 0.85)) and not (cls == "cage" and method == "gf")
                metrics = dict(success=ok, ee_length=float(rng.uniform(0.5, 1.5)), cspace_length=2.0, ee_ldj=-5.0,
                               cspace_ldj=-4.0, min_clearance=0.01, final_error=0.0 if ok else 0.5)
                rows.append(bench_row(f"{cls}/{i:04d}", cls, label, method, batches, 0, 1.0, 2.0, metrics, 1.5))
    return rows


def bar_heights(ax, n_labels, n_classes):
    """Bar heights as drawn, [label][class] (bars are added label by label)."""
    h = [p.get_height() for p in ax.patches]
    assert len(h) == n_labels * n_classes
    return np.array(h).reshape(n_labels, n_classes)


def test_figure_shows_the_success_rates_and_lengths_of_the_rows():
    rows = make_rows()
    fig = plots.bench_summary_figure(rows)
    ax_success, ax_length = fig.axes[:2]
    classes = ["box", "cage", "table_under_pick"]
    assert [t.get_text() for t in ax_length.get_xticklabels()] == classes
    success = bar_heights(ax_success, len(LABELS), len(classes))
    length = bar_heights(ax_length, len(LABELS), len(classes))
    for j, (label, _, _) in enumerate(LABELS):
        for i, cls in enumerate(classes):
            group = [r for r in rows if r["class"] == cls and r["label"] == label]
            ok = [r["ee_length"] for r in group if r["success"]]
            assert math.isclose(success[j, i], 100.0 * len(ok) / len(group))
            assert math.isclose(length[j, i], float(np.mean(ok)) if ok else 0.0)  # "NA" groups: no bar
    # GF never succeeds on cage: an NA mark instead of a length
    assert any(t.get_text() == "NA" for t in ax_length.texts)
    assert [t.get_text() for t in ax_success.get_legend().get_texts()] == [lab for lab, _, _ in LABELS]


def test_png_is_a_real_image(tmp_path):
    out = plots.save_bench_summary(make_rows(1), tmp_path / "figs" / "bench.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(out)
    assert img.ndim == 3 and img.shape[0] > 300 and img.shape[1] > 300
    assert img[..., :3].std() > 0.05  # not blank


def test_plot_from_a_jsonl_file_with_non_finite_values(tmp_path):
    rows = make_rows(2)
    rows[0]["ee_ldj"] = math.nan
    rows[1]["min_clearance"] = math.inf
    jsonl = tmp_path / "rows.jsonl"
    jsonl.write_text("\n".join(json.dumps(_enc(r), allow_nan=False) for r in rows) + "\n")
    out = plots.plot_bench_file(jsonl, tmp_path / "b.png", title="test")
    assert out.stat().st_size > 1000


def test_no_rows_is_an_error():
    with pytest.raises(ValueError, match="no benchmark rows"):
        plots.bench_summary_figure([])


def test_cli_registration(tmp_path):
    jsonl = tmp_path / "rows.jsonl"
    jsonl.write_text("\n".join(json.dumps(_enc(r)) for r in make_rows(3)))
    parser = argparse.ArgumentParser(prog="gfcs")
    plots.register_cli(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["plot", str(jsonl), "--out", str(tmp_path / "c.png")])
    assert args.func(args) == 0
    assert (tmp_path / "c.png").stat().st_size > 1000


def make_history():
    """A training history as ``gfcs train --history`` writes it: 8 solves, 2 trainings, 3 validations."""
    history = [{"event": "validate", "step": 0, "trainings": 0, "mean_cost": 6.0, "solved": 3, "n": 4}]
    for step in range(8):
        history.append({"event": "solve", "step": step, "problem": f"p{step % 4}", "best_cost": 5.0 - 0.1 * step,
                        "inserted": 4})
        if step in (3, 7):
            k = 1 + step // 4
            history.append({"event": "train", "step": step, "losses": [3.0 / k, 2.0 / k, 1.5 / k], "seconds": 1.0})
            history.append({"event": "validate", "step": step + 1, "trainings": k, "mean_cost": 5.0 + 0.5 * (k - 1),
                            "solved": 4, "n": 4})
    return history


def test_training_figure_draws_the_history(tmp_path):
    history = make_history()
    fig = plots.training_figure(history)
    ax_cost, ax_loss, ax_val = fig.axes
    x, y = ax_cost.lines[0].get_data()
    np.testing.assert_array_equal(x, np.arange(1, 9))
    np.testing.assert_allclose(y, [h["best_cost"] for h in history if h["event"] == "solve"])
    assert [line.get_xdata()[0] for line in ax_cost.lines[1:]] == [4, 8]  # the trainings
    assert [len(line.get_xdata()) for line in ax_loss.lines] == [3, 3]
    np.testing.assert_array_equal(ax_loss.lines[1].get_xdata(), [4, 5, 6])  # the second training follows
    learned, star, uniform = ax_val.lines
    np.testing.assert_array_equal(learned.get_ydata(), [5.0, 5.5])
    assert list(star.get_xdata()) == [1] and list(uniform.get_ydata()) == [6.0, 6.0]
    # without validation the panel says so; a history without solves is an error
    plain = plots.training_figure([h for h in history if h["event"] != "validate"])
    assert "--holdout" in plain.axes[2].texts[0].get_text()
    with pytest.raises(ValueError, match="no solve events"):
        plots.training_figure([h for h in history if h["event"] != "solve"])
    # gfcs plot tells a history file from benchmark rows
    path = tmp_path / "hist.json"
    path.write_text(json.dumps(history, indent=1))
    out = plots.plot_file(path, tmp_path / "t.png")
    img = mpimg.imread(out)
    assert img.ndim == 3 and img[..., :3].std() > 0.05


def test_totals_count_every_class_and_take_the_medians():
    from gfcs.results import format_totals

    rows = make_rows()
    for k, r in enumerate(rows):
        r["time"], r["wall_time"] = 0.1 * k, 0.1 * k + 0.05
    lines = format_totals(rows).splitlines()
    assert [line.split(":")[0] for line in lines] == [label for label, _, _ in LABELS]
    for line, (label, _, _) in zip(lines, LABELS):
        mine = [r for r in rows if r["label"] == label]
        solved = sum(r["success"] for r in mine)
        assert f"{solved}/18 solved ({100 * solved / 18:.1f} %)" in line
        assert f"median time {np.median([r['time'] for r in mine]):.3f} s" in line
        assert f"whole solve {np.median([r['wall_time'] for r in mine]):.3f} s" in line



def test_totals_take_the_medians_over_planned_problems_and_count_the_refused():
    from gfcs.results import format_totals

    rows = make_rows()
    for k, r in enumerate(rows):
        r["time"], r["wall_time"] = 0.1 * k, 0.1 * k + 0.05
    refused = [r for r in rows if r["label"] == LABELS[0][0]][:2]
    for r in refused:  # rows of problems refused before planning, as gfcs bench writes them
        r.update(success=False, time="NaN", wall_time="NaN", error="CollisionError: the goal state is in collision")
    line = format_totals(rows).splitlines()[0]
    planned = [r for r in rows if r["label"] == LABELS[0][0] and "error" not in r]
    assert "nan" not in line
    assert f"median time {np.median([r['time'] for r in planned]):.3f} s" in line
    assert "(2 refused before planning" in line
