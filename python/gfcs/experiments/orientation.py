"""End-effector pose control with a geometric fabric (GF App. G), and a GFCS problem whose goal is a pose.

* ``reach``: the reaching fabric of GF Sec. VII (:data:`gfcs.experiments.panda.REACHING_CONFIG`) with App. G's
  orientation attractors switched on: the hand's three unit axes, each a task space x = R e_k (k = x, y, z)
  carrying the same attractor design as the position (VII-A3), toward the target rotation's axes. The
  hand visits :data:`POSES` in turn, :data:`HOLD` s each, from the ready configuration at 100 Hz.
  Measured over time: the position error ‖p − p_d‖ (m) and the orientation error, the angle of R_dᵀR (rad).
* ``gfcs``: a generated table-pick problem whose request is a MoveIt pose goal (position within
  :data:`POSITION_TOLERANCE` of the hand's TCP at the generated goal, XYZ-Euler orientation within
  :data:`ANGLE_TOLERANCE` about each axis), solved by :func:`gfcs.planning.solve` (the pose goal becomes a
  joint goal by inverse kinematics, :mod:`gfcs.pose_goal`); measured: success and the final pose's
  violations of the goal's tolerances.

Units: metres, radians, seconds; poses in the Panda's base frame.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any, Dict, List

import numpy as np

__all__ = ["POSES", "ORIENTATION_CONFIG", "reach", "gfcs_pose_goal", "run", "plot", "summary_text", "add_cli"]

DT = 0.01  #: integration step [s]
HOLD = 5.0  #: time per pose [s]
POSITION_TOLERANCE = 0.005  #: the GFCS pose goal's position tolerance [m]
ANGLE_TOLERANCE = 0.05  #: the GFCS pose goal's orientation tolerance about each axis [rad]


def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


#: The ready hand rotation (z down, x forward) and the targets: (position m, rotation 3 × 3), rotated from
#: it by 30° about z, 45° about the world x, and 60° about the world y then 20° about z.
_DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
POSES = [
    (np.array([0.45, 0.15, 0.45]), _rot("z", np.pi / 6) @ _DOWN),
    (np.array([0.40, -0.20, 0.50]), _rot("x", np.pi / 4) @ _DOWN),
    (np.array([0.55, 0.00, 0.35]), _rot("z", np.pi / 9) @ _rot("y", np.pi / 3) @ _DOWN),
]
#: REACHING_CONFIG with the App. G axis attractors on, geometry and potential gains 5 (the defaults, 1, leave
#: 0.9-5.6° and 0.8-9.9 mm after 5 s at these poses; 5 leaves 0.2-0.6° and 0.5-2 mm).
ORIENTATION_CONFIG: Dict[str, Any] = {"ee_orientation": {"enabled": True, "geometry": {"gain": 5.0},
                                                         "potential": {"gain": 5.0}}}


def _angle(r: np.ndarray, rd: np.ndarray) -> float:
    """The angle (rad) of the rotation R_dᵀR."""
    return float(np.arccos(np.clip((np.trace(rd.T @ r) - 1.0) / 2.0, -1.0, 1.0)))


def reach(hold: float = HOLD) -> Dict[str, Any]:
    """App. G: the hand driven to each pose of :data:`POSES` in turn; errors every step and at each hold's end."""
    import gfcs
    from gfcs.experiments.panda import READY, REACHING_CONFIG
    from gfcs.pose_goal import quaternion_xyzw

    robot = gfcs.Robot.panda()
    config = gfcs.FabricConfig(REACHING_CONFIG).replace(ORIENTATION_CONFIG)
    fabric = gfcs.Fabric(robot, gfcs.Scene(), config)
    ee = robot.link_index(robot.ee_link)
    q, qd = READY.copy(), np.zeros(READY.shape[0])
    pos_err: List[float] = []
    ang_err: List[float] = []
    path, targets, hands = [], [], []
    final = []
    for p, r in POSES:
        target = (p, quaternion_xyzw(r))
        for _ in range(int(round(hold / DT))):
            qdd = np.asarray(fabric.acceleration(q, qd, READY, ee_target=target))
            qd = qd + DT * qdd
            q = q + DT * qd
            pose = np.asarray(robot.link_poses(q))[ee]
            pos_err.append(float(np.linalg.norm(pose[:3, 3] - p)))
            ang_err.append(_angle(pose[:3, :3], r))
            path.append(q.copy())
            targets.append(p)
            hands.append(pose[:3, 3].copy())
        final.append({"position_error": pos_err[-1], "orientation_error": ang_err[-1]})
    return {"final": final, "position_error": np.asarray(pos_err), "orientation_error": np.asarray(ang_err),
            "q": np.asarray(path), "target": np.asarray(targets), "hand": np.asarray(hands),
            "scene": gfcs.Scene(),
            "max_final_position_error": max(f["position_error"] for f in final),
            "max_final_orientation_error": max(f["orientation_error"] for f in final)}


def gfcs_pose_goal(seed: int = 0, time_limit: float = 5.0) -> Dict[str, Any]:
    """A generated table-pick problem with a pose goal (orientation tolerance :data:`ANGLE_TOLERANCE`),
    solved by GFCS; returns success and the final configuration's pose-goal violations."""
    import gfcs
    from gfcs.generators import Primitive, generate, pose_request_yaml, scene_yaml
    from gfcs.planning import solve
    from gfcs.pose_goal import pose_errors
    from gfcs.problems import load_mbm

    generated = generate("table_pick", 1, seed=seed)[0]
    with tempfile.TemporaryDirectory() as tmp:
        scene, request = Path(tmp) / "scene.yaml", Path(tmp) / "request.yaml"
        primitives = [Primitive(**d) if isinstance(d, dict) else d for d in generated.meta["primitives"]]
        scene.write_text(scene_yaml(primitives, generated.name))
        request.write_text(pose_request_yaml(generated.robot, generated.q0, generated.goal,
                                             position_tolerance=POSITION_TOLERANCE,
                                             angle_tolerance=ANGLE_TOLERANCE))
        problem = load_mbm(scene, request, robot=gfcs.Robot.panda(), name=f"table_pick pose goal, seed {seed}")
    result = solve(problem, time_limit=time_limit)
    errors = pose_errors(problem.robot, problem.meta["pose_goal"], result.trajectory.q[-1])
    return {"seed": seed, "success": bool(result.success), "position_violation": float(errors[0]),
            "orientation_violation": float(errors[1]), "position_tolerance": POSITION_TOLERANCE,
            "angle_tolerance": ANGLE_TOLERANCE, "duration": float(result.metrics["duration"])}


def run(seed: int = 0, with_gfcs: bool = True) -> Dict[str, Any]:
    """Both parts (``gfcs`` only when ``with_gfcs``)."""
    out = {"reach": reach()}
    if with_gfcs:
        out["gfcs"] = gfcs_pose_goal(seed)
    return out


def summary_text(res: Dict[str, Any]) -> str:
    r = res["reach"]
    lines = [f"GF App. G pose reaching ({len(r['final'])} poses, {HOLD:.0f} s each): final position errors "
             + ", ".join(f"{f['position_error'] * 1000:.2f}" for f in r["final"]) + " mm; orientation errors "
             + ", ".join(f"{np.degrees(f['orientation_error']):.2f}" for f in r["final"]) + " deg"]
    if "gfcs" in res:
        g = res["gfcs"]
        lines.append(f"GFCS pose goal (±{g['angle_tolerance']} rad, {g['position_tolerance'] * 1000:.0f} mm): "
                     f"{'solved' if g['success'] else 'NOT solved'}, position violation "
                     f"{g['position_violation'] * 1000:.3f} mm, orientation violation {g['orientation_violation']:.4f} rad")
    return "\n".join(lines)


def plot(res: Dict[str, Any], out: Any) -> Any:
    """Position and orientation errors over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gfcs.plots import save_png

    r = res["reach"]
    t = np.arange(1, len(r["position_error"]) + 1) * DT
    fig, ax = plt.subplots(1, 2, figsize=(10.4, 4.0))
    ax[0].semilogy(t, r["position_error"])
    ax[0].set(xlabel="time [s]", ylabel="‖p − p_d‖ [m]", title="App. G: position error")
    ax[1].semilogy(t, np.maximum(np.degrees(r["orientation_error"]), 1e-6))
    ax[1].set(xlabel="time [s]", ylabel="angle of R_dᵀR [deg]", title="App. G: orientation error")
    fig.tight_layout()
    return save_png(fig, out)


def _cmd(args: argparse.Namespace) -> int:
    from gfcs.experiments import report

    res = run(args.seed, with_gfcs=not args.no_gfcs)
    motion = ("position_error", "orientation_error", "q", "target", "hand", "scene")
    claims = {"reach": {k: v for k, v in res["reach"].items() if k not in motion}}
    if "gfcs" in res:
        claims["gfcs"] = res["gfcs"]
    report(summary_text(res), claims, args.json, plot(res, args.out) if args.out else None)
    if args.rrd_dir:
        from gfcs.experiments.panda import PandaExperiments, record

        for path in record(PandaExperiments(results={"orientation": {"bent": res["reach"]}}, model="shipped"),
                           args.rrd_dir):
            print(f"wrote {path}")
    return 0


def add_cli(experiment_subparsers: Any) -> argparse.ArgumentParser:
    """Add ``orientation`` under ``gfcs experiment``."""
    from gfcs.experiments import add_output_options

    p = experiment_subparsers.add_parser(
        "orientation", help="GF App. G: hand pose reaching; a GFCS problem with a pose goal",
        description="Drive the Panda's hand to target poses with the fabric's position and axis attractors "
                    "(GF App. G) and solve a generated problem whose goal is a pose with an orientation "
                    "tolerance; print the errors, optionally write a figure and JSON.",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the generated pose-goal problem (default 0)")
    p.add_argument("--no-gfcs", action="store_true", help="skip the GFCS pose-goal problem")
    add_output_options(p, recording="DIR/orientation.rrd")
    p.set_defaults(func=_cmd)
    return p
