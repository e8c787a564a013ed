"""Running a benchmark: the problem suites of ``gfcs bench`` and the rows of each problem's solves.

:func:`load_problems` builds a suite (a MotionBenchMaker folder or generated problems), :func:`bench_problem`
solves one problem with each method and turns the solves into rows (:func:`gfcs.results.bench_row`), and
:func:`run_bench` runs a whole suite, one task per problem on an executor (:mod:`gfcs.executors`: in this
process or on a Ray cluster), writing the rows to a JSON-lines file as each problem finishes. Each problem
is solved with a seed derived from the run's seed and its name (:func:`problem_seed`), so its rows do not
depend on where or in which order it ran; ``resume`` keeps the problems an earlier run finished.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

from gfcs.baselines.ompl_planner import DEFAULT_PLANNER_TIME

if TYPE_CHECKING:
    from gfcs.executors import Executor

__all__ = ["load_mbm_suite", "load_problems", "bench_problem", "error_rows", "run_bench", "Suite", "BenchJob",
           "bench_task", "problem_seed", "resume_rows", "suite_problems"]


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


#: Result file names of the GFCS motions behind rows that the solve did not return start with this
#: (``gfcs-1b``, ``gfcs-<B>b``: :func:`bench_problem`); recordings show the returned motions only.
UNRETURNED = "gfcs-"


def bench_problem(problem: Any, methods: Sequence[str], batches: int, population: int, seed: int,
                  n_commands: int = 1, sampler: Any = None, fabric_config: Any = None,
                  threads: Optional[int] = None, settings: Any = None,
                  retry: bool = True, solve_options: Optional[Dict[str, Any]] = None,
                  planner_times: Sequence[float] = (DEFAULT_PLANNER_TIME,),
                  ) -> Tuple[List[Dict[str, Any]], Dict[str, Any]]:
    """Rows (:func:`gfcs.results.bench_row`) and results of the methods on one problem, one solve each.

    GFCS yields the paper's Table I rows from the solve's attempt records: "Ours (1 b)" (what its first
    attempt held after one batch, selected and judged as a one-batch solve would: the same seed gives the
    same first batch) and "Ours (B b)" (its first attempt after all B batches: a solve without retries);
    with ``retry`` and a preset that has retry policies a third row, "Ours (B b, retry)", is what the solve
    returned (time: every attempt). GF yields "GF". ``solve_options``: further keyword arguments of
    :func:`gfcs.planning.solve` for every method (e.g. ``preset``, ``time_limit``, ``mesh_margin``; GF
    ignores the GFCS-only ones such as ``length_slack``). A sampling-based method (``rrtconnect``, ``biest``,
    ``bitstar``: :func:`gfcs.baselines.plan_ompl`) plans once per time in ``planner_times`` [s], one row each
    (:func:`_baseline_rows`).

    Returns:
        The rows, and the results by the name of their result file (``<problem>.<name>.json``, which each
        row names under ``"result"``), so that a validator judges the motion behind every row: the
        solves' returned results under their method (a sampling-based method with several planner times:
        ``<method>-<time>s``), and the motions of GFCS rows that the solve did not return under
        ``gfcs-1b`` (the first batch) and ``gfcs-<B>b`` (the first attempt, when a retry followed it).
    """
    from gfcs import planning
    from gfcs.baselines import is_ompl_method
    from gfcs.cli import _no_retry
    from gfcs.results import bench_row

    options = {"settings": settings, **(solve_options or {})}
    retry_row = _retry_row(retry, options)
    rows: List[Dict[str, Any]] = []
    results: Dict[str, Any] = {}

    def add(row: Dict[str, Any], name: str, result: Any) -> None:
        rows.append({**row, "result": name})
        results[name] = result

    for method in methods:
        if is_ompl_method(method):
            for row, name, res in _baseline_rows(problem, method, seed, planner_times, fabric_config, options):
                add(row, name, res)
            continue
        gfcs_only = {"record_first_batch": batches > 1, **({} if retry else _no_retry())} if method == "gfcs" else {}
        res = planning.solve(problem, method=method, batches=batches, population=population, n_commands=n_commands,
                             seed=seed, sampler=sampler, fabric_config=fabric_config, threads=threads,
                             **gfcs_only, **options)
        if method == "gf":
            add(bench_row(problem.name, problem.cls, "GF", "gf", 0, seed, res.solve_time, res.cost, res.metrics,
                          res.wall_time), "gf", res)
            continue
        first = res.attempt_records[0]
        if batches > 1:
            one = first.first_batch
            add(bench_row(problem.name, problem.cls, "Ours (1 b)", "gfcs", 1, seed, one.solve_time, one.cost,
                          one.metrics, one.wall_time), f"{UNRETURNED}1b", one)
        whole = bench_row(problem.name, problem.cls, f"Ours ({batches} b)", "gfcs", batches, seed,
                          first.result.solve_time, first.result.cost, first.result.metrics, first.time)
        if len(res.attempt_records) == 1:  # the first attempt's motion is the one returned
            add(whole, "gfcs", res)
        else:
            add(whole, f"{UNRETURNED}{batches}b", first.result)
            results["gfcs"] = res  # the returned motion is kept whether or not a row shows it
        if retry_row:
            add(bench_row(problem.name, problem.cls, f"Ours ({batches} b, retry)", "gfcs", batches, seed,
                          res.solve_time, res.cost, res.metrics, res.wall_time), "gfcs", res)
    return rows, results


def _baseline_rows(problem: Any, method: str, seed: int, planner_times: Sequence[float], fabric_config: Any,
                   options: Dict[str, Any]) -> List[Tuple[Dict[str, Any], str, Any]]:
    """(row, result file name, result) of the sampling-based ``method`` on ``problem``, one per planner time,
    planned on the preset's first sphere model with its fabric margin, timed within the same limits
    (``options["finish"]``) and judged with the same mesh margin as GFCS. Labels:
    :func:`gfcs.baselines.planner_label`; file names: ``method``, with several times ``<method>-<time>s``."""
    from gfcs import metrics, planning
    from gfcs.baselines import plan_ompl, planner_label
    from gfcs.results import bench_row

    preset = planning.get_preset(options.get("preset", "default"))
    several = len(planner_times) > 1
    out = []
    for t in planner_times:
        res = plan_ompl(problem, method, t, seed, thin_spheres=preset.thin_spheres,
                        element_spheres=preset.element_spheres, fabric_config=fabric_config,
                        finish=options.get("finish"),
                        mesh_margin=options.get("mesh_margin", metrics.DEFAULT_MESH_MARGIN))
        row = bench_row(problem.name, problem.cls, planner_label(method, t, with_time=several), method, 0, seed,
                        res.solve_time, res.cost, res.metrics, res.wall_time)
        out.append((row, f"{method}-{t:g}s" if several else method, res))
    return out


def error_rows(problem: Any, methods: Sequence[str], batches: int, seed: int, message: str,
               planner_times: Sequence[float] = (DEFAULT_PLANNER_TIME,),
               retry_row: bool = False) -> List[Dict[str, Any]]:
    """The rows of a problem whose solve raised ``message``: one failed row per row :func:`bench_problem`
    would have written (GFCS: "Ours (1 b)" when ``batches`` > 1, "Ours (B b)", and "Ours (B b, retry)" with
    ``retry_row``; a sampling-based method one per planner time), every measure NaN, with the error under
    ``"error"``."""
    from gfcs.baselines import is_ompl_method, planner_label
    from gfcs.results import bench_row

    metrics: Dict[str, Any] = {k: math.nan for k in ("ee_length", "cspace_length", "ee_ldj", "cspace_ldj",
                                                      "min_clearance", "final_error")}
    metrics["success"] = False
    rows = []
    for method in methods:
        if is_ompl_method(method):
            labels = [(planner_label(method, t, len(planner_times) > 1), 0) for t in planner_times]
        elif method == "gf":
            labels = [("GF", 0)]
        else:
            labels = ([("Ours (1 b)", 1)] if batches > 1 else []) + [(f"Ours ({batches} b)", batches)]
            labels += [(f"Ours ({batches} b, retry)", batches)] if retry_row else []
        for label, n in labels:
            row = bench_row(problem.name, problem.cls, label, method, n, seed, math.nan, math.inf, metrics,
                            math.nan)
            row["error"] = message
            rows.append(row)
    return rows


@dataclass(frozen=True)
class Suite:
    """A problem suite as a recipe that pickles: ``build(*args)`` returns the problems. Ray workers get the
    recipe instead of the problems (a :class:`gfcs.Robot`, a scene and a mesh checker do not pickle) and
    build the suite once per worker process (:func:`suite_problems`). ``build`` must be a function
    importable on the workers (a module-level function) and ``args`` must pickle."""

    build: Callable[..., Sequence[Any]]
    args: Tuple[Any, ...] = ()


#: Suites built in this process, by the SHA-256 of the pickled recipe.
_BUILT: Dict[bytes, Dict[str, Any]] = {}


def _key(suite: Suite) -> bytes:
    import pickle

    return hashlib.sha256(pickle.dumps(suite)).digest()


def suite_problems(suite: Suite, built: Optional[Sequence[Any]] = None, quiet: bool = False) -> Dict[str, Any]:
    """The problems of ``suite`` by name, built on the first call in this process and cached (a Ray worker
    builds a suite once). ``built``: the problems, already built from this recipe (the driver's copy, which
    is then not built again). ``quiet``: drop what building prints on stderr (problems left out, sphere
    notes; a worker's copy of what the driver already printed)."""
    import io

    key = _key(suite)
    if built is not None:
        _BUILT[key] = _by_name(built)
    if key not in _BUILT:
        with contextlib.redirect_stderr(io.StringIO()) if quiet else contextlib.nullcontext():
            _BUILT[key] = _by_name(suite.build(*suite.args))
    return _BUILT[key]


def _by_name(problems: Sequence[Any]) -> Dict[str, Any]:
    """``problems`` by name; names must be unique (rows and resumed runs name problems)."""
    from gfcs.errors import InvalidValueError

    out: Dict[str, Any] = {}
    for p in problems:
        if p.name in out:
            raise InvalidValueError(f"problems: two problems are named {p.name!r}; a benchmark needs unique names")
        out[p.name] = p
    return out


def _retry_row(retry: bool, solve_options: Optional[Dict[str, Any]]) -> bool:
    """Whether :func:`bench_problem` writes a GFCS "retry" row: with ``retry`` and a preset (of
    ``solve_options``, default "default") that has retry policies."""
    from gfcs import planning

    preset = (solve_options or {}).get("preset", "default")
    return bool(retry) and bool(planning.get_preset(preset).policies())


def problem_seed(seed: int, name: str) -> int:
    """The seed of problem ``name`` in a run seeded ``seed``: a 31-bit integer from numpy's
    ``SeedSequence`` over ``seed`` and the SHA-256 of the name, so it depends on nothing but the two (not on
    the order of the problems, the process or the worker that solves it)."""
    import numpy as np

    digest = hashlib.sha256(name.encode("utf-8")).digest()
    words = [int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4)]
    return int(np.random.SeedSequence([int(seed), *words]).generate_state(1)[0] >> 1)


@dataclass(frozen=True)
class BenchJob:
    """What every problem's task of a run shares (sent to a Ray cluster once): where the problems come
    from (``problems``: by name, for a local run; ``suite``: a recipe, for workers) and the keyword
    arguments of :func:`bench_problem` besides the problem and its seed. ``keep_results``: return the
    results too (for recordings and result files); from a worker, as their JSON holds them."""

    methods: Tuple[str, ...]
    kwargs: Dict[str, Any]
    problems: Optional[Dict[str, Any]] = None
    suite: Optional[Suite] = None
    keep_results: bool = False

    def problem(self, name: str) -> Any:
        return (self.problems if self.problems is not None else suite_problems(self.suite, quiet=True))[name]

    def error_rows(self, problem: Any, seed: int, message: str) -> List[Dict[str, Any]]:
        """:func:`error_rows` of ``problem`` under this run's methods and options."""
        return error_rows(problem, self.methods, self.kwargs["batches"], seed, message,
                          self.kwargs.get("planner_times", (DEFAULT_PLANNER_TIME,)),
                          _retry_row(self.kwargs.get("retry", True), self.kwargs.get("solve_options")))


def bench_task(job: BenchJob, name: str, seed: int) -> Tuple[List[Dict[str, Any]], Dict[str, Any]]:
    """One problem's task: :func:`bench_problem` (or :func:`error_rows` when the solve raised a user error,
    so that one bad problem does not end the bench)."""
    from gfcs.cli import _message, _user_error_types

    problem = job.problem(name)
    try:
        rows, results = bench_problem(problem, job.methods, seed=seed, **job.kwargs)
    except _user_error_types() as e:
        message = f"{type(e).__name__}: {_message(e)}"
        print(f"gfcs: bench: {problem.name}: {message}", file=sys.stderr)
        return job.error_rows(problem, seed, message), {}
    if not job.keep_results:
        return rows, {}
    if job.problems is not None:
        return rows, results
    from gfcs.results import SolveResult

    # what a result file holds (its JSON), without the in-memory objects that do not pickle (robot, attempts)
    return rows, {name: SolveResult.from_json(r.to_json()) for name, r in results.items()}


def resume_rows(jsonl: str, methods: Sequence[str]) -> Tuple[List[Dict[str, Any]], set]:
    """(rows kept, names of finished problems) of an earlier run's ``jsonl``: a problem is finished when it
    has a row of every method in ``methods``. The file is rewritten with only the kept rows (the finished
    problems' and the left-out ones), dropping an unfinished problem's rows and a line cut short by an
    interrupted write, so that appending the remaining problems leaves every problem in it once."""
    from gfcs.results import read_rows

    if not Path(jsonl).exists():
        return [], set()
    lines = Path(jsonl).read_text().splitlines()
    rows = []
    for number, line in enumerate(lines):
        try:
            rows.extend(read_rows([line]))
        except ValueError:
            if number < len(lines) - 1:  # only the last line may be cut short
                raise
    seen: Dict[str, set] = {}
    for r in rows:
        if "left_out" not in r:
            seen.setdefault(r["problem"], set()).add(r.get("method"))
    finished = {name for name, got in seen.items() if set(methods) <= got}
    left_out = {r["problem"]: r for r in rows if "left_out" in r}  # one row each
    kept = list(left_out.values()) + [r for r in rows if "left_out" not in r and r["problem"] in finished]
    tmp = Path(str(jsonl) + ".tmp")
    tmp.write_text("".join(_line(r) for r in kept))
    os.replace(tmp, jsonl)
    return kept, finished


def _line(row: Dict[str, Any]) -> str:
    from gfcs.results import _enc

    return json.dumps(_enc(row), allow_nan=False) + "\n"


class _Progress:
    """The progress bar of a run: problems done (of the whole suite, resumed ones included), the success so
    far of each method (its last row of each problem: the final result), and tqdm's rate and ETA."""

    def __init__(self, total: int, done_rows: List[Dict[str, Any]], methods: Sequence[str], enabled: bool,
                 desc: str) -> None:
        from tqdm.auto import tqdm

        self.methods = list(methods)
        self.solved = {m: 0 for m in self.methods}
        self.tried = {m: 0 for m in self.methods}
        by_problem: Dict[str, List[Dict[str, Any]]] = {}
        for r in done_rows:
            if "left_out" not in r:
                by_problem.setdefault(r["problem"], []).append(r)
        for problem_rows in by_problem.values():
            self.count(problem_rows)
        self.bar = tqdm(total=total, initial=len(by_problem), desc=desc, unit="problem", disable=not enabled)
        self.bar.set_postfix_str(self.text())

    def count(self, rows: List[Dict[str, Any]]) -> None:
        last = {r.get("method"): r for r in rows}
        for m in self.methods:
            if m in last:
                self.tried[m] += 1
                self.solved[m] += bool(last[m].get("success"))

    def text(self) -> str:
        return ", ".join(f"{m} {self.solved[m]}/{self.tried[m]} solved" for m in self.methods)

    def update(self, rows: List[Dict[str, Any]]) -> None:
        self.count(rows)
        self.bar.set_postfix_str(self.text(), refresh=False)
        self.bar.update(1)

    def close(self) -> None:
        self.bar.close()


def run_bench(problems: Union[Sequence[Any], Suite], methods: Sequence[str], batches: int = 5,
              population: int = 32, seed: int = 0, n_commands: int = 1, sampler: Any = None,
              fabric_config: Any = None, threads: Optional[int] = None, settings: Any = None,
              jsonl: Optional[str] = None, rrd_dir: Optional[str] = None, progress: bool = True,
              retry: bool = True, solve_options: Optional[Dict[str, Any]] = None,
              results_dir: Optional[str] = None, left_out: Sequence[Tuple[str, str]] = (),
              executor: Optional[Executor] = None, resume: bool = False,
              seeding: str = "problem", planner_times: Sequence[float] = (DEFAULT_PLANNER_TIME,),
              ) -> List[Dict[str, Any]]:
    """Benchmark ``methods`` on ``problems`` (rows: :func:`bench_problem`), one task per problem on
    ``executor`` (default :class:`gfcs.executors.LocalExecutor`; a Ray executor needs ``problems`` as a
    :class:`Suite`). Rows go to ``jsonl`` as each problem finishes; with ``resume`` the problems already in
    ``jsonl`` are kept and skipped (:func:`resume_rows`), else the file is started afresh. Each problem is
    solved with :func:`problem_seed` (``seed``, its name) (``seeding="run"``: with ``seed`` itself), so its
    rows do not depend on the executor, the order or the worker. With ``results_dir``, the result behind
    every row (with its trajectory, as ``gfcs solve --json`` writes it) goes to
    ``<results_dir>/<class>_<NNNN>.<name>.json``, ``name`` being the row's ``result``
    (:func:`bench_problem`). ``left_out``: (name, reason) of the suite's problems
    that were not run (:func:`load_mbm_suite`); each becomes a :func:`gfcs.results.left_out_row`.
    ``planner_times``: the planning times [s] of the sampling-based methods (:func:`bench_problem`).

    Returns:
        All rows: the left-out ones, then each problem's in the order they finished (resumed ones first).
    """
    from gfcs.cli import _viz
    from gfcs.errors import InvalidValueError
    from gfcs.executors import LocalExecutor, RayExecutor, describe
    from gfcs.results import left_out_row

    if seeding not in ("problem", "run"):
        raise InvalidValueError(f"seeding: expected 'problem' or 'run', got {seeding!r}")
    executor = executor or LocalExecutor(threads)
    suite = problems if isinstance(problems, Suite) else None
    if isinstance(executor, RayExecutor) and suite is None:
        raise InvalidValueError("problems: a Ray executor needs a gfcs.bench.Suite (a recipe the workers build "
                                "the problems from), not Problem objects (they hold a Robot, which does not pickle)")
    by_name = suite_problems(suite) if suite is not None else _by_name(problems)
    if rrd_dir:
        _viz()  # fail before the first problem when the extra is missing
    for folder in (rrd_dir, results_dir):
        if folder:
            Path(folder).mkdir(parents=True, exist_ok=True)
    rows, finished = resume_rows(jsonl, methods) if (resume and jsonl) else ([], set())
    known = {r["problem"] for r in rows if "left_out" in r}
    new_left = [left_out_row(name, reason) for name, reason in left_out if name not in known]
    kwargs = dict(batches=batches, population=population, n_commands=n_commands, sampler=sampler,
                  fabric_config=fabric_config, threads=threads or executor.threads, settings=settings,
                  retry=retry, solve_options=solve_options, planner_times=tuple(planner_times))
    job = BenchJob(tuple(methods), kwargs, None if isinstance(executor, RayExecutor) else by_name, suite,
                   keep_results=bool(rrd_dir or results_dir))
    seeds = {name: problem_seed(seed, name) if seeding == "problem" else seed
             for name in by_name if name not in finished}
    tasks = [(name, (name, s)) for name, s in seeds.items()]
    bar = _Progress(len(by_name), rows, methods, progress, f"bench [{describe(executor)}]")
    rows = new_left + rows
    with (open(jsonl, "a" if resume else "w") if jsonl else contextlib.nullcontext()) as out:
        _write(out, new_left)
        try:
            for done in executor.run(bench_task, job, tasks):
                new, results = _outcome(done, by_name[done.key], job, seeds[done.key])
                rows.extend(new)
                _write(out, new)
                _keep(by_name[done.key], results, rrd_dir, results_dir)
                bar.update(new)
        finally:
            bar.close()
    return rows


def _outcome(done: Any, problem: Any, job: BenchJob, seed: int) -> Tuple[List[Dict[str, Any]], Dict[str, Any]]:
    """The rows and results of a finished task; error rows when the executor could not complete it."""
    if done.error is None:
        return done.value
    print(f"gfcs: bench: {problem.name}: {done.error}", file=sys.stderr)
    return job.error_rows(problem, seed, done.error), {}


def _write(out: Any, rows: List[Dict[str, Any]]) -> None:
    """Append ``rows`` to the open JSONL ``out`` (None: nothing) and flush, so a finished problem is on disk."""
    if out is not None and rows:
        out.write("".join(_line(r) for r in rows))
        out.flush()


def _keep(problem: Any, results: Dict[str, Any], rrd_dir: Optional[str], results_dir: Optional[str]) -> None:
    """The recording (the returned results) and the result files (every result, by its file name: see
    :func:`bench_problem`) of one problem (when asked for)."""
    from gfcs.cli import _record

    stem = problem.name.replace("/", "_")
    if rrd_dir:
        returned = [r for name, r in results.items() if not name.startswith(UNRETURNED)]
        _record(problem, returned, str(Path(rrd_dir) / (stem + ".rrd")))
    if results_dir:
        for name, res in results.items():
            (Path(results_dir) / f"{stem}.{name}.json").write_text(res.to_json())
