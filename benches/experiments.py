#!/usr/bin/env python3
"""Runs the papers' experiments (`gfcs experiment ...`) and writes each one's printed report as a fragment of
BENCHMARKS.md (``benches/results/<name>.md``), under a heading that names the command.

    python benches/experiments.py                  # every experiment of EXPERIMENTS
    python benches/experiments.py particles        # one
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path
from typing import Dict, List, Sequence, Tuple

RESULTS = Path(__file__).resolve().parent / "results"

#: fragment name -> (heading, arguments of `gfcs experiment`).
EXPERIMENTS: Dict[str, Tuple[str, List[str]]] = {
    "particles": ("Particle experiment (GF Sec. VI)", ["particles", "--out", "runs/particles.png"]),
    "reactivity": ("Reactivity (GFCS Sec. V)", ["reactivity", "--limit", "20"]),
}


def run(name: str) -> Path:
    heading, arguments = EXPERIMENTS[name]
    Path("runs").mkdir(exist_ok=True)
    cmd = [sys.executable, "-m", "gfcs", "experiment", *arguments]
    print("$", " ".join(cmd), file=sys.stderr)
    start = time.perf_counter()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    took = time.perf_counter() - start
    text = (f"## {heading}\n\nWritten by `python benches/experiments.py {name}`: the report of "
            f"`gfcs experiment {' '.join(arguments)}` ({took:.0f} s on this machine).\n\n```text\n"
            f"{out.rstrip()}\n```\n")
    path = RESULTS / f"{name}.md"
    path.write_text(text)
    return path


def main(argv: Sequence[str] = ()) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("names", nargs="*", metavar="NAME", help=f"experiments among {list(EXPERIMENTS)} (default: all)")
    args = p.parse_args(list(argv) or None)
    unknown = set(args.names) - set(EXPERIMENTS)
    if unknown:
        p.error(f"unknown experiment(s) {sorted(unknown)}; choose from {list(EXPERIMENTS)}")
    for name in args.names or EXPERIMENTS:
        print(run(name))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
