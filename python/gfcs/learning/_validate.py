"""Input validation shared by the learning modules: shapes and finiteness, raising gfcs exceptions.

Every public function of :mod:`gfcs.learning` that takes user arrays validates them here, so a wrong
shape raises :class:`gfcs.errors.ShapeError` naming the argument and the expected shape, a NaN or an
infinity raises :class:`gfcs.errors.NonFiniteError`, and a bad setting raises
:class:`gfcs.errors.ConfigError` (all three are ``ValueError`` subclasses).
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from gfcs.errors import ConfigError, NonFiniteError, ShapeError

__all__ = ["as_float_array", "check_positive", "check_positive_int", "ConfigError", "ShapeError"]


def _shape_text(shape: Sequence[Optional[int]]) -> str:
    parts = ["N" if s is None else str(s) for s in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"


def as_float_array(name: str, value, shape: Sequence[Optional[int]]) -> np.ndarray:
    """Convert ``value`` to a C-contiguous float64 array of the given shape and check it is finite.

    ``shape`` lists the expected size of every axis, ``None`` meaning "any size". Raises ``ShapeError``
    (``"<name>: expected shape (N, 3), got (4,)"``) or ``NonFiniteError`` naming ``name``.
    """
    try:
        arr = np.ascontiguousarray(np.asarray(value, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{name}: expected a float array of shape {_shape_text(shape)}: {exc}") from None
    ok = arr.ndim == len(shape) and all(s is None or s == g for s, g in zip(shape, arr.shape))
    if not ok:
        raise ShapeError(f"{name}: expected shape {_shape_text(shape)}, got {tuple(arr.shape)}")
    if not np.all(np.isfinite(arr)):
        raise NonFiniteError(f"{name} contains NaN or infinite values")
    return arr


def check_positive(name: str, value: float) -> float:
    """Return ``float(value)`` when it is finite and > 0, else raise ``ConfigError`` naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"invalid {name}: expected a positive number, got {value!r}") from None
    if not np.isfinite(v) or v <= 0.0:
        raise ConfigError(f"invalid {name}: expected a positive number, got {value!r}")
    return v


def check_positive_int(name: str, value: int, minimum: int = 1) -> int:
    """Return ``int(value)`` when it is an integer >= ``minimum``, else raise ``ConfigError``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ConfigError(f"invalid {name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)
