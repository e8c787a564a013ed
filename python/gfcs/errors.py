"""The gfcs exception hierarchy.

The classes are defined in the compiled extension ``gfcs._core`` (so that the Rust core raises exactly these)
and re-exported here. Every message names its culprit: the file, link, joint, field or argument.

==========================  =====================================  ===========================================
class                       bases                                  raised for
==========================  =====================================  ===========================================
``GfcsError``               ``Exception``                          base class; also internal errors (a Rust
                                                                   panic surfaces as ``GfcsError("internal
                                                                   error: ...")``)
``UrdfError``               ``GfcsError``                          malformed or inconsistent URDF
``LinkError``               ``GfcsError``, ``KeyError``            unknown link or joint name
``MeshError``               ``GfcsError``, ``OSError``             missing or unreadable mesh file
``ShapeError``              ``GfcsError``, ``ValueError``          array of the wrong shape
``NonFiniteError``          ``GfcsError``, ``ValueError``          NaN or infinite input
``FormatError``             ``GfcsError``, ``ValueError``          malformed field in a YAML/SRDF/JSON/TOML file
``InvalidValueError``       ``GfcsError``, ``ValueError``          value out of range (radius, time step, gain)
``ConfigError``             alias of ``InvalidValueError``
``IoError``                 ``GfcsError``, ``OSError``             I/O failure on a path
``MissingFileError``        ``IoError``, ``FileNotFoundError``     a file or folder that does not exist
                                                                   (raised by the Python layer)
``GenerationError``         ``GfcsError``, ``RuntimeError``        no valid problem found in the draws a
                                                                   generator may make
``CollisionError``          ``GfcsError``, ``ValueError``          a start or goal state whose collision meshes
                                                                   touch an obstacle or each other (MoveIt
                                                                   refuses such a request)
``GfcsWarning``             ``UserWarning``                        (a warning) input accepted but not fully
                                                                   applied: MoveIt scene fields, SRDF entries
                                                                   for links the robot lacks, a thread count
                                                                   above the cap
==========================  =====================================  ===========================================

Integer arguments (thread counts, iteration counts, obstacle ids, link indices) are checked with their name:
a negative or non-integer value raises ``InvalidValueError``.
"""

import warnings

from gfcs._core import (
    ConfigError,
    FormatError,
    GfcsError,
    GfcsWarning,
    InvalidValueError,
    IoError,
    LinkError,
    MeshError,
    NonFiniteError,
    ShapeError,
    UrdfError,
)


# One SRDF is read by every robot model a solve loads (its planning spheres, its collision meshes): what it
# names that the robot lacks is said once per process. Appended, so a user's own filters take precedence.
warnings.filterwarnings("once", message=r"SRDF .* not in robot", category=GfcsWarning, append=True)


class MissingFileError(IoError, FileNotFoundError):
    """A file or folder that does not exist (``errno`` ENOENT when built as ``MissingFileError(2, text,
    path)``); catchable as ``gfcs.GfcsError`` and as ``FileNotFoundError``."""


class GenerationError(GfcsError, RuntimeError):
    """A problem generator found no valid start and goal within the draws it may make."""


class CollisionError(GfcsError, ValueError):
    """A problem whose start or goal state puts the robot's collision meshes in contact with an obstacle or
    with each other: no motion from or to it can be collision-free (MoveIt refuses such a request)."""


__all__ = [
    "GfcsError",
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
    "GfcsWarning",
]
