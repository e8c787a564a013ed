"""Wall time of `gfcs bench` on one suite with the local executor and with Ray (1 and 2 workers), the rows
of the runs compared problem by problem, and the per-task overhead of the Ray executor.

    python benches/scaleout.py --shared ../shared --out runs/scaleout

runs ``gfcs bench --problems <shared>/mbm --robot mbm --limit 10 --time-limit 0`` (70 MotionBenchMaker
Panda problems, GF and GFCS, the default preset without its time budget: a solve cut short by the budget
depends on the machine's load, so runs compared row by row go without it) three times as a user would (a
new process each; the Ray runs start their own local Ray, which is part of their wall time), then times
Ray's per-task overhead with tasks that do nothing. Prints a markdown table (BENCHMARKS.md, "Scale-out (Ray)") and writes ``<out>/scaleout.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Dict, List

#: Row fields that are measured times (they differ between any two runs of the same solve).
TIMES = ("time", "wall_time")


def bench(args: argparse.Namespace, name: str, extra: List[str]) -> Dict[str, Any]:
    """One `gfcs bench` run in a new process: its wall time and rows, and the load average before it."""
    rows = args.out / f"{name}.jsonl"
    cmd = [sys.executable, "-m", "gfcs", "bench", "--problems", str(args.shared / "mbm"), "--robot", "mbm",
           "--limit", str(args.limit), "--time-limit", str(args.time_limit), "--json", str(rows), "--no-progress",
           *extra]
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    lines = [json.loads(s) for s in rows.read_text().splitlines() if s.strip()]
    solved = [r for r in lines if r.get("label") == "Ours (5 b, retry)"]
    return {"name": name, "command": " ".join(["gfcs", *cmd[3:]]), "wall_s": wall, "rows": lines, "load": load,
            "problems": len({r["problem"] for r in lines}), "solved": sum(r["success"] for r in solved),
            "solve_s": sum(r["wall_time"] for r in lines if r.get("label") in ("GF", "Ours (5 b, retry)"))}


def compare(a: List[Dict[str, Any]], b: List[Dict[str, Any]]) -> Dict[str, Any]:
    """Rows of two runs by (problem, label), every field but the times: how many, and which differ."""
    def key(rows: List[Dict[str, Any]]) -> Dict[Any, Dict[str, Any]]:
        return {(r["problem"], r["label"]): {k: v for k, v in r.items() if k not in TIMES} for r in rows}

    ka, kb = key(a), key(b)
    differ = sorted(k for k in set(ka) | set(kb) if ka.get(k) != kb.get(k))
    return {"rows": len(ka), "problems": len({p for p, _ in ka}), "differing": [list(k) for k in differ]}


def _noop(shared: Any, i: int) -> int:
    return i


def task_overhead(n: int) -> Dict[str, float]:
    """Seconds to start a local Ray with 1 CPU, and per task of ``n`` tasks that do nothing (submit,
    schedule, run, return) through :class:`gfcs.executors.RayExecutor` with 1 worker."""
    from gfcs.executors import RayExecutor

    t0 = time.perf_counter()
    executor = RayExecutor(workers=1, threads=1)
    start = time.perf_counter() - t0
    list(executor.run(_noop, None, [(i, (i,)) for i in range(10)]))  # the worker process started
    t0 = time.perf_counter()
    done = list(executor.run(_noop, None, [(i, (i,)) for i in range(n)]))
    per_task = (time.perf_counter() - t0) / n
    executor.close()
    assert sorted(d.value for d in done) == list(range(n))
    return {"ray_start_s": start, "per_task_s": per_task, "tasks": n}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shared", type=Path, default=Path("../shared"))
    ap.add_argument("--out", type=Path, default=Path("runs/scaleout"))
    ap.add_argument("--limit", type=int, default=10, help="problems per class (default 10: 70 problems)")
    ap.add_argument("--time-limit", type=float, default=0.0, help="gfcs bench --time-limit (default 0: none)")
    ap.add_argument("--overhead-tasks", type=int, default=300)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    runs = [bench(args, "local", []),
            bench(args, "ray1", ["--executor", "ray", "--workers", "1"]),
            bench(args, "ray2", ["--executor", "ray", "--workers", "2"])]
    overhead = task_overhead(args.overhead_tasks)
    same = {r["name"]: compare(runs[0]["rows"], r["rows"]) for r in runs[1:]}
    print("| executor | wall time (s) | problems | GFCS solved | sum of solve times (s) | load before |")
    print("|---|---|---|---|---|---|")
    for r in runs:
        print(f"| {r['name']} | {r['wall_s']:.1f} | {r['problems']} | {r['solved']} | {r['solve_s']:.1f} | "
              f"{r['load']:.1f} |")
    for name, c in same.items():
        print(f"local vs {name}: {c['rows']} rows of {c['problems']} problems, {len(c['differing'])} differ "
              f"(all fields but time, wall_time)")
    print(f"Ray start {overhead['ray_start_s']:.1f} s; per task {overhead['per_task_s'] * 1e3:.2f} ms "
          f"({overhead['tasks']} empty tasks, 1 worker)")
    summary = {"runs": [{k: v for k, v in r.items() if k != "rows"} for r in runs], "compare": same,
               "overhead": overhead}
    (args.out / "scaleout.json").write_text(json.dumps(summary, indent=1))
    return 0 if all(not c["differing"] for c in same.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
