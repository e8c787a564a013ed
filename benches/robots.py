#!/usr/bin/env python3
"""Per-robot figures of `gfcs bench` on MotionBenchMaker problems: success and solve time per class, the
largest speed/limit ratio, and the time budget, for every robot in one table.

Runs `gfcs bench` (as a new user would: the robot's spherized URDF and its SRDF as shipped) for each robot
whose problems and files are in the shared data folder, writes one JSONL file per robot into --out, and
prints a markdown section (also written to --out/robots.PRESET.md) for BENCHMARKS.md.

Example (problems 1-10 of each class, the default preset and 5 s budget)::

    python benches/robots.py --shared ../shared --limit 10 --out runs/robots
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Dict, List

#: robot name -> (problem folder, robot folder, spherized URDF, SRDF), relative to the shared folder.
ROBOTS = {
    "Panda (MotionBenchMaker)": ("mbm", "robots/mbm_panda", "panda_spherized.urdf", "panda.srdf"),
    "UR5": ("mbm_ur5", "robots/mbm_ur5", "ur5_spherized.urdf", "ur5.srdf"),
    "Fetch": ("mbm_fetch", "robots/mbm_fetch", "fetch_spherized.urdf", "fetch.srdf"),
}


def run(shared: Path, name: str, out: Path, limit: int, preset: str, time_limit: float) -> Path:
    problems, folder, urdf, srdf = ROBOTS[name]
    rows = out / f"{problems}.{preset}.jsonl"
    cmd = [sys.executable, "-m", "gfcs", "bench", "--problems", str(shared / problems),
           "--robot", str(shared / folder / urdf), "--srdf", str(shared / folder / srdf),
           "--method", "gfcs", "--preset", preset, "--time-limit", str(time_limit), "--limit", str(limit),
           "--json", str(rows), "--no-progress"]
    print("$", " ".join(cmd), file=sys.stderr)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return rows


def section(name: str, rows_file: Path) -> List[str]:
    """Markdown lines: per class the success of the final result (every attempt the preset allows), the
    median and largest whole-solve wall time, and the largest speed/limit ratio of the returned motions."""
    rows = [json.loads(line) for line in rows_file.read_text().splitlines() if line.strip()]
    final: Dict[str, Dict[str, dict]] = {}
    for r in rows:  # the last row of a problem is its final result (the retry row when there is one)
        if r.get("method") == "gfcs" and "label" in r:
            final.setdefault(r["class"], {})[r["problem"]] = r
    lines = [f"**{name}** (`{rows_file.name}`)", "",
             "| class | solved | median solve (s) | slowest solve (s) | max speed/limit |",
             "|---|---|---|---|---|"]
    every: List[dict] = []
    for cls in sorted(final):
        rs = list(final[cls].values())
        every += rs
        walls = [float(r["wall_time"]) for r in rs]
        ratio = max((float(r.get("velocity_ratio", 0.0)) for r in rs if r["success"]), default=float("nan"))
        lines.append(f"| {cls} | {sum(r['success'] for r in rs)}/{len(rs)} | {statistics.median(walls):.2f} | "
                     f"{max(walls):.2f} | {ratio:.3f} |")
    walls = [float(r["wall_time"]) for r in every]
    lines.append(f"| all | {sum(r['success'] for r in every)}/{len(every)} | {statistics.median(walls):.2f} | "
                 f"{max(walls):.2f} | |")
    return lines + [""]


def main(argv: List[str] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shared", type=Path, default=Path("../shared"), help="shared data folder")
    ap.add_argument("--out", type=Path, required=True, help="folder for the JSONL rows and robots.PRESET.md")
    ap.add_argument("--limit", type=int, default=10, help="problems per class (default 10)")
    ap.add_argument("--preset", default="default", choices=["default", "paper"])
    ap.add_argument("--time-limit", type=float, default=5.0, help="solve budget, s (default 5)")
    ap.add_argument("--robots", nargs="+", default=list(ROBOTS), choices=list(ROBOTS))
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    lines: List[str] = []
    for name in args.robots:
        lines += section(name, run(args.shared, name, args.out, args.limit, args.preset, args.time_limit))
    text = "\n".join(lines)
    (args.out / f"robots.{args.preset}.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
