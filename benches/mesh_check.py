#!/usr/bin/env python3
"""Cost of the exact mesh checks on a robot with detailed meshes (``gfcs.MeshChecker``).

For random configurations within the joint limits (seeded) of a MotionBenchMaker robot (or of the shipped
Panda with its convex collision polytopes, ``--robot shipped``; or of any robot, ``--urdf``, without obstacles),
times:

* ``self_clearance`` per state (exact self-distance, unbounded: penetration depths included), apart for the
  states whose links are clear and those in contact;
* ``min_self_clearance`` over the states with a 3 mm cutoff (what a solve's mesh verdict asks);
* ``clearance`` per state against the problem's scene;
* ``sweep`` (the continuous verdict) of straight paths between consecutive random states, split into
  rows 0.01 rad apart, against the same scene.

Prints a Markdown table (median and largest per call, seconds) and, with ``--json``, the raw times.

Example::

    GFCS_SHARED=../shared python benches/mesh_check.py --robot ur5 --states 60
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

import gfcs
from gfcs import problems, srdf_groups
from scaling import best_of  # benches/ is the script's folder

GROUPS = {"ur5": "manipulator", "fetch": "arm_with_torso", "panda": "panda_arm"}
#: The shipped Panda with its convex collision polytopes (``gfcs.problems.shipped_panda_checker``), in the
#: MotionBenchMaker Panda's scene.
SHIPPED = "shipped"


def shared_folder(shared_arg: Optional[str]) -> Path:
    """The shared data folder: ``shared_arg``, else GFCS_SHARED or ``../shared``; exits when there is none."""
    shared = Path(shared_arg) if shared_arg else problems.shared_dir()
    if shared is None:
        raise SystemExit("shared data folder not found: pass --shared or set GFCS_SHARED")
    return shared


def mbm_robot_checker(shared: Path, name: str) -> Tuple[Any, Any]:
    """(robot planning the group of ``GROUPS``, mesh checker of its URDF and SRDF) of the MotionBenchMaker robot
    ``name`` (a key of ``GROUPS``) of the shared data folder."""
    folder = shared / "robots" / f"mbm_{name}"
    urdf, srdf = folder / f"{name}_spherized.urdf", folder / f"{name}.srdf"
    robot, _ = srdf_groups.robot_for_group(str(urdf), str(srdf), GROUPS[name], mesh_dir=str(folder))
    return robot, problems.urdf_mesh_checker(folder / f"{name}.urdf", robot, mesh_dir=folder, srdf=srdf)


def mbm_problems_dir(shared: Path, name: str) -> Path:
    """The MotionBenchMaker problem folder of robot ``name`` (the Panda's for the shipped Panda)."""
    return shared / ("mbm" if name in ("panda", SHIPPED) else f"mbm_{name}")


def mbm_robot(name: str, shared_arg: Optional[str]) -> Tuple[Any, Any, Any]:
    """(robot, mesh checker, table_pick/0001's scene) of a MotionBenchMaker robot of the shared data folder, or
    of the shipped Panda in the MotionBenchMaker Panda's scene."""
    shared = shared_folder(shared_arg)
    if name == SHIPPED:
        robot, checker = gfcs.Robot.panda(), problems.shipped_panda_checker()
    else:
        robot, checker = mbm_robot_checker(shared, name)
    mbm = mbm_problems_dir(shared, name) / "table_pick"
    return robot, checker, problems.load_mbm(mbm / "scene0001.yaml", mbm / "request0001.yaml", robot=robot).scene


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shared", default=None, help="shared data folder (default: GFCS_SHARED or ../shared)")
    ap.add_argument("--robot", choices=sorted(GROUPS) + [SHIPPED], default="ur5")
    ap.add_argument("--states", type=int, default=60)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-sweep", action="store_true", help="leave out the sweep (e.g. to time a build before it)")
    ap.add_argument("--json", help="write the raw times here")
    ap.add_argument("--urdf", help="any robot instead: its URDF (with collision meshes), checked without obstacles")
    ap.add_argument("--srdf", help="with --urdf: its SRDF")
    ap.add_argument("--group", help="with --urdf: the SRDF group whose joints are sampled")
    ap.add_argument("--mesh-dir", help="with --urdf: the folder that resolves its package:// paths")
    args = ap.parse_args()
    if args.urdf:
        if not (args.srdf and args.group):
            raise SystemExit("--urdf needs --srdf and --group")
        robot, _ = srdf_groups.robot_for_group(args.urdf, args.srdf, args.group, mesh_dir=args.mesh_dir)
        checker, scene, name = gfcs.MeshChecker(robot), gfcs.Scene(), f"{Path(args.urdf).name} ({args.group})"
    else:
        robot, checker, scene = mbm_robot(args.robot, args.shared)
        name = args.robot
    rng = np.random.default_rng(args.seed)
    lo, hi = np.asarray(robot.lower), np.asarray(robot.upper)
    qs = rng.uniform(lo, hi, size=(args.states, robot.dof))
    times: Dict[str, List[float]] = {"self_clearance, clear states": [], "self_clearance, states in contact": [],
                                     "clearance": []}
    for q in qs:
        t = best_of(lambda: checker.self_clearance(q), 1)
        clear = float(checker.self_clearance(q)) > 0
        times["self_clearance, clear states" if clear else "self_clearance, states in contact"].append(t)
        if len(scene):
            times["clearance"].append(best_of(lambda: checker.clearance(scene, q), 1))
    times["min_self_clearance (3 mm cutoff)"] = [best_of(lambda: checker.min_self_clearance(qs, cutoff=0.003), 1)]
    for a, b in zip(qs[:-1], [] if args.no_sweep else qs[1:]):
        rows = max(2, int(np.ceil(np.max(np.abs(b - a)) / 0.01)) + 1)
        path = np.linspace(a, b, rows)
        times.setdefault("sweep", []).append(best_of(lambda: checker.sweep(scene, path), 1))
    print(f"{name}: {checker.num_shapes} collision shapes, {checker.num_self_pairs} self pairs, "
          f"{args.states} random states (seed {args.seed})\n")
    print("| query | calls | median (s) | largest (s) |\n|---|---|---|---|")
    for query, ts in times.items():
        if ts:
            print(f"| {query} | {len(ts)} | {statistics.median(ts):.3g} | {max(ts):.3g} |")
    if args.json:
        Path(args.json).write_text(json.dumps(times))


if __name__ == "__main__":
    main()
