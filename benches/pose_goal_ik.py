#!/usr/bin/env python
"""Time of turning a pose goal into a joint goal (``gfcs.pose_goal.goal_configuration``), per problem.

Each problem's joint goal is rewritten as the hand TCP's pose (``gfcs.generators.pose_request_yaml``: a 1 mm
sphere, 0.01 rad per axis), written next to its scene, loaded back with ``gfcs.problems.load_mbm`` — which
parses the request and runs the inverse kinematics — and timed (best of ``--repeat``). The problems are the
first ``--limit`` of each MotionBenchMaker class (``$GFCS_SHARED/mbm`` or ``<repo>/../shared/mbm``, the MBM
Panda with its mesh checker), or generated ones with the shipped Panda (``--generated``). Prints the median
and largest time and how far the chosen joint goal is from the start against the original goal's distance;
``--json`` writes them.

    python benches/pose_goal_ik.py --limit 10          # BENCHMARKS.md, "Pose goals"
    python benches/pose_goal_ik.py --generated --limit 2
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from gfcs import bench, generators, problems


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--limit", type=int, default=3, help="problems per class (default 3)")
    ap.add_argument("--repeat", type=int, default=3, help="timings per problem, best kept (default 3)")
    ap.add_argument("--generated", action="store_true", help="generated problems and the shipped Panda")
    ap.add_argument("--json", metavar="OUT.json", help="write the figures as JSON")
    args = ap.parse_args()
    import gfcs

    shared = None if args.generated else problems.shared_dir()
    source = str(shared / "mbm") if shared is not None and (shared / "mbm").is_dir() else None
    if source is None and not args.generated:
        raise SystemExit("no MotionBenchMaker problems: set GFCS_SHARED or use --generated")
    robot = problems.mbm_panda() if source else gfcs.Robot.panda()
    suite = bench.load_problems(SimpleNamespace(problems=source, classes=None, limit=args.limit, skip=0,
                                              problem_seed=0), robot)
    times, ratios = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k, p in enumerate(suite):
            folder = Path(tmp) / str(k)
            if source:  # the MBM scene as it is, the goal rewritten as a pose
                folder.mkdir()
                scene, request = folder / "scene0001.yaml", folder / "request0001.yaml"
                scene.write_text(Path(p.meta["scene_file"]).read_text())
                request.write_text(generators.pose_request_yaml(p.robot, p.q0, p.goal))
            else:
                (written,) = generators.write_problems([p], folder, pose_goals=True)
                scene, request = written / "scene0001.yaml", written / "request0001.yaml"
            best = np.inf
            for _ in range(args.repeat):
                start = time.perf_counter()
                posed = problems.load_mbm(scene, request, robot)
                best = min(best, time.perf_counter() - start)
            times.append(best)
            ratios.append(np.linalg.norm(posed.goal - posed.q0) / max(np.linalg.norm(p.goal - p.q0), 1e-12))
    figures = {"problems": len(times), "ms_median": 1e3 * float(np.median(times)),
               "ms_max": 1e3 * float(np.max(times)), "goal_distance_ratio_median": float(np.median(ratios)),
               "goal_distance_ratio_max": float(np.max(ratios)), "robot": str(robot.name),
               "source": source or "generated"}
    print(f"{figures['problems']} pose goals ({figures['source']}): load + IK {figures['ms_median']:.1f} ms median, "
          f"{figures['ms_max']:.1f} ms at most; start-to-goal distance {figures['goal_distance_ratio_median']:.2f}x "
          f"the original joint goal's (median), {figures['goal_distance_ratio_max']:.2f}x at most")
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
