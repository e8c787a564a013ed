"""Shared pytest fixtures for gfcs.

``shared_dir`` locates the development data (MotionBenchMaker problems, the MBM Panda) at
``<repo root>/../shared``, overridable by the environment variable ``GFCS_SHARED``. When it is absent the
test is skipped with the reason, except under CI (``CI=true``) where its absence is a failure.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent


def load_script(relative: str) -> ModuleType:
    """Import the script ``<repo root>/<relative>`` (a tool or bench, not part of the package) as a module
    named after its file, registered in ``sys.modules`` (dataclasses and worker processes look it up)."""
    path = REPO_ROOT / relative
    loaded = sys.modules.get(path.stem)
    if loaded is not None and Path(getattr(loaded, "__file__", "")) == path:
        return loaded  # one module object per script (pickling by reference needs it)
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault(path.stem, module)
    spec.loader.exec_module(module)
    return module


def shared_path() -> Path:
    """The shared data directory (it may not exist)."""
    override = os.environ.get("GFCS_SHARED")
    return Path(override) if override else REPO_ROOT.parent / "shared"


def require_shared(*parts: str) -> Path:
    """Path ``<shared>/<parts...>``; skip when absent outside CI, fail when absent under CI."""
    path = shared_path().joinpath(*parts)
    if not path.exists():
        reason = f"shared data not found: {path} (set GFCS_SHARED to its location)"
        if os.environ.get("CI") == "true":
            pytest.fail(reason + "; CI=true requires it")
        pytest.skip(reason)
    return path


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Tests write gfcs's disk cache (:mod:`gfcs.cache`) into a temporary directory of their own, never the
    user's, unless GFCS_CACHE_DIR is set."""
    os.environ.setdefault("GFCS_CACHE_DIR", str(tmp_path_factory.mktemp("gfcs_cache")))


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The shared data directory (skip/fail rule of :func:`require_shared`)."""
    return require_shared()


@pytest.fixture(scope="session")
def mbm_panda_dir() -> Path:
    """``<shared>/robots/mbm_panda`` (skip/fail rule of :func:`require_shared`)."""
    return require_shared("robots", "mbm_panda")


@pytest.fixture(scope="session")
def mbm_dir() -> Path:
    """``<shared>/mbm``: MotionBenchMaker problems (skip/fail rule of :func:`require_shared`)."""
    return require_shared("mbm")


@pytest.fixture(scope="session")
def fake_optimum():
    """``fake_optimum(xs, costs)``: an ``OptimResult`` holding the candidates ``xs`` (K, dim) with ``costs``
    (K,), as :func:`gfcs.optimize.solve_gfcop` returns them (for testing the candidate selection)."""
    import numpy as np

    from gfcs import optimize

    def make(xs, costs):
        xs, costs = np.asarray(xs, dtype=float), np.asarray(costs, dtype=float)
        order = np.argsort(costs, kind="stable")
        return optimize.OptimResult(best_x=xs[order[0]], best_cost=float(costs[order[0]]), top_x=xs[order],
                                    top_costs=costs[order], all_x=xs, all_costs=costs,
                                    all_batches=np.zeros(len(xs), int), batch_best_costs=costs[order[:1]],
                                    batch_best_x=xs[order[:1]], batch_times=np.zeros(1))

    return make
