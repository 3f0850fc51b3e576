"""Measurement control: where in a chunk of samples a measurement starts or stops.

Crossings: "rising" at sample i when the previous value is below the level and sample i reaches it
(>=); "falling" when the previous value is above and sample i is at or below. The sample that crosses
belongs to the curve (first pair at a start, last pair at a stop). Times: a stop at time T keeps the
samples with t <= T and is decided once a sample with t >= T has been seen.
"""
from __future__ import annotations

import numpy as np

_T_ABS, _T_REL = 1e-11, 1e-13   # tolerance on times (s) against rounding of sample times


def crossing(values: np.ndarray, previous: float | None, level: float, direction: str, first: int) -> int | None:
    """First index >= ``first`` where ``values`` crosses ``level`` in ``direction`` (``previous`` is the
    value just before ``values[0]``, None if unknown)."""
    before = np.concatenate([[np.nan if previous is None else previous], values[:-1]])[first:]
    now = values[first:]
    hit = (before < level) & (now >= level) if direction == "rising" else (before > level) & (now <= level)
    idx = np.flatnonzero(hit)
    return first + int(idx[0]) if idx.size else None


def first_at_or_after(t: np.ndarray, when: float, first: int) -> int | None:
    """First index >= ``first`` with t >= ``when``."""
    i = max(first, int(np.searchsorted(t, when - _T_ABS - _T_REL * abs(when), "left")))
    return i if i < t.size else None


def last_up_to(t: np.ndarray, when: float) -> int | None:
    """Last index with t <= ``when``, once the chunk reaches ``when`` (else None: not decided yet)."""
    tol = _T_ABS + _T_REL * abs(when)
    if t[-1] < when - tol:
        return None
    return int(np.searchsorted(t, when + tol, "right")) - 1
