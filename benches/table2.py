#!/usr/bin/env python3
"""GFCS Table II: the learned first batch against the uniform one, as the paper measures it.

For each seed: ``gfcs train`` on problems 1-``--train`` of every MotionBenchMaker class (timed), then both
samplers solve problems ``--train``+1 to 50 of every class with one CMA-ES batch of the ``paper`` preset, with
the same per-problem seed (``gfcs.learning.evaluate_first_batch``), each returned motion written to
``OUT/seed<S>/`` and judged by the independent validator (``tools/check_trajectories.py`` on the Panda's
collision meshes and SRDF, as Table I's): a row succeeds when gfcs claims it and the validator finds it valid.
Differences (learned − uniform) get 95 % bootstrap intervals over problems: success in points of percent, hand
path and time over the problems both solve. Writes ``OUT/table2.jsonl`` (every row, with its seed and
``claimed_success``) and the fragment ``benches/results/learning.md``.

    python benches/table2.py --problems ../shared/mbm --seeds 0 1 2 --out runs/table2
    python benches/table2.py --problems ../shared/mbm --out runs/table2 --render   # from the rows only

Seeds run one at a time keep the others' rows (``--seeds 2`` after ``--seeds 0 1`` makes three).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, Dict, List, Sequence, Tuple

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from report import verdicts  # noqa: E402  (the benches import each other as scripts)
from table1 import ROBOTS, run_validator  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
LABELS = ("No learning", "Learning")


def train(args: argparse.Namespace, seed: int) -> Tuple[Path, float]:
    """Train one model; (model path, wall time in s)."""
    model = args.out / f"model.{seed}.pt"
    cmd = [sys.executable, "-m", "gfcs", "train", "--problems", str(args.problems), "--robot", "mbm",
           "--limit", str(args.train), *(["--classes", *args.classes] if args.classes else []), "--seed", str(seed), "--preset", "paper", "--out", str(model),
           "--history", str(args.out / f"history.{seed}.json"), "--no-progress", *args.train_args]
    print("$", " ".join(cmd), file=sys.stderr)
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return model, time.perf_counter() - start


def evaluate(args: argparse.Namespace, model: Path, seed: int) -> List[Dict[str, Any]]:
    """Both samplers' rows of one seed, each judged by the validator (``success``: claimed and valid)."""
    from gfcs import problems
    from gfcs.learning import EBMSampler, evaluate_first_batch
    from gfcs.planning import UniformSampler

    suite = problems.load_mbm_dir(args.problems, robot=problems.mbm_panda(), skip=args.train,
                                  limit=args.test_limit, classes=args.classes)
    rows: List[Dict[str, Any]] = []
    folder = args.out / f"seed{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    evaluate_first_batch(suite, UniformSampler(), EBMSampler(str(model)), labels=LABELS, seed=1000 * seed,
                         preset="paper", progress=True, per_problem=rows, results_dir=str(folder))
    valid = verdicts(validate(args, folder))
    return [{**r, "run_seed": seed, "claimed_success": bool(r["success"]),
             "success": valid.get((r["problem"], r["result"]), (False, False))[0]} for r in rows]


def validate(args: argparse.Namespace, folder: Path) -> Path:
    """The validator's verdicts on the results in ``folder`` (the MotionBenchMaker Panda's meshes and SRDF,
    beside the problems folder as in ../shared): the file it wrote."""
    out = folder.with_name(folder.name + ".validated.jsonl")
    run_validator(args.problems, args.problems.resolve().parent / ROBOTS["mbm_panda"][1], "mbm_panda", folder,
                  out, args.jobs)
    return out


def bootstrap(values: np.ndarray, n: int = 10_000, seed: int = 0) -> Tuple[float, float, float]:
    """(mean, 2.5 %, 97.5 %) of the mean of ``values`` over ``n`` resamples."""
    rng = np.random.default_rng(seed)
    means = values[rng.integers(0, values.size, size=(n, values.size))].mean(axis=1)
    return float(values.mean()), float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))


def differences(rows: List[Dict[str, Any]]) -> Dict[str, Tuple[float, float, float, int]]:
    """Learned − uniform per (run seed, problem): success [points of %], hand path [m] and time [s] where both
    succeed; each (mean, low, high, n)."""
    pairs: Dict[Tuple[int, str], Dict[str, Dict[str, Any]]] = {}
    for r in rows:
        pairs.setdefault((r["run_seed"], r["problem"]), {})[r["label"]] = r
    both = [p for p in pairs.values() if len(p) == 2]
    out: Dict[str, Tuple[float, float, float, int]] = {}
    success = np.array([100.0 * (int(p[LABELS[1]]["success"]) - int(p[LABELS[0]]["success"])) for p in both])
    out["success (points of %)"] = (*bootstrap(success), success.size)
    solved = [p for p in both if p[LABELS[0]]["success"] and p[LABELS[1]]["success"]]
    for key, title in (("ee_length", "hand path (m)"), ("time", "time (s)")):
        d = np.array([float(p[LABELS[1]][key]) - float(p[LABELS[0]][key]) for p in solved])
        if d.size:
            out[title] = (*bootstrap(d), d.size)
    return out


def read_rows(path: Path) -> List[Dict[str, Any]]:
    """The rows of ``OUT/table2.jsonl`` (none when it does not exist yet)."""
    if not path.is_file():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def render(rows: List[Dict[str, Any]], times: Dict[str, float], args: argparse.Namespace) -> List[str]:
    seeds = sorted({r["run_seed"] for r in rows})
    lines = ["## GFCS Table II: learned against uniform first batch", "",
             f"Written by `python benches/table2.py --problems {args.problems} --seeds "
             f"{' '.join(map(str, seeds))}"
             + (f" --test-limit {args.test_limit}" if args.test_limit else "")
             + (f" --train-args {' '.join(args.train_args)}" if args.train_args else "")
             + f"`: trained on problems 1-{args.train} of every MBM Panda class (the "
             f"paper preset, τ = 1 for the negatives and the sampler), tested on problems {args.train + 1}-"
             f"{50 if not args.test_limit else args.train + args.test_limit} "
             "with one batch of 32, the same per-problem seed for both samplers; solved: claimed by gfcs and "
             "valid by the independent validator (meshes, SRDF pairs, limits). Training wall time per seed: "
             + ", ".join(f"{float(t):.0f} s" for t in times.values()) + ".", "",
             "| seed | sampler | solved | mean hand path (m) | mean time (s) |", "|---|---|---|---|---|"]
    for s in seeds:
        for label in LABELS:
            rs = [r for r in rows if r["run_seed"] == s and r["label"] == label]
            ok = [r for r in rs if r["success"]]
            lines.append(f"| {s} | {label} | {len(ok)}/{len(rs)} | "
                         f"{np.mean([float(r['ee_length']) for r in ok]):.3f} | "
                         f"{np.mean([float(r['time']) for r in ok]):.3f} |")
    lines += ["", "Learned − uniform, pooled over seeds and problems (95 % bootstrap interval):", "",
              "| difference | mean | interval | pairs |", "|---|---|---|---|"]
    for title, (mean, low, high, n) in differences(rows).items():
        lines.append(f"| {title} | {mean:+.3f} | [{low:+.3f}, {high:+.3f}] | {n} |")
    return lines


def main(argv: Sequence[str] = ()) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--problems", type=Path, default=Path("../shared/mbm"))
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    p.add_argument("--train", type=int, default=25, help="training problems per class (the rest test)")
    p.add_argument("--test-limit", type=int, default=None, help="test problems per class (default: the rest)")
    p.add_argument("--classes", nargs="+", default=None, help="only these classes (default: all seven)")
    p.add_argument("--out", type=Path, default=Path("runs/table2"))
    p.add_argument("--jobs", type=int, default=2, help="validator processes")
    p.add_argument("--render", action="store_true", help="write the fragment from OUT/table2.jsonl only")
    p.add_argument("--train-args", nargs=argparse.REMAINDER, default=[],
                   help="further gfcs train options (e.g. --executor ray), last")
    args = p.parse_args(list(argv) or None)
    args.out.mkdir(parents=True, exist_ok=True)
    rows_file, times_file = args.out / "table2.jsonl", args.out / "train_times.json"
    times: Dict[str, float] = json.loads(times_file.read_text()) if times_file.is_file() else {}
    rows = read_rows(rows_file)
    if not args.render:
        for seed in args.seeds:  # a seed's rows replace that seed's earlier ones; other seeds' are kept
            model, times[str(seed)] = train(args, seed)
            rows = [r for r in rows if r["run_seed"] != seed] + evaluate(args, model, seed)
            rows_file.write_text("".join(json.dumps(r) + "\n" for r in rows))
            times_file.write_text(json.dumps(times))
    if not rows:
        p.error(f"no rows in {rows_file}: run it without --render first")
    lines = render(rows, times, args)
    (RESULTS / "learning.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
