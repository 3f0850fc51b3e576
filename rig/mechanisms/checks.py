"""Argument checks shared by the mechanism classes."""
from __future__ import annotations

import math
from numbers import Integral, Real
from typing import Any

import numpy as np


def whole(value: Any, minimum: int, what: str, maximum: int | None = None) -> int:
    """``value`` as an int if it is a whole number (Python or numpy integer, not a bool) >= ``minimum`` (and <=
    ``maximum``); else a ValueError starting with ``what``."""
    if (isinstance(value, bool) or not isinstance(value, Integral) or value < minimum
            or (maximum is not None and value > maximum)):
        raise ValueError(f"{what} must be a whole number >= {minimum}" + (f" and <= {maximum}" if maximum else "")
                         + f", got {value!r}")
    return int(value)


def finite(value: Any, what: str) -> float:
    """``value`` as a float if it is a finite real number (not a bool or a string); else a ValueError starting with
    ``what``."""
    if isinstance(value, (bool, str, bytes)) or not isinstance(value, Real) or not math.isfinite(value):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def positive(value: Any, what: str, unit: str = "", at_most: float | None = None, hint: str = "") -> float:
    """:func:`finite` and > 0 (and ≤ ``at_most``); the message names ``what``, its ``unit`` and a ``hint`` for a value
    above ``at_most`` (e.g. "did you mean mm")."""
    v = finite(value, what)
    if not v > 0.0 or (at_most is not None and v > at_most):
        bound = f" and at most {at_most:g} {unit}".rstrip() if at_most is not None else ""
        raise ValueError(f"{what} must be positive{bound}, got {value!r} {unit}".rstrip()
                         + (f": {hint}" if hint and at_most is not None and v > at_most else ""))
    return v


def degrees_hint(angle: float) -> str:
    """A hint for an angle (rad) of π or more but below 90: no angle between shafts or of a tooth is that large, so it
    was likely meant in degrees; empty otherwise (a value with a unit needs no hint)."""
    return (f": the angle is in radians: did you mean {angle:g}° = {math.radians(angle):.4g} rad?"
            if math.pi <= angle < 90.0 else "")


def finite_array(values: Any, what: str) -> np.ndarray:
    """``values`` as a float array if they are numbers (not strings) and every entry is finite; else a ValueError
    starting with ``what``."""
    try:
        if isinstance(values, (str, bytes)):
            raise TypeError
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be finite numbers, got {values!r}") from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} must be finite, got {values!r}" if arr.size < 5 else f"{what} must be finite "
                         f"({int(np.count_nonzero(~np.isfinite(arr)))} of {arr.size} values are not)")
    return arr
