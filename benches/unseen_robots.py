#!/usr/bin/env python3
"""Robots the project was never developed on, run as a new user would: `gfcs generate`, `gfcs bench` and
`tools/check_trajectories.py` on the MoveIt/ROS descriptions of the `example-robot-data` package (URDF,
SRDF, collision meshes; no spheres: gfcs fits them).

The package's SRDFs written for Pinocchio disable no link pairs, and a MoveIt SRDF disables at least the
adjacent ones (MoveIt Setup Assistant's "Adjacent"): for those robots (``adjacent=True`` below) the SRDF
used for planning and validation is the package's with every pair of adjacent links with collision
geometry disabled (links without geometry skipped, as Setup Assistant does), written into --out.

Get the descriptions (the wheel holds only data files)::

    pip download example-robot-data==6.0.0 --no-deps -d erd && unzip -q erd/*.whl -d erd/x
    python benches/unseen_robots.py --share erd/x/cmeel.prefix/share --out runs/unseen

Writes the fragment ``benches/results/unseen_robots.md`` (for ``benches/report.py``) and one folder of
problems, results and verdicts per robot under --out.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

ROOT = Path(__file__).resolve().parents[1]
FRAGMENT = ROOT / "benches" / "results" / "unseen_robots.md"
RETRY_LABEL = "Ours (5 b, retry)"


@dataclass(frozen=True)
class Case:
    """One robot: its title, URDF and SRDF (relative to ``<share>/example-robot-data/robots``; "" for none), the link whose
    pose the validator reports, whether to add the adjacent pairs to the SRDF or the whole collision matrix
    ``gfcs collision-matrix`` writes (MoveIt Setup Assistant's), extra CLI flags, and a rewrite of the SRDF text
    (applied first) where the package's does not fit its URDF."""

    title: str
    urdf: str
    srdf: str
    ee_link: str
    adjacent: bool = False
    matrix: bool = False
    flags: Tuple[str, ...] = field(default_factory=tuple)
    rewrite: Optional[Callable[[str], str]] = None


def with_groups(text: str, groups: str) -> str:
    """SRDF ``text`` with the ``<group>`` elements ``groups`` added at its end."""
    return text.replace("</robot>", groups + "</robot>")


def arm_groups(left: List[str], right: List[str]) -> str:
    """MoveIt's two-arm groups ``left_arm``, ``right_arm`` and ``both_arms`` of the given joint names."""
    def joints(names: List[str]) -> str:
        return "".join(f'<joint name="{j}"/>' for j in names)

    return (f'<group name="left_arm">{joints(left)}</group><group name="right_arm">{joints(right)}</group>'
            f'<group name="both_arms">{joints(left)}{joints(right)}</group>')


def baxter_srdf(text: str) -> str:
    """The package's Baxter SRDF made MoveIt's: its group names every joint with a ``baxter/`` prefix that the
    URDF's joints lack (MoveIt would find no joint), and it has no arm groups; MoveIt's Baxter configuration
    has ``left_arm``, ``right_arm`` and ``both_arms`` (shoulder s0 to wrist w2)."""
    arm = ("s0", "s1", "e0", "e1", "w0", "w1", "w2")
    return with_groups(text.replace("baxter/", ""),
                       arm_groups([f"left_{j}" for j in arm], [f"right_{j}" for j in arm]))


def tiago_srdf(text: str) -> str:
    """An SRDF for TIAGo (the package has none) with the ``arm_torso`` group of its MoveIt configuration: the
    lift (prismatic) and the seven arm joints."""
    joints = "".join(f'<joint name="{j}"/>' for j in ["torso_lift_joint"] + [f"arm_{i}_joint" for i in range(1, 8)])
    return with_groups(text, f'<group name="arm_torso">{joints}</group>')


def tiago_pro_srdf(text: str) -> str:
    """An SRDF for TIAGo Pro (the package has none) with groups of its MoveIt configuration's kind: each arm,
    both arms, and both arms with the lift (prismatic, 0.035 m/s)."""
    def arm(side: str) -> List[str]:
        return [f"arm_{side}_{i}_joint" for i in range(1, 8)]

    return with_groups(text, arm_groups(arm("left"), arm("right")) +
                       '<group name="both_arms_torso"><joint name="torso_lift_joint"/><group name="both_arms"/></group>')


def centauro_srdf(text: str) -> str:
    """The package's Centauro SRDF (chain groups, no collision matrix) with a ``both_arms`` group of its two arm
    chains."""
    return with_groups(text, '<group name="both_arms"><group name="left_arm"/><group name="right_arm"/></group>')


def g1_srdf(text: str) -> str:
    """An SRDF for the Unitree G1 (the package has none): each arm as a chain from the torso to its hand, the
    waist's three joints, and ``arms_waist``, both arms with the waist (17 joints)."""
    return with_groups(text, '<group name="left_arm"><chain base_link="torso_link" tip_link="left_rubber_hand"/>'
                       '</group><group name="right_arm"><chain base_link="torso_link" tip_link="right_rubber_hand"/>'
                       '</group><group name="arms_waist"><joint name="waist_yaw_joint"/><joint name="waist_roll_joint"/>'
                       '<joint name="waist_pitch_joint"/><group name="left_arm"/><group name="right_arm"/></group>')


def romeo_srdf(text: str) -> str:
    """The package's MoveIt SRDF of Romeo (Setup Assistant's collision matrix) with arm groups added: its only
    group, ``all``, moves the legs, the head and the hands too; a manipulation configuration has ``left_arm``,
    ``right_arm`` and ``both_arms`` (shoulder pitch to wrist pitch)."""
    arm = ("ShoulderPitch", "ShoulderYaw", "ElbowRoll", "ElbowYaw", "WristRoll", "WristYaw", "WristPitch")
    return with_groups(text, arm_groups([f"L{j}" for j in arm], [f"R{j}" for j in arm]))


CASES = (
    Case("UFactory xArm7 (7 joints)", "xarm_description/urdf/xarm7.urdf", "xarm_description/srdf/xarm7.srdf",
         "link_eef"),
    Case("Kinova Gen2 j2s6s200 (6)", "kinova_description/robots/kinova.urdf", "kinova_description/srdf/kinova.srdf",
         "j2s6s200_end_effector", adjacent=True),
    Case("Unitree Z1 (6)", "z1_description/urdf/z1.urdf", "z1_description/srdf/z1.srdf", "gripperMover",
         adjacent=True),
    Case("UR3 with gripper (6)", "ur_description/urdf/ur3_gripper.urdf", "ur_description/srdf/ur3_gripper.srdf",
         "tool0"),
    Case("PR2, both arms (14)", "pr2_description/urdf/pr2.urdf", "pr2_description/srdf/pr2.srdf",
         "l_wrist_roll_link", flags=("--group", "arms")),
    Case("ANYmal B with a Kinova arm (6; 12 leg joints held)", "anymal_b_simple_description/robots/anymal-kinova.urdf",
         "anymal_b_simple_description/srdf/anymal-kinova.srdf", "j2s6s200_end_effector", flags=("--group", "arm")),
    Case("Unitree B1 with a Z1 arm (7; 12 leg joints held)", "b1_description/urdf/b1-z1.urdf",
         "b1_description/srdf/b1-z1.srdf", "gripperMover", adjacent=True, flags=("--group", "arm")),
    Case("SO-100 (6, gripper joint planned)", "so_arm_description/urdf/so100.urdf", "", "jaw", matrix=True),
    Case("Baxter, both arms (14)", "baxter_description/urdf/baxter.urdf", "baxter_description/srdf/baxter_manipulation.srdf",
         "left_wrist", flags=("--group", "both_arms"), rewrite=baxter_srdf),
    Case("TIAGo, lift and arm (8; head and hand held)", "tiago_description/robots/tiago.urdf", "", "arm_tool_link",
         matrix=True, flags=("--group", "arm_torso"), rewrite=tiago_srdf),
    Case("TIAGo Pro, both arms and lift (15; head and grippers held)", "tiago_pro_description/robots/tiago_pro.urdf",
         "", "arm_left_tool_link", matrix=True, flags=("--group", "both_arms_torso"), rewrite=tiago_pro_srdf),
    Case("Romeo, left arm (7; legs, head and hands held)", "romeo_description/urdf/romeo.urdf",
         "romeo_description/srdf/romeo_moveit.srdf", "l_wrist", flags=("--group", "left_arm"), rewrite=romeo_srdf),
    Case("Romeo, both arms (14)", "romeo_description/urdf/romeo.urdf", "romeo_description/srdf/romeo_moveit.srdf",
         "l_wrist", flags=("--group", "both_arms"), rewrite=romeo_srdf),
    Case("TALOS, both arms and torso (16; legs, head and grippers at half_sitting)",
         "talos_data/robots/talos_full_v2.urdf", "talos_data/srdf/talos.srdf", "wrist_left_ft_tool_link",
         flags=("--group", "all_arms_torso")),
    Case("Centauro, both arms (14; legs, wheels and torso held)", "centauro_description/urdf/centauro.urdf",
         "centauro_description/srdf/centauro.srdf", "arm1_8", matrix=True, flags=("--group", "both_arms"),
         rewrite=centauro_srdf),
    Case("Unitree G1, both arms and waist (17; legs held)", "g1_description/urdf/g1_29dof_rev_1_0.urdf", "",
         "left_rubber_hand", matrix=True, flags=("--group", "arms_waist"), rewrite=g1_srdf),
)


def adjacent_srdf(urdf: Path, srdf: Path) -> str:
    """``srdf`` with a ``disable_collisions`` (reason "Adjacent") for every pair of links of ``urdf`` with
    collision geometry that the kinematic tree joins directly, links without geometry skipped."""
    from gfcs.collision_matrix import DisabledPair, adjacent_pairs, srdf_with_pairs

    return srdf_with_pairs([DisabledPair(p, c, "Adjacent") for p, c in adjacent_pairs(urdf)], "", srdf)


def run(cmd: List[str], log: Path) -> str:
    """Run ``cmd``; its stderr and stdout appended to ``log``; its stdout returned (a failure stops here)."""
    out = subprocess.run(cmd, capture_output=True, text=True)
    with log.open("a") as f:
        f.write("$ " + " ".join(cmd) + "\n" + out.stderr + out.stdout + "\n")
    if out.returncode not in (0, 1):  # 1: generate or bench with a class or a problem that failed
        raise SystemExit(f"{' '.join(cmd)} exited {out.returncode}; see {log}")
    return out.stdout + out.stderr


def bench_case(case: Case, share: Path, out: Path, n: int, jobs: int) -> Dict[str, object]:
    """Generate, plan and validate one robot; its row of the table."""
    robots = share / "example-robot-data" / "robots"
    group = case.flags[case.flags.index("--group") + 1] if "--group" in case.flags else ""
    folder = out / "_".join(filter(None, (case.urdf.split("/")[0], group)))  # one folder per robot and group
    folder.mkdir(parents=True, exist_ok=True)
    log = folder / "log.txt"
    log.write_text("")
    urdf, srdf = robots / case.urdf, robots / case.srdf
    if not case.srdf:  # a description without an SRDF: an empty one, for the adjacent pairs below
        srdf = folder / (urdf.stem + ".srdf")
        srdf.write_text(f'<robot name="{urdf.stem}"></robot>')
    if case.rewrite is not None:
        written = folder / (srdf.stem + "_moveit.srdf")
        written.write_text(case.rewrite(srdf.read_text()))
        srdf = written
    if case.adjacent:
        written = folder / (srdf.stem + "_adjacent.srdf")
        written.write_text(adjacent_srdf(urdf, srdf))
        srdf = written
    if case.matrix:
        written = folder / (srdf.stem + "_matrix.srdf")
        run([sys.executable, "-m", "gfcs", "collision-matrix", str(urdf), "--mesh-dir", str(share), "--srdf", str(srdf),
             "-o", str(written), "--no-progress"], log)
        srdf = written
    robot = ["--robot", str(urdf), "--srdf", str(srdf), "--mesh-dir", str(share), *case.flags]
    problems, results, rows, verdicts = (folder / "problems", folder / "results", folder / "bench.jsonl",
                                         folder / "validated.jsonl")
    for p in (rows, verdicts):
        p.unlink(missing_ok=True)
    generated = run([sys.executable, "-m", "gfcs", "generate", "--out", str(problems), "--n", str(n), *robot], log)
    started = time.perf_counter()
    run([sys.executable, "-m", "gfcs", "bench", "--problems", str(problems), *robot, "--method", "gfcs",
         "--no-progress", "--json", str(rows), "--results-dir", str(results)], log)
    bench_s = time.perf_counter() - started
    run([sys.executable, str(ROOT / "tools" / "check_trajectories.py"), str(results), "--problems", str(problems),
         "--urdf", str(urdf), "--srdf", str(srdf), "--mesh-dir", str(share), "--ee-link", case.ee_link,
         "--jobs", str(jobs), "--json", str(verdicts)], log)
    final = [json.loads(line) for line in rows.read_text().splitlines() if line.strip()]
    final = [r for r in final if r.get("label") == RETRY_LABEL]
    judged = [json.loads(line) for line in verdicts.read_text().splitlines() if line.strip()]
    claims = [v for v in judged if v.get("claimed_success")]
    fitted = next((line for line in generated.splitlines() if "spheres fitted" in line), "")
    classes = sorted({r["class"] for r in final})
    return {
        "robot": case.title,
        "problems": len(final),
        "classes": len(classes),
        "solved": sum(bool(r.get("success")) for r in final),
        "claims": len(claims),
        "valid": sum(bool(v.get("valid")) for v in claims),
        "median_solve_s": statistics.median(float(r["wall_time"]) for r in final) if final else float("nan"),
        "max_speed_ratio": max((float(v.get("speed_ratio") or 0.0) for v in claims), default=float("nan")),
        "min_clearance_mm": 1e3 * min((float(v["clearance"]) for v in claims), default=float("nan")),
        "bench_s": bench_s,
        "spheres": fitted.split("the fabric uses ")[-1].split(" spheres")[0] if fitted else "",
    }


def fragment(rows: List[Dict[str, object]], n: int) -> str:
    lines = [
        "## Robots the project never ran on",
        "",
        "Written by `python benches/unseen_robots.py --share SHARE --n {n}` on the descriptions of the "
        "`example-robot-data` package 6.0.0 (URDF, SRDF, collision meshes; no spheres: gfcs fits them), as a new "
        "user would run them: `gfcs generate --n {n}` (each class it can fill), `gfcs bench --method gfcs`, and "
        "`tools/check_trajectories.py` on the robot's meshes, SRDF pairs, limits and velocity limits. The Kinova's "
        "and the Z1's SRDFs (written for Pinocchio) disable no pair, and the B1's leaves the Z1 gripper's two "
        "halves enabled; they are used with their adjacent pairs disabled, as MoveIt Setup Assistant writes them. "
        "The UR3's SRDF has no group: its requests plan the robot's joints. The legged robots' arm groups hold "
        "the legs at 0. The Baxter's SRDF prefixes its joints with `baxter/`, which its URDF does not, and has "
        "no arm group: it is used with the prefix removed and MoveIt's `both_arms` group added. Romeo's MoveIt SRDF "
        "has only a whole-body group: its arm groups are added, the rest held at 0. The SO-100, TIAGo and TIAGo Pro "
        "have no SRDF: `gfcs collision-matrix` writes one (MoveIt Setup Assistant's matrix, 10,000 samples), "
        "TIAGo's with the `arm_torso` group of its MoveIt configuration, TIAGo Pro's with a group of both arms and "
        "the lift (`both_arms_torso`, 15 joints); the SO-100's requests plan all six joints. TALOS plans its SRDF's "
        "`all_arms_torso` group, the other joints held at its SRDF state `half_sitting` (whose floating base pose is "
        "no URDF joint). Centauro's SRDF has chain groups and no collision matrix: `gfcs collision-matrix` writes "
        "it, with a `both_arms` group of its two arm chains added; its wheels are revolute joints without limits "
        "(a zero range, held at 0). The G1 has no SRDF: one with its arms as chains from the torso and the "
        "waist's three joints (`arms_waist`, 17 joints), matrix by `gfcs collision-matrix`.".format(n=n),
        "",
        "| robot (joints) | problems (classes) | solved | claims valid | median whole solve (s) "
        "| max speed/limit | min mesh clearance (mm) |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r['robot']} | {r['problems']} ({r['classes']}) | {r['solved']}/{r['problems']} "
                     f"| {r['valid']}/{r['claims']} | {r['median_solve_s']:.2f} | {r['max_speed_ratio']:.2f} "
                     f"| {r['min_clearance_mm']:.1f} |")
    return "\n".join(lines) + "\n"


def main(argv: Optional[List[str]] = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--share", type=Path, required=True,
                   help="folder holding example-robot-data/robots (the wheel's cmeel.prefix/share)")
    p.add_argument("--out", type=Path, default=Path("runs/unseen"), help="working folder (default runs/unseen)")
    p.add_argument("--n", type=int, default=3, help="problems per class (default 3)")
    p.add_argument("--jobs", type=int, default=2, help="validator processes (default 2)")
    p.add_argument("--fragment", type=Path, default=FRAGMENT, help=f"markdown written (default {FRAGMENT})")
    args = p.parse_args(argv)
    if not (args.share / "example-robot-data" / "robots").is_dir():
        p.error(f"--share {args.share}: no example-robot-data/robots in it")
    rows = []
    for case in CASES:
        row = bench_case(case, args.share, args.out, args.n, args.jobs)
        print(json.dumps(row), flush=True)
        rows.append(row)
    (args.out / "unseen_robots.json").write_text(json.dumps(rows, indent=1))
    args.fragment.write_text(fragment(rows, args.n))
    print(fragment(rows, args.n))
    return 0


if __name__ == "__main__":
    sys.exit(main())
