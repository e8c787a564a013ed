#!/usr/bin/env python3
"""GFCS Table I for the MotionBenchMaker robots: every method and preset on the same problems, each returned
motion judged by the independent validator (``tools/check_trajectories.py``, FCL on the robot's collision
meshes and its SRDF), into result files that ``benches/report.py`` turns into BENCHMARKS.md.

For each robot (``--robots``) and run (``--runs``) it calls ``gfcs bench`` once, writing

* ``OUT/<robot>.<run>.jsonl``: the bench rows (``gfcs.results.bench_row``);
* ``OUT/<robot>.<run>/``: the motion behind every row with its trajectory (``result`` of the row);
* ``OUT/<robot>.<run>.validated.jsonl``: the validator's verdict on each of them.

Runs: ``default`` (GF and GFCS with the default preset: 1 b, 5 b, 5 b with the retry policies), ``paper``
(GFCS as the paper writes it: 1 b, 5 b), ``ompl`` (RRTConnect, Bi-EST, BIT* with ``--planner-time``; needs
the ``baselines`` extra) and ``bitstar6`` (BIT* with 6 s). Example, problems 1-10 of each class::

    python benches/table1.py --shared ../shared --limit 10 --out benches/results/table1
    python benches/report.py
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path
from typing import Any, Dict, List, Sequence, Tuple

#: robot -> (problem folder, robot folder, spherized URDF, mesh URDF, SRDF, validator's end-effector link),
#: relative to the shared folder.
ROBOTS: Dict[str, Tuple[str, str, str, str, str, str]] = {
    "mbm_panda": ("mbm", "robots/mbm_panda", "panda_spherized.urdf", "panda.urdf", "panda.srdf", "panda_hand"),
    "ur5": ("mbm_ur5", "robots/mbm_ur5", "ur5_spherized.urdf", "ur5.urdf", "ur5.srdf", "ee_link"),
    "fetch": ("mbm_fetch", "robots/mbm_fetch", "fetch_spherized.urdf", "fetch.urdf", "fetch.srdf", "wrist_roll_link"),
}

#: run -> the methods and options of its ``gfcs bench`` call.
RUNS: Dict[str, List[str]] = {
    "default": ["--method", "gf", "gfcs", "--preset", "default"],
    "paper": ["--method", "gfcs", "--preset", "paper"],
    "ompl": ["--method", "rrtconnect", "biest", "bitstar", "--planner-time", "1.2"],
    "bitstar6": ["--method", "bitstar", "--planner-time", "6"],
}


def bench(shared: Path, robot: str, run: str, out: Path, args: argparse.Namespace) -> None:
    problems, folder, spherized, _, srdf, _ = ROBOTS[robot]
    stem = out / f"{robot}.{run}"
    cmd = [sys.executable, "-m", "gfcs", "bench", "--problems", str(shared / problems),
           "--robot", str(shared / folder / spherized), "--srdf", str(shared / folder / srdf),
           *RUNS[run], "--seed", str(args.seed), "--time-limit", str(args.time_limit),
           "--json", f"{stem}.jsonl", "--results-dir", str(stem), "--no-progress"]
    if args.limit:
        cmd += ["--limit", str(args.limit)]
    if args.threads:
        cmd += ["--threads", str(args.threads)]
    print("$", " ".join(cmd), file=sys.stderr)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def validate(shared: Path, robot: str, run: str, out: Path, jobs: int) -> None:
    problems, folder, *_ = ROBOTS[robot]
    stem = out / f"{robot}.{run}"
    run_validator(shared / problems, shared / folder, robot, stem, Path(f"{stem}.validated.jsonl"), jobs)


def run_validator(problems: Path, robot_dir: Path, robot: str, results: Path, out: Path, jobs: int) -> None:
    """``tools/check_trajectories.py`` on the result files in ``results`` (problems in ``problems``, the
    robot files of ``ROBOTS[robot]`` in ``robot_dir``), its verdicts written to ``out`` (JSON lines)."""
    *_, mesh_urdf, srdf, ee_link = ROBOTS[robot]
    tool = Path(__file__).resolve().parents[1] / "tools" / "check_trajectories.py"
    cmd = [sys.executable, str(tool), str(results), "--problems", str(problems),
           "--urdf", str(robot_dir / mesh_urdf), "--srdf", str(robot_dir / srdf),
           "--ee-link", ee_link, "--jobs", str(jobs), "--json", str(out)]
    print("$", " ".join(cmd), file=sys.stderr)
    # exit code 1: some claimed successes are not valid, which the verdicts record; the table goes on
    code = subprocess.run(cmd, stdout=subprocess.DEVNULL).returncode
    if code not in (0, 1):
        raise SystemExit(f"the validator failed on {results} (exit code {code})")


def machine_info() -> Dict[str, Any]:
    """The CPU model, its cores, the commit, the date and the load average now."""
    import datetime
    import os
    import platform

    cpu = platform.processor() or platform.machine()
    info = Path("/proc/cpuinfo")
    if info.is_file():
        names = [line.split(":", 1)[1].strip() for line in info.read_text().splitlines()
                 if line.startswith("model name")]
        cpu = names[0] if names else cpu
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=Path(__file__).resolve().parent).stdout.strip() or "unknown"
    return {"cpu": cpu, "cores": os.cpu_count(), "commit": commit, "date": datetime.date.today().isoformat(),
            "load": os.getloadavg()[0]}


def write_machine(out: Path, stem: str) -> None:
    """Record in ``OUT/machine.json`` under ``stem`` (``<robot>.<run>``) :func:`machine_info` of that run."""
    import json

    path = out / "machine.json"
    runs = json.loads(path.read_text()) if path.is_file() else {}
    runs[stem] = machine_info()
    path.write_text(json.dumps(runs, indent=1) + "\n")


def main(argv: Sequence[str] = ()) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--shared", type=Path, default=Path("../shared"), help="the shared data folder")
    p.add_argument("--out", type=Path, default=Path("benches/results/table1"), help="result folder")
    p.add_argument("--robots", nargs="+", choices=sorted(ROBOTS), default=sorted(ROBOTS))
    p.add_argument("--runs", nargs="+", choices=list(RUNS), default=list(RUNS))
    p.add_argument("--limit", type=int, default=None, help="problems per class (default: all)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--time-limit", type=float, default=5.0, help="budget of each GFCS solve, s")
    p.add_argument("--threads", type=int, default=None, help="threads of each solve")
    p.add_argument("--jobs", type=int, default=2, help="validator processes")
    p.add_argument("--no-validate", action="store_true", help="bench only")
    p.add_argument("--validate-only", action="store_true", help="validate existing results only")
    args = p.parse_args(list(argv) or None)
    args.out.mkdir(parents=True, exist_ok=True)
    for robot in args.robots:
        for run in args.runs:
            if not args.validate_only:
                write_machine(args.out, f"{robot}.{run}")
                bench(args.shared, robot, run, args.out, args)
            if not args.no_validate:
                validate(args.shared, robot, run, args.out, args.jobs)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
