"""Every error the Python layer raises on bad input is a ``gfcs.GfcsError`` naming its culprit; the
builtin classes callers already catch (ValueError, FileNotFoundError) still catch them."""

from __future__ import annotations

import gfcs
import numpy as np
import pytest
from gfcs import blend, generators, metrics, problems


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
