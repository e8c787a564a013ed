"""Results of GFCS solves and benchmark rows (GFCS Sec. V, Table I).

* :class:`Trajectory`: a sampled joint trajectory (t, q, q̇).
* :class:`SolveResult`: everything :func:`gfcs.planning.solve` produces for one problem, with
  ``to_json()`` / ``from_json()`` (strict JSON: NaN and ±inf are written as the strings ``"NaN"``,
  ``"Infinity"``, ``"-Infinity"`` and read back as floats).
* Benchmark rows: :func:`bench_row` builds one flat dict per (problem, method label) — the line format of
  ``gfcs bench --json results.jsonl``; :func:`summarize` and :func:`format_table` turn rows into the
  per-class tables of GFCS Table I (mean ± std over the successful problems).

Row format (keys of :func:`bench_row`), one JSON object per line:
``problem`` (str), ``class`` (str), ``label`` (e.g. ``"GF"``, ``"Ours (1 b)"``, ``"Ours (5 b)"``),
``method`` (``"gf"`` | ``"gfcs"``), ``batches`` (int, CMA-ES batches behind the row; 0 for GF),
``seed`` (int), ``success`` (bool), ``time`` [s] (optimisation wall time up to that batch, or the GF
rollout time: the paper's time), ``wall_time`` [s] (the whole solve behind the row: optimisation, rollout
and validation of the returned motion, retries), ``cost`` (GFCS eq. 4), ``ee_length`` [m], ``cspace_length`` [rad], ``ee_ldj``,
``cspace_ldj``, ``min_clearance`` [m] (collision spheres), ``final_error`` [rad]; when the trajectory was
validated against collision meshes also ``mesh_clearance`` and ``mesh_self_clearance`` [m] (the smallest
mesh distance to the obstacles and between non-adjacent links; ``inf``: none within
``gfcs.metrics.mesh_report_cutoff(mesh margin)``); ``velocity_ratio`` (the largest finite-difference joint speed over its
URDF velocity limit, ≤ 1 within the limits); for a robot with several end effectors (a group spanning two arms) also ``ee_lengths``
({link: hand path [m]}, every hand; ``ee_length`` is the first's). Rows of :func:`gfcs.bench.bench_problem`
also name the result file of their motion under ``result`` (``<class>_<NNNN>.<result>.json`` in
``gfcs bench --results-dir``).

A problem of the suite that was not run (its start or goal outside the robot's joint limits, see
:func:`gfcs.bench.load_mbm_suite`) has one row of its own, :func:`left_out_row`: ``problem``, ``class`` and
``left_out`` (str, the reason) and no other key. :func:`summarize` leaves such rows out of the tables and
:func:`format_totals` counts them on a line of their own.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from gfcs.errors import InvalidValueError, ShapeError

__all__ = [
    "Trajectory",
    "SolveResult",
    "bench_row",
    "left_out_row",
    "summarize",
    "format_table",
    "format_totals",
    "TABLE_COLUMNS",
    "read_rows",
]

_NONFINITE = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def _enc(x: Any) -> Any:
    """JSON-ready copy of ``x``: numpy -> lists/scalars, non-finite floats -> strings."""
    if isinstance(x, np.ndarray):
        # an array of finite numbers or of booleans is JSON-ready as its list (the trajectories: most of a
        # result); one holding non-finite floats or objects goes element by element
        if x.dtype.kind in "biu" or (x.dtype.kind == "f" and bool(np.isfinite(x).all())):
            return x.tolist()
        return _enc(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        if math.isnan(v):
            return "NaN"
        if math.isinf(v):
            return "Infinity" if v > 0 else "-Infinity"
        return v
    if isinstance(x, dict):
        return {str(k): _enc(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_enc(v) for v in x]
    return x


def _dec_float(x: Any) -> float:
    """A float written by :func:`_enc` (number or one of the non-finite spellings)."""
    if isinstance(x, str):
        if x in _NONFINITE:
            return _NONFINITE[x]
        raise InvalidValueError(f"expected a number, got {x!r}")
    if x is None:
        return math.nan
    return float(x)


def _dec_array(x: Any, ndim: int, width: int = 0) -> np.ndarray:
    """A float array written by :func:`_enc`; empty inputs get shape (0,) or (0, width)."""

    def walk(v: Any) -> Any:
        return [walk(e) for e in v] if isinstance(v, list) else _dec_float(v)

    a = np.asarray(walk(x), dtype=np.float64)
    if a.size == 0:
        return np.zeros((0, width)) if ndim == 2 else np.zeros(0)
    if a.ndim != ndim:
        raise ShapeError(f"expected a {ndim}-D array, got shape {a.shape}")
    return a


def _dec_value(x: Any) -> Any:
    """Metrics values: floats (with non-finite spellings), bools, ints, strings, nested dicts."""
    if isinstance(x, str) and x in _NONFINITE:
        return _NONFINITE[x]
    if isinstance(x, dict):
        return {k: _dec_value(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_dec_value(v) for v in x]
    return x


@dataclass
class Trajectory:
    """A joint trajectory sampled at the integration step.

    Attributes:
        t: (T,) times [s], increasing, starting at 0.
        q: (T, dof) joint positions [rad].
        qd: (T, dof) joint velocities [rad/s].
        raw_q: (T', dof) the fabric's own rollout before finishing (re-timing, goal blend), sampled at the
            integration step, or None; kept in memory for its metrics, not written to JSON.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    raw_q: Optional[np.ndarray] = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=np.float64).reshape(-1)
        self.q = np.asarray(self.q, dtype=np.float64)
        self.qd = np.asarray(self.qd, dtype=np.float64)
        n = self.t.shape[0]
        if self.q.ndim != 2 or self.q.shape[0] != n:
            raise ShapeError(f"q: expected shape ({n}, dof), got {self.q.shape}")
        if self.qd.shape != self.q.shape:
            raise ShapeError(f"qd: expected shape {self.q.shape}, got {self.qd.shape}")

    def __len__(self) -> int:
        """Number of samples T."""
        return int(self.t.shape[0])

    def to_dict(self) -> Dict[str, Any]:
        """JSON-ready dict {t, q, qd}."""
        return {"t": _enc(self.t), "q": _enc(self.q), "qd": _enc(self.qd)}

    @classmethod
    def from_dict(cls, d: Dict[str, Any], dof: int) -> "Trajectory":
        """Inverse of :meth:`to_dict` (``dof`` fixes the shape of empty trajectories)."""
        return cls(
            t=_dec_array(d["t"], 1),
            q=_dec_array(d["q"], 2, dof),
            qd=_dec_array(d["qd"], 2, dof),
        )


@dataclass
class SolveResult:
    """The outcome of one solve (GFCS Alg. 1 followed by a rollout of the best command sequence).

    Attributes:
        problem: problem name.
        cls: problem class (e.g. ``"bookshelf_small"``), "" when unknown.
        method: ``"gfcs"`` (optimised command sequence) or ``"gf"`` (the goal as the only command).
        seed: the seed of the solve.
        q0, qd0, goal: (dof,) start configuration [rad], start velocity [rad/s], goal [rad].
        commands: (n, dof) the free commands q_g^1..q_g^n of GFCS eq. 4 (the goal q_g^{n+1} is implied;
            n = 0 for ``"gf"``).
        cost: GFCS eq. 4 cost Σ t_i* + p·1 [s] of ``commands`` (plus the collision penalty when the
            rollout collides, see :mod:`gfcs.optimize`).
        reached: the final rollout reached the goal within t_max.
        t_stars: (n + 1,) time spent on each command [s] (eq. 2).
        trajectory: the rolled-out joint trajectory of ``commands`` then the goal.
        success: goal reached within tolerance, no collision (obstacles and self), limits respected.
        metrics: :func:`gfcs.metrics.trajectory_metrics` of ``trajectory``.
        top: the best m candidates of the optimisation as (candidate (n·dof,), cost), lowest cost first.
        batch_times: (B,) wall time of each CMA-ES batch [s] (sampling, evaluation, update; the first
            batch's sampling is the warm-start sampler's).
        batch_best_costs: (B,) best cost found so far after each batch (non-increasing; anytime).
        batch_best_commands: (B, n·dof) the best candidate so far after each batch.
        n_evaluations: number of candidate sequences evaluated.
        solve_time: wall time of the optimisation [s] (Σ batch_times; the GF rollout time for ``"gf"``):
            the paper's "time" (GFCS Table I).
        wall_time: wall time of the whole :func:`gfcs.planning.solve` call [s]: the optimisation, the
            rollout and validation of the returned candidate (and of the ones it checked before it) and
            every retry; 0 when unknown (a result written without it).
        settings: rollout and optimiser settings used (dt, t_max, tol, ...).
        fabric_config: the fabric configuration as a dict (None: the defaults).
        joint_names: the robot's joint names, the order of every (dof,) vector and of the trajectory's
            columns ([] when unknown: a result written without them).
        pose_goal: the request's pose goal when the problem had one (``problem.meta["pose_goal"]``, see
            :mod:`gfcs.pose_goal`; ``goal`` is the joint goal found for it), else None.
        preset: the planner preset (``"default"`` or ``"paper"``, :mod:`gfcs.planning.presets`); "" when
            unknown.
        time_limit: the solve's time budget [s], None for none.
        attempts: every attempt of the solve, in order (:meth:`gfcs.planning.attempts.AttemptRecord.to_dict`:
            label, proposing policy, settings, outcome, cost, time, evaluations); [] for ``"gf"``.
    """

    problem: str
    cls: str
    method: str
    seed: int
    q0: np.ndarray
    qd0: np.ndarray
    goal: np.ndarray
    commands: np.ndarray
    cost: float
    reached: bool
    t_stars: np.ndarray
    trajectory: Trajectory
    success: bool
    metrics: Dict[str, Any] = field(default_factory=dict)
    top: List[Tuple[np.ndarray, float]] = field(default_factory=list)
    batch_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    batch_best_costs: np.ndarray = field(default_factory=lambda: np.zeros(0))
    batch_best_commands: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    n_evaluations: int = 0
    solve_time: float = 0.0
    wall_time: float = 0.0
    settings: Dict[str, Any] = field(default_factory=dict)
    fabric_config: Optional[Dict[str, Any]] = None
    joint_names: List[str] = field(default_factory=list)
    pose_goal: Optional[Dict[str, Any]] = None
    preset: str = ""
    time_limit: Optional[float] = None
    attempts: List[Dict[str, Any]] = field(default_factory=list)
    #: The robot the result was solved with (in memory only, not serialised); used by
    #: :func:`gfcs.planning.replay`.
    robot: Any = field(default=None, repr=False, compare=False)
    #: The solve's :class:`gfcs.planning.attempts.AttemptRecord` list with each attempt's own result (in
    #: memory only); ``gfcs bench`` builds its rows from it.
    attempt_records: List[Any] = field(default_factory=list, repr=False, compare=False)

    @property
    def dof(self) -> int:
        """Number of joints."""
        return int(np.asarray(self.goal).shape[0])

    @property
    def n_commands(self) -> int:
        """Number n of free commands."""
        return int(np.asarray(self.commands).shape[0])

    def to_dict(self, include_trajectory: bool = True) -> Dict[str, Any]:
        """JSON-ready dict (numpy arrays as nested lists, non-finite floats as strings)."""
        d: Dict[str, Any] = {
            "problem": self.problem,
            "cls": self.cls,
            "method": self.method,
            "seed": int(self.seed),
            "q0": _enc(self.q0),
            "qd0": _enc(self.qd0),
            "goal": _enc(self.goal),
            "commands": _enc(self.commands),
            "cost": _enc(self.cost),
            "reached": bool(self.reached),
            "t_stars": _enc(self.t_stars),
            "success": bool(self.success),
            "metrics": _enc(self.metrics),
            "top": [{"candidate": _enc(c), "cost": _enc(v)} for c, v in self.top],
            "batch_times": _enc(self.batch_times),
            "batch_best_costs": _enc(self.batch_best_costs),
            "batch_best_commands": _enc(self.batch_best_commands),
            "n_evaluations": int(self.n_evaluations),
            "solve_time": _enc(self.solve_time),
            "wall_time": _enc(self.wall_time),
            "settings": _enc(self.settings),
            "fabric_config": _enc(self.fabric_config),
            "joint_names": list(self.joint_names),
            "preset": self.preset,
            "time_limit": _enc(self.time_limit),
            "attempts": _enc(self.attempts),
        }
        if self.pose_goal is not None:
            d["pose_goal"] = self.pose_goal
        if include_trajectory:
            d["trajectory"] = self.trajectory.to_dict()
        return d

    def to_json(self, include_trajectory: bool = True, indent: Optional[int] = None) -> str:
        """Strict JSON text of :meth:`to_dict`."""
        return json.dumps(self.to_dict(include_trajectory), indent=indent, allow_nan=False)

    @classmethod
    def from_dict(cls, d: Dict[str, Any]) -> "SolveResult":
        """Inverse of :meth:`to_dict`. Without a stored trajectory, ``trajectory`` is empty (T = 0)."""
        goal = _dec_array(d["goal"], 1)
        dof = goal.shape[0]
        n_cmd_dim = _dec_array(d["commands"], 2, dof).shape[0] * dof
        traj = d.get("trajectory")
        return cls(
            problem=str(d["problem"]),
            cls=str(d.get("cls", "")),
            method=str(d["method"]),
            seed=int(d["seed"]),
            q0=_dec_array(d["q0"], 1),
            qd0=_dec_array(d["qd0"], 1),
            goal=goal,
            commands=_dec_array(d["commands"], 2, dof),
            cost=_dec_float(d["cost"]),
            reached=bool(d["reached"]),
            t_stars=_dec_array(d["t_stars"], 1),
            trajectory=(
                Trajectory.from_dict(traj, dof)
                if traj is not None
                else Trajectory(np.zeros(0), np.zeros((0, dof)), np.zeros((0, dof)))
            ),
            success=bool(d["success"]),
            metrics=_dec_value(d.get("metrics", {})),
            top=[(_dec_array(e["candidate"], 1), _dec_float(e["cost"])) for e in d.get("top", [])],
            batch_times=_dec_array(d.get("batch_times", []), 1),
            batch_best_costs=_dec_array(d.get("batch_best_costs", []), 1),
            batch_best_commands=_dec_array(d.get("batch_best_commands", []), 2, n_cmd_dim),
            n_evaluations=int(d.get("n_evaluations", 0)),
            solve_time=_dec_float(d.get("solve_time", 0.0)),
            wall_time=_dec_float(d.get("wall_time", 0.0)),
            settings=_dec_value(d.get("settings", {})),
            fabric_config=_dec_value(d.get("fabric_config")),
            joint_names=[str(n) for n in d.get("joint_names", [])],
            pose_goal=d.get("pose_goal"),
            preset=str(d.get("preset", "")),
            time_limit=None if d.get("time_limit") is None else _dec_float(d["time_limit"]),
            attempts=_dec_value(d.get("attempts", [])),
        )

    @classmethod
    def from_json(cls, text: str) -> "SolveResult":
        """Inverse of :meth:`to_json`."""
        return cls.from_dict(json.loads(text))


# ---------------------------------------------------------------------------------- benchmark rows
#: Metric columns of GFCS Table I: (row key, column title).
TABLE_COLUMNS: Tuple[Tuple[str, str], ...] = (
    ("ee_length", "EE len"),
    ("cspace_length", "C-space len"),
    ("time", "Times (s)"),
    ("ee_ldj", "EE-LDJ"),
    ("cspace_ldj", "C-space-LDJ"),
)


def planned_robot(result: Any, problem: Any) -> Any:
    """The robot ``result`` was planned on: :func:`gfcs.planning.models.planned_robot`."""
    from gfcs.planning.models import planned_robot as resolve

    return resolve(result, problem)


def bench_row(
    problem: str,
    cls: str,
    label: str,
    method: str,
    batches: int,
    seed: int,
    time: float,
    cost: float,
    metrics: Dict[str, Any],
    wall_time: float,
) -> Dict[str, Any]:
    """One benchmark row (see the module docstring for the keys) from trajectory metrics."""
    mesh = {key: float(metrics[key]) for key in ("mesh_clearance", "mesh_self_clearance", "velocity_ratio",
                                                 "raw_ee_ldj", "raw_cspace_ldj")
            if key in metrics}
    # a robot with several end effectors (a group spanning two arms) reports every hand's path
    hands = metrics.get("ee_lengths") or {}
    if len(hands) > 1:
        mesh["ee_lengths"] = {str(link): float(v) for link, v in hands.items()}
    return {
        "problem": problem,
        "class": cls,
        "label": label,
        "method": method,
        "batches": int(batches),
        "seed": int(seed),
        "success": bool(metrics["success"]),
        "time": float(time),
        "wall_time": float(wall_time),
        "cost": float(cost),
        "ee_length": float(metrics["ee_length"]),
        "cspace_length": float(metrics["cspace_length"]),
        "ee_ldj": float(metrics["ee_ldj"]),
        "cspace_ldj": float(metrics["cspace_ldj"]),
        "min_clearance": float(metrics["min_clearance"]),
        "final_error": float(metrics["final_error"]),
        **mesh,
    }


def left_out_row(problem: str, reason: str) -> Dict[str, Any]:
    """The row of a problem ``"<class>/<NNNN>"`` that a suite left out, and why (see the module docstring)."""
    return {"problem": problem, "class": problem.split("/")[0], "left_out": reason}


def _run(rows: Iterable[Dict[str, Any]]) -> List[Dict[str, Any]]:
    """The rows of problems that were run (without :func:`left_out_row` rows)."""
    return [r for r in rows if "left_out" not in r]


def summarize(rows: Iterable[Dict[str, Any]]) -> Dict[str, Dict[str, Dict[str, Any]]]:
    """Per class and label: n, % success, and (mean, std) of each Table I column over successful rows.

    Args:
        rows: benchmark rows (:func:`bench_row`; rows read back from JSONL may hold the non-finite
            spellings of :func:`SolveResult.to_json`, which are decoded).

    Returns:
        ``{class: {label: {"n": int, "success": percent, key: (mean, std) or None, ...}}}`` with classes
        and labels in first-seen order; a column is None when no successful row has a finite value.
    """
    groups: Dict[str, Dict[str, List[Dict[str, Any]]]] = {}
    for r in _run(rows):
        groups.setdefault(str(r["class"]), {}).setdefault(str(r["label"]), []).append(r)
    out: Dict[str, Dict[str, Dict[str, Any]]] = {}
    for c, by_label in groups.items():
        out[c] = {}
        for label, rs in by_label.items():
            ok = [r for r in rs if bool(r["success"])]
            entry: Dict[str, Any] = {"n": len(rs), "success": 100.0 * len(ok) / len(rs)}
            for key, _ in TABLE_COLUMNS:
                vals = np.array([_dec_float(r[key]) for r in ok], dtype=np.float64)
                vals = vals[np.isfinite(vals)]
                entry[key] = (float(vals.mean()), float(vals.std())) if vals.size else None
            out[c][label] = entry
    return out


def _fmt(stat: Optional[Tuple[float, float]]) -> str:
    if stat is None:
        return "NA"
    mean, std = stat
    digits = 3 if abs(mean) < 1.0 else 2
    return f"{mean:.{digits}f} ± {std:.{digits}f}"


def format_table(summary: Dict[str, Dict[str, Dict[str, Any]]], markdown: bool = True) -> str:
    """Tables in the layout of GFCS Table I, one per class.

    Args:
        summary: the output of :func:`summarize`.
        markdown: markdown tables (for BENCHMARKS.md) or aligned plain text (for a terminal).
    """
    header = ["Method", "% Success", "n"] + [title for _, title in TABLE_COLUMNS]
    blocks: List[str] = []
    for c, by_label in summary.items():
        body = [
            [label, f"{e['success']:.0f}", str(e["n"])] + [_fmt(e[key]) for key, _ in TABLE_COLUMNS]
            for label, e in by_label.items()
        ]
        if markdown:
            lines = [f"### {c}", "", "| " + " | ".join(header) + " |",
                     "|" + "|".join("---" for _ in header) + "|"]
            lines += ["| " + " | ".join(row) + " |" for row in body]
        else:
            widths = [max(len(r[i]) for r in [header] + body) for i in range(len(header))]
            fmt_row = lambda row: "  ".join(v.ljust(w) for v, w in zip(row, widths))  # noqa: E731
            lines = [f"{c}", fmt_row(header), fmt_row(["-" * w for w in widths])]
            lines += [fmt_row(row) for row in body]
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks) + "\n"


def format_totals(rows: Iterable[Dict[str, Any]]) -> str:
    """One line per label over every class: problems solved (a problem refused before planning, a row with
    an ``error``, counts as not solved), and the median over its planned problems of ``time`` (the
    optimisation, GFCS Table I's measure) and of ``wall_time`` (the whole solve), in s, with how many were
    refused; then how many problems were left out (:func:`left_out_row`), when any were."""
    rows = list(rows)
    by_label: Dict[str, List[Dict[str, Any]]] = {}
    for r in _run(rows):
        by_label.setdefault(str(r["label"]), []).append(r)
    lines = []
    for label, rs in by_label.items():
        solved = sum(bool(r["success"]) for r in rs)
        planned = [r for r in rs if "error" not in r]
        line = f"{label}: {solved}/{len(rs)} solved ({100.0 * solved / len(rs):.1f} %)"
        if planned:
            time = np.median([_dec_float(r["time"]) for r in planned])
            wall = np.median([_dec_float(r["wall_time"]) for r in planned])
            line += f", median time {time:.3f} s, whole solve {wall:.3f} s"
        if len(planned) < len(rs):
            line += f" ({len(rs) - len(planned)} refused before planning, their errors in the rows)"
        lines.append(line)
    n_left = len(rows) - len(_run(rows))
    if n_left:
        lines.append(f"left out (start or goal not valid for the robot): {n_left} problem(s)")
    return "\n".join(lines) + "\n"


def read_rows(lines: Sequence[str]) -> List[Dict[str, Any]]:
    """Parse JSONL benchmark rows (blank lines ignored)."""
    return [_dec_value(json.loads(s)) for s in lines if s.strip()]
