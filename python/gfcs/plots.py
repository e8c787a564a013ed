"""Matplotlib figures of benchmark results (Agg backend: no display needed).

:func:`bench_summary_figure` draws, per problem class and per method row label (``"GF"``,
``"Ours (1 b)"``, ``"Ours (5 b)"``...), the success rate and the end-effector (EE) path length, mean ± std
over the successful problems, from the benchmark rows of ``gfcs bench --json`` (one JSON object per line,
see :mod:`gfcs.results` for the keys: ``class``, ``label``, ``success``, ``ee_length`` [m], ...). The
statistics are those of :func:`gfcs.results.summarize`, the function behind the GFCS Table I layout
printed by ``gfcs bench``.

:func:`training_figure` draws a training run of ``gfcs train`` (Algorithm 2 of GFCS) from its history
(``gfcs train --history``, :attr:`gfcs.learning.train.TrainResult.history`): the best cost of every
solve, the InfoNCE loss of every epoch, and the validation score of every trained model.

``gfcs plot FILE --out FIG.png`` (:func:`register_cli`) writes the bench figure from a row file
(``gfcs bench --json``) or the training figure from a history file (``gfcs train --history``).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from gfcs.errors import InvalidValueError
from gfcs.results import read_rows, summarize

__all__ = ["new_figure", "bench_summary_figure", "save_bench_summary", "plot_bench_file", "training_figure",
           "save_training_figure", "plot_file", "register_cli"]

PathLike = Union[str, "Path"]


def new_figure(figsize: Tuple[float, float]) -> Any:
    """A ``matplotlib.figure.Figure`` on the Agg canvas, outside pyplot (no global state, no display,
    nothing to close; garbage-collected like any object)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def _grouped_bars(ax: Any, classes: Sequence[str], labels: Sequence[str],
                  values: Dict[Tuple[str, str], Optional[Tuple[float, float]]], ylabel: str,
                  errors: bool, value_format: Optional[str] = None) -> None:
    """Bars grouped by class, one bar per label; ``values[(class, label)] = (height, err)`` or None
    (drawn as "NA"). ``errors``: draw ±err bars; ``value_format``: write each height above its bar."""
    width = 0.8 / max(len(labels), 1)
    x = np.arange(len(classes), dtype=np.float64)
    colors = [f"C{i % 10}" for i in range(len(labels))]
    for j, label in enumerate(labels):
        offs = x - 0.4 + width * (j + 0.5)
        h = np.array([values[(c, label)][0] if values.get((c, label)) else math.nan for c in classes])
        e = np.array([values[(c, label)][1] if values.get((c, label)) else 0.0 for c in classes])
        ax.bar(offs, np.nan_to_num(h, nan=0.0), width, color=colors[j], label=label,
               yerr=np.where(np.isfinite(h), e, 0.0) if errors else None, capsize=2 if errors else 0)
        for xo, hv in zip(offs, h):
            if not np.isfinite(hv):
                ax.text(xo, 0.0, "NA", ha="center", va="bottom", fontsize=7)
            elif value_format:
                ax.text(xo, hv, format(hv, value_format), ha="center", va="bottom", fontsize=7)
    ax.set_xticks(x)
    ax.set_xticklabels(classes, rotation=20, ha="right")
    ax.set_ylabel(ylabel)
    ax.grid(axis="y", alpha=0.3)


def bench_summary_figure(rows: Iterable[Dict[str, Any]], title: Optional[str] = None) -> Any:
    """A two-panel figure of benchmark rows: success rate [%] and EE path length [m] per class and label.

    Args:
        rows: benchmark rows (:func:`gfcs.results.bench_row`, or read back with
            :func:`gfcs.results.read_rows`).
        title: figure title (default: the number of problems and classes).

    Returns:
        A ``matplotlib.figure.Figure`` (Agg canvas, see :func:`new_figure`). The EE length bars
        are mean ± std over the successful problems of a (class, label); "NA" marks groups with none.

    Raises:
        ValueError: no rows.
    """
    rows = list(rows)
    if not rows:
        raise InvalidValueError("bench_summary_figure: no benchmark rows")
    summary = summarize(rows)
    classes = list(summary)
    labels: List[str] = []
    for by_label in summary.values():
        labels.extend(lab for lab in by_label if lab not in labels)
    success = {(c, lab): (e["success"], 0.0) for c, by in summary.items() for lab, e in by.items()}
    length = {(c, lab): e["ee_length"] for c, by in summary.items() for lab, e in by.items()}
    counts = {(c, lab): e["n"] for c, by in summary.items() for lab, e in by.items()}

    fig = new_figure((max(6.0, 1.4 * len(classes) + 2.5), 7.0))
    ax_s, ax_l = fig.subplots(2, 1, sharex=True)
    _grouped_bars(ax_s, classes, labels, success, "success [%]", errors=False, value_format=".0f")
    ax_s.set_ylim(0.0, 112.0)
    _grouped_bars(ax_l, classes, labels, length, "EE path length [m]\n(mean ± std, successful)", errors=True)
    ax_s.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), fontsize=8, ncol=min(len(labels), 5),
                frameon=False)
    n_problems = len({str(r.get("problem")) for r in rows})
    n_min = min(counts.values())
    n_max = max(counts.values())
    n_text = f"{n_min}" if n_min == n_max else f"{n_min}-{n_max}"
    fig.suptitle(title or f"{n_problems} problems, {len(classes)} classes ({n_text} per class and method)")
    fig.tight_layout()
    return fig


def save_png(fig: Any, out: PathLike, dpi: int = 120) -> Path:
    """Save ``fig`` as a PNG at ``out`` (parent folders created) and close it."""
    import matplotlib.pyplot as plt

    target = Path(out)
    target.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(target, dpi=dpi, format="png")
    plt.close(fig)
    return target


def save_bench_summary(rows: Iterable[Dict[str, Any]], out: PathLike, title: Optional[str] = None,
                       dpi: int = 120) -> Path:
    """Draw :func:`bench_summary_figure` and save it as a PNG at ``out`` (parent folders created)."""
    return save_png(bench_summary_figure(rows, title), out, dpi)


def plot_bench_file(jsonl: PathLike, out: PathLike, title: Optional[str] = None) -> Path:
    """The summary figure of a ``gfcs bench --json`` row file, saved as a PNG at ``out``."""
    rows = read_rows(Path(jsonl).read_text().splitlines())
    return save_bench_summary(rows, out, title)


def training_figure(history: Sequence[Dict[str, Any]], title: Optional[str] = None) -> Any:
    """A three-panel figure of a ``gfcs train`` history (events ``solve``, ``train``, ``validate``).

    Panels: the best cost [s] of every solve against the solve number, with the trainings as vertical
    lines; the mean InfoNCE loss (eq. 9) of every epoch, the trainings one after the other; the validation
    score [s] (mean first-batch cost on the held-out problems) after every training, with the uniform
    sampler's as a dashed line and the best training marked (this panel says "no validation" when the
    run had no held-out problems).

    Raises:
        ValueError: no ``solve`` event in ``history``.
    """
    solves = [h for h in history if h.get("event") == "solve"]
    if not solves:
        raise InvalidValueError("training_figure: the history has no solve events")
    trains = [h for h in history if h.get("event") == "train"]
    checks = [h for h in history if h.get("event") == "validate"]
    from matplotlib.ticker import MaxNLocator

    fig = new_figure((8.0, 8.0))
    ax_c, ax_l, ax_v = fig.subplots(3, 1)
    steps = np.array([h["step"] + 1 for h in solves], dtype=np.float64)
    ax_c.plot(steps, [h["best_cost"] for h in solves], ".", ms=3, color="C0")
    for h in trains:
        ax_c.axvline(h["step"] + 1, color="0.7", lw=0.6)
    ax_c.set_xlabel("solve")
    ax_c.set_ylabel("best cost [s]")
    ax_c.set_yscale("log")  # a failed solve costs its penalty (eq. 8), far above the motion times
    start = 0
    for k, h in enumerate(trains):
        losses = np.asarray(h["losses"], dtype=np.float64)
        ax_l.plot(start + np.arange(1, len(losses) + 1), losses, color=f"C{k % 10}", lw=1.0)
        start += len(losses)
    ax_l.set_xlabel("epoch (trainings in turn)")
    ax_l.set_ylabel("InfoNCE loss")
    trained = [h for h in checks if h["trainings"] > 0]
    if trained:
        x = [h["trainings"] for h in trained]
        y = [h["mean_cost"] for h in trained]
        ax_v.plot(x, y, "o-", color="C1", label="learned")
        best = min(trained, key=lambda h: h["mean_cost"])
        ax_v.plot([best["trainings"]], [best["mean_cost"]], "*", ms=14, color="C3",
                  label=f"best (training {best['trainings']})")
        for h in checks:
            if h["trainings"] == 0:
                ax_v.axhline(h["mean_cost"], color="0.4", ls="--", lw=1.0, label="uniform")
        ax_v.legend(fontsize=8)
    else:
        ax_v.text(0.5, 0.5, "no validation (gfcs train --holdout)", ha="center", va="center",
                  transform=ax_v.transAxes)
    ax_v.set_xlabel("training")
    ax_v.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax_v.set_ylabel("validation cost [s]")
    for ax in (ax_c, ax_l, ax_v):
        ax.grid(alpha=0.3)
    fig.suptitle(title or f"gfcs train: {len(solves)} solves, {len(trains)} trainings")
    fig.tight_layout()
    return fig


def save_training_figure(history: Sequence[Dict[str, Any]], out: PathLike, title: Optional[str] = None,
                         dpi: int = 120) -> Path:
    """Draw :func:`training_figure` and save it as a PNG at ``out`` (parent folders created)."""
    return save_png(training_figure(history, title), out, dpi)


def plot_file(path: PathLike, out: PathLike, title: Optional[str] = None) -> Path:
    """PNG at ``out`` of a ``gfcs bench --json`` row file or of a ``gfcs train --history`` file (a JSON
    list of events), told apart by content."""
    text = Path(path).read_text()
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        data = None  # several JSON lines: benchmark rows
    if isinstance(data, list) and all(isinstance(h, dict) and "event" in h for h in data):
        return save_training_figure(data, out, title)
    return save_bench_summary(read_rows(text.splitlines()), out, title)


def _cmd_plot(args: argparse.Namespace) -> int:
    path = plot_file(args.rows, args.out, args.title)
    print(f"wrote {path}")
    return 0


def register_cli(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``gfcs plot RESULTS.jsonl --out FIG.png`` to ``subparsers``."""
    p = subparsers.add_parser(
        "plot", help="plot benchmark rows or a training history",
        description="Draw, as a PNG, the success rate and the end-effector path length per class and "
                    "method from the rows written by `gfcs bench --json`, or the solve costs, losses and "
                    "validation scores of a `gfcs train --history` file.",
    )
    p.add_argument("rows", metavar="FILE", help="benchmark rows (.jsonl) or training history (.json)")
    p.add_argument("--out", required=True, metavar="FIG.png", help="PNG to write")
    p.add_argument("--title", help="figure title")
    p.set_defaults(func=_cmd_plot)
    return p
