#!/usr/bin/env python3
"""What the contact-first order of the mesh checks saves when a selection judges candidates.

For the first ``--limit`` MotionBenchMaker problems of each class of a robot with collision meshes, solves once
(the default preset, seed 0) and rolls out the ``--top`` best candidates of the optimisation (the ones a
selection judges first), finished as a solve finishes them. Each candidate is then judged on the meshes by
``gfcs.metrics.mesh_check`` twice, interleaved: in path order and contact-first (``likely_contact``: the
sphere model's clearance per sample, what ``trajectory_metrics`` passes), with the same margin and, as in a
selection, a deadline (far off: it never ends a check), so that both check in calls of 8, 16, 32, ... states. Reports the
verdicts (they must agree) and the seconds per judgement, for the candidates that fail and those that pass.

Example::

    GFCS_SHARED=../shared python benches/mesh_order.py --robot ur5 --limit 3 --json out.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path
from typing import Any, Dict, List

import numpy as np

import gfcs
from gfcs import metrics, problems
from gfcs.planning import get_preset, rollout_commands, solve
from mesh_check import GROUPS, mbm_problems_dir, mbm_robot_checker, shared_folder  # benches/ is the script's folder


def load(shared: Path, name: str, limit: int) -> List[Any]:
    """The first ``limit`` problems of each class, with the robot's mesh checker."""
    robot, checker = mbm_robot_checker(shared, name)
    return problems.load_mbm_dir(mbm_problems_dir(shared, name), limit=limit, robot=robot, mesh_checker=checker)


def judge(problem: Any, q: np.ndarray, contact_first: bool) -> Dict[str, Any]:
    """One mesh judgement of the path ``q``: its verdict and seconds."""
    likely = None
    if contact_first:
        likely = np.minimum(metrics.obstacle_clearance(problem.robot, problem.scene, q),
                            metrics.self_clearance(problem.robot, q))
    began = time.perf_counter()
    # with a deadline far off, as a selection judges (its budget's deadline): calls of 8, 16, 32, ... states
    _, _, ok, complete = metrics.mesh_check(problem.mesh_checker, problem.scene, q, deadline=began + 3600.0,
                                            likely_contact=likely)
    return {"ok": bool(ok), "complete": bool(complete), "seconds": time.perf_counter() - began}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shared", default=None, help="shared data folder (default: GFCS_SHARED or ../shared)")
    ap.add_argument("--robot", choices=sorted(GROUPS), default="ur5")
    ap.add_argument("--limit", type=int, default=3, help="problems per class")
    ap.add_argument("--top", type=int, default=8, help="candidates judged per problem")
    ap.add_argument("--json", type=Path, default=None, help="write the raw judgements here")
    args = ap.parse_args()
    shared = shared_folder(args.shared)
    rows = []
    settings = get_preset("default").settings
    for problem in load(shared, args.robot, args.limit):
        try:
            result = solve(problem, top_m=args.top)
        except gfcs.CollisionError as e:  # a start or goal in collision: no candidates to judge
            print(f"skipped: {e}")
            continue
        fabric = gfcs.Fabric(problem.robot, problem.scene)
        dof = len(problem.goal)
        for rank, (x, _cost) in enumerate(result.top):
            traj, *_ = rollout_commands(fabric, problem.q0, problem.qd0, problem.goal,
                                        np.asarray(x, dtype=np.float64).reshape(-1, dof), settings)
            plain = judge(problem, traj.q, False)
            first = judge(problem, traj.q, True)
            if (plain["ok"], plain["complete"]) != (first["ok"], first["complete"]):
                raise SystemExit(f"{problem.name} candidate {rank}: verdicts differ: {plain} vs {first}")
            rows.append({"problem": problem.name, "rank": rank, "ok": plain["ok"], "states": len(traj.q),
                         "path_order_s": plain["seconds"], "contact_first_s": first["seconds"]})
    print(f"{args.robot}: {len({r['problem'] for r in rows})} problems, {len(rows)} candidates judged, the same "
          "verdicts both ways\n")
    print("| candidates | count | path order: median / total (s) | contact-first: median / total (s) |")
    print("|---|---|---|---|")
    for label, keep in (("failing on the meshes", False), ("passing", True)):
        part = [r for r in rows if r["ok"] == keep]
        if not part:
            continue
        cells = [f"{statistics.median(r[k] for r in part):.4f} / {sum(r[k] for r in part):.2f}"
                 for k in ("path_order_s", "contact_first_s")]
        print(f"| {label} | {len(part)} | {cells[0]} | {cells[1]} |")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
