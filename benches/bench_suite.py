#!/usr/bin/env python
"""Benchmark suite: GFCS and the GF baseline on MotionBenchMaker problems (GFCS Sec. V, Table I).

Runs the same code as ``gfcs bench`` over ``<shared>/mbm`` (``$GFCS_SHARED`` or ``<repo>/../shared``) when
it exists, else over a generated suite (``--generated``, or forced with ``--generated``), and writes

* ``<out>/results.jsonl``: one row per problem and method label (format: :mod:`gfcs.results`);
* ``<out>/table.md``: per-class tables in the layout of GFCS Table I (for BENCHMARKS.md), headed by the
  command, machine and settings used.

Examples::

    python benches/bench_suite.py --limit 10                      # 10 problems per MBM class
    python benches/bench_suite.py --generated --limit 5 --out benches/results/generated
    python benches/bench_suite.py --classes bookshelf_small --methods gfcs gf --batches 5
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path
from types import SimpleNamespace
from typing import List, Optional, Sequence


def parse_args(argv: Optional[Sequence[str]] = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    p.add_argument("--problems", metavar="DIR", help="MotionBenchMaker folder (default: <shared>/mbm)")
    p.add_argument("--generated", action="store_true", help="use generated problems instead of MBM files")
    p.add_argument("--classes", nargs="+", metavar="CLASS", help="only these classes")
    p.add_argument("--limit", type=int, default=None, help="problems per class (generated default: 10)")
    p.add_argument("--problem-seed", type=int, default=0, help="seed of the generated suite")
    p.add_argument("--methods", nargs="+", choices=["gfcs", "gf"], default=["gf", "gfcs"])
    p.add_argument("--batches", type=int, default=5)
    p.add_argument("--population", type=int, default=32)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--config", metavar="FILE", help="fabric configuration file")
    p.add_argument("--robot", choices=["auto", "panda", "mbm"], default="auto",
                   help="shipped Panda, or the MotionBenchMaker Panda from <shared> (auto, the default: the "
                        "MBM Panda for MotionBenchMaker files, whose goals collide with the shipped Panda's "
                        "more conservative spheres; the shipped Panda for generated problems)")
    p.add_argument("--out", default="benches/results", help="output folder (default benches/results)")
    p.add_argument("--no-progress", action="store_true")
    return p.parse_args(argv)


def main(argv: Optional[Sequence[str]] = None) -> int:
    args = parse_args(argv)
    import gfcs
    from gfcs import bench, problems
    from gfcs.results import format_table, summarize

    source = args.problems
    if source is None and not args.generated:
        shared = problems.shared_dir()
        if shared is not None and (shared / "mbm").is_dir():
            source = str(shared / "mbm")
    robot_kind = args.robot if args.robot != "auto" else ("mbm" if source else "panda")
    robot = problems.mbm_panda() if robot_kind == "mbm" else gfcs.Robot.panda()
    suite_args = SimpleNamespace(problems=source, classes=args.classes, limit=args.limit, skip=0,
                                 problem_seed=args.problem_seed)
    suite = bench.load_problems(suite_args, robot)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    rows = bench.run_bench(suite, args.methods, batches=args.batches, population=args.population,
                         seed=args.seed, fabric_config=args.config, threads=args.threads,
                         jsonl=str(out / "results.jsonl"), progress=not args.no_progress)
    wall = time.perf_counter() - start
    summary = summarize(rows)
    header: List[str] = [
        "## GFCS benchmark",
        "",
        f"- command: `python benches/bench_suite.py {' '.join(argv if argv is not None else sys.argv[1:])}`",
        f"- problems: {len(suite)} from {source or 'the generated suite (gfcs.generators, seed %d)' % args.problem_seed}",
        f"- robot: {robot.name} ({robot_kind}: {len(robot.sphere_radii)} collision spheres), methods: {', '.join(args.methods)}, batches {args.batches}, "
        f"population {args.population}, seed {args.seed}, threads {args.threads or os.cpu_count()}",
        f"- machine: {platform.processor() or platform.machine()}, {os.cpu_count()} logical cores, "
        f"Python {platform.python_version()}, gfcs {gfcs.__version__}",
        f"- wall time: {wall:.1f} s",
        "- cells: mean ± std over successful problems; Times = optimisation wall time up to that batch "
        "(GF: the rollout)",
        "",
    ]
    table = "\n".join(header) + "\n" + format_table(summary, markdown=True)
    (out / "table.md").write_text(table)
    print(format_table(summary, markdown=False))
    print(f"rows: {out / 'results.jsonl'}\ntable: {out / 'table.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
