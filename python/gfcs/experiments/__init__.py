"""Experiments of the papers, reproducible from the command line (``gfcs experiment <name>``).

- :mod:`gfcs.experiments.particles`: the particle systems of GF Sec. VI (Fig. 1): four variants (unbent /
  bent × Riemannian / Finsler) at two desired speeds, with the paper's qualitative claims measured.
- :mod:`gfcs.experiments.panda`: the Franka Panda experiments of GF Sec. VII (wall approach, ring-constricted
  navigation, reaching among moving obstacles), the fabric against the same components unbent.

The submodules are imported on demand: ``import gfcs.experiments`` loads neither matplotlib nor the
experiments themselves.
"""

from __future__ import annotations

import argparse
import importlib
from typing import Any

__all__ = ["EXPERIMENTS", "register_cli"]

#: ``gfcs experiment <name>`` -> module defining ``add_cli(experiment_subparsers)``.
EXPERIMENTS = {
    "particles": "gfcs.experiments.particles",
    "panda": "gfcs.experiments.panda",
}


def register_cli(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``gfcs experiment <name> ...`` to ``subparsers`` (from ``ArgumentParser.add_subparsers``),
    one nested subcommand per entry of :data:`EXPERIMENTS`."""
    p = subparsers.add_parser(
        "experiment", help="the GF paper's experiments (Sec. VI particles, Sec. VII Panda)",
        description="Run an experiment of the papers and write its figure and measured claims.",
    )
    sub = p.add_subparsers(dest="experiment", metavar="EXPERIMENT")
    sub.required = True
    for module_name in EXPERIMENTS.values():
        importlib.import_module(module_name).add_cli(sub)
    return p
