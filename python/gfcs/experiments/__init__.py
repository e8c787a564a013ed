"""Experiments of the papers, reproducible from the command line (``gfcs experiment <name>``).

- :mod:`gfcs.experiments.particles`: the particle systems of GF Sec. VI (Fig. 1): four variants (unbent /
  bent × Riemannian / Finsler) at two desired speeds, with the paper's qualitative claims measured.
- :mod:`gfcs.experiments.panda`: the Franka Panda experiments of GF Sec. VII (wall approach, ring-constricted
  navigation, reaching among moving obstacles), the fabric against the same components unbent.
- :mod:`gfcs.experiments.reactivity`: GFCS Sec. V's reactivity: solved motions replayed, without
  re-optimising, after a new obstacle is put on their path.
- :mod:`gfcs.experiments.constrained`: GF App. F, the hand held on a plane (constrained fabric).
- :mod:`gfcs.experiments.orientation`: GF App. G, reaching a hand pose (position and axis attractors).

The submodules are imported on demand: ``import gfcs.experiments`` loads neither matplotlib nor the
experiments themselves.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from pathlib import Path
from typing import Any, Optional

__all__ = ["EXPERIMENTS", "register_cli", "report"]

#: ``gfcs experiment <name>`` -> module defining ``add_cli(experiment_subparsers)``.
EXPERIMENTS = {
    "particles": "gfcs.experiments.particles",
    "panda": "gfcs.experiments.panda",
    "reactivity": "gfcs.experiments.reactivity",
    "constrained": "gfcs.experiments.constrained",
    "orientation": "gfcs.experiments.orientation",
}


def register_cli(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``gfcs experiment <name> ...`` to ``subparsers`` (from ``ArgumentParser.add_subparsers``),
    one nested subcommand per entry of :data:`EXPERIMENTS`."""
    p = subparsers.add_parser(
        "experiment", help="the papers' experiments (GF Sec. VI particles, Sec. VII Panda; GFCS Sec. V reactivity)",
        description="Run an experiment of the papers and write its figure and measured claims.",
    )
    sub = p.add_subparsers(dest="experiment", metavar="EXPERIMENT")
    sub.required = True
    for module_name in EXPERIMENTS.values():
        importlib.import_module(module_name).add_cli(sub)
    return p


def _plain(x: Any) -> Any:
    """JSON-safe copy: numpy scalars as Python numbers, non-finite floats as None."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if hasattr(x, "item") and not isinstance(x, (str, bytes)):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def add_output_options(p: argparse.ArgumentParser, what: str = "the figures", figure_required: bool = False,
                       recording: Optional[str] = None) -> None:
    """The output options of an experiment command: ``--out FIG.png``, ``--json [OUT.json]`` (``what`` as
    JSON; no file name: to stdout, the summary to stderr) and, when ``recording`` says what it holds,
    ``--rrd-dir DIR`` (a rerun recording; the viz extra)."""
    p.add_argument("--out", required=figure_required, metavar="FIG.png", help="PNG to write")
    if recording is not None:
        p.add_argument("--rrd-dir", metavar="DIR", help=f"write a rerun recording, {recording} (viz extra; "
                                                        "open with gfcs view)")
    p.add_argument("--json", nargs="?", const="-", metavar="OUT.json",
                   help=f"write {what} as JSON (no file name: to stdout, the summary to stderr)")


def report(text: str, claims: Any, json_target: Optional[str], figure: Optional[Path] = None) -> None:
    """What an experiment command prints and writes: the summary ``text`` (and the figure written), on
    stdout, or on stderr when the claims go to stdout (``json_target`` "-"); the ``claims`` as JSON to the
    file ``json_target`` (none when None)."""
    info = sys.stderr if json_target == "-" else sys.stdout
    print(text, file=info)
    if figure is not None:
        print(f"wrote {figure}", file=info)
    if json_target:
        payload = json.dumps(_plain(claims), indent=2, allow_nan=False) + "\n"
        if json_target == "-":
            sys.stdout.write(payload)
        else:
            Path(json_target).write_text(payload)
