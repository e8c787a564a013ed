#!/usr/bin/env python
"""Scaling curves of the fabric and the planner: how the time grows with obstacles, collision spheres,
batch size and threads, and how a solve's time grows with the problem.

Curves (each a markdown table on stdout, all in ``--json``, plotted into ``--plot`` when matplotlib is
installed):

* ``obstacles``: µs per fabric step of a 200-step rollout in Rust (``Fabric.rollout``, record off) and per
  ``Fabric.acceleration`` call from Python, against the number of sphere obstacles (radius 3 cm, seeded,
  uniform in a shell 0.25-0.9 m around the shipped Panda's base, clear of its free-space path; 1 to 1,000).
* ``spheres``: the same rollout in a 10-obstacle scene against the number of robot collision spheres: the
  shipped Panda's 57 spheres, each replaced by k spheres of the same centre and radius (k = 1, 2, 4, 8),
  self-collision off so that only the obstacle part scales.
* ``batch``: ``Fabric.evaluate`` of N one-command candidates (N = 8-128, seeded uniform commands, the
  10-obstacle scene) on 1 and 2 threads: ms per batch and the speed-up.
* ``solve``: ``gfcs.planning.solve`` (the default preset, 5 batches, no time limit, one thread pool) on the
  first ``--limit`` MotionBenchMaker problems of each class (MBM Panda): optimisation time against the best
  cost t* (the length of the rollouts, the measure of difficulty the cost itself gives).

Every timing is the best of ``--repeat`` runs (the machine may be shared: best-of filters interference).

    GFCS_SHARED=../shared python benches/scaling.py --json scaling.json --plot scaling.png
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any, Callable, Dict, List

import gfcs
import numpy as np

START = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
GOAL = np.array([0.9, 0.3, 0.2, -1.6, -0.1, 1.9, 0.6])
STEPS = 200


def best_of(fn: Callable[[], Any], repeat: int) -> float:
    """The shortest of ``repeat`` wall times of ``fn()`` [s]."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def sphere_scene(n: int, seed: int = 0) -> Any:
    """``n`` sphere obstacles of 3 cm, uniform in a shell 0.25-0.9 m around the base, above the floor, each
    at least 3 cm from the shipped Panda's spheres along its free-space path from START to GOAL (the
    rollouts pass them without contact, within the barriers' influence)."""
    robot = gfcs.Robot.panda()
    path = gfcs.Fabric(robot).rollout(START, None, GOAL, t_max=STEPS * 0.01, tol=1e-9, stall_window=0.0).q
    centres = np.asarray(robot.sphere_centers(path[::5])).reshape(-1, 3)
    radii = np.tile(np.asarray(robot.sphere_radii), len(path[::5]))
    rng = np.random.default_rng(seed)
    scene = gfcs.Scene()
    while len(scene) < n:
        p = rng.uniform([-0.9, -0.9, 0.05], [0.9, 0.9, 1.0])
        if 0.25 < np.linalg.norm(p) < 0.9 and np.min(np.linalg.norm(centres - p, axis=1) - radii) > 0.06:
            scene.add_sphere(p, 0.03)
    return scene


def rollout_us(fabric: Any, repeat: int) -> float:
    """µs per step of a STEPS-step rollout from START toward GOAL (integration included)."""
    run = lambda: fabric.rollout(START, None, GOAL, t_max=STEPS * 0.01, tol=1e-9, stall_window=0.0,
                                 record=False)
    steps = max(int(run().steps), 1)
    return 1e6 * best_of(run, repeat) / steps


def python_us(fabric: Any, repeat: int) -> float:
    """µs per ``Fabric.acceleration`` call from Python along the first 200 steps of the rollout."""
    r = fabric.rollout(START, None, GOAL, t_max=STEPS * 0.01, tol=1e-9, stall_window=0.0)
    states = list(zip(r.q, r.qd))

    def calls() -> None:
        for q, qd in states:
            fabric.acceleration(q, qd, GOAL)

    return 1e6 * best_of(calls, repeat) / len(states)


def curve_obstacles(args: argparse.Namespace) -> List[Dict[str, float]]:
    robot = gfcs.Robot.panda()
    rows = []
    for n in (1, 3, 10, 30, 100, 300, 1000):
        fabric = gfcs.Fabric(robot, sphere_scene(n))
        rows.append({"obstacles": n, "rollout_us": rollout_us(fabric, args.repeat),
                     "python_us": python_us(fabric, args.repeat)})
    return rows


def replicated_spheres(robot: Any, k: int, path: str) -> Any:
    """The shipped Panda with each collision sphere repeated ``k`` times (written to ``path``)."""
    centres = np.asarray(robot.sphere_centers(np.zeros(robot.dof)))
    poses = np.asarray(robot.link_poses(np.zeros(robot.dof)))
    index = {name: i for i, name in enumerate(robot.link_names)}
    spheres = []
    for c, r, link in zip(centres, robot.sphere_radii, robot.sphere_links):
        pose = poses[index[link]]
        local = pose[:3, :3].T @ (c - pose[:3, 3])
        spheres += [{"link": link, "center": local.tolist(), "radius": float(r)}] * k
    with open(path, "w") as f:
        json.dump({"spheres": spheres}, f)
    return gfcs.Robot.from_urdf(gfcs.panda_urdf(), spheres=path)


def curve_spheres(args: argparse.Namespace) -> List[Dict[str, float]]:
    import tempfile

    base = gfcs.Robot.panda()
    scene = sphere_scene(10)
    config = {"self_collision": {"enabled": False}}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in (1, 2, 4, 8):
            robot = replicated_spheres(base, k, f"{tmp}/spheres_{k}.json")
            fabric = gfcs.Fabric(robot, scene, config)
            rows.append({"spheres": len(robot.sphere_radii), "rollout_us": rollout_us(fabric, args.repeat)})
    return rows


def curve_batch(args: argparse.Namespace) -> List[Dict[str, float]]:
    robot = gfcs.Robot.panda()
    fabric = gfcs.Fabric(robot, sphere_scene(10))
    rng = np.random.default_rng(0)
    lo, up = np.asarray(robot.lower), np.asarray(robot.upper)
    rows = []
    for n in (8, 16, 32, 64, 128):
        cands = rng.uniform(lo, up, size=(n, 7))
        row: Dict[str, float] = {"candidates": n}
        for threads in (1, 2):
            t = best_of(lambda c=cands, k=threads: fabric.evaluate(START, None, GOAL, c, threads=k), args.repeat)
            row[f"ms_{threads}t"] = 1e3 * t
        row["speedup"] = row["ms_1t"] / row["ms_2t"]
        rows.append(row)
    return rows


def curve_solve(args: argparse.Namespace) -> List[Dict[str, float]]:
    import os
    from pathlib import Path

    from gfcs import planning, problems

    robot = problems.mbm_panda()
    shared = os.environ.get("GFCS_SHARED")
    root = (Path(shared) if shared else Path(__file__).resolve().parents[2] / "shared") / "mbm"
    rows = []
    for cls in problems.CLASSES:
        for p in problems.load_mbm_dir(root / cls, limit=args.limit, robot=robot, invalid=[]):
            r = planning.solve(p, time_limit=None)
            rows.append({"class": cls, "problem": p.name, "obstacles": len(p.scene), "cost_s": float(r.cost),
                         "optimisation_s": float(r.solve_time), "first_batch_s": float(r.batch_times[0]),
                         "success": bool(r.success)})
    return rows


CURVES = {"obstacles": curve_obstacles, "spheres": curve_spheres, "batch": curve_batch, "solve": curve_solve}


def table(rows: List[Dict[str, Any]]) -> str:
    keys = list(rows[0])
    fmt = lambda v: f"{v:.3g}" if isinstance(v, float) else str(v)
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def slope(rows: List[Dict[str, Any]], x: str, y: str) -> float:
    """Least-squares exponent b of y ∝ x^b over the rows (the complexity a curve shows)."""
    xs = np.log([r[x] for r in rows])
    ys = np.log([r[y] for r in rows])
    return float(np.polyfit(xs, ys, 1)[0])


def plot(results: Dict[str, List[Dict[str, Any]]], path: str) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib missing: no plot")
        return
    specs = {"obstacles": ("obstacles", ["rollout_us", "python_us"], "µs per step"),
             "spheres": ("spheres", ["rollout_us"], "µs per step"),
             "batch": ("candidates", ["ms_1t", "ms_2t"], "ms per batch"),
             "solve": ("cost_s", ["optimisation_s", "first_batch_s"], "s")}
    names = [n for n in specs if n in results]
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names), 3.6), squeeze=False)
    for ax, name in zip(axes[0], names):
        x, ys, label = specs[name]
        rows = results[name]
        for y in ys:
            ax.plot([r[x] for r in rows], [r[y] for r in rows], "o" if name == "solve" else "o-", label=y)
        if name != "solve":
            ax.set_xscale("log")
            ax.set_yscale("log")
        ax.set_xlabel(x)
        ax.set_ylabel(label)
        ax.set_title(name)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot: {path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--curves", nargs="+", choices=list(CURVES), default=list(CURVES))
    ap.add_argument("--repeat", type=int, default=5, help="best of this many runs per timing (default 5)")
    ap.add_argument("--limit", type=int, default=2, help="MBM problems per class for the solve curve")
    ap.add_argument("--json", help="write every row here")
    ap.add_argument("--plot", help="write the figure here (PNG)")
    args = ap.parse_args()
    results: Dict[str, List[Dict[str, Any]]] = {}
    for name in args.curves:
        results[name] = CURVES[name](args)
        print(f"\n## {name}\n\n{table(results[name])}")
    if "obstacles" in results:
        rows = [r for r in results["obstacles"] if r["obstacles"] >= 10]
        print(f"\nobstacles ≥ 10: rollout step ∝ n^{slope(rows, 'obstacles', 'rollout_us'):.2f}")
    if "spheres" in results:
        print(f"spheres: rollout step ∝ S^{slope(results['spheres'], 'spheres', 'rollout_us'):.2f}")
    if "solve" in results:
        print(f"solve: optimisation ∝ t*^{slope(results['solve'], 'cost_s', 'optimisation_s'):.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)
    if args.plot:
        plot(results, args.plot)


if __name__ == "__main__":
    main()
