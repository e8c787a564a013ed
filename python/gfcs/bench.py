"""Running a benchmark: the problem suites of ``gfcs bench`` and the rows of each problem's solves.

:func:`load_problems` builds a suite (a MotionBenchMaker folder or generated problems), :func:`bench_problem`
solves one problem with each method and turns the solves into rows (:func:`gfcs.results.bench_row`), and
:func:`run_bench` runs a whole suite, writing the rows to a JSON-lines file as they are produced.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

__all__ = ["load_mbm_suite", "load_problems", "bench_problem", "error_rows", "run_bench"]


def load_mbm_suite(folder: str, classes: Optional[Sequence[str]], limit: Optional[int], robot: Any,
                   skip: int = 0, left_out: Optional[List[Tuple[str, str]]] = None) -> List[Any]:
    """:func:`gfcs.problems.load_mbm_dir`, leaving out (and listing on stderr) the problems that cannot be
    loaded (a malformed file) or whose start or goal lies outside the robot's joint limits: one such
    problem does not stop a whole suite.

    Args:
        left_out: when a list, (problem name, reason) of each problem left out is appended to it.
    """
    from gfcs import problems

    invalid: List[Tuple[str, str]] = []
    suite = problems.load_mbm_dir(folder, classes=classes, limit=limit, robot=robot, skip=skip, invalid=invalid)
    if invalid:
        print(f"gfcs: left out {len(invalid)} problem(s) not valid for this robot or not loadable:", file=sys.stderr)
        for _, message in invalid:
            print(f"  {message}", file=sys.stderr)
    if left_out is not None:
        left_out.extend(invalid)
    return suite


def load_problems(args: argparse.Namespace, robot: Any,
                  left_out: Optional[List[Tuple[str, str]]] = None) -> List[Any]:
    """The suite of ``gfcs bench``: a MotionBenchMaker folder, or generated problems (``left_out``: see
    :func:`load_mbm_suite`; a generated suite leaves none out)."""
    from gfcs import generators, problems

    if args.problems:
        return load_mbm_suite(args.problems, args.classes, args.limit, robot, args.skip, left_out)
    classes = args.classes or list(problems.CLASSES)
    n = args.limit if args.limit is not None else 10
    suite: List[Any] = []
    for c in classes:
        suite.extend(generators.generate(c, n, seed=args.problem_seed, robot=robot))
    return suite


def bench_problem(problem: Any, methods: Sequence[str], batches: int, population: int, seed: int,
                  n_commands: int = 1, sampler: Any = None, fabric_config: Any = None,
                  threads: Optional[int] = None, settings: Any = None,
                  retry: bool = True, solve_options: Optional[Dict[str, Any]] = None,
                  ) -> Tuple[List[Dict[str, Any]], List[Any]]:
    """Rows (:func:`gfcs.results.bench_row`) and results of the methods on one problem, one solve each.

    GFCS yields the paper's Table I rows from the solve's attempt records: "Ours (1 b)" (what its first
    attempt held after one batch, selected and judged as a one-batch solve would: the same seed gives the
    same first batch) and "Ours (B b)" (its first attempt after all B batches: a solve without retries);
    with ``retry`` and a preset that has retry policies a third row, "Ours (B b, retry)", is what the solve
    returned (time: every attempt). GF yields "GF". ``solve_options``: further keyword arguments of
    :func:`gfcs.planning.solve` for every method (e.g. ``preset``, ``time_limit``, ``mesh_margin``; GF
    ignores the GFCS-only ones such as ``length_slack``).
    """
    from gfcs import planning
    from gfcs.cli import _no_retry
    from gfcs.results import bench_row

    options = {"settings": settings, **(solve_options or {})}
    has_policies = bool(planning.get_preset(options.get("preset", "default")).policies())
    rows: List[Dict[str, Any]] = []
    results: List[Any] = []
    for method in methods:
        gfcs_only = {"record_first_batch": batches > 1, **({} if retry else _no_retry())} if method == "gfcs" else {}
        res = planning.solve(problem, method=method, batches=batches, population=population, n_commands=n_commands,
                             seed=seed, sampler=sampler, fabric_config=fabric_config, threads=threads,
                             **gfcs_only, **options)
        results.append(res)
        if method == "gf":
            rows.append(bench_row(problem.name, problem.cls, "GF", "gf", 0, seed, res.solve_time,
                                  res.cost, res.metrics, res.wall_time))
            continue
        first = res.attempt_records[0]
        if batches > 1:
            one = first.first_batch
            rows.append(bench_row(problem.name, problem.cls, "Ours (1 b)", "gfcs", 1, seed,
                                  one.solve_time, one.cost, one.metrics, one.wall_time))
        rows.append(bench_row(problem.name, problem.cls, f"Ours ({batches} b)", "gfcs", batches, seed,
                              first.result.solve_time, first.result.cost, first.result.metrics, first.time))
        if retry and has_policies:
            rows.append(bench_row(problem.name, problem.cls, f"Ours ({batches} b, retry)", "gfcs", batches,
                                  seed, res.solve_time, res.cost, res.metrics, res.wall_time))
    return rows, results


def error_rows(problem: Any, methods: Sequence[str], batches: int, seed: int, message: str) -> List[Dict[str, Any]]:
    """The rows of a problem whose solve raised ``message``: one failed row per method (the labels of
    :func:`bench_problem`'s final rows), every measure NaN, with the error under ``"error"``."""
    from gfcs.results import bench_row

    metrics: Dict[str, Any] = {k: math.nan for k in ("ee_length", "cspace_length", "ee_ldj", "cspace_ldj",
                                                      "min_clearance", "final_error")}
    metrics["success"] = False
    rows = []
    for method in methods:
        label, n = ("GF", 0) if method == "gf" else (f"Ours ({batches} b)", batches)
        row = bench_row(problem.name, problem.cls, label, method, n, seed, math.nan, math.inf, metrics, math.nan)
        row["error"] = message
        rows.append(row)
    return rows


def run_bench(problems: Sequence[Any], methods: Sequence[str], batches: int = 5, population: int = 32,
              seed: int = 0, n_commands: int = 1, sampler: Any = None, fabric_config: Any = None,
              threads: Optional[int] = None, settings: Any = None, jsonl: Optional[str] = None,
              rrd_dir: Optional[str] = None, progress: bool = True, retry: bool = True,
              solve_options: Optional[Dict[str, Any]] = None,
              results_dir: Optional[str] = None,
              left_out: Sequence[Tuple[str, str]] = ()) -> List[Dict[str, Any]]:
    """Benchmark ``methods`` on ``problems``; rows are appended to ``jsonl`` as they are produced (rows:
    :func:`bench_problem`). With ``results_dir``, the returned result of every method on every problem
    (with its trajectory, as ``gfcs solve --json`` writes it) goes to ``<results_dir>/<class>_<NNNN>.<method>.json``,
    for validators of your own (e.g. ``tools/check_trajectories.py``). ``left_out``: (name, reason) of the
    suite's problems that were not run (:func:`load_mbm_suite`); each becomes a
    :func:`gfcs.results.left_out_row`, written first.

    Returns:
        All rows, the left-out ones first (see :mod:`gfcs.results` for the row format).
    """
    from tqdm.auto import tqdm

    from gfcs.cli import _message, _record, _user_error_types, _viz
    from gfcs.results import _enc, left_out_row

    rows: List[Dict[str, Any]] = [left_out_row(name, reason) for name, reason in left_out]
    if rrd_dir:
        _viz()  # fail before the first problem when the extra is missing
    for folder in (rrd_dir, results_dir):
        if folder:
            Path(folder).mkdir(parents=True, exist_ok=True)
    out = open(jsonl, "w") if jsonl else None

    def write(new: List[Dict[str, Any]]) -> None:
        if out is not None:
            for r in new:
                out.write(json.dumps(_enc(r), allow_nan=False) + "\n")
            out.flush()

    try:
        write(rows)
        bar = tqdm(problems, desc="bench", unit="problem", disable=not progress)
        for problem in bar:
            bar.set_postfix_str(problem.name)
            try:
                new, results = bench_problem(problem, methods, batches, population, seed, n_commands, sampler,
                                             fabric_config, threads, settings, retry, solve_options)
            except _user_error_types() as e:  # one bad problem does not end the bench
                message = f"{type(e).__name__}: {_message(e)}"
                print(f"gfcs: bench: {problem.name}: {message}", file=sys.stderr)
                new, results = error_rows(problem, methods, batches, seed, message), []
            rows.extend(new)
            write(new)
            stem = problem.name.replace("/", "_")
            if rrd_dir:
                _record(problem, results, str(Path(rrd_dir) / (stem + ".rrd")))
            if results_dir:
                for res in results:
                    (Path(results_dir) / f"{stem}.{res.method}.json").write_text(res.to_json())
    finally:
        if out is not None:
            out.close()
    return rows
