#!/usr/bin/env python3
"""The first fit of collision spheres to a robot's meshes (``gfcs.sphere_fit.fitted_spheres``), as a new user's
first ``gfcs solve`` on a robot without spheres pays it: each run in a fresh process with the disk cache off
(``GFCS_CACHE_DIR=off``), so the import of the mesh reader and the reading of the meshes count.

Robots from the ``example-robot-data`` package 6.0.0 (see ``benches/unseen_robots.py`` for getting it)::

    python benches/sphere_fit.py --share erd/x/cmeel.prefix/share --repeat 3

Writes the fragment ``benches/results/sphere_fit.md`` (for ``benches/report.py``): per robot, the links fitted,
the spheres, and the median and spread of the wall times of ``--repeat`` runs (robots interleaved).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Dict, List

ROOT = Path(__file__).resolve().parent.parent
FRAGMENT = ROOT / "benches" / "results" / "sphere_fit.md"

#: (title, URDF below example-robot-data/robots)
ROBOTS = (
    ("UFactory xArm7", "xarm_description/urdf/xarm7.urdf"),
    ("PR2", "pr2_description/urdf/pr2.urdf"),
    ("TALOS", "talos_data/robots/talos_full_v2.urdf"),
    ("TIAGo Pro", "tiago_pro_description/robots/tiago_pro.urdf"),
    ("Unitree G1", "g1_description/urdf/g1_29dof_rev_1_0.urdf"),
)

#: One fit, timed in its own process; prints {"links", "spheres", "seconds"}.
CHILD = """
import json, sys, time
import gfcs
from gfcs import sphere_fit
robot = gfcs.Robot.from_urdf(sys.argv[1], mesh_dir=sys.argv[2])
t = time.perf_counter()
spheres = sphere_fit.fitted_spheres(robot)
print(json.dumps({"links": len({s[0] for s in spheres}), "spheres": len(spheres),
                  "seconds": time.perf_counter() - t}))
"""


def fit_once(urdf: Path, share: Path) -> Dict[str, float]:
    env = {**os.environ, "GFCS_CACHE_DIR": "off"}
    out = subprocess.run([sys.executable, "-c", CHILD, str(urdf), str(share)], capture_output=True, text=True,
                         env=env, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def fragment(rows: List[Dict[str, object]], repeat: int) -> str:
    lines = ["## First sphere fit of a robot without spheres", "",
             f"Written by `python benches/sphere_fit.py --share SHARE --repeat {repeat}`: "
             "`gfcs.sphere_fit.fitted_spheres` on the collision meshes of `example-robot-data` 6.0.0 robots, each "
             "run in a fresh process with the cache off (a new user's first `gfcs solve` on the robot; later "
             "calls read the cache), robots interleaved; wall seconds of the fit, the mesh reader's import and "
             "the reading of the meshes included.", "",
             "| robot | links fitted | spheres | median fit (s) | range (s) |", "|---|---|---|---|---|"]
    for r in rows:
        times = r["seconds"]
        lines.append(f"| {r['robot']} | {r['links']} | {r['spheres']} | {statistics.median(times):.2f} "
                     f"| {min(times):.2f}-{max(times):.2f} |")
    return "\n".join(lines) + "\n"


def main(argv: List[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--share", type=Path, required=True,
                   help="folder holding example-robot-data/robots (the wheel's cmeel.prefix/share)")
    p.add_argument("--repeat", type=int, default=3, help="runs per robot (default 3)")
    p.add_argument("--fragment", type=Path, default=FRAGMENT, help=f"markdown written (default {FRAGMENT})")
    args = p.parse_args(argv)
    robots = args.share / "example-robot-data" / "robots"
    if not robots.is_dir():
        p.error(f"--share {args.share}: no example-robot-data/robots in it")
    if args.repeat < 1:
        p.error(f"--repeat must be >= 1, got {args.repeat}")
    rows: List[Dict[str, object]] = [{"robot": title, "seconds": []} for title, _ in ROBOTS]
    for _ in range(args.repeat):
        for row, (_, urdf) in zip(rows, ROBOTS):
            fit = fit_once(robots / urdf, args.share)
            row.update(links=fit["links"], spheres=fit["spheres"])
            row["seconds"].append(fit["seconds"])  # type: ignore[union-attr]
            print(json.dumps({"robot": row["robot"], **fit}), flush=True)
    args.fragment.write_text(fragment(rows, args.repeat))
    print(fragment(rows, args.repeat))
    return 0


if __name__ == "__main__":
    sys.exit(main())
