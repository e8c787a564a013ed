"""First-batch comparison of two samplers (GFCS Sec. V, "The Effect of Learning", Table II).

Table II compares the motion found after the *first* CMA-ES batch when that batch is drawn uniformly
("No learning") against drawn from the learned EBM ("Learning"). :func:`evaluate_first_batch` runs both
on the same problems with the same per-problem seed (paired comparison) and returns one summary row per
sampler with the Table II columns (% success; mean ± std over the successful problems of EE length,
C-space length, EE-LDJ, C-space-LDJ; plus the optimisation time), built with
:func:`gfcs.results.bench_row` / :func:`gfcs.results.summarize`. No torch needed here: any object with
the sampler protocol works.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

from ._validate import ConfigError, check_positive_int

__all__ = ["evaluate_first_batch", "format_first_batch_table", "TABLE2_COLUMNS"]

#: Columns of GFCS Table II: (row key, title).
TABLE2_COLUMNS: Tuple[Tuple[str, str], ...] = (
    ("ee_length", "EE len"),
    ("cspace_length", "C-space len"),
    ("ee_ldj", "EE-LDJ"),
    ("cspace_ldj", "C-space-LDJ"),
    ("time", "Times (s)"),
)

_GROUP = "first batch"


def evaluate_first_batch(
    problems: Sequence[Any],
    sampler_a: Any,
    sampler_b: Any,
    labels: Tuple[str, str] = ("No learning", "Learning"),
    population: int = 32,
    n_commands: int = 1,
    seed: int = 0,
    solve_fn: Optional[Callable[..., Any]] = None,
    progress: bool = False,
    per_problem: Optional[List[Dict[str, Any]]] = None,
    preset: str = "default",
    results_dir: Optional[str] = None,
) -> List[Dict[str, Any]]:
    """Solve every problem with one CMA-ES batch warm-started by each sampler; one row per sampler.

    Args:
        problems: :class:`gfcs.problems.Problem` list.
        sampler_a, sampler_b: sampler-protocol objects (``None``: the preset's,
            :class:`~gfcs.planning.ApproachSampler` for ``default``), e.g. ``UniformSampler()`` (the paper's "No
            learning") and ``EBMSampler("model.pt")``.
        labels: row labels for ``sampler_a`` and ``sampler_b``.
        population: candidates in the batch; n_commands: free commands.
        seed: problem ``i`` is solved with seed ``seed + i`` by both samplers.
        solve_fn: ``solve_fn(problem, batches=1, population=…, n_commands=…, seed=…, sampler=…)`` returning
            a :class:`gfcs.results.SolveResult`; default :func:`gfcs.planning.solve` with no retry policy
            (``policies=[]``) and ``preset``, so that each row is one attempt of one batch.
        preset: the planner preset of the default ``solve_fn`` (``"default"`` or ``"paper"``).
        progress: tqdm bar over the problems.
        per_problem: if a list is given, the per-problem benchmark rows are appended to it.
        results_dir: if given, every result is written there as ``<class>_<NNNN>.<result>.json`` (the names
            of ``gfcs bench --results-dir``, which ``tools/check_trajectories.py`` judges), ``result`` being
            the row's own key: the label in lower case, words joined by ``-``.

    Returns:
        ``[{"label", "n", "success" (percent), "ee_length": (mean, std) | None, "cspace_length",
        "ee_ldj", "cspace_ldj", "time"}, …]``, first ``sampler_a`` then ``sampler_b``. Lengths in m (EE)
        and rad (C-space), LDJ dimensionless, time in s.
    """
    from tqdm.auto import tqdm

    from gfcs.results import bench_row, summarize

    if len(problems) == 0:
        raise ConfigError("evaluate_first_batch: no problems given")
    if len(labels) != 2 or labels[0] == labels[1]:
        raise ConfigError(f"labels: expected two distinct labels, got {labels!r}")
    population = check_positive_int("population", population)
    n_commands = check_positive_int("n_commands", n_commands)
    if solve_fn is None:
        from functools import partial

        from gfcs.planning import solve

        solve_fn = partial(solve, policies=[], preset=preset)
    rows: List[Dict[str, Any]] = []
    for i, problem in enumerate(tqdm(problems, disable=not progress, desc="first batch", unit="problem")):
        for label, sampler in zip(labels, (sampler_a, sampler_b)):
            res = solve_fn(problem, batches=1, population=population, n_commands=n_commands,
                           seed=seed + i, sampler=sampler)
            name = str(getattr(problem, "name", i))
            row = bench_row(name, _GROUP, label, "gfcs", 1, seed + i, float(res.solve_time), float(res.cost),
                            res.metrics, float(res.wall_time))
            if results_dir is not None:
                row["result"] = "-".join(label.lower().split())
                Path(results_dir, f"{name.replace('/', '_')}.{row['result']}.json").write_text(res.to_json())
            rows.append(row)
    if per_problem is not None:
        per_problem.extend(rows)
    summary = summarize(rows)[_GROUP]
    return [{"label": label, **{k: summary[label][k] for k in ("n", "success")},
             **{k: summary[label][k] for k, _ in TABLE2_COLUMNS}} for label in labels]


def format_first_batch_table(rows: Sequence[Dict[str, Any]], markdown: bool = True) -> str:
    """Rows of :func:`evaluate_first_batch` as a table in the layout of GFCS Table II."""
    from gfcs.results import format_table

    summary = {"First batch: uniform vs learned sampler (GFCS Table II)": {
        r["label"]: {"n": r["n"], "success": r["success"], **{k: r.get(k) for k, _ in TABLE2_COLUMNS}}
        for r in rows}}
    return format_table(summary, markdown=markdown)
