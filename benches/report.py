#!/usr/bin/env python3
"""Writes BENCHMARKS.md from result files: nothing in it is typed by hand.

* GFCS Table I per robot, from ``benches/results/table1/<robot>.<run>.jsonl`` (``benches/table1.py``): one
  table per class with GF, the sampling-based planners, GFCS with the ``paper`` and the ``default`` preset,
  and, for the Panda, the paper's own rows (``benches/data/paper_table1.json``). A row's success is the
  validator's verdict (``<robot>.<run>.validated.jsonl``) on the result file the row names (``result``:
  every row of ``gfcs bench`` has one, the first batch's and the first attempt's motions included); rows
  the validator did not judge (rows of an older run without file names, whose motion was not returned)
  keep gfcs's own mesh-judged success, marked †. Problems that gfcs refused before planning (rows with an
  ``error``: a start or goal in collision, which no motion can leave or reach) count in no row of their run
  and are listed under the robot's totals, so that every row of a run has the same problems.
* Every other section is a fragment ``benches/results/<name>.md`` written by the bench script named in it,
  in the order of :data:`FRAGMENTS`.

Run ``python benches/report.py`` (``--check`` exits 1 when BENCHMARKS.md differs from what it would write).
"""

from __future__ import annotations

import argparse
import collections
import json
import math
import statistics
import sys
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benches" / "results"
PAPER = ROOT / "benches" / "data" / "paper_table1.json"

#: robot stem -> title.
ROBOT_TITLES = {"mbm_panda": "Panda (MotionBenchMaker)", "ur5": "UR5", "fetch": "Fetch"}
#: run -> prefix of its GFCS labels ("Ours (1 b)" -> "GFCS paper (1 b)").
RUN_PREFIX = {"paper": "GFCS paper", "default": "GFCS default"}
#: class order of the tables (MotionBenchMaker names) and the paper's names.
CLASSES = {"bookshelf_small": "single shelf", "bookshelf_tall": "tall shelf", "bookshelf_thin": "thin shelf",
           "box": "box", "cage": "cage", "table_pick": "table pick (not in the paper)",
           "table_under_pick": "table under"}
#: Table I columns: row key, title, digits.
COLUMNS: Tuple[Tuple[str, str], ...] = (("ee_length", "EE len (m)"), ("cspace_length", "C-space len (rad)"),
                                        ("time", "Time (s)"), ("ee_ldj", "EE-LDJ"), ("cspace_ldj", "C-space-LDJ"))
#: fragments after Table I, in order: file stem under benches/results.
FRAGMENTS = ("unseen_robots", "sphere_fit", "gf_causes", "ldj", "learning", "speed", "mesh_checks", "scaling", "particles", "experiments", "reactivity",
             "scaleout", "reliability")


def read_jsonl(path: Path) -> List[Dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def number(x: Any) -> float:
    """A row value as a float (rows spell non-finite values as strings)."""
    return {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}.get(x, x) if isinstance(x, str) \
        else float(x)


def verdicts(path: Path) -> Dict[Tuple[str, str], Tuple[bool, bool]]:
    """(problem, method) -> (the validator found the returned motion valid (a claimed failure: False), and
    found its path valid with the joint speeds not checked: ``check_trajectories.is_valid(row,
    speed=False)``, whatever the claim)."""
    out: Dict[Tuple[str, str], Tuple[bool, bool]] = {}
    if not path.is_file():
        return out
    checker = _checker()
    for v in read_jsonl(path):
        name = Path(v["file"]).name  # <class>_<NNNN>.<method>.json
        stem, method = name[:-len(".json")].rsplit(".", 1)
        cls, num = stem.rsplit("_", 1)
        claimed = bool(v.get("claimed_success"))
        out[(f"{cls}/{num}", method)] = (claimed and bool(v.get("valid")), checker.is_valid(v, speed=False))
    return out


def _checker() -> Any:
    """``tools/check_trajectories.py`` as a module (the one definition of a verdict), imported as the tools
    import each other."""
    tools = str(ROOT / "tools")
    if tools not in sys.path:
        sys.path.insert(0, tools)
    import check_trajectories

    return check_trajectories


def judged_rows(robot: str) -> Tuple[List[Dict[str, Any]], Dict[str, Any], Dict[str, str]]:
    """Every row of a robot's runs with ``label`` as the table shows it and ``success`` as judged (see the
    module docstring; ``judged`` False where gfcs's own verdict stands), the runs' provenance, and the
    problems gfcs refused before planning (problem -> the error of its first such row), whose rows are
    left out of every run that refused them."""
    rows: List[Dict[str, Any]] = []
    provenance: Dict[str, Any] = {}
    refused: Dict[str, str] = {}
    for path in sorted((RESULTS / "table1").glob(f"{robot}.*.jsonl")):
        run = path.name[len(robot) + 1:-len(".jsonl")]
        if run.endswith(".validated"):
            continue
        provenance[run] = path.relative_to(ROOT).as_posix()
        valid = verdicts(path.with_name(f"{robot}.{run}.validated.jsonl"))
        run_rows = [r for r in read_jsonl(path) if "label" in r]
        errors = {r["problem"]: r["error"] for r in run_rows if "error" in r}
        for problem, error in errors.items():
            refused.setdefault(problem, error)
        run_rows = [r for r in run_rows if r["problem"] not in errors]
        returned = {}  # rows without a file name: the last row of a problem and method is the returned motion
        for i, r in enumerate(run_rows):
            returned[(r["problem"], r["method"])] = i
        for i, r in enumerate(run_rows):
            r = dict(r)
            key = (r["problem"], r["result"]) if "result" in r else \
                (r["problem"], r["method"]) if returned[(r["problem"], r["method"])] == i else None
            r["judged"] = key in valid
            if r["judged"]:
                r["path_success"] = valid[key][1]
                r["success"] = bool(r["success"]) and valid[key][0]
            if r["method"] == "gfcs":
                r["label"] = r["label"].replace("Ours", RUN_PREFIX.get(run, f"GFCS {run}"))
            rows.append(r)
    return rows, provenance, refused


def escape(label: str) -> str:
    """A label as markdown text (BIT* keeps its star)."""
    return label.replace("*", "\\*")


def label_rank(label: str) -> Tuple[int, str]:
    """Table order: GF, the sampling-based planners, GFCS paper, GFCS default (the issue's Table I rows)."""
    for i, prefix in enumerate(("GF", "RRTConnect", "Bi-EST", "BIT", "GFCS paper", "GFCS default")):
        if label == prefix or (prefix != "GF" and label.startswith(prefix)):
            return i, label
    return 9, label


def by_label(rows: List[Dict[str, Any]]) -> Dict[str, List[Dict[str, Any]]]:
    """Rows grouped by label, in table order."""
    labels: Dict[str, List[Dict[str, Any]]] = {}
    for r in rows:
        labels.setdefault(r["label"], []).append(r)
    return dict(sorted(labels.items(), key=lambda kv: label_rank(kv[0])))


def stat(values: Sequence[float], digits: int = 2) -> str:
    vals = [v for v in values if math.isfinite(v)]
    if not vals:
        return "NA"
    mean, std = statistics.fmean(vals), statistics.pstdev(vals)
    d = 3 if abs(mean) < 1 else digits
    return f"{mean:.{d}f} ± {std:.{d}f}"


def paper_stat(x: Any) -> str:
    if x is None:
        return "NA"
    if isinstance(x, list):
        return f"{x[0]:g} ± {x[1]:g}"
    return f"{x:g}"


def class_table(cls: str, rows: List[Dict[str, Any]], paper: Optional[Dict[str, Any]]) -> List[str]:
    header = ["Method", "% Success", "n"] + [title for _, title in COLUMNS]
    lines = [f"#### {cls} ({CLASSES.get(cls, cls)})", "", "| " + " | ".join(header) + " |",
             "|" + "---|" * len(header)]
    for label, rs in by_label(rows).items():
        ok = [r for r in rs if r["success"]]
        mark = "" if all(r["judged"] for r in rs) else " †"
        cells = [escape(label) + mark, f"{100.0 * len(ok) / len(rs):.0f}", str(len(rs))]
        cells += [stat([number(r[key]) for r in ok]) for key, _ in COLUMNS]
        lines.append("| " + " | ".join(cells) + " |")
    for label, e in (paper or {}).items():
        cells = [f"paper: {escape(label)}", paper_stat(e["success"]), "50"]
        cells += [paper_stat(e[key]) for key, _ in COLUMNS]
        lines.append("| " + " | ".join(cells) + " |")
    return lines + [""]


def totals(rows: List[Dict[str, Any]]) -> List[str]:
    labels = by_label(rows)
    lines = ["| Method | solved | paths valid, speeds not checked | judged by the validator | median time (s) | "
             "median whole solve (s) |", "|---|---|---|---|---|---|"]
    for label, rs in labels.items():
        solved = sum(bool(r["success"]) for r in rs)
        judged = sum(bool(r["judged"]) for r in rs)
        paths = sum(bool(r.get("path_success")) for r in rs)
        path_cell = f"{paths}/{judged} ({100.0 * paths / judged:.1f} %)" if judged else "–"
        lines.append(f"| {escape(label)} | {solved}/{len(rs)} ({100.0 * solved / len(rs):.1f} %) | {path_cell} | "
                     f"{judged}/{len(rs)} | "
                     f"{statistics.median(number(r['time']) for r in rs):.3f} | "
                     f"{statistics.median(number(r['wall_time']) for r in rs):.3f} |")
    return lines + [""]


def ldj_table(rows: List[Dict[str, Any]]) -> List[str]:
    """LDJ of the returned motions against the fabric's own rollouts (``raw_*``), over the successful rows of
    every class; methods without a fabric rollout (the sampling-based planners) are left out."""
    labels: Dict[str, List[Dict[str, Any]]] = {}
    for r in rows:
        if r["success"] and "raw_cspace_ldj" in r:
            labels.setdefault(r["label"], []).append(r)
    if not labels:
        return []
    lines = ["LDJ of the returned motion and of the fabric's own rollout before finishing (start re-timing, "
             "goal blend, limit re-timing), successful problems of every class:", "",
             "| Method | EE-LDJ returned | EE-LDJ rollout | C-space-LDJ returned | C-space-LDJ rollout |",
             "|---|---|---|---|---|"]
    for label, rs in labels.items():
        cells = [stat([number(r[k]) for r in rs]) for k in ("ee_ldj", "raw_ee_ldj", "cspace_ldj", "raw_cspace_ldj")]
        lines.append(f"| {escape(label)} | " + " | ".join(cells) + " |")
    return lines + [""]


def rejections_table(rows: List[Dict[str, Any]]) -> List[str]:
    """Of the paths the sampling-based planners returned, how many are not valid and why: spheres in
    collision between the states the planner checked (at MoveIt's motion-check resolution), or collision
    meshes within the mesh margin (clear for the spheres, as the planner checked them)."""
    from gfcs.metrics import DEFAULT_MESH_MARGIN as margin

    planners = {label: rs for label, rs in by_label(rows).items() if rs and rs[0]["method"] not in ("gfcs", "gf")}
    if not planners:
        return []
    lines = ["Paths the sampling-based planners returned (a path within their time), those that are not valid "
             "(the verdict of the Success column), and of these the ones in sphere collision between the "
             "states the planner checked, and the ones clear for the spheres with the collision meshes within "
             "the mesh margin:", "",
             "| Method | path returned | not valid | spheres between checked states | meshes within the margin |",
             "|---|---|---|---|---|"]
    for label, rs in planners.items():
        returned = [r for r in rs if math.isfinite(number(r["cost"]))]
        rejected = [r for r in returned if not r["success"]]
        spheres = sum(number(r["min_clearance"]) < 0 for r in rejected)
        meshes = sum(number(r["min_clearance"]) >= 0 and min(number(r.get("mesh_clearance", math.inf)),
                     number(r.get("mesh_self_clearance", math.inf))) <= margin for r in rejected)
        lines.append(f"| {escape(label)} | {len(returned)}/{len(rs)} | {len(rejected)} | {spheres} | {meshes} |")
    return lines + [""]


def table1_section() -> List[str]:
    paper = json.loads(PAPER.read_text())["classes"] if PAPER.is_file() else {}
    machine = RESULTS / "table1" / "machine.json"
    lines = ["## GFCS Table I: MotionBenchMaker", "",
             "Written by `python benches/table1.py` (then `python benches/report.py`). Mean ± std over the "
             "successful problems; time is the optimisation (GFCS) or planning time, the whole solve's in the "
             "totals. Success is the independent validator's verdict "
             "(`tools/check_trajectories.py`: FCL on the robot's collision meshes and SRDF, limits, speeds, "
             "goal), on the result file of each row, the first batch's and the first attempt's motions included; "
             "† marks rows of runs that did not write those motions, which keep gfcs's own mesh-judged "
             "success. \"Paths valid, speeds not checked\" counts, of the "
             "judged motions, those the validator passes on everything but the URDF velocity limits: the `paper` preset is "
             "GFCS as written, which does not time its motions to the robot's limits (the UR5's arm joints "
             "allow 0.5 rad/s). \"5 b\" is at most five batches: the `default` preset ends an attempt's "
             "optimisation after two batches that lowered its best cost by at most 1 %, the `paper` preset runs "
             "all five. The paper's rows are its Table I "
             "(`benches/data/paper_table1.json`; its 50 problems per class are not these).", ""]
    if machine.is_file():
        runs = json.loads(machine.read_text())
        lines += ["| run | machine | commit | date | load average at its start |", "|---|---|---|---|---|"]
        lines += [f"| {stem} | {m['cpu']}, {m['cores']} cores | {m['commit']} | {m['date']} | {m['load']:.1f} |"
                  for stem, m in sorted(runs.items())] + [""]
    for robot, title in ROBOT_TITLES.items():
        rows, provenance, refused = judged_rows(robot)
        if not rows:
            lines += [f"### {title}", "", "Not measured at the current code (`python benches/table1.py "
                      f"--robots {robot}`).", ""]
            continue
        lines += [f"### {title}", "", "Result files: " + ", ".join(f"`{p}`" for p in provenance.values()), ""]
        lines += totals(rows)
        if refused:
            kinds = collections.Counter(error.split(":")[0] for error in refused.values())
            lines += [f"Refused before planning, in no row: {len(refused)} problem(s) ("
                      + ", ".join(sorted(refused)) + "; " + ", ".join(f"{k} ×{n}" for k, n in sorted(kinds.items()))
                      + ")" + (": a start or goal in collision, which no motion leaves or reaches" if
                               set(kinds) == {"CollisionError"} else "") + ".", ""]
        lines += ldj_table(rows)
        lines += rejections_table(rows)
        for cls in [c for c in CLASSES if any(r["class"] == c for r in rows)]:
            lines += class_table(cls, [r for r in rows if r["class"] == cls],
                                 paper.get(cls) if robot == "mbm_panda" else None)
    return lines


def render() -> str:
    lines = ["# Benchmarks", "",
             "Generated by `python benches/report.py` from the result files under `benches/results/`; each "
             "section names the script that writes its results. How the defaults were chosen: "
             "[docs/tuning.md](docs/tuning.md).", ""]
    lines += table1_section()
    for name in FRAGMENTS:
        path = RESULTS / f"{name}.md"
        if path.is_file():
            lines += [path.read_text().rstrip(), ""]
    return "\n".join(lines).rstrip() + "\n"


def main(argv: Sequence[str] = ()) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=ROOT / "BENCHMARKS.md")
    p.add_argument("--check", action="store_true", help="exit 1 when --out differs from the rendering")
    args = p.parse_args(list(argv) or None)
    text = render()
    if args.check:
        return 0 if args.out.is_file() and args.out.read_text() == text else 1
    args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
