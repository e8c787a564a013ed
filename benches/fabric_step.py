#!/usr/bin/env python
"""Cost of one fabric step inside GFCS: ``Fabric.evaluate`` (the batched rollouts of Alg. 1) per step, and
of the default warm start (``ApproachSampler.sample``, which the first batch adds).

For the first ``--limit`` MotionBenchMaker problems of each class (``$GFCS_SHARED/mbm`` or
``<repo>/../shared/mbm``, the MBM Panda; ``--generated`` uses the generated suite and the shipped Panda),
rolls out ``--population`` warm-start candidates (``ApproachSampler``, seed 0) once with trajectories to
count the integration steps, then times the same batch on 1 and on 2 threads (best of ``--repeat``).
Prints µs per step on one thread, wall µs per step on two, and the speed-up, then the median and largest
warm-start time per problem (best of ``--repeat``, all cores); ``--json`` writes them.

    python benches/fabric_step.py                 # BENCHMARKS.md, "Per fabric step inside GFCS"
    python benches/fabric_step.py --generated --limit 2
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from gfcs import optimize, problems


def load(args: argparse.Namespace) -> list:
    """The problems, as ``benches/bench_suite.py`` loads them (MBM Panda for MBM, shipped Panda else)."""
    import gfcs
    from gfcs import bench

    shared = None if args.generated else problems.shared_dir()
    source = str(shared / "mbm") if shared is not None and (shared / "mbm").is_dir() else None
    if source is None and not args.generated:
        raise SystemExit("no MotionBenchMaker problems: set GFCS_SHARED or use --generated")
    robot = problems.mbm_panda() if source else gfcs.Robot.panda()
    suite = SimpleNamespace(problems=source, classes=None, limit=args.limit, skip=0, problem_seed=0)
    return bench.load_problems(suite, robot)


def best_time(fabric, p, candidates, kwargs, threads: int, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fabric.evaluate(p.q0, p.qd0, p.goal, candidates, threads=threads, **kwargs)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--limit", type=int, default=1, help="problems per class (default 1)")
    ap.add_argument("--population", type=int, default=32, help="candidates per batch (default 32)")
    ap.add_argument("--repeat", type=int, default=3, help="timings per thread count, best kept (default 3)")
    ap.add_argument("--generated", action="store_true", help="generated problems and the shipped Panda")
    ap.add_argument("--json", metavar="OUT.json", help="write the figures as JSON")
    args = ap.parse_args()
    kwargs = optimize.RolloutSettings().as_kwargs()
    steps, t1, t2, warm = 0, 0.0, 0.0, []
    for p in load(args):
        fabric = optimize.make_fabric(p)
        sampling = []
        for _ in range(args.repeat):
            start = time.perf_counter()
            candidates = optimize.ApproachSampler().sample(p, args.population, np.random.default_rng(0))
            sampling.append(time.perf_counter() - start)
        warm.append(min(sampling))
        *_, trajectories = fabric.evaluate(p.q0, p.qd0, p.goal, candidates, return_trajectories=True, **kwargs)
        steps += sum(len(tr.t) for tr in trajectories)
        t1 += best_time(fabric, p, candidates, kwargs, 1, args.repeat)
        t2 += best_time(fabric, p, candidates, kwargs, 2, args.repeat)
    out = {"steps": steps, "us_per_step_1_thread": t1 / steps * 1e6, "wall_us_per_step_2_threads": t2 / steps * 1e6,
           "speedup": t1 / t2, "warm_start_ms_median": float(np.median(warm)) * 1e3,
           "warm_start_ms_max": max(warm) * 1e3}
    print(f"{steps} steps: {out['us_per_step_1_thread']:.2f} µs/step on 1 thread, "
          f"{out['wall_us_per_step_2_threads']:.2f} µs/step wall on 2 (speed-up {out['speedup']:.2f})")
    print(f"warm start ({args.population} candidates): {out['warm_start_ms_median']:.2f} ms median, "
          f"{out['warm_start_ms_max']:.2f} ms at most over {len(warm)} problems")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
