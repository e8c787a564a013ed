#!/usr/bin/env python
"""Writes the Speed section of BENCHMARKS.md (``benches/results/speed.md``) from measurements taken now, on
this machine: every figure in it comes from one run of this script.

Measured, in this order (the machine should be quiet: the load average at the start is recorded):

1. **The fabric step in Rust** (criterion, ``cargo bench -p fabric-core --bench acceleration``): the
   median of each case of ``crates/fabric-core/benches/acceleration.rs``.
2. **The fabric step from Python against the `fabrics` package** (``benches/compare_fabrics.py``, once per
   engine, ``--repeats`` interleaved runs; `fabrics` runs in its own environment, ``--fabrics-python``, since
   it pins numpy 1.26): medians of the per-step times, and their ratio.
3. **The built-in problem from the shell** (``python -m gfcs solve --json``, ``--repeats`` runs, as the
   default preset runs it (early stop after two stalled batches) and with every batch, ``--stall-batches 0``):
   the optimisation, the first batch, the whole solve (the result's ``wall_time``) and the wall time of the
   process.
4. **Early stop of CMA-ES** on the first 10 MotionBenchMaker Panda problems of each class
   (``gfcs bench --time-limit 0 --stall-batches K``, K = 0, 1, 2): success, time and path lengths.
5. **Scaling curves** (``benches/scaling.py``): tables, fitted exponents and ``docs/figures/scaling.png``.

The targets are those of the speed issue; each is marked met or not met from the figure measured.

    GFCS_SHARED=../shared python benches/speed.py --fabrics-python fenv/bin/python
    python benches/report.py

The raw measurements go to ``benches/results/speed.json``; ``--rewrite`` writes the page from them again.
"""

from __future__ import annotations

import argparse
import compileall
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from scaling import slope, table  # noqa: E402  (the curves' own table and fit)
from table1 import machine_info  # noqa: E402

#: criterion case -> row label of the criterion table.
CRITERION_CASES = {
    "panda_box_scene": "shipped Panda, box scene",
    "panda_free_space": "shipped Panda, free space",
    "mbm_panda_box_scene": "MBM Panda (59 spheres), box scene",
    "mbm_panda_free_space": "MBM Panda, free space",
    "mbm_panda_cage_scene": "MBM Panda, cage scene",
}


def shared_dir() -> Path:
    env = os.environ.get("GFCS_SHARED")
    return Path(env) if env else ROOT.parent / "shared"


def run(cmd: Sequence[str], **kwargs: Any) -> subprocess.CompletedProcess:
    """Run ``cmd`` in the repository with the shared data folder set. Python may write its bytecode cache
    (an installed package has one), so that the processes timed here do not compile gfcs every time."""
    print("$", " ".join(str(c) for c in cmd), file=sys.stderr)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["GFCS_SHARED"] = str(shared_dir())
    return subprocess.run([str(c) for c in cmd], check=True, env=env, cwd=ROOT, **kwargs)


def criterion_median(folder: str) -> Optional[float]:
    """Criterion's median (µs) of the case written to ``target/criterion/<folder>`` (group and case as one
    folder name), None when absent."""
    est = ROOT / "target" / "criterion" / folder / "new" / "estimates.json"
    return json.loads(est.read_text())["median"]["point_estimate"] / 1e3 if est.is_file() else None


def criterion(measurement_time: float) -> Dict[str, Dict[str, float]]:
    """Criterion's median (µs) of every case, with ψ and without (``_no_psi``), and under "budget" the cage
    step's parts: the same states with the obstacle barrier off, one obstacle barrier evaluation, and the
    mean leaves per cage evaluation (the last count the benchmark prints)."""
    proc = run(["cargo", "bench", "-p", "fabric-core", "--bench", "acceleration", "--", "--warm-up-time", "1",
                "--measurement-time", str(measurement_time)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
               text=True)
    out: Dict[str, Dict[str, float]] = {}
    for case in CRITERION_CASES:
        for suffix in ("", "_no_psi"):
            value = criterion_median(f"acceleration_{case}{suffix}")
            if value is not None:
                out.setdefault(case, {})[suffix or "psi"] = value
    leaves = re.findall(r"mean leaves per evaluation along the recorded rollout: ([0-9.]+)", proc.stderr)
    budget = {"obstacles_off": criterion_median("acceleration_mbm_panda_cage_scene_obstacles_off_no_psi"),
              "barrier": criterion_median("barrier_obstacle_eval")}
    if leaves and "mbm_panda_cage_scene" in out:
        budget["leaves"] = float(leaves[-1])
    out["budget"] = {k: v for k, v in budget.items() if v is not None}
    return out


def compare_fabrics(fabrics_python: Optional[str], repeats: int) -> List[Dict[str, Any]]:
    """``repeats`` interleaved runs of both engines: per run {gfcs: figures, fabrics: figures or None}."""
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeats):
            row: Dict[str, Any] = {}
            for engine, python in (("gfcs", sys.executable), ("fabrics", fabrics_python)):
                if python is None:
                    row[engine] = None
                    continue
                path = Path(tmp) / f"{engine}.json"
                run([python, ROOT / "benches" / "compare_fabrics.py", "--engine", engine, "--json", path],
                    stdout=subprocess.DEVNULL)
                row[engine] = json.loads(path.read_text())
            runs.append(row)
    return runs


def builtin_solves(repeats: int, extra: Sequence[str] = ()) -> List[Dict[str, float]]:
    """``gfcs solve`` of the built-in problem ``repeats`` times: optimisation, first batch, whole solve and
    process wall time (s)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "solve.json"
        # the package's bytecode compiled, as pip does at installation (an import does not write it where
        # PYTHONDONTWRITEBYTECODE is set), then one untimed run: the file system cache
        import gfcs

        compileall.compile_dir(str(Path(gfcs.__file__).parent), quiet=1)
        run([sys.executable, "-m", "gfcs", "solve", "--json", path, *extra], stdout=subprocess.DEVNULL)
        for _ in range(repeats):
            t0 = time.perf_counter()
            run([sys.executable, "-m", "gfcs", "solve", "--json", path, *extra], stdout=subprocess.DEVNULL)
            shell = time.perf_counter() - t0
            r = json.loads(path.read_text())
            rows.append({"optimisation": r["solve_time"], "first_batch": r["batch_times"][0],
                         "batches": len(r["batch_times"]), "solve": r["wall_time"], "shell": shell,
                         "cost": r["cost"], "success": r["success"]})
    return rows


def stall_study(limit: int, ks: Sequence[int]) -> Dict[int, List[Dict[str, Any]]]:
    """The 5-batch GFCS rows of ``gfcs bench`` on the MBM Panda with ``--stall-batches K`` for each K."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for k in ks:
            path = Path(tmp) / f"stall{k}.jsonl"
            run([sys.executable, "-m", "gfcs", "bench", "--problems", shared_dir() / "mbm", "--robot", "mbm",
                 "--limit", str(limit), "--method", "gfcs", "--time-limit", "0", "--stall-batches", str(k),
                 "--json", path, "--no-progress"], stdout=subprocess.DEVNULL)
            out[k] = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return out


def scaling(repeat: int, plot: Path) -> Dict[str, List[Dict[str, Any]]]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scaling.json"
        run([sys.executable, ROOT / "benches" / "scaling.py", "--repeat", str(repeat), "--limit", "1",
             "--json", path, "--plot", plot], stdout=subprocess.DEVNULL)
        return json.loads(path.read_text())


def med(values: Sequence[float]) -> float:
    return float(statistics.median(values))


def span(values: Sequence[float], scale: float = 1.0, fmt: str = ".3f") -> str:
    """'lo–hi' of the values times ``scale``."""
    return f"{min(values) * scale:{fmt}}–{max(values) * scale:{fmt}}"


def verdict(value: float, target: float, larger_is_better: bool = False) -> str:
    ok = value >= target if larger_is_better else value <= target
    return "met" if ok else "**not met**"


def write(args: argparse.Namespace, m: Dict[str, Any], crit: Dict[str, Dict[str, float]],
          cmp_runs: List[Dict[str, Any]], solves: List[Dict[str, float]], default_solves: List[Dict[str, float]],
          stall: Dict[int, List[Dict[str, Any]]], curves: Dict[str, List[Dict[str, Any]]]) -> str:
    L: List[str] = ["## Speed", ""]
    L.append(f"Written by `python benches/speed.py` on {m['cpu']} ({m['cores']} cores), commit {m['commit']}, "
             f"{m['date']}, load average {m['load']:.2f} at its start. Every figure below is from that one run.")
    L += ["", "```bash", "GFCS_SHARED=../shared python benches/speed.py --fabrics-python fenv/bin/python",
          "python -m venv fenv && fenv/bin/pip install fabrics   # the peer, in its own environment", "```", ""]

    g_py = [r["gfcs"]["median_us"] for r in cmp_runs]
    g_rs = [r["gfcs"]["rollout_us_per_step"] for r in cmp_runs]
    f_py = [r["fabrics"]["median_us"] for r in cmp_runs if r["fabrics"]]
    ratios = [r["fabrics"]["median_us"] / r["gfcs"]["median_us"] for r in cmp_runs if r["fabrics"]]
    cage = crit.get("mbm_panda_cage_scene", {}).get("_no_psi")
    free = crit.get("mbm_panda_free_space", {}).get("_no_psi")
    L += ["**Targets** (each the median of its measurements below):", "",
          "| measure | target | now | |", "|---|---|---|---|"]
    if free is not None:
        L.append(f"| fabric step, MBM Panda in free space (criterion, Rust) | ≤ 2 µs | {free:.2f} µs | {verdict(free, 2.0)} |")
    if cage is not None:
        L.append(f"| fabric step, MBM Panda in the cage scene (criterion, Rust) | ≤ 5 µs | {cage:.2f} µs | {verdict(cage, 5.0)} |")
    L.append(f"| fabric step from Python, 10 obstacles (`Fabric.acceleration`) | ≤ 5 µs | {med(g_py):.2f} µs | {verdict(med(g_py), 5.0)} |")
    if ratios:
        L.append(f"| ratio to `fabrics` `compute_action`, 10 obstacles | ≥ 350 | {med(ratios):.0f} | {verdict(med(ratios), 350, True)} |")
    opt = [s["optimisation"] for s in solves]
    L.append(f"| built-in problem: five batches (optimisation) | ≤ 0.3 s | {med(opt):.3f} s | {verdict(med(opt), 0.3)} |")
    L.append(f"| built-in problem: five batches and selection (whole solve) | ≤ 0.3 s | {med([s['solve'] for s in solves]):.3f} s | {verdict(med([s['solve'] for s in solves]), 0.3)} |")
    L.append(f"| built-in problem: first batch | ≤ 0.06 s | {med([s['first_batch'] for s in solves]):.3f} s | {verdict(med([s['first_batch'] for s in solves]), 0.06)} |")
    shell = med([s['shell'] for s in default_solves])
    L.append(f"| `gfcs solve` from the shell | ≤ 0.5 s | {shell:.3f} s | {verdict(shell, 0.5)} |")

    L += ["", f"**Fabric step from Python against `fabrics`** (`benches/compare_fabrics.py`: the MBM Panda with "
          f"{cmp_runs[0]['gfcs']['spheres']} spheres and {cmp_runs[0]['gfcs']['self_pairs']} self pairs, "
          f"{cmp_runs[0]['gfcs']['obstacles']} sphere obstacles, 1000 explicit Euler steps; median µs per "
          f"acceleration query; {len(cmp_runs)} interleaved runs):", "",
          "| run | gfcs `Fabric.acceleration` | gfcs rollout in Rust, per step | `fabrics` `compute_action` | `fabrics` CasADi function alone | ratio |",
          "|---|---|---|---|---|---|"]
    for i, r in enumerate(cmp_runs, 1):
        f = r["fabrics"]
        fc = (f"{f['median_us']:.0f} µs", f"{f['casadi_median_us']:.0f} µs",
              f"{f['median_us'] / r['gfcs']['median_us']:.0f}") if f else ("–", "–", "–")
        L.append(f"| {i} | {r['gfcs']['median_us']:.2f} µs | {r['gfcs']['rollout_us_per_step']:.2f} µs | {fc[0]} | {fc[1]} | {fc[2]} |")
    if f_py:
        L.append(f"| median | {med(g_py):.2f} µs | {med(g_rs):.2f} µs | {med(f_py):.0f} µs | "
                 f"{med([r['fabrics']['casadi_median_us'] for r in cmp_runs if r['fabrics']]):.0f} µs | {med(ratios):.0f} |")
    else:
        L += ["", "(`fabrics` not measured in this run: no `--fabrics-python`.)"]

    L += ["", "**Criterion** (`cargo bench -p fabric-core --bench acceleration`, bench profile = fat LTO, "
          f"{args.measurement_time:g} s per case; µs, criterion's median; \"no ψ\" is a rollout's workspace, "
          "which does not evaluate the forcing potential ψ: the same q̈ bit for bit):", "",
          "| case | with ψ | no ψ |", "|---|---|---|"]
    for case, label in CRITERION_CASES.items():
        c = crit.get(case)
        if c:
            L.append(f"| {label} | {c.get('psi', float('nan')):.2f} | {c.get('_no_psi', float('nan')):.2f} |")
    budget = crit.get("budget", {})
    if cage is not None and {"obstacles_off", "barrier", "leaves"} <= set(budget):
        rest = cage - budget["obstacles_off"]
        L += ["", f"Where the cage step goes: the same states with the obstacle barrier off take "
              f"{budget['obstacles_off']:.2f} µs (kinematics, self-collision, attractors, the solve); the other "
              f"{rest:.2f} µs are the obstacle leaves with their broadphase queries and distances, "
              f"{budget['leaves']:.1f} leaves per step in all (joint limits and self-collision included). One "
              f"obstacle barrier evaluation alone (`barrier/obstacle_eval`: metric, geometry with its brake, "
              f"forcing) takes {budget['barrier'] * 1e3:.1f} ns."]

    L += ["", f"**The built-in problem** (`python -m gfcs solve --json x.json`, {len(solves)} runs each; s):", "",
          "| | batches | optimisation | first batch | whole solve | process wall time | cost t* |",
          "|---|---|---|---|---|---|---|"]
    for label, rows in (("default (early stop)", default_solves), ("every batch, `--stall-batches 0`", solves)):
        L.append(f"| {label} | {rows[0]['batches']} | {span([r['optimisation'] for r in rows])} | "
                 f"{span([r['first_batch'] for r in rows])} | {span([r['solve'] for r in rows])} | "
                 f"{span([r['shell'] for r in rows])} | {span([r['cost'] for r in rows], fmt='.2f')} |")
    L += ["", "`gfcs solve` loads none of torch, matplotlib, rerun, scipy or trimesh (tested in "
          "`tests/test_cli.py`). The process wall time beyond the whole solve is Python's start-up, the imports "
          "of numpy and cma, and the generation of the built-in problem."]

    base = stall.get(0, [])
    def five(rows: List[Dict[str, Any]], label: str) -> List[Dict[str, Any]]:
        return [r for r in rows if r.get("label") == label and "error" not in r]
    L += ["", "**Early stop of CMA-ES** (`solve(..., stall_batches=K, stall_tol=0.01)`, CLI `--stall-batches K`: "
          "after a batch, the optimisation stops when the last K batches lowered the best cost by at most 1 % of "
          "it, `gfcs.planning.gfcop.stalled`; K = 2 in the default preset, 0 in the paper preset, which keeps all its "
          "batches). "
          f"The first {args.stall_limit} MBM Panda problems of each class, `--time-limit 0` so that the budget plays no part:",
          "", "```bash", f"gfcs bench --problems ../shared/mbm --robot mbm --limit {args.stall_limit} --method gfcs "
          "--time-limit 0 --stall-batches K", "```", "",
          "| K | success (5 b) | success (retry) | median optimisation (s) | mean cost t* (s) | mean EE length (m) | mean C-space length (rad) | same cost as K = 0 |",
          "|---|---|---|---|---|---|---|---|"]
    cost0 = {r["problem"]: r["cost"] for r in five(base, "Ours (5 b)")}
    for k, rows in stall.items():
        b5, rt = five(rows, "Ours (5 b)"), five(rows, "Ours (5 b, retry)")
        ok = [r for r in b5 if r["success"]]
        mean = lambda key: statistics.fmean(float(r[key]) for r in ok) if ok else float("nan")  # noqa: E731
        same = sum(1 for r in b5 if r["problem"] in cost0 and float(r["cost"]) == float(cost0[r["problem"]]))
        L.append(f"| {k} | {len(ok)}/{len(b5)} | {sum(r['success'] for r in rt)}/{len(rt)} | "
                 f"{med([float(r['time']) for r in b5]):.3f} | {mean('cost'):.3f} | {mean('ee_length'):.3f} | "
                 f"{mean('cspace_length'):.3f} | {'–' if k == 0 else f'{same}/{len(b5)}'} |")

    L += ["", f"**Scaling curves** (`benches/scaling.py --repeat {args.scaling_repeat} --limit 1`, best of "
          f"{args.scaling_repeat} per point; the shipped Panda, 3 cm sphere obstacles in a shell 0.25–0.9 m around "
          "its base clear of its free-space path, a 200-step rollout toward a fixed goal): figure "
          "`docs/figures/scaling.png`.", ""]
    if "obstacles" in curves:
        rows = curves["obstacles"]
        L += ["Time per step against obstacles:", "", table(rows), ""]
        fits = []
        for lo, label in ((10, "from 10 obstacles on"), (100, "from 100 on")):
            part = [r for r in rows if r["obstacles"] >= lo]
            if len(part) >= 2:  # a fit needs two points
                fits.append(f"{label}: {slope(part, 'obstacles', 'rollout_us'):.2f}")
        L.append(f"Fitted exponent {'; '.join(fits)}. Flat up to ~10 "
                 "obstacles (the fixed cost: kinematics, self-collision, the solve), then growing toward linear as the "
                 "leaves (one per sphere–obstacle pair within the influence radius, as many as the obstacles within "
                 "reach of the arm) outweigh the fixed cost; the broadphase (a BVH beyond 16 obstacles) costs little.")
    if "spheres" in curves:
        L += ["", "Time per step against collision spheres (each of the 57 repeated k times; 10 obstacles; "
              "self-collision off):", "", table(curves["spheres"]), "",
              f"Fitted exponent: {slope(curves['spheres'], 'spheres', 'rollout_us'):.2f} (linear: sphere centres, "
              "per-sphere culling and the leaves of the spheres near obstacles)."]
    if "batch" in curves:
        L += ["", "A batch of one-command candidates (`Fabric.evaluate`, 10 obstacles) on 1 and 2 threads (ms):",
              "", table(curves["batch"]), "", "Linear in the candidates: each is an independent rollout."]
    if "solve" in curves:
        L += ["", "Solve time against difficulty (the default preset, 5 batches, no time limit, the first MBM "
              "Panda problem of each class; the best cost t* measures how long the motion is):", "",
              table(curves["solve"]), "",
              f"Fitted exponent of the optimisation time in t*: {slope(curves['solve'], 'cost_s', 'optimisation_s'):.2f}: "
              "most candidates of a batch run to the rollout cap or to the goal whatever the best one does."]
    return "\n".join(L) + "\n"


def main(argv: Sequence[str] = ()) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fabrics-python", help="python of an environment with `fabrics` installed (default: skip it)")
    p.add_argument("--repeats", type=int, default=5, help="interleaved runs of the fabrics comparison and solves")
    p.add_argument("--measurement-time", type=float, default=3.0, help="criterion seconds per case")
    p.add_argument("--stall-limit", type=int, default=10, help="MBM Panda problems per class of the early-stop study")
    p.add_argument("--scaling-repeat", type=int, default=3, help="best-of count of the scaling curves")
    p.add_argument("--out", type=Path, default=ROOT / "benches" / "results" / "speed.md")
    p.add_argument("--measurements", type=Path, default=ROOT / "benches" / "results" / "speed.json",
                   help="the raw measurements, written by a run and read by --rewrite")
    p.add_argument("--rewrite", action="store_true", help="write the page from --measurements, measuring nothing")
    args = p.parse_args(list(argv) or None)
    if args.rewrite:
        raw = json.loads(args.measurements.read_text())
    else:
        raw = {"machine": machine_info()}
        if raw["machine"]["load"] > 0.5:
            print(f"speed: load average {raw['machine']['load']:.2f} at the start: the machine is not quiet",
                  file=sys.stderr)
        raw["criterion"] = criterion(args.measurement_time)
        raw["fabrics"] = compare_fabrics(args.fabrics_python, args.repeats)
        raw["solves"] = builtin_solves(args.repeats, ["--stall-batches", "0"])
        raw["default_solves"] = builtin_solves(args.repeats)
        raw["stall"] = stall_study(args.stall_limit, (0, 1, 2))
        raw["curves"] = scaling(args.scaling_repeat, ROOT / "docs" / "figures" / "scaling.png")
        raw["options"] = {k: getattr(args, k) for k in ("measurement_time", "stall_limit", "scaling_repeat")}
        args.measurements.write_text(json.dumps(raw, indent=1) + "\n")
    opts = argparse.Namespace(**raw["options"])
    stall = {int(k): v for k, v in raw["stall"].items()}
    args.out.write_text(write(opts, raw["machine"], raw["criterion"], raw["fabrics"], raw["solves"],
                              raw["default_solves"], stall, raw["curves"]))
    print(f"wrote {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
