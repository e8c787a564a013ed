"""Every error the Python layer raises on bad input is a ``gfcs.GfcsError`` naming its culprit; the
builtin classes callers already catch (ValueError, FileNotFoundError) still catch them."""

from __future__ import annotations

import ast
from pathlib import Path

import gfcs
import numpy as np
import pytest
from gfcs import blend, generators, metrics, problems

PACKAGE = Path(gfcs.__file__).parent
BUILTIN = {"ValueError", "TypeError", "KeyError", "RuntimeError", "FileNotFoundError", "OSError"}


def test_no_module_raises_a_bare_builtin_error():
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call):
                func = node.exc.func
                if isinstance(func, ast.Name) and func.id in BUILTIN:
                    offenders.append(f"{path.relative_to(PACKAGE)}:{node.lineno} {func.id}")
    assert not offenders, "bare builtin errors raised: " + ", ".join(offenders)


def test_python_errors_are_gfcs_errors_and_name_their_argument(tmp_path):
    with pytest.raises(gfcs.InvalidValueError, match="dt"):
        metrics.dimensionless_jerk(np.zeros((5, 2)), dt=0.0)
    with pytest.raises(gfcs.InvalidValueError, match="velocity limits"):
        blend.limit_dynamics(np.arange(3.0), np.zeros((3, 2)), np.zeros((3, 2)), 0.01, velocity=[1.0])
    with pytest.raises(gfcs.MissingFileError, match="nowhere") as e:
        problems.load_mbm_dir(tmp_path / "nowhere")
    assert isinstance(e.value, FileNotFoundError) and isinstance(e.value, gfcs.GfcsError)
    with pytest.raises(gfcs.GfcsError, match="count|n"):
        generators.generate("box", -1)
