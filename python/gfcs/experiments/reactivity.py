"""Reactivity of GFCS (GFCS Sec. V, "Reactive Motion Generation", Fig. 4), measured.

The paper solves "table under", "box" and "single shelf" problems, then "randomly generate[s] new
obstacles, blocking the previously solved motion trajectory", replays the optimised commands without
re-optimising and observes that the motion "can consistently generate collision-free trajectories which
avoid the new obstacles". Here, per problem:

1. solve it with GFCS (:func:`gfcs.optimize.solve`, seeded);
2. add one sphere (radius uniform in :data:`RADII`, seeded) centred on the hand's path at a point drawn
   from its middle half (by arc length) — so the solved motion runs straight into it — kept only when the
   start and the goal stay clear of it by :data:`START_GOAL_CLEARANCE` with the collision spheres (up to
   :data:`TRIES` draws, else the problem is counted as ``no_block``);
3. check that the solved trajectory collides with it (``blocked``: the sphere model's clearance < 0);
4. replay the same commands in the new scene (:func:`gfcs.optimize.replay`: the fabric reacts, nothing
   is re-optimised) and record whether the replay is collision-free, reaches the goal, and succeeds (both,
   within the joint limits, and with the collision meshes clear when the problem has a mesh checker).

Units: metres, seconds.
"""

from __future__ import annotations

import argparse
import zlib
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

__all__ = ["CLASSES", "RADII", "blocking_sphere", "react", "run", "summary_text", "plot", "add_cli"]

#: The classes of GFCS Sec. V's reactivity study ("table under", "box", "single shelf").
CLASSES = ("table_under_pick", "box", "bookshelf_small")
#: Range of the new sphere's radius [m].
RADII = (0.03, 0.06)
#: Clearance [m] the start and the goal keep from the new sphere (collision spheres).
START_GOAL_CLEARANCE = 0.01
#: Draws of a blocking sphere before giving up on a problem.
TRIES = 50


def blocking_sphere(problem: Any, result: Any, rng: np.random.Generator) -> Optional[Dict[str, Any]]:
    """A sphere on the middle half of the solved hand path that the start and goal clear, or None."""
    from gfcs import metrics

    robot = problem.robot
    q = np.asarray(result.trajectory.q, dtype=np.float64)
    hand = np.asarray(robot.ee_position(q), dtype=np.float64)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(hand, axis=0), axis=1))])
    if s[-1] <= 0.0:
        return None
    middle = np.nonzero((s >= 0.25 * s[-1]) & (s <= 0.75 * s[-1]))[0]
    ends = np.stack([problem.q0, problem.goal])
    for _ in range(TRIES):
        centre, radius = hand[rng.choice(middle)], float(rng.uniform(*RADII))
        scene = problem.scene.copy()
        scene.add_sphere(centre, radius, name="new_obstacle")
        if np.all(metrics.obstacle_clearance(robot, scene, ends) >= START_GOAL_CLEARANCE):
            return {"centre": centre.tolist(), "radius": radius, "scene": scene}
    return None


def react(problem: Any, seed: int = 0, batches: int = 5) -> Dict[str, Any]:
    """Steps 1-4 of the module docstring for one problem: a JSON-ready dict."""
    from gfcs import metrics, optimize
    from gfcs.results import planned_robot

    row: Dict[str, Any] = {"problem": str(problem.name), "class": str(problem.cls)}
    result = optimize.solve(problem, batches=batches, seed=seed)
    row["solved"] = bool(result.success)
    if not result.success:
        return row
    rng = np.random.default_rng([seed, zlib.crc32(str(problem.name).encode())])
    sphere = blocking_sphere(problem, result, rng)
    row["no_block"] = sphere is None
    if sphere is None:
        return row
    scene = sphere.pop("scene")
    row.update(sphere)
    before = metrics.obstacle_clearance(planned_robot(result, problem), scene, np.asarray(result.trajectory.q)).min()
    row["blocked"] = bool(before < 0.0)
    row["solved_clearance"] = float(before)
    again = optimize.replay(result, scene, robot=problem.robot, mesh_checker=problem.mesh_checker)
    m = again.metrics
    row.update(replay_collision_free=bool(m["min_clearance"] >= 0.0 and m["min_self_clearance"] >= 0.0),
               replay_reached=bool(again.reached), replay_success=bool(again.success),
               replay_clearance=float(m["min_clearance"]), replay_ee_length=float(m["ee_length"]),
               solved_ee_length=float(result.metrics["ee_length"]))
    return row


def run(problems: Sequence[Any], seed: int = 0, batches: int = 5, progress: bool = False) -> List[Dict[str, Any]]:
    """:func:`react` on every problem (a tqdm bar with ``progress``)."""
    items: Any = problems
    if progress:
        from tqdm.auto import tqdm

        items = tqdm(problems, desc="reactivity", unit="problem")
    return [react(p, seed=seed, batches=batches) for p in items]


def totals(rows: Sequence[Dict[str, Any]]) -> Dict[str, Dict[str, int]]:
    """Per class (and ``all``): problems, solved, blocked, and of the blocked ones the replays that are
    collision-free, reach the goal, and succeed."""
    out: Dict[str, Dict[str, int]] = {}
    for r in rows:
        for key in (r["class"], "all"):
            t = out.setdefault(key, dict.fromkeys(("problems", "solved", "no_block", "blocked",
                                                   "collision_free", "reached", "success"), 0))
            t["problems"] += 1
            t["solved"] += int(r["solved"])
            t["no_block"] += int(r.get("no_block", False))
            if r.get("blocked"):
                t["blocked"] += 1
                t["collision_free"] += int(r["replay_collision_free"])
                t["reached"] += int(r["replay_reached"])
                t["success"] += int(r["replay_success"])
    return out


def summary_text(rows: Sequence[Dict[str, Any]]) -> str:
    """One line per class: solved problems, those where no sphere could be placed ("no place"), those whose
    motion the new sphere blocks, and of these the replays that avoid it, reach the goal, and succeed."""
    lines = ["GFCS Sec. V reactivity: a new sphere on the solved hand path, the same commands replayed",
             f"{'class':<18} {'solved':>8} {'no place':>8} {'blocked':>8} {'coll.-free':>10} {'reached':>8} "
             f"{'success':>8}"]
    t_all = totals(rows)
    for cls, t in sorted(t_all.items(), key=lambda kv: kv[0] == "all"):  # "all" last
        lines.append(f"{cls:<18} {t['solved']:>4}/{t['problems']:<3} {t['no_block']:>8} {t['blocked']:>8} "
                     f"{t['collision_free']:>10} {t['reached']:>8} {t['success']:>8}")
    return "\n".join(lines)


def plot(rows: Sequence[Dict[str, Any]], out: Any) -> Path:
    """Bars per class: blocked motions, and of them the replays collision-free, reaching, succeeding."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = totals(rows)
    names = [c for c in t if c != "all"]
    keys = ("blocked", "collision_free", "reached", "success")
    fig, ax = plt.subplots(figsize=(1.8 + 1.6 * len(names), 3.6))
    x = np.arange(len(names))
    for k, key in enumerate(keys):
        ax.bar(x + (k - 1.5) * 0.2, [t[n][key] for n in names], width=0.2, label=key.replace("_", "-"))
    ax.set_xticks(x, names)
    ax.set(ylabel="problems", title="GFCS Sec. V: replays among new obstacles")
    ax.legend(fontsize=8)
    fig.tight_layout()
    from gfcs.plots import save_png

    return save_png(fig, out)


def _cmd_reactivity(args: argparse.Namespace) -> int:
    from gfcs import bench, cli
    from gfcs.experiments import report

    args.classes = args.classes or list(CLASSES)
    args.skip = 0
    robot = cli._robot(args)
    suite = cli._with_mesh_checker(args, bench.load_problems(args, robot))
    rows = run(suite, seed=args.seed, batches=args.batches, progress=args.progress)
    report(summary_text(rows), {"seed": args.seed, "totals": totals(rows), "rows": rows}, args.json,
           plot(rows, args.out) if args.out else None)
    return 0


def add_cli(experiment_subparsers: Any) -> argparse.ArgumentParser:
    """Add ``reactivity`` under ``gfcs experiment``."""
    from gfcs.experiments import add_output_options

    from gfcs import cli

    p = experiment_subparsers.add_parser(
        "reactivity", help="GFCS Sec. V reactivity: solved motions replayed among new obstacles",
        description="Solve problems with GFCS, put a new sphere on each solved hand path, replay the same "
                    "commands (no re-optimisation) and count the replays that avoid it and reach the goal.",
    )
    p.add_argument("--problems", metavar="DIR", help="MotionBenchMaker folder (default: generated problems)")
    p.add_argument("--classes", nargs="+", metavar="CLASS",
                   help=f"classes (default: {' '.join(CLASSES)}, the paper's)")
    p.add_argument("--limit", type=int, default=10, help="problems per class (default 10)")
    p.add_argument("--problem-seed", type=int, default=0, help="seed of generated problems (default 0)")
    p.add_argument("--seed", type=int, default=0, help="seed of the solves and the new spheres (default 0)")
    p.add_argument("--batches", type=int, default=5, help="CMA-ES batches per solve (default 5)")
    add_output_options(p, "the rows and totals")
    p.add_argument("--progress", action="store_true", help="show a progress bar")
    cli._add_robot_options(p)
    p.set_defaults(func=_cmd_reactivity)
    return p
