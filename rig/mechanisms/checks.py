"""Argument checks shared by the mechanism classes."""
from __future__ import annotations

from numbers import Integral
from typing import Any


def whole(value: Any, minimum: int, what: str) -> int:
    """``value`` as an int if it is a whole number (Python or numpy integer, not a bool) >= ``minimum``; else a
    ValueError starting with ``what``."""
    if isinstance(value, bool) or not isinstance(value, Integral) or value < minimum:
        raise ValueError(f"{what} must be a whole number >= {minimum}, got {value!r}")
    return int(value)
