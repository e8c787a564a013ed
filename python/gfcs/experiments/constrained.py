"""Constrained geometric fabrics (GF Lemma IV.3, Sec. IV-E, App. F, Fig. 5): the Panda's hand held on a plane
while it reaches targets off the plane and avoids an obstacle.

The constraint is the scalar C(q) = nᵀ(p(q) − p₀) = 0, with p the hand origin (``panda_hand``), n the
plane's unit normal and p₀ a point of it (m). Each step of 100 Hz semi-implicit Euler:

1. the unconstrained fabric acceleration q̈_d (GF Sec. VII-A's design, :data:`gfcs.experiments.panda
   .REACHING_CONFIG`, the hand attracted to the target);
2. its projection onto the constraint (Lemma IV.3, App. D-B): q̈ = q̈_d − J_c^# (J_c q̈_d + J̇_c q̇) with the
   metric-weighted inverse J_c^# = M̃⁻¹J_cᵀ (J_c M̃⁻¹ J_cᵀ)⁻¹, M̃ the fabric's root metric: the least change
   of q̈_d in the M̃ norm with C̈ = 0, i.e. the constraint force J_cᵀλ of the Lemma; the fabric acts in the
   constraint's null space, J_c = nᵀJ_p (1 × dof);
3. the Euler update, then the Gauss-Newton projection of the state onto the manifold, App. F's
   correction of the discretisation's drift: q ← q − J_c^# C(q), :data:`GAUSS_NEWTON_ITERATIONS` times, and
   q̇ ← q̇ − J_c^# J_c q̇ (the velocity tangent to the plane).

The metric matters: with the identity instead of M̃ the projection ignores the priority the barriers'
metrics give to obstacle directions, and the hand's spheres sink into the obstacle (``--identity-metric``).

App. F solves a penalised discrete program (λ C(q_{k+1})², Δt = 0.04 s, four Gauss-Newton iterations); the
projection here is the λ → ∞ limit of that penalty with the fabric's own time step. Measured: the
constraint violation |C| over time (GF: micrometres) and the hand's distance, at the end of each target's
hold, to the closest point of the plane to the target (GF: within 1 mm).
"""

from __future__ import annotations

import argparse
from typing import Any, Dict, List, Sequence

import numpy as np

__all__ = ["PLANE_POINT", "PLANE_NORMAL", "TARGETS", "ConstrainedReacher", "run", "plot", "summary_text",
           "add_cli"]

DT = 0.01  #: integration step [s] (100 Hz, as GF Sec. VII)
HOLD = 5.0  #: time per target [s]
GAUSS_NEWTON_ITERATIONS = 4  #: App. F: four Gauss-Newton iterations per time step
PLANE_POINT = np.array([0.45, 0.0, 0.40])  #: a point of the plane [m]
PLANE_NORMAL = np.array([0.2, 0.0, 1.0]) / np.linalg.norm([0.2, 0.0, 1.0])  #: unit normal (tilted 11°)
#: targets (m), off the plane by up to 6 cm, visited in turn (GF Fig. 5: orange points)
TARGETS = np.array([[0.55, 0.25, 0.42], [0.40, -0.25, 0.33], [0.60, -0.10, 0.44], [0.35, 0.15, 0.36]])
OBSTACLE = ([0.50, 0.02, 0.40], 0.05)  #: a sphere on the plane, between the first two targets (centre m, radius m)


def on_plane(x: np.ndarray) -> np.ndarray:
    """The closest point of the plane to ``x`` (3,)."""
    return x - float(PLANE_NORMAL @ (x - PLANE_POINT)) * PLANE_NORMAL


class ConstrainedReacher:
    """The shipped Panda under the reaching fabric of GF Sec. VII with its hand constrained to the plane."""

    def __init__(self, obstacle: bool = True, dt: float = DT, identity_metric: bool = False) -> None:
        import gfcs
        from gfcs.experiments.panda import READY, REACHING_CONFIG

        self.robot = gfcs.Robot.panda()
        scene = gfcs.Scene()
        if obstacle:
            scene.add_sphere(*OBSTACLE, name="obstacle")
        self.fabric = gfcs.Fabric(self.robot, scene, gfcs.FabricConfig(REACHING_CONFIG))
        self.posture, self.dt, self.identity_metric = READY.copy(), float(dt), bool(identity_metric)
        self.link = self.robot.link_names[self.robot.link_names.index("panda_hand")]
        self.q, self.qd = self.project(READY.copy(), iterations=50), np.zeros(READY.shape[0])
        self.violation: List[float] = []
        self.drift: List[float] = []  # |C| after the Euler update, before the Gauss-Newton projection
        self.hand: List[np.ndarray] = []
        self.clearance: List[float] = []
        self.path: List[np.ndarray] = []
        self.targets: List[np.ndarray] = []
        self.scene = scene

    def constraint(self, q: np.ndarray) -> tuple:
        """C(q) (m) and its row Jacobian J_c (dof,)."""
        c = float(PLANE_NORMAL @ (self.robot.ee_position(q) - PLANE_POINT))
        return c, PLANE_NORMAL @ np.asarray(self.robot.point_jacobian(q, self.link))

    def inverse(self, jc: np.ndarray) -> np.ndarray:
        """J_c^# (dof,): M̃⁻¹J_cᵀ / (J_c M̃⁻¹ J_cᵀ), with M̃ the fabric's metric at the last evaluation
        (the identity before it, or with ``identity_metric``)."""
        m = None if self.identity_metric else self.fabric.metric()
        w = jc if m is None else np.linalg.solve(m, jc)
        return w / float(jc @ w)

    def project(self, q: np.ndarray, iterations: int = GAUSS_NEWTON_ITERATIONS) -> np.ndarray:
        """Gauss-Newton steps q ← q − J_c^# C(q) onto the manifold C = 0."""
        for _ in range(iterations):
            c, jc = self.constraint(q)
            q = q - self.inverse(jc) * c
        return q

    def step(self, target: np.ndarray) -> None:
        """One constrained step toward ``target`` (3,)."""
        qdd = np.asarray(self.fabric.acceleration(self.q, self.qd, self.posture,
                                                  ee_target=(target, (0.0, 0.0, 0.0, 1.0))))
        self.clearance.append(float(self.fabric.diagnostics()["min_clearance"]))
        _, jc = self.constraint(self.q)
        curvature = float(PLANE_NORMAL @ np.asarray(self.robot.point_jdot_qdot(self.q, self.qd, self.link)))
        qdd = qdd - self.inverse(jc) * (float(jc @ qdd) + curvature)
        self.qd = self.qd + self.dt * qdd
        self.drift.append(abs(self.constraint(self.q + self.dt * self.qd)[0]))
        self.q = self.project(self.q + self.dt * self.qd)
        _, jc = self.constraint(self.q)
        self.qd = self.qd - self.inverse(jc) * float(jc @ self.qd)
        c, _ = self.constraint(self.q)
        self.violation.append(abs(c))
        self.hand.append(np.asarray(self.robot.ee_position(self.q), dtype=np.float64))
        self.path.append(self.q.copy())
        self.targets.append(np.asarray(target, dtype=np.float64))


def run(targets: Sequence[Sequence[float]] = TARGETS, hold: float = HOLD, obstacle: bool = True,
        dt: float = DT, identity_metric: bool = False) -> Dict[str, Any]:
    """Visit ``targets`` in turn, ``hold`` s each. Returns the violation over time (m), the hand's final
    distance to each target's closest plane point (m) and the smallest sphere-model clearance (m)."""
    r = ConstrainedReacher(obstacle=obstacle, dt=dt, identity_metric=identity_metric)
    errors = []
    for target in np.asarray(targets, dtype=np.float64):
        for _ in range(int(round(hold / dt))):
            r.step(target)
        errors.append(float(np.linalg.norm(r.hand[-1] - on_plane(target))))
    violation = np.asarray(r.violation)
    return {"dt": dt, "metric": "identity" if identity_metric else "fabric", "targets": np.asarray(targets).tolist(), "settle_errors": errors,
            "max_violation": float(violation.max()), "mean_violation": float(violation.mean()),
            "max_drift": float(np.max(r.drift)), "min_clearance": float(np.min(r.clearance)),
            "violation": violation, "hand": np.asarray(r.hand), "q": np.asarray(r.path),
            "target": np.asarray(r.targets), "scene": r.scene}


def summary_text(res: Dict[str, Any]) -> str:
    worst = max(res["settle_errors"])
    return (f"GF App. F constrained fabric (hand on a plane, {res['metric']} metric, dt {res['dt']} s, {GAUSS_NEWTON_ITERATIONS} Gauss-Newton "
            f"iterations/step): max violation {res['max_violation']:.2e} m, mean {res['mean_violation']:.2e} m "
            f"(before the projection: up to {res['max_drift']:.2e} m); "
            f"hand to the target's plane point after each hold: worst {worst * 1000:.3f} mm "
            f"({', '.join(f'{e * 1000:.3f}' for e in res['settle_errors'])} mm); min clearance "
            f"{res['min_clearance'] * 1000:.1f} mm")


def plot(res: Dict[str, Any], out: Any) -> Any:
    """Violation over time (log scale) and the hand's distance to the current target's plane point."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gfcs.plots import save_png

    t = np.arange(1, len(res["violation"]) + 1) * res["dt"]
    steps = len(t) // len(res["targets"])
    goal = np.repeat([on_plane(np.asarray(x)) for x in res["targets"]], steps, axis=0)[: len(t)]
    fig, ax = plt.subplots(1, 2, figsize=(10.4, 4.0))
    ax[0].semilogy(t, np.maximum(res["violation"], 1e-18))
    ax[0].set(xlabel="time [s]", ylabel="|C(q)| [m]", title="constraint violation (hand on the plane)")
    ax[1].semilogy(t, np.linalg.norm(res["hand"] - goal, axis=1))
    ax[1].axhline(1e-3, color="grey", lw=0.8, ls="--")
    ax[1].set(xlabel="time [s]", ylabel="hand to target's plane point [m]", title="reaching on the plane")
    fig.tight_layout()
    return save_png(fig, out)


def _cmd(args: argparse.Namespace) -> int:
    from gfcs.experiments import report

    res = run(dt=args.dt, obstacle=not args.no_obstacle, identity_metric=args.identity_metric)
    claims = {k: v for k, v in res.items() if k not in ("violation", "hand", "q", "target", "scene")}
    report(summary_text(res), claims, args.json, plot(res, args.out) if args.out else None)
    if args.rrd_dir:
        from gfcs.experiments.panda import PandaExperiments, record

        for path in record(PandaExperiments(results={"constrained": {"bent": res}}, model="shipped"), args.rrd_dir):
            print(f"wrote {path}")
    return 0


def add_cli(experiment_subparsers: Any) -> argparse.ArgumentParser:
    """Add ``constrained`` under ``gfcs experiment``."""
    from gfcs.experiments import add_output_options

    p = experiment_subparsers.add_parser(
        "constrained", help="GF App. F: the Panda's hand held on a plane while reaching (constrained fabric)",
        description="Reach targets off a plane with the hand constrained to the plane (null-space projection "
                    "of the fabric and Gauss-Newton projection of the state); print the constraint violation "
                    "and settling errors, optionally write a figure and JSON.",
    )
    p.add_argument("--dt", type=float, default=DT, help=f"time step [s] (default {DT}; App. F used 0.04)")
    p.add_argument("--identity-metric", action="store_true",
                   help="project with the identity instead of the fabric's metric M̃ (for comparison)")
    p.add_argument("--no-obstacle", action="store_true", help="leave the sphere on the plane out")
    add_output_options(p, recording="DIR/constrained.rrd")
    p.set_defaults(func=_cmd)
    return p
