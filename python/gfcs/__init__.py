"""gfcs: geometric fabrics and Geometric Fabric Command Sequences.

The compiled core (``gfcs._core``, Rust) holds the robot model, the scene, the fabric and the rollouts;
this package re-exports it and adds the Python layers (problems, optimisation, metrics, learning, viz).

Quick start::

    import gfcs
    robot = gfcs.Robot.panda()
    scene = gfcs.Scene()
    scene.add_sphere([0.5, 0.0, 0.4], 0.1)
    fabric = gfcs.Fabric(robot, scene)
    q0 = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785]
    goal = [0.4, -0.5, -0.3, -2.0, 0.2, 1.4, 0.9]
    result = fabric.rollout(q0, None, goal)           # GFCS eq. 1-3: result.t_star, result.q (T, 7)

Conventions: SI units (m, rad, s); arrays float64; signed distance positive outside; quaternions [x, y, z, w].

The Python submodules (``problems``, ``generators``, ``optimize``, ``results``, ``metrics``, ``learning``,
``viz``, ``plots``, ``experiments``, ``cli``) are imported on first attribute access, so that a missing
optional dependency (torch, rerun) never breaks ``import gfcs``.
"""

from __future__ import annotations

import importlib as _importlib
from typing import TYPE_CHECKING as _TYPE_CHECKING
from typing import Any as _Any

from gfcs import errors
from gfcs._core import (
    Fabric,
    FabricConfig,
    MeshChecker,
    Rmpflow,
    Robot,
    Rollout,
    Scene,
    SequenceRollout,
    __version__,
    load_motion_plan_request,
    panda_srdf,
    panda_urdf,
    particle_acceleration,
    particle_defaults,
    particle_rollout,
)
from gfcs.errors import (
    CollisionError,
    ConfigError,
    FormatError,
    GenerationError,
    GfcsError,
    GfcsWarning,
    InvalidValueError,
    IoError,
    LinkError,
    MeshError,
    MissingFileError,
    NonFiniteError,
    ShapeError,
    UrdfError,
)

if _TYPE_CHECKING:  # pragma: no cover
    from gfcs import metrics, optimize, problems  # noqa: F401

#: Python submodules loaded lazily by :func:`__getattr__`.
_LAZY_SUBMODULES = frozenset(
    {"problems", "generators", "optimize", "results", "metrics", "learning", "viz", "plots", "experiments", "cli"}
)

__all__ = [
    "Robot",
    "Scene",
    "Fabric",
    "FabricConfig",
    "Rmpflow",
    "MeshChecker",
    "Rollout",
    "SequenceRollout",
    "load_motion_plan_request",
    "panda_urdf",
    "panda_srdf",
    "errors",
    "GfcsError",
    "GfcsWarning",
    "UrdfError",
    "LinkError",
    "MeshError",
    "ShapeError",
    "NonFiniteError",
    "FormatError",
    "InvalidValueError",
    "ConfigError",
    "IoError",
    "MissingFileError",
    "GenerationError",
    "CollisionError",
    "particle_acceleration",
    "particle_defaults",
    "particle_rollout",
    "__version__",
]


def __getattr__(name: str) -> _Any:
    """Import the submodule ``gfcs.<name>`` on first access (PEP 562)."""
    if name in _LAZY_SUBMODULES:
        module = _importlib.import_module(f"gfcs.{name}")
        globals()[name] = module
        return module
    raise AttributeError(f"module 'gfcs' has no attribute '{name}'")


def __dir__() -> list[str]:
    """Public names and the lazily imported submodules."""
    return sorted(set(__all__) | _LAZY_SUBMODULES)
