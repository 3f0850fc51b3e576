"""Measurement control: where in a chunk of samples a measurement starts or stops.

Crossings are Schmitt triggers: a "rising" trigger is armed by a value below level − hysteresis and fires
at the first sample that then reaches the level (>=); "falling" is armed above level + hysteresis and
fires at or below the level. With hysteresis 0: the previous value below (above) the level, this one at or
beyond it. Noise around the level cannot fire a trigger again until the signal has left the band. The
sample that crosses belongs to the curve (first pair at a start, last pair at a stop). Times: a stop at time T keeps the
samples with t <= T and is decided once a sample with t >= T has been seen.
"""
from __future__ import annotations

import numpy as np

_T_ABS, _T_REL = 1e-11, 1e-13   # tolerance on times (s) against rounding of sample times


def crossing(values: np.ndarray, previous: float | None, level: float, direction: str, first: int,
             hysteresis: float = 0.0, armed: bool = False) -> tuple[int | None, bool]:
    """First index >= ``first`` where ``values`` cross ``level`` in ``direction`` once armed (see the module
    docstring), and whether the trigger is armed at the end when it did not fire (else False). The sample
    before ``values[first]`` (``previous`` when ``first`` is 0, None if unknown) can arm it; ``armed``: it was
    armed already (carried over from the previous chunk)."""
    sign = 1.0 if direction == "rising" else -1.0
    before = values[first - 1] if first > 0 else previous
    lower = sign * level - hysteresis          # the trigger arms below this (in the direction's sign)
    armed = armed or (before is not None and sign * before < lower)
    v = sign * values[first:]
    if v.size == 0:
        return None, armed
    arms = v < lower
    armed_before = np.empty(v.size, dtype=bool)
    armed_before[0] = armed
    np.logical_or(armed, np.logical_or.accumulate(arms[:-1]), out=armed_before[1:])
    idx = np.flatnonzero(armed_before & (v >= sign * level))
    if idx.size:
        return first + int(idx[0]), False
    return None, bool(armed or arms.any())


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
