#!/usr/bin/env python
"""One fabric step of gfcs against the `fabrics` package (Spahn et al., CasADi), on one machine.

Same robot (the MotionBenchMaker Panda URDF, ``$GFCS_SHARED/robots/mbm_panda`` or ``<repo>/../shared``), same
``--obstacles`` sphere obstacles (radius 5 cm, seeded positions around the arm, none touching it at the
start), same start, and a joint goal (gfcs) whose hand position is the `fabrics` planner's goal. Each engine drives the
arm there for ``--steps`` explicit Euler steps of 10 ms, and the time of every acceleration query is taken
(median of the steps, µs). The two engines need different environments (`fabrics` pins numpy 1.26), so run
the script once per engine:

    python benches/compare_fabrics.py --engine gfcs
    /path/to/venv-with-fabrics/bin/python benches/compare_fabrics.py --engine fabrics

What each evaluates per step:

* gfcs: ``Fabric.acceleration`` from Python (the MBM Panda's 81 collision spheres against every obstacle,
  self-collision between the sphere pairs the SRDF leaves, joint limits, joint and hand attractors,
  energization, speed control), and the same fabric stepped in Rust by ``Fabric.rollout`` (µs per step of
  the whole rollout, integration included).
* fabrics: ``ParameterizedFabricPlanner.compute_action`` with one sphere per collision link (links 3-7 and
  the hand; `fabrics` skips links 1-2, whose positions are constant), the same obstacles, joint limits,
  self-collision of the hand with links 2-4 and a hand position goal, and the CasADi function alone.

``--json`` writes the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

START = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
GOAL = np.array([0.9, 0.3, 0.2, -1.6, -0.1, 1.9, 0.6])
#: panda_hand's position at GOAL [m] (the `fabrics` planner's goal; `run_gfcs` checks it to 1 mm)
GOAL_HAND = np.array([0.3128, 0.5696, 0.4608])
LIMITS = [[-2.8973, 2.8973], [-1.7628, 1.7628], [-2.8973, 2.8973], [-3.0718, -0.0698], [-2.8973, 2.8973],
          [-0.0175, 3.7525], [-2.8973, 2.8973]]
RADIUS = 0.05
DT = 0.01


def shared_dir() -> Path:
    env = os.environ.get("GFCS_SHARED")
    return Path(env) if env else Path(__file__).resolve().parent.parent.parent / "shared"


def obstacles(n: int, seed: int = 0) -> np.ndarray:
    """(n, 3) sphere centres [m]: seeded, 0.3-0.8 m from the base, above the floor, away from the start
    and goal hand positions (at least 0.25 m)."""
    rng = np.random.default_rng(seed)
    keep_out = np.array([[0.307, 0.0, 0.59], GOAL_HAND])  # the hand at START and at GOAL
    out = []
    while len(out) < n:
        p = rng.uniform([-0.8, -0.8, 0.1], [0.8, 0.8, 0.9])
        if 0.3 < np.linalg.norm(p[:2]) < 0.8 and np.linalg.norm(keep_out - p, axis=1).min() > 0.25:
            out.append(p)
    return np.array(out)


def timed_steps(accel, steps: int) -> tuple:
    """Euler-integrate q̈ = accel(q, q̇) from START at rest; per-call times [s] and the final q."""
    q, qd = START.copy(), np.zeros(7)
    times = []
    for _ in range(steps):
        t0 = time.perf_counter()
        qdd = accel(q, qd)
        times.append(time.perf_counter() - t0)
        qd = qd + DT * qdd
        q = q + DT * qd
    return times, q


def run_gfcs(args: argparse.Namespace) -> dict:
    import gfcs
    from gfcs import problems

    robot = problems.mbm_panda()
    if np.linalg.norm(np.asarray(robot.ee_position(GOAL)) - GOAL_HAND) > 1e-3:
        raise SystemExit(f"GOAL_HAND is not the hand at GOAL: {robot.ee_position(GOAL)}")
    scene = gfcs.Scene()
    for c in obstacles(args.obstacles):
        scene.add_sphere(c, RADIUS)
    fabric = gfcs.Fabric(robot, scene)
    times, q = timed_steps(lambda q, qd: fabric.acceleration(q, qd, GOAL), args.steps)
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        r = fabric.rollout(START, np.zeros(7), GOAL, dt=DT, t_max=args.steps * DT, tol=1e-9, stall_window=0.0,
                           record=False)
        best = min(best, time.perf_counter() - t0)
    n = int(r.steps)
    hand = np.asarray(robot.ee_position(q))
    return {"engine": "gfcs", "version": gfcs.__version__, "spheres": len(robot.sphere_radii),
            "self_pairs": len(robot.self_collision_pairs), "obstacles": args.obstacles,
            "median_us": 1e6 * statistics.median(times), "rollout_us_per_step": 1e6 * best / max(n, 1),
            "rollout_steps": n, "final_hand": hand.tolist()}


def run_fabrics(args: argparse.Namespace) -> dict:
    import logging

    from fabrics.planner.parameterized_planner import ParameterizedFabricPlanner
    from forwardkinematics.urdfFks.generic_urdf_fk import GenericURDFFk
    from mpscenes.goals.goal_composition import GoalComposition

    logging.disable(logging.WARNING)
    urdf = (shared_dir() / "robots" / "mbm_panda" / "panda.urdf").read_text()
    fk = GenericURDFFk(urdf, root_link="panda_link0", end_links=["panda_hand"])
    planner = ParameterizedFabricPlanner(7, fk)
    links = ["panda_link3", "panda_link4", "panda_link5", "panda_link6", "panda_link7", "panda_hand"]
    goal_xyz = GOAL_HAND.tolist()
    goal = GoalComposition(name="goal", content_dict={"subgoal0": {
        "weight": 1.0, "is_primary_goal": True, "indices": [0, 1, 2], "parent_link": "panda_link0",
        "child_link": "panda_hand", "desired_position": goal_xyz, "epsilon": 0.02, "type": "staticSubGoal"}})
    built = time.perf_counter()
    planner.set_components(collision_links=links,
                           self_collision_pairs={"panda_hand": ["panda_link2", "panda_link3", "panda_link4"]},
                           goal=goal, number_obstacles=args.obstacles, limits=LIMITS)
    planner.concretize()
    built = time.perf_counter() - built
    centres = obstacles(args.obstacles)
    kwargs = {"x_goal_0": np.array(goal_xyz), "weight_goal_0": 1.0,
              "radius_body_links": {link: 0.08 for link in links}}
    for i, c in enumerate(centres):
        kwargs[f"x_obst_{i}"], kwargs[f"radius_obst_{i}"] = c, RADIUS
    times, q = timed_steps(lambda q, qd: planner.compute_action(q=q, qdot=qd, **kwargs), args.steps)
    funs = planner._funs  # the CasADi function alone, with the arguments compute_action last gave it
    raw = []
    for _ in range(args.steps):
        t0 = time.perf_counter()
        funs._function(**funs._argument_dictionary)
        raw.append(time.perf_counter() - t0)
    import fabrics

    return {"engine": "fabrics", "version": getattr(fabrics, "__version__", "0.10"), "collision_links": len(links),
            "obstacles": args.obstacles, "build_s": built, "median_us": 1e6 * statistics.median(times),
            "casadi_median_us": 1e6 * statistics.median(raw), "final_q": q.tolist()}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--engine", choices=["gfcs", "fabrics"], required=True)
    p.add_argument("--obstacles", type=int, default=10, help="sphere obstacles (default 10)")
    p.add_argument("--steps", type=int, default=1000, help="Euler steps of 10 ms (default 1000)")
    p.add_argument("--json", help="write the figures here")
    args = p.parse_args()
    out = run_gfcs(args) if args.engine == "gfcs" else run_fabrics(args)
    print(json.dumps(out, indent=1))
    if args.json:
        Path(args.json).write_text(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
