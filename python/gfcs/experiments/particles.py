"""The particle experiment of GF Sec. VI (Fig. 1): how Finsler metrics and bending shape behaviour.

A fan of 2-D particles starts at rest to the right of a circular obstacle and is attracted to a target on
its left (point attraction, GF Sec. VI-A; circle repulsion, Sec. VI-B). Four systems are compared, each
regulated to two desired speeds v_d = 2 and 4 m/s (GF App. E-B, eq. 40-46):

- unbent Riemannian (classical mechanics), unbent Finsler (velocity-gated barrier metric, no bending),
- bent Riemannian, bent Finsler (a full geometric fabric: geometry energized by the energy, eq. 17).

The systems themselves run in Rust (``gfcs.particle_rollout``, ``fabric-core`` ``fabric/particle.rs``);
this module lays out the particles, measures the paper's claims (GF Sec. VI-C) and draws the figure:

1. every particle reaches the target except the centre one, shot straight at the obstacle's local
   minimum (``reached``);
2. bent systems change their paths less between the two speeds (``path_change``: mean point-wise
   distance after arc-length resampling, and the Hausdorff distance, m);
3. unbent systems push the centre particle farther out from the obstacle (``centre_standoff``: its final
   distance to the circle, ‖q_T − q_o‖ − r, m) and swing paths wider (``max_lateral_deviation``: largest
   distance of a path from its straight start-target line, m);
4. Finsler metrics let particles head straight to the target once past the obstacle (shorter paths:
   ``mean_path_length``, m).

Units: metres and seconds (the paper's particle world is dimensionless; the defaults of
``gfcs.particle_defaults()`` set the target at (−3, 0) and a unit circle at the origin).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from gfcs.errors import InvalidValueError, ShapeError

__all__ = [
    "VARIANTS",
    "SPEEDS",
    "ParticleSetup",
    "VariantRun",
    "ParticleExperiment",
    "fan_starts",
    "resample_by_arc_length",
    "mean_pointwise_distance",
    "hausdorff_distance",
    "lateral_deviation",
    "run",
    "measure_claims",
    "plot",
    "summary_text",
    "add_cli",
    "register_cli",
]

#: The four systems of GF Sec. VI, in the row order of GF Fig. 1 (Riemannian rows first, then Finsler).
VARIANTS: Tuple[str, ...] = ("unbent_riemannian", "bent_riemannian", "unbent_finsler", "bent_finsler")
#: Desired speeds v_d of GF Fig. 1, m/s.
SPEEDS: Tuple[float, ...] = (2.0, 4.0)


@dataclass
class ParticleSetup:
    """Layout and integration settings of the experiment.

    Attributes:
        n_particles: number of particles, odd (≥ 3) so that one starts on the target-obstacle axis.
        start_radius: distance of every start from the target, m (starts lie on an arc around it).
        half_angle: half opening of the fan seen from the target, degrees (0 < half_angle < 90).
        dt: integration step, s (semi-implicit Euler, as the GF/GFCS rollouts).
        t_max: time budget per particle, s.
        tol: distance to the target that counts as reached, m.
        resample: points per path for the path comparisons (arc-length resampling).
        params: overrides of ``gfcs.particle_defaults()`` (target, obstacle_center, obstacle_radius,
            gains...).
    """

    n_particles: int = 11
    start_radius: float = 6.0
    half_angle: float = 35.0
    dt: float = 0.01
    t_max: float = 15.0
    tol: float = 0.01
    resample: int = 200
    params: Dict[str, Any] = field(default_factory=dict)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid field."""
        if int(self.n_particles) != self.n_particles or self.n_particles < 3 or self.n_particles % 2 == 0:
            raise InvalidValueError(f"n_particles must be an odd integer ≥ 3, got {self.n_particles}")
        if not (math.isfinite(self.half_angle) and 0.0 < self.half_angle < 90.0):
            raise InvalidValueError(f"half_angle must lie in (0, 90) degrees, got {self.half_angle}")
        for name in ("start_radius", "dt", "t_max", "tol"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0):
                raise InvalidValueError(f"{name} must be a positive number, got {v!r}")
        if int(self.resample) < 2:
            raise InvalidValueError(f"resample must be ≥ 2, got {self.resample}")


@dataclass
class VariantRun:
    """The particles of one variant at one speed.

    Attributes:
        variant, speed: the system and its desired speed v_d (m/s).
        paths: N arrays (T_i, 2) of positions, m (T_i samples at ``dt``, until reached or ``t_max``).
        reached: (N,) reached the target within ``tol``.
        t_star: (N,) time to reach, or ``t_max``, s.
        min_clearance: (N,) minimum over the path of ‖q − q_o‖ − r, m (< 0: inside the circle).
    """

    variant: str
    speed: float
    paths: List[np.ndarray]
    reached: np.ndarray
    t_star: np.ndarray
    min_clearance: np.ndarray


@dataclass
class ParticleExperiment:
    """Result of :func:`run`: the set-up, the particle parameters used, the starts, every run, the claims.

    Attributes:
        setup: the :class:`ParticleSetup`.
        params: the full particle parameters (defaults merged with ``setup.params``).
        starts: (N, 2) start positions, m; ``centre`` is the index of the one on the axis.
        runs: ``{(variant, speed): VariantRun}``.
        claims: :func:`measure_claims` of the runs.
    """

    setup: ParticleSetup
    params: Dict[str, Any]
    starts: np.ndarray
    centre: int
    speeds: Tuple[float, ...]
    variants: Tuple[str, ...]
    runs: Dict[Tuple[str, float], VariantRun]
    claims: Dict[str, Any] = field(default_factory=dict)


# ---------------------------------------------------------------------------------------- geometry
def fan_starts(n: int, radius: float, half_angle_deg: float, target: Sequence[float],
               obstacle_center: Sequence[float]) -> np.ndarray:
    """Starts on an arc of ``radius`` around the target, on the far side of the obstacle.

    The arc is centred on the ray from the target through the obstacle centre, spanning ±half_angle_deg;
    the middle start (index n // 2 for odd n) lies on that ray, aimed straight at the obstacle.

    Returns:
        (n, 2) positions, m.
    """
    target = np.asarray(target, dtype=np.float64).reshape(2)
    axis = np.asarray(obstacle_center, dtype=np.float64).reshape(2) - target
    norm = float(np.linalg.norm(axis))
    if norm == 0.0:
        raise InvalidValueError("the target and the obstacle centre coincide: no direction for the fan")
    base = math.atan2(axis[1], axis[0])
    angles = base + np.deg2rad(np.linspace(-half_angle_deg, half_angle_deg, int(n)))
    return target + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def resample_by_arc_length(path: np.ndarray, k: int) -> np.ndarray:
    """``k`` points equally spaced along the polyline ``path`` (T, d) by arc length, (k, d).

    A path of zero length (or one sample) gives ``k`` copies of its first point.
    """
    p = np.asarray(path, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] == 0:
        raise ShapeError(f"path: expected shape (T, d) with T ≥ 1, got {p.shape}")
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    if s[-1] <= 0.0:
        return np.repeat(p[:1], int(k), axis=0)
    u = np.linspace(0.0, s[-1], int(k))
    return np.column_stack([np.interp(u, s, p[:, j]) for j in range(p.shape[1])])


def mean_pointwise_distance(a: np.ndarray, b: np.ndarray, k: int = 200) -> float:
    """Mean distance between corresponding points of ``a`` and ``b`` after arc-length resampling to ``k``
    points each (a path-shape difference that ignores timing), m."""
    ra, rb = resample_by_arc_length(a, k), resample_by_arc_length(b, k)
    return float(np.mean(np.linalg.norm(ra - rb, axis=1)))


def hausdorff_distance(a: np.ndarray, b: np.ndarray, k: int = 200) -> float:
    """Symmetric Hausdorff distance between the arc-length resamplings (``k`` points) of two paths, m."""
    ra, rb = resample_by_arc_length(a, k), resample_by_arc_length(b, k)
    d = np.linalg.norm(ra[:, None, :] - rb[None, :, :], axis=2)
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))


def lateral_deviation(path: np.ndarray, start: Sequence[float], target: Sequence[float]) -> float:
    """Largest distance of ``path`` (T, 2) from the straight line through ``start`` and ``target``, m."""
    p = np.asarray(path, dtype=np.float64)
    s = np.asarray(start, dtype=np.float64)
    d = np.asarray(target, dtype=np.float64) - s
    n = float(np.linalg.norm(d))
    if n == 0.0:
        return float(np.max(np.linalg.norm(p - s, axis=1)))
    rel = p - s
    return float(np.max(np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0]) / n))


def _path_length(path: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


# ---------------------------------------------------------------------------------------------- run
def run(setup: Optional[ParticleSetup] = None, speeds: Sequence[float] = SPEEDS,
        variants: Sequence[str] = VARIANTS) -> ParticleExperiment:
    """Roll out every particle of every variant at every speed (Rust, in parallel) and measure the claims.

    Args:
        setup: layout and settings (default :class:`ParticleSetup`).
        speeds: desired speeds v_d, m/s; at least two, the claims compare the first and the last.
        variants: subset of :data:`VARIANTS`; the bent/unbent comparisons need both of a metric type.

    Returns:
        A :class:`ParticleExperiment` with its ``claims`` filled.
    """
    import gfcs

    setup = setup or ParticleSetup()
    setup.validate()
    speeds = tuple(float(s) for s in speeds)
    if len(speeds) < 2 or not all(math.isfinite(s) and s > 0.0 for s in speeds):
        raise InvalidValueError(f"speeds: expected at least two positive speeds, got {speeds}")
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown or not variants:
        raise InvalidValueError(f"variants: expected a non-empty subset of {VARIANTS}, got {list(variants)}")
    params = dict(gfcs.particle_defaults())
    params.pop("speed", None)
    params.update(setup.params)
    starts = fan_starts(setup.n_particles, setup.start_radius, setup.half_angle, params["target"],
                        params["obstacle_center"])
    runs: Dict[Tuple[str, float], VariantRun] = {}
    for variant in variants:
        for speed in speeds:
            rollouts = gfcs.particle_rollout(variant, speed, starts, dt=setup.dt, t_max=setup.t_max,
                                             tol=setup.tol, **params)
            runs[(variant, speed)] = VariantRun(
                variant=variant,
                speed=speed,
                paths=[np.asarray(r.q, dtype=np.float64).reshape(-1, 2) for r in rollouts],
                reached=np.array([bool(r.reached) for r in rollouts]),
                t_star=np.array([float(r.t_star) for r in rollouts]),
                min_clearance=np.array([float(r.min_clearance) for r in rollouts]),
            )
    exp = ParticleExperiment(setup=setup, params=params, starts=starts, centre=setup.n_particles // 2,
                             speeds=speeds, variants=tuple(variants), runs=runs)
    exp.claims = measure_claims(exp)
    return exp


def measure_claims(exp: ParticleExperiment) -> Dict[str, Any]:
    """The GF Sec. VI-C claims measured on the runs (see the module docstring); JSON-ready.

    Returns:
        ``{"setup": {...}, "variants": {variant: {...}}, "checks": {claim: bool}}``. Per variant:
        ``reached`` (per speed: list of bools), ``all_but_centre_reach`` (every speed),
        ``centre_reached``, ``path_change`` / ``path_change_hausdorff`` (mean over particles between the
        first and last speed, m), ``path_change_per_particle``, ``centre_standoff`` and
        ``max_lateral_deviation`` (per speed, m), ``mean_path_length`` (per speed, reached particles, m),
        ``min_clearance`` (per speed, m), ``mean_time`` (per speed, reached particles, s).
    """
    s0, s1 = exp.speeds[0], exp.speeds[-1]
    c = exp.centre
    target = np.asarray(exp.params["target"], dtype=np.float64)
    centre_xy = np.asarray(exp.params["obstacle_center"], dtype=np.float64)
    radius = float(exp.params["obstacle_radius"])
    k = int(exp.setup.resample)
    others = [i for i in range(exp.starts.shape[0]) if i != c]
    per_variant: Dict[str, Any] = {}
    for v in exp.variants:
        a, b = exp.runs[(v, s0)], exp.runs[(v, s1)]
        change = [mean_pointwise_distance(pa, pb, k) for pa, pb in zip(a.paths, b.paths)]
        haus = [hausdorff_distance(pa, pb, k) for pa, pb in zip(a.paths, b.paths)]
        entry: Dict[str, Any] = {
            "reached": {}, "centre_standoff": {}, "max_lateral_deviation": {}, "mean_path_length": {},
            "min_clearance": {}, "mean_time": {},
        }
        for s in exp.speeds:
            r = exp.runs[(v, s)]
            key = f"{s:g}"
            entry["reached"][key] = [bool(x) for x in r.reached]
            entry["centre_standoff"][key] = float(np.linalg.norm(r.paths[c][-1] - centre_xy) - radius)
            entry["max_lateral_deviation"][key] = max(
                lateral_deviation(r.paths[i], exp.starts[i], target) for i in others)
            done = [i for i in range(len(r.paths)) if r.reached[i]]
            entry["mean_path_length"][key] = (float(np.mean([_path_length(r.paths[i]) for i in done]))
                                              if done else math.nan)
            entry["mean_time"][key] = float(np.mean(r.t_star[done])) if done else math.nan
            entry["min_clearance"][key] = float(np.min(r.min_clearance))
        entry["all_but_centre_reach"] = bool(all(exp.runs[(v, s)].reached[i] for s in exp.speeds for i in others))
        entry["centre_reached"] = {f"{s:g}": bool(exp.runs[(v, s)].reached[c]) for s in exp.speeds}
        entry["path_change"] = float(np.mean(change))
        entry["path_change_hausdorff"] = float(np.mean(haus))
        entry["path_change_per_particle"] = [float(x) for x in change]
        per_variant[v] = entry

    checks: Dict[str, bool] = {}
    for metric in ("riemannian", "finsler"):
        unbent, bent = f"unbent_{metric}", f"bent_{metric}"
        if unbent in per_variant and bent in per_variant:
            u, g = per_variant[unbent], per_variant[bent]
            checks[f"bent_{metric}_changes_less"] = bool(
                g["path_change"] < u["path_change"] and g["path_change_hausdorff"] < u["path_change_hausdorff"])
            checks[f"unbent_{metric}_pushes_centre_farther"] = bool(
                all(u["centre_standoff"][s] > g["centre_standoff"][s] for s in u["centre_standoff"]))
    checks["all_but_centre_reach"] = bool(all(e["all_but_centre_reach"] for e in per_variant.values()))
    checks["centre_stuck"] = bool(not any(any(e["centre_reached"].values()) for e in per_variant.values()))
    checks["no_penetration"] = bool(all(min(e["min_clearance"].values()) >= 0.0 for e in per_variant.values()))
    for metric in ("unbent", "bent"):
        r, f = per_variant.get(f"{metric}_riemannian"), per_variant.get(f"{metric}_finsler")
        if r is not None and f is not None:
            checks[f"{metric}_finsler_paths_shorter"] = bool(
                all(f["mean_path_length"][s] < r["mean_path_length"][s] for s in r["mean_path_length"]))
    return {
        "setup": {
            "n_particles": int(exp.setup.n_particles), "speeds": list(exp.speeds), "compared": [s0, s1],
            "start_radius": exp.setup.start_radius, "half_angle_deg": exp.setup.half_angle, "dt": exp.setup.dt,
            "t_max": exp.setup.t_max, "tol": exp.setup.tol, "resample": k, "centre_index": int(c),
            "params": {key: (list(val) if isinstance(val, (list, tuple)) else val)
                       for key, val in exp.params.items()},
        },
        "variants": per_variant,
        "checks": checks,
    }


# -------------------------------------------------------------------------------------------- figure
def plot(exp: ParticleExperiment, out: Any, dpi: int = 130) -> Path:
    """Draw the experiment like GF Fig. 1 and save it as a PNG.

    Layout: columns unbent / bent; rows Riemannian at each speed, then Finsler at each speed. Each panel
    shows the obstacle (grey disc), the target (square), the starts (dots) and the paths (one colour per
    particle, ✕ where a particle stopped without reaching the target); the title gives the number of
    particles that reached the target and, at the last speed, the mean path change from the first speed.

    Returns:
        The path written.
    """
    from matplotlib.patches import Circle

    from gfcs.plots import new_figure

    metrics = [m for m in ("riemannian", "finsler") if any(v.endswith(m) for v in exp.variants)]
    kinds = [k for k in ("unbent", "bent") if any(v.startswith(k + "_") for v in exp.variants)]
    rows = [(m, s) for m in metrics for s in exp.speeds]
    fig = new_figure((3.6 * len(kinds) + 0.6, 2.7 * len(rows) + 0.8))
    axes = np.atleast_2d(fig.subplots(len(rows), len(kinds), sharex=True, sharey=True, squeeze=False))
    target = np.asarray(exp.params["target"], dtype=np.float64)
    centre_xy = np.asarray(exp.params["obstacle_center"], dtype=np.float64)
    radius = float(exp.params["obstacle_radius"])
    all_pts = np.vstack([exp.starts, target[None]] + [p for r in exp.runs.values() for p in r.paths])
    lo, hi = all_pts.min(axis=0) - 0.4, all_pts.max(axis=0) + 0.4
    import matplotlib

    cmap = matplotlib.colormaps["viridis"]
    colors = [cmap(x) for x in np.linspace(0.05, 0.95, exp.starts.shape[0])]
    for i, (metric, speed) in enumerate(rows):
        for j, kind in enumerate(kinds):
            ax = axes[i, j]
            variant = f"{kind}_{metric}"
            ax.add_patch(Circle(tuple(centre_xy), radius, color="0.75", zorder=1))
            ax.plot(*target, marker="s", color="k", markersize=6, zorder=4)
            ax.set_aspect("equal")
            ax.set_xlim(lo[0], hi[0])
            ax.set_ylim(lo[1], hi[1])
            run_ = exp.runs.get((variant, speed))
            if run_ is None:
                ax.set_axis_off()
                continue
            for n, path in enumerate(run_.paths):
                ax.plot(path[:, 0], path[:, 1], color=colors[n], lw=1.2, zorder=2)
                ax.plot(*exp.starts[n], "o", color=colors[n], markersize=3.5, zorder=3)
                if not run_.reached[n]:
                    ax.plot(*path[-1], "x", color="crimson", markersize=6, zorder=5)
            title = f"{kind} {metric}, $v_d$ = {speed:g}: {int(run_.reached.sum())}/{len(run_.paths)} reach"
            if speed == exp.speeds[-1] and len(exp.speeds) > 1:
                change = exp.claims["variants"][variant]["path_change"]
                title += f"\npath change vs $v_d$ = {exp.speeds[0]:g}: {change:.3f} m"
            ax.set_title(title, fontsize=8.5)
            ax.tick_params(labelsize=7)
    fig.suptitle("GF Sec. VI particles: unbent (left) vs bent (right) fabrics", fontsize=10)
    fig.tight_layout()
    from gfcs.plots import save_png

    return save_png(fig, out, dpi)


def summary_text(claims: Dict[str, Any]) -> str:
    """A plain-text table of the measured claims (one row per variant) and the checks."""
    setup = claims["setup"]
    s0, s1 = setup["compared"]
    speeds = [f"{s:g}" for s in setup["speeds"]]
    head = (f"{'variant':<18} {'reach':>7} {'Δpath':>7} {'Δhaus':>7} "
            + " ".join(f"{'standoff@' + s:>11}" for s in speeds) + " "
            + " ".join(f"{'lateral@' + s:>10}" for s in speeds) + " "
            + " ".join(f"{'length@' + s:>9}" for s in speeds) + " "
            + " ".join(f"{'clear@' + s:>9}" for s in speeds))
    lines = [f"GF Sec. VI particles: {setup['n_particles']} particles, speeds {', '.join(speeds)} m/s; "
             f"Δpath/Δhaus = mean point-wise / Hausdorff path change between v_d = {s0:g} and {s1:g} (m); "
             "standoff = final distance of the centre particle to the circle (m); lateral = max distance "
             "from the start-target line (m); length = mean path length of reaching particles (m); "
             "clear = min distance to the circle (m)", head]
    n = setup["n_particles"]
    for v, e in claims["variants"].items():
        reach = min(sum(r) for r in e["reached"].values())
        lines.append(f"{v:<18} {f'{reach}/{n}':>7} {e['path_change']:>7.3f} {e['path_change_hausdorff']:>7.3f} "
                     + " ".join(f"{e['centre_standoff'][s]:>11.3f}" for s in speeds) + " "
                     + " ".join(f"{e['max_lateral_deviation'][s]:>10.3f}" for s in speeds) + " "
                     + " ".join(f"{e['mean_path_length'][s]:>9.3f}" for s in speeds) + " "
                     + " ".join(f"{e['min_clearance'][s]:>9.4f}" for s in speeds))
    lines.append("checks: " + ", ".join(f"{k}={'yes' if v else 'NO'}" for k, v in claims["checks"].items()))
    return "\n".join(lines)


# ----------------------------------------------------------------------------------------------- CLI
def _cmd_particles(args: argparse.Namespace) -> int:
    from gfcs.experiments import report

    setup = ParticleSetup(n_particles=args.n_particles, half_angle=args.half_angle, t_max=args.t_max)
    exp = run(setup, speeds=args.speeds)
    report(summary_text(exp.claims), exp.claims, args.json, plot(exp, args.out))
    return 0


def add_cli(experiment_subparsers: Any) -> argparse.ArgumentParser:
    """Add ``particles`` under ``gfcs experiment`` (``experiment_subparsers`` is the nested subparsers)."""
    from gfcs.experiments import add_output_options

    p = experiment_subparsers.add_parser(
        "particles", help="GF Sec. VI particle systems (Fig. 1)",
        description="Roll out a fan of particles around a circular obstacle for the four GF Sec. VI systems "
                    "(unbent/bent x Riemannian/Finsler) at desired speeds 2 and 4, write a figure like GF "
                    "Fig. 1 and print the measured claims (reach, path change between speeds, centre "
                    "particle stand-off, lateral deviation).",
    )
    add_output_options(p, "the claims", figure_required=True)
    p.add_argument("--n-particles", type=int, default=11, help="particles, odd (default 11)")
    p.add_argument("--half-angle", type=float, default=35.0, help="half opening of the fan, degrees (default 35)")
    p.add_argument("--t-max", type=float, default=15.0, help="time budget per particle, s (default 15)")
    p.add_argument("--speeds", type=float, nargs="+", default=list(SPEEDS), help="desired speeds (default 2 4)")
    p.set_defaults(func=_cmd_particles)
    return p


def register_cli(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``gfcs experiment ...`` (every experiment, this one included) to the top-level ``subparsers``."""
    from gfcs.experiments import register_cli as register_experiments

    return register_experiments(subparsers)
