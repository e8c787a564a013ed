#!/usr/bin/env python3
"""How the LDJ of GFCS motions depends on the rate they are sampled at: the same successful motions (result
files of ``benches/table1.py``), their joint paths taken every k-th sample, LDJ recomputed. A smooth motion
has the same LDJ at every rate (the closed forms in tests/test_metrics.py hold to 1e-3 from 20 samples up);
a motion whose acceleration changes from one integration step to the next does not. Writes the markdown
fragment ``benches/results/ldj.md`` that ``benches/report.py`` includes.

    python benches/ldj_sampling.py runs/table1/mbm_panda.paper runs/table1/mbm_panda.default
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import List, Sequence

import numpy as np

from gfcs import metrics

STRIDES = (1, 2, 5, 10, 20)


def ldj_by_stride(folder: Path) -> List[List[float]]:
    """Per stride, the C-space LDJ of every successful GFCS motion in ``folder``."""
    out: List[List[float]] = [[] for _ in STRIDES]
    for f in sorted(folder.glob("*.gfcs.json")):
        r = json.loads(f.read_text())
        if not r.get("success"):
            continue
        t = np.asarray(r["trajectory"]["t"], dtype=np.float64)
        q = np.asarray(r["trajectory"]["q"], dtype=np.float64)
        if t.size < 8:
            continue
        if not np.allclose(np.diff(t), t[1] - t[0], atol=1e-9):
            t, q = metrics.uniform_resample(t, q)
        dt = float(t[1] - t[0])
        for i, k in enumerate(STRIDES):
            out[i].append(metrics.log_dimensionless_jerk(q[::k], dt * k))
    return out


def main(argv: Sequence[str] = ()) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folders", nargs="+", type=Path, help="result folders (benches/table1.py's <robot>.<run>)")
    p.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results" / "ldj.md")
    args = p.parse_args(list(argv) or None)
    header = "| motions | " + " | ".join(f"every {k} ({100 / k:g} Hz)" for k in STRIDES) + " |"
    lines = ["## LDJ and the sampling rate", "",
             "Written by `python benches/ldj_sampling.py " + " ".join(str(f) for f in args.folders) + "`. "
             "C-space LDJ (mean ± std) of the same successful motions, their joint paths sampled every k-th "
             "integration step (100 Hz). A smooth motion keeps its LDJ at every rate; these motions gain "
             "several units as the rate drops, so much of their jerk is step-to-step change of the fabric's "
             "acceleration (barrier leaves switching on and off, the speed controller), which a coarser "
             "sampling does not see. The paper does not state the rate of its LDJ (its figures: −5 to −7.5); "
             "the rate accounts for part of the difference from ours, not for all of it.", "", header, "|---|" + "---|" * len(STRIDES)]
    for folder in args.folders:
        cells = []
        for values in ldj_by_stride(folder):
            v = np.asarray(values)
            v = v[np.isfinite(v)]
            cells.append(f"{v.mean():.2f} ± {v.std():.2f}" if v.size else "NA")
        lines.append(f"| {folder.name} ({len(values)} motions) | " + " | ".join(cells) + " |")
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
