"""The Franka Panda experiments of GF Sec. VII: task-space reaching with a geometric fabric and RMPflow.

The fabric is GF Sec. VII-A's design on the shipped Panda (:data:`REACHING_CONFIG`): joint-space attraction
to the ready posture (geometry only: a posture in the null space of the reach), distance-space repulsion
(joint limits, self-collision and obstacles: barrier geometry and potential) and end-effector position
attraction of the hand (``panda_hand`` origin: geometry and potential), with the speed control's goal switch
on the hand's distance to its target (``speed.goal_space = "ee"``). Three systems are compared
(:data:`VARIANTS`): the fabric (``bent``); the same components *unbent* (``mode = "unbent"``: the classical
Lagrangian system of the same Finsler energies, forced by the same potentials, without the geometries); and
RMPflow (``rmpflow``, :class:`gfcs.Rmpflow`: Cheng et al. 2018 with the hand-designed Franka leaves of RMP²,
the paper's own tuned RMP not being public) on the same robot, scene and task maps. All run at 100 Hz with
semi-implicit Euler, as in GF, from rest at the ready configuration. The arm's collision spheres are the
thin model by default (:data:`MODELS`; the shipped covering spheres make the hand 22 cm across).

* ``wall`` (VII-B, Fig. 2): a wall whose face is the plane x = :data:`WALL_X`; the hand's target starts 20 cm
  before the face and advances 1 cm toward it every 5 s (21 targets, the last on the face). Per target: the
  hand's distance to its target at the end of its 5 s (the convergence error, m) and the hand origin's
  closest approach to the face (m). Claims: the largest target distance from the wall whose error
  exceeds 1 mm (where convergence "degrades"; GF: ~6 cm for the fabric, ~9 cm for their RMP), and the
  closest approach (GF: the fabric comes ~50 % closer).
* ``rings`` (VII-C, Fig. 3): five rings of 2.5 cm spheres one behind the other along the x axis, the hand's
  target beyond the last. The paper's "ring radius starts at 17 cm and decreases to 13 cm" is read both ways
  (:func:`ring_radii`): as the sphere centres' radius (free openings 14.5-10.5 cm) and as the free opening.
  Measured: the rings the hand passes through (its origin crosses the ring's plane inside the ring's free
  radius), whether it reaches the target (within 1 cm in :data:`RING_TIME`), and the smallest
  sphere-model clearance (< 0: collision).
* ``dynamic`` (VII-D, Fig. 4): 19 seeded random targets, one every 5 s, among two static spheres and
  three moving ones (speeds 0.2–0.39 m/s, bouncing inside a box); the policy is given the obstacles'
  positions and velocities at every step. Targets are drawn in a box in front of the robot regardless of
  the obstacles, so some lie in or next to one (unreachable while it is there), as random targets do.
  Measured over 10 seeds (:func:`dynamic_seeds`, means with 95 % intervals): the targets reached (the hand
  within 1 cm of the target at some step of its 5 s; GF: 16 of 19 with the fabric, 11 with the RMP) and the
  collision rate (the percentage of steps at which a collision sphere overlaps an obstacle; GF: 0.4 % and
  8.18 %).

Units: metres, seconds, radians; positions in the Panda's base frame (x forward, z up).
"""

from __future__ import annotations

import argparse
import functools
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Sequence, Tuple

import numpy as np

from gfcs.errors import InvalidValueError

__all__ = [
    "REACHING_CONFIG", "VARIANTS", "MODELS", "EXPERIMENTS", "Settings", "SETTINGS", "ring_radii", "dynamic_seeds", "READY", "WALL_X", "RING_RADII", "RING_TIME",
    "Reacher", "wall", "rings", "dynamic", "run", "plot", "record", "summary_text", "add_cli",
]

#: The systems compared: the geometric fabric, the same components without bending, and RMPflow
#: (:class:`gfcs.Rmpflow`, Cheng et al. 2018, with the RMP² Franka leaves) on the same robot and scene.
VARIANTS = ("bent", "unbent", "rmpflow")
#: Collision-sphere models of the hand: ``thin`` (:func:`gfcs.problems.thin_sphere_model`: links 5-7 and the
#: hand fitted to within a few mm of the Franka meshes, the hand 20.5 cm across its fingers' opening
#: direction) and ``shipped`` (the covering spheres, the hand 22 cm across: wider than the last ring's
#: 21 cm opening).
MODELS = ("thin", "shipped")
#: The three experiments of GF Sec. VII, in the paper's order.
EXPERIMENTS = ("wall", "rings", "dynamic")
#: Start and posture: the Panda's ready configuration [rad].
READY = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
#: Fabric for task-space reaching (merged over the defaults): a weak posture (joint attraction without
#: potential, so that it does not pull the hand off its target), the goal damper switched on the hand's
#: distance (m) with B = 10 /s and r = 5 cm (with the defaults, B = 20 and r = 0.15, the hand crept in:
#: 1.5 mm left after 5 s in free space; with these it is within 1 mm after 2.0–2.4 s and 0.013 mm after 5 s).
REACHING_CONFIG: Dict[str, Any] = {
    "joint_attraction": {"geometry": {"gain": 0.2}, "potential": {"gain": 0.0}},
    "speed": {"goal_space": "ee", "goal_damping": 10.0, "goal_switch_radius": 0.05},
}
DT = 0.01  #: integration step [s] (100 Hz)
#: Euler sub-steps of RMPflow per step (1 kHz): at 100 Hz RMPflow with the RMP² leaves diverges near
#: obstacles (6 of 10 seeds of the dynamic task; the velocity alternates in sign step by step as the
#: collision leaves' velocity gates and 1 cm repulsion scale switch), so it is integrated ten times finer.
RMP_SUBSTEPS = 10
HOLD = 5.0  #: time per target [s] (GF: a new target every five seconds)
REACHED = 0.01  #: a target counts as reached within this distance [m]
WALL_X = 0.62  #: x of the wall's face [m]
WALL_TARGET = (0.45, 0.0)  #: (y, z) of the wall targets [m]
RING_RADII = (0.17, 0.16, 0.15, 0.14, 0.13)  #: ring radii, sphere centres to axis [m]
RING_BALL = 0.025  #: radius of the ring spheres [m]
RING_X = (0.40, 0.46, 0.52, 0.58, 0.64)  #: x of the ring planes [m]
RING_READINGS = ("centre", "opening")  #: readings of the paper's ring radius, see :func:`ring_radii`
RING_AXIS = (0.0, 0.40)  #: (y, z) of the rings' common axis [m]
RING_TARGET_X = 0.74  #: x of the target beyond the last ring [m]
RING_TIME = 10.0  #: time budget of the ring task [s]
MOVING_RADIUS = 0.06  #: radius of the moving spheres of the dynamic task [m]
START_CLEARANCE = 0.05  #: the moving spheres' least clearance from the arm's spheres at the start [m]
#: Per-step data of the results (drawn by :func:`record`, left out of the claims).
MOTION_KEYS = ("hand", "q", "target", "scene", "moving")


@dataclass
class Settings:
    """Overrides of the compared systems, for ablations from the command line: ``fabric`` merged over
    :data:`REACHING_CONFIG` (both fabric variants), ``rmpflow`` the :class:`gfcs.Rmpflow` config, and
    ``rmp_substeps`` RMPflow's Euler sub-steps per step."""

    fabric: Dict[str, Any] = field(default_factory=dict)
    rmpflow: Dict[str, Any] = field(default_factory=dict)
    rmp_substeps: int = RMP_SUBSTEPS


#: The settings every :class:`Reacher` is built with (the CLI's ``--fabric-config``, ``--rmp-config`` and
#: ``--rmp-substeps`` set them).
SETTINGS = Settings()


class Reacher:
    """The shipped Panda (sphere model ``model``) under a reaching policy in a scene (a fabric, bent or
    unbent, or RMPflow; ``fabric`` holds either): ``step`` integrates one semi-implicit Euler step toward
    the hand target and records the hand position and the sphere-model clearance of the state."""

    def __init__(self, variant: str, scene: Any, model: str = "thin") -> None:
        import gfcs
        from gfcs.problems import thin_sphere_model

        if variant not in VARIANTS:
            raise InvalidValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
        if model not in MODELS:
            raise InvalidValueError(f"model must be one of {MODELS}, got {model!r}")
        self.robot = gfcs.Robot.panda()
        if model == "thin":
            self.robot = thin_sphere_model(self.robot)
        self.substeps = SETTINGS.rmp_substeps if variant == "rmpflow" else 1
        if variant == "rmpflow":
            self.fabric = gfcs.Rmpflow(self.robot, scene, SETTINGS.rmpflow or None)
            self.diagnostics = self.fabric.diagnostics
        else:
            config = gfcs.FabricConfig(REACHING_CONFIG).replace(SETTINGS.fabric).replace(mode=variant)
            self.fabric = gfcs.Fabric(self.robot, scene, config)
            # the clearance only: the forcing potential ψ is not evaluated again
            self.diagnostics = functools.partial(self.fabric.diagnostics, potential=False)
        self.q, self.qd = READY.copy(), np.zeros(READY.shape[0])
        self.hand: List[np.ndarray] = []
        self.clearance: List[float] = []
        self.path: List[np.ndarray] = []  # q after every step
        self.targets: List[np.ndarray] = []  # the target of every step

    def step(self, target: np.ndarray) -> np.ndarray:
        """One step toward ``target`` (3,); returns the hand position after it."""
        pose = (target, (0.0, 0.0, 0.0, 1.0))
        for k in range(self.substeps):
            qdd = self.fabric.acceleration(self.q, self.qd, READY, ee_target=pose)
            if k == 0:  # the clearance of the step-start state, as for the fabric
                self.clearance.append(float(self.diagnostics()["min_clearance"]))
            self.qd = self.qd + DT / self.substeps * np.asarray(qdd)
            self.q = self.q + DT / self.substeps * self.qd
        hand = np.asarray(self.robot.ee_position(self.q), dtype=np.float64)
        self.hand.append(hand)
        self.path.append(self.q.copy())
        self.targets.append(np.asarray(target, dtype=np.float64))
        return hand

    def motion(self, scene: Any) -> Dict[str, Any]:
        """What :func:`record` draws: ``q`` (T, dof), ``target`` (T, 3) and the static ``scene``."""
        return {"q": np.asarray(self.path), "target": np.asarray(self.targets), "scene": scene}


def wall(variant: str, distances: Sequence[float] = tuple(np.round(np.arange(0.20, -0.001, -0.01), 3)),
         model: str = "thin") -> Dict[str, Any]:
    """GF VII-B for one variant: a target ``d`` m before the wall's face for each ``d`` of ``distances``
    in turn, :data:`HOLD` s each. Returns the per-target errors and closest approaches and the claims."""
    import gfcs

    scene = gfcs.Scene()
    scene.add_box([0.02, 1.2, 1.0], pose=([WALL_X + 0.01, 0.0, 0.5], [0.0, 0.0, 0.0, 1.0]), name="wall")
    r = Reacher(variant, scene, model)
    errors, approach = [], []
    for d in distances:
        target = np.array([WALL_X - d, *WALL_TARGET])
        hands = [r.step(target) for _ in range(int(round(HOLD / DT)))]
        errors.append(float(np.linalg.norm(hands[-1] - target)))
        approach.append(float(WALL_X - max(h[0] for h in hands)))
    degraded = [d for d, e in zip(distances, errors) if e > 1e-3]
    return {"distances": [float(d) for d in distances], "errors": errors, "closest_approach": approach,
            "degrades_below": float(max(degraded)) if degraded else None,
            "min_approach": float(min(approach)), "min_clearance": float(min(r.clearance)),
            "hand": np.asarray(r.hand), **r.motion(scene)}


def ring_radii(reading: str = "centre") -> Tuple[float, ...]:
    """Radii (m) of the ring spheres' centres for a reading of GF VII-C's "ring radius": ``centre`` (the
    sphere centres' distance to the axis is 17-13 cm, free openings 14.5-10.5 cm) or ``opening`` (the free
    opening is 17-13 cm, centres 2.5 cm further out)."""
    if reading not in RING_READINGS:
        raise InvalidValueError(f"reading must be one of {RING_READINGS}, got {reading!r}")
    return tuple(r + (RING_BALL if reading == "opening" else 0.0) for r in RING_RADII)


def rings(variant: str, model: str = "thin", reading: str = "centre") -> Dict[str, Any]:
    """GF VII-C for one variant: the rings of :func:`ring_radii` at :data:`RING_X`, the target beyond."""
    import gfcs

    scene = gfcs.Scene()
    radii = ring_radii(reading)
    for x, radius in zip(RING_X, radii):
        n = int(np.ceil(2 * np.pi * radius / (2 * RING_BALL)))  # touching spheres
        for a in np.linspace(0.0, 2 * np.pi, n, endpoint=False):
            scene.add_sphere([x, RING_AXIS[0] + radius * np.cos(a), RING_AXIS[1] + radius * np.sin(a)], RING_BALL)
    target = np.array([RING_TARGET_X, *RING_AXIS])
    r = Reacher(variant, scene, model)
    hand = np.asarray([r.step(target) for _ in range(int(round(RING_TIME / DT)))])
    passed = []
    for x, radius in zip(RING_X, radii):
        k = np.nonzero((hand[:-1, 0] < x) & (hand[1:, 0] >= x))[0]  # first crossing of the ring's plane
        if len(k) == 0:
            passed.append(False)
            continue
        a, b = hand[k[0]], hand[k[0] + 1]
        at = a + (x - a[0]) / (b[0] - a[0]) * (b - a)
        passed.append(bool(np.hypot(at[1] - RING_AXIS[0], at[2] - RING_AXIS[1]) < radius - RING_BALL))
    error = np.linalg.norm(hand - target, axis=1)
    return {"rings_passed": passed, "n_passed": int(sum(passed)), "reached": bool(error.min() < REACHED),
            "final_error": float(error[-1]), "min_clearance": float(min(r.clearance)), "hand": hand,
            **r.motion(scene)}


def dynamic(variant: str, seed: int = 0, n_targets: int = 19, model: str = "thin") -> Dict[str, Any]:
    """GF VII-D for one variant: ``n_targets`` targets (seeded), :data:`HOLD` s each, among static and
    moving spheres whose poses and velocities the fabric is given every step."""
    import gfcs

    rng = np.random.default_rng(seed)
    lo, hi = np.array([0.25, -0.5, 0.15]), np.array([0.70, 0.5, 0.80])  # where the moving spheres bounce
    scene = gfcs.Scene()
    scene.add_sphere([0.45, 0.35, 0.30], 0.08, name="static0")
    scene.add_sphere([0.45, -0.35, 0.60], 0.08, name="static1")
    static = scene.copy()
    moving = []
    shipped = gfcs.Robot.panda()  # the covering spheres: a start clear of them is clear of the thin ones
    centres, radii = np.asarray(shipped.sphere_centers(READY)), np.asarray(shipped.sphere_radii)
    for k in range(3):
        direction = rng.normal(size=3)
        velocity = rng.uniform(0.2, 0.39) * direction / np.linalg.norm(direction)
        position = rng.uniform(lo, hi)
        # a moving sphere starts at least START_CLEARANCE from the arm at rest (a start inside the arm
        # would be a collision no policy can avoid)
        while np.min(np.linalg.norm(centres - position, axis=1) - radii) < MOVING_RADIUS + START_CLEARANCE:
            position = rng.uniform(lo, hi)
        moving.append([scene.add_sphere(position, MOVING_RADIUS, name=f"moving{k}", velocity=velocity), position,
                       velocity])
    targets = rng.uniform([0.30, -0.40, 0.25], [0.60, 0.40, 0.70], size=(n_targets, 3))
    r = Reacher(variant, scene, model)
    reached, errors, positions = [], [], []
    diverged = False
    for target in targets:
        best = np.inf
        for _ in range(0 if diverged else int(round(HOLD / DT))):
            for m in moving:  # move, bounce off the box, and tell the fabric
                m[1] = m[1] + DT * m[2]
                out = (m[1] < lo) | (m[1] > hi)
                m[2] = np.where(out, -m[2], m[2])
                r.fabric.update_obstacle(m[0], pose=(m[1], (0.0, 0.0, 0.0, 1.0)), velocity=m[2])
            try:
                best = min(best, float(np.linalg.norm(r.step(target) - target)))
            except gfcs.NonFiniteError:  # the policy's state blew up: this and the later targets are missed
                diverged = True
                break
            positions.append([m[1] for m in moving])
        reached.append(best < REACHED)
        errors.append(best)
    clearance = np.asarray(r.clearance[: len(r.hand)])
    return {"targets": targets.tolist(), "reached": reached, "n_reached": int(sum(reached)), "diverged": diverged,
            "closest": errors, "collision_rate": float(np.mean(clearance < 0.0)),
            "min_clearance": float(clearance.min()), "hand": np.asarray(r.hand), **r.motion(static),
            "moving": np.asarray(positions), "moving_radius": MOVING_RADIUS}


@dataclass
class PandaExperiments:
    """Results per experiment and variant (the dicts of :func:`wall`, :func:`rings`, :func:`dynamic`)."""

    results: Dict[str, Dict[str, Dict[str, Any]]] = field(default_factory=dict)
    seed: int = 0
    model: str = "thin"

    def claims(self) -> Dict[str, Any]:
        """The results without their per-step data (:data:`MOTION_KEYS`), JSON-ready."""
        return {"seed": self.seed, "model": self.model, **{e: {v: {k: x for k, x in res.items() if k not in MOTION_KEYS}
                                          for v, res in by.items()} for e, by in self.results.items()}}


def dynamic_seeds(variant: str, seeds: Sequence[int], model: str = "thin") -> Dict[str, Any]:
    """:func:`dynamic` for every seed of ``seeds``: the first seed's full result (for the figure and the
    recording) with, over the seeds, the targets reached and the collision rates per seed and their means
    with 95 % Student-t intervals (``*_ci95``: (low, high), the low end clipped at 0), and the seeds whose
    policy diverged (``diverged_seeds``: their remaining targets count as missed)."""
    from scipy import stats

    runs = [dynamic(variant, int(s), model=model) for s in seeds]
    out = dict(runs[0])
    out["seeds"] = [int(s) for s in seeds]
    out["diverged_seeds"] = [int(s) for s, r in zip(seeds, runs) if r["diverged"]]
    for key in ("n_reached", "collision_rate"):
        x = np.asarray([r[key] for r in runs], dtype=np.float64)
        half = float(stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else np.nan
        out[f"{key}_per_seed"] = x.tolist()
        out[f"{key}_mean"] = float(x.mean())
        out[f"{key}_ci95"] = [max(float(x.mean() - half), 0.0), float(x.mean() + half)]  # counts, rates ≥ 0
    return out


def run(experiments: Sequence[str] = EXPERIMENTS, seed: int = 0, n_seeds: int = 10, model: str = "thin",
        variants: Sequence[str] = VARIANTS) -> PandaExperiments:
    """Run ``experiments`` (names of :data:`EXPERIMENTS`) for ``variants`` with the sphere model ``model``:
    the dynamic task over seeds ``seed`` .. ``seed + n_seeds − 1``, the rings in both readings of
    :func:`ring_radii` (``opening`` under the ``opening`` key of the ``centre`` result)."""
    unknown = [e for e in experiments if e not in EXPERIMENTS]
    if unknown:
        raise InvalidValueError(f"unknown experiment(s) {unknown}; choose from {EXPERIMENTS}")
    out = PandaExperiments(seed=seed, model=model)
    from tqdm import tqdm

    for e in experiments:
        out.results[e] = {}
        for v in tqdm(variants, desc=f"GF VII {e}", leave=False, disable=None):
            if e == "dynamic":
                out.results[e][v] = dynamic_seeds(v, range(seed, seed + n_seeds), model)
            elif e == "wall":
                out.results[e][v] = wall(v, model=model)
            else:
                res = rings(v, model)
                opening = rings(v, model, reading="opening")
                res["opening"] = {k: opening[k] for k in ("rings_passed", "n_passed", "reached", "final_error",
                                                          "min_clearance")}
                out.results[e][v] = res
    return out


def summary_text(exp: PandaExperiments) -> str:
    """The measured claims, one line per experiment and variant."""
    lines = [f"GF Sec. VII, shipped Panda ({exp.model} spheres), 100 Hz semi-implicit Euler (RMPflow: "
             f"{SETTINGS.rmp_substeps} sub-steps); bent = geometric fabric, unbent = the "
             "same energies and potentials without the geometries, rmpflow = RMPflow (RMP² Franka leaves)"]
    variants = next(iter(exp.results.values())).keys() if exp.results else ()
    for v in variants:
        if "wall" in exp.results:
            w = exp.results["wall"][v]
            worst = "none" if w["degrades_below"] is None else f"{w['degrades_below'] * 100:.0f} cm"
            lines.append(f"wall     {v:<7} error > 1 mm from a target {worst} before the wall on; closest "
                         f"approach {w['min_approach'] * 100:.1f} cm; min clearance {w['min_clearance'] * 1000:.1f} mm")
        if "rings" in exp.results:
            g = exp.results["rings"][v]
            lines.append(f"rings    {v:<7} {g['n_passed']}/{len(RING_RADII)} rings passed, target "
                         f"{'reached' if g['reached'] else 'NOT reached'} (final error {g['final_error'] * 1000:.1f} "
                         f"mm), min clearance {g['min_clearance'] * 1000:.1f} mm"
                         + (f"; radii read as openings: {g['opening']['n_passed']}/{len(RING_RADII)}, target "
                            f"{'reached' if g['opening']['reached'] else 'NOT reached'}" if "opening" in g else ""))
        if "dynamic" in exp.results:
            d = exp.results["dynamic"][v]
            if "seeds" in d:
                lo, hi = d["n_reached_ci95"]
                clo, chi = d["collision_rate_ci95"]
                lines.append(f"dynamic  {v:<7} {d['n_reached_mean']:.1f}/{len(d['reached'])} targets reached "
                             f"(95 % CI {lo:.1f}-{hi:.1f}, {len(d['seeds'])} seeds), collision rate "
                             f"{d['collision_rate_mean'] * 100:.2f} % of steps (95 % CI {clo * 100:.2f}-{chi * 100:.2f})"
                             + (f"; diverged: seeds {d['diverged_seeds']}" if d["diverged_seeds"] else ""))
            else:
                lines.append(f"dynamic  {v:<7} {d['n_reached']}/{len(d['reached'])} targets reached, collision "
                             f"rate {d['collision_rate'] * 100:.2f} % of steps, min clearance "
                             f"{d['min_clearance'] * 1000:.1f} mm")
    return "\n".join(lines)


def plot(exp: PandaExperiments, out: Any) -> Path:
    """One panel per experiment run: wall errors against the target's distance to the wall; the hand's
    distance from the rings' axis against x, with the rings' free radii; the hand's distance to its
    current target over time in the dynamic task."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [e for e in EXPERIMENTS if e in exp.results]
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 4.0), squeeze=False)
    colors = {"bent": "tab:blue", "unbent": "tab:orange", "rmpflow": "tab:green"}
    for ax, name in zip(axes[0], names):
        for v, res in exp.results[name].items():
            if name == "wall":
                ax.semilogy(np.asarray(res["distances"]) * 100, np.maximum(res["errors"], 1e-6), "o-",
                            color=colors[v], label=v)
                ax.axhline(1e-3, color="grey", lw=0.8, ls="--")
                ax.set(xlabel="target distance to the wall [cm]", ylabel="final hand error [m]",
                       title="VII-B wall approach")
            elif name == "rings":
                h = res["hand"]
                ax.plot(h[:, 0], np.hypot(h[:, 1] - RING_AXIS[0], h[:, 2] - RING_AXIS[1]) * 100, color=colors[v],
                        label=f"{v}: {res['n_passed']}/{len(RING_RADII)} rings")
                ax.set(xlabel="hand x [m]", ylabel="hand distance from the rings' axis [cm]",
                       title="VII-C ring-constricted navigation")
            else:
                t = np.arange(len(res["hand"])) * DT
                steps = int(round(HOLD / DT))
                target = np.repeat(np.asarray(res["targets"]), steps, axis=0)[: len(t)]
                ax.semilogy(t, np.linalg.norm(res["hand"] - target, axis=1), color=colors[v], lw=0.8,
                            label=f"{v}: {res['n_reached']}/{len(res['reached'])} reached")
                ax.axhline(REACHED, color="grey", lw=0.8, ls="--")
                ax.set(xlabel="time [s]", ylabel="hand distance to its target [m]",
                       title="VII-D dynamic obstacle reaching")
        if name == "rings":
            for x, radius in zip(RING_X, RING_RADII):
                ax.plot([x, x], [(radius - RING_BALL) * 100, (radius + RING_BALL) * 100], color="k", lw=3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    from gfcs.plots import save_png

    return save_png(fig, out)


def record(exp: PandaExperiments, directory: Any, every: int = 2) -> List[Path]:
    """Rerun recordings, one per experiment (``<directory>/<name>.rrd``): the obstacles, both variants'
    collision spheres and hand paths on the ``time`` timeline (every ``every``-th step), the hand targets,
    and the moving spheres of the dynamic task. Needs the ``viz`` extra (rerun-sdk)."""
    import rerun as rr

    import gfcs
    from gfcs import viz

    robot = Reacher("bent", gfcs.Scene(), exp.model).robot
    radii = np.asarray(robot.sphere_radii, dtype=np.float64)
    colors = {"bent": (40, 110, 220), "unbent": (240, 140, 30), "rmpflow": (40, 170, 70)}
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, by in exp.results.items():
        path = folder / f"{name}.rrd"
        rec = rr.RecordingStream("gfcs-panda-experiments")
        rec.save(str(path))
        rec.send_recording_name(f"GF Sec. VII {name}")
        rec.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        first = next(iter(by.values()))
        viz._log_obstacles(rec, first["scene"])
        steps = np.arange(0, first["q"].shape[0], max(int(every), 1))
        time = [rr.TimeColumn(viz.TIMELINE, duration=(steps + 1) * DT)]
        n = steps.shape[0]
        rec.send_columns("/world/target", indexes=time,
                         columns=rr.Points3D.columns(positions=first["target"][steps]).partition([1] * n))
        rec.log("/world/target", rr.Points3D.from_fields(colors=[viz._GREEN], radii=[0.02]), static=True)
        if "moving" in first:
            m = first["moving"][steps]
            rec.log("/world/moving", rr.Points3D.from_fields(colors=[(150, 150, 160)]), static=True)
            rec.send_columns("/world/moving", indexes=time, columns=rr.Points3D.columns(
                positions=m.reshape(-1, 3), radii=np.full(m.shape[0] * m.shape[1], first["moving_radius"])
            ).partition([m.shape[1]] * n))
        for v, res in by.items():
            centres = np.asarray(robot.sphere_centers(res["q"][steps]), dtype=np.float64)
            s = centres.shape[1]
            rec.log(f"/{v}/spheres", rr.Points3D.from_fields(colors=[(*colors[v], 160)]), static=True)
            rec.send_columns(f"/{v}/spheres", indexes=time, columns=rr.Points3D.columns(
                positions=centres.reshape(-1, 3), radii=np.tile(radii, n)).partition([s] * n))
            rec.log(f"/{v}/hand_path", rr.LineStrips3D([res["hand"]], colors=[colors[v]], radii=[0.003]),
                    static=True)
        rec.flush()
        rec.disconnect()
        written.append(path)
    return written


# ----------------------------------------------------------------------------------------------- CLI
def _cmd_panda(args: argparse.Namespace) -> int:
    import json

    from gfcs.experiments import report

    SETTINGS.fabric = json.loads(args.fabric_config) if args.fabric_config else {}
    SETTINGS.rmpflow = json.loads(args.rmp_config) if args.rmp_config else {}
    SETTINGS.rmp_substeps = args.rmp_substeps

    exp = run(args.only or EXPERIMENTS, seed=args.seed, n_seeds=args.seeds, model=args.model,
              variants=args.variants or VARIANTS)
    report(summary_text(exp), exp.claims(), args.json, plot(exp, args.out) if args.out else None)
    if args.rrd_dir:
        for path in record(exp, args.rrd_dir):
            print(f"wrote {path}", file=sys.stderr if args.json == "-" else sys.stdout)
    return 0


def add_cli(experiment_subparsers: Any) -> argparse.ArgumentParser:
    """Add ``panda`` under ``gfcs experiment``."""
    from gfcs.experiments import add_output_options

    p = experiment_subparsers.add_parser(
        "panda", help="GF Sec. VII Franka Panda reaching (wall, rings, dynamic obstacles)",
        description="Run the GF Sec. VII Panda experiments with the geometric fabric, the same components "
                    "unbent and RMPflow: wall approach (VII-B), ring-constricted navigation (VII-C) and reaching among "
                    "moving obstacles (VII-D); print the measured claims, optionally write a figure and JSON.",
    )
    p.add_argument("--only", nargs="+", choices=EXPERIMENTS, help="run only these (default: all three)")
    p.add_argument("--seed", type=int, default=0, help="first seed of the dynamic task's targets and obstacles (default 0)")
    p.add_argument("--seeds", type=int, default=10, help="number of seeds of the dynamic task (default 10)")
    p.add_argument("--model", choices=MODELS, default="thin",
                   help="collision-sphere model of the arm (default thin: passes the 13 cm rings' reading as openings)")
    p.add_argument("--variants", nargs="+", choices=VARIANTS, help="systems to run (default: all three)")
    p.add_argument("--fabric-config", metavar="JSON", help="fabric gains merged over REACHING_CONFIG (ablations)")
    p.add_argument("--rmp-config", metavar="JSON", help="RMPflow config merged over its defaults (ablations)")
    p.add_argument("--rmp-substeps", type=int, default=RMP_SUBSTEPS,
                   help=f"RMPflow's Euler sub-steps per 10 ms step (default {RMP_SUBSTEPS}; 1 = 100 Hz)")
    add_output_options(p, "the claims", recording="one per experiment, DIR/<name>.rrd")
    p.set_defaults(func=_cmd_panda)
    return p
