"""Argument checks of the planning package: each raises :class:`gfcs.errors.InvalidValueError` (a
:class:`gfcs.GfcsError` and a ``ValueError``) whose message names the argument."""

from __future__ import annotations

import math
from typing import Any, Optional

import numpy as np

from gfcs.errors import InvalidValueError

__all__ = ["non_negative", "positive", "fraction", "integer_at_least", "optional_time_limit"]


def _number(name: str, value: Any, unit: str, rule: str) -> float:
    if isinstance(value, bool):
        raise InvalidValueError(f"{name} must be {rule}{unit}, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise InvalidValueError(f"{name} must be {rule}{unit}, got {value!r}") from None


def non_negative(name: str, value: Any, unit: str = "") -> float:
    """``value`` as a float; InvalidValueError naming ``name`` unless it is a finite number ≥ 0."""
    v = _number(name, value, unit, "a finite number ≥ 0")
    if not (math.isfinite(v) and v >= 0):
        raise InvalidValueError(f"{name} must be a finite number ≥ 0{unit}, got {value!r}")
    return v


def positive(name: str, value: Any, unit: str = "") -> float:
    """``value`` as a float; InvalidValueError naming ``name`` unless it is a finite number > 0."""
    v = _number(name, value, unit, "a finite number > 0")
    if not (math.isfinite(v) and v > 0):
        raise InvalidValueError(f"{name} must be a finite number > 0{unit}, got {value!r}")
    return v


def fraction(name: str, value: Any) -> float:
    """``value`` as a float; InvalidValueError naming ``name`` unless it is a number in (0, 1]."""
    v = _number(name, value, "", "a number in (0, 1]")
    if not 0.0 < v <= 1.0:
        raise InvalidValueError(f"{name} must be a number in (0, 1], got {value!r}")
    return v


def integer_at_least(name: str, value: Any, low: int) -> int:
    """``value`` as an int; InvalidValueError naming ``name`` unless it is an integer ≥ ``low`` (bools and
    floats with a fractional part are refused)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer, float, np.floating)):
        raise InvalidValueError(f"{name} must be an integer ≥ {low}, got {value!r}")
    if isinstance(value, (float, np.floating)) and not float(value).is_integer():
        raise InvalidValueError(f"{name} must be an integer ≥ {low}, got {value!r}")
    v = int(value)
    if v < low:
        raise InvalidValueError(f"{name} must be an integer ≥ {low}, got {value!r}")
    return v


def worker_threads(value: Any) -> Optional[int]:
    """A ``threads`` argument of a whole solve: None (all cores) or an integer ≥ 1, capped at
    ``gfcs._core.max_threads()`` with one ``GfcsWarning`` here, so that the many core calls of a solve do not
    each warn."""
    if value is None:
        return None
    n = integer_at_least("threads", value, 1)
    from gfcs import _core
    from gfcs.errors import GfcsWarning

    cap = int(_core.max_threads())
    if n > cap:
        import warnings

        warnings.warn(f"threads={n} exceeds 4 x the {cap // 4} cores: running on {cap} threads", GfcsWarning,
                      stacklevel=3)
        return cap
    return n


def optional_time_limit(value: Any) -> Optional[float]:
    """A time budget [s]: None (no limit) or a finite number > 0."""
    return None if value is None else positive("time_limit", value, " [s]")
