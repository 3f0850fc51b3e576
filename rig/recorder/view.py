"""Decimation for the view channels: at most one sample per period of a fixed grid.

A view channel carries one message per sample (``{"t": s, "<signal>": value}``) so that a viewer's
time plot gets one point per sample; blocks of 1000 samples would give one point per block.
"""
from __future__ import annotations

import math

import numpy as np

SNAP = 8 * np.finfo(np.float64).eps   # relative distance of t * rate to a whole period taken as on it (rounding)


class Decimator:
    """Picks the first sample in each period ``1/rate`` (grid anchored at t = 0); keeps its place across
    calls, so a stream cut into any pieces gives the same picks. A sample time that lies on a period's start
    within the rounding of ``t * rate`` (0.29 s at 100 Hz gives 28.999999999999996) starts that period."""

    def __init__(self, rate: float):
        if not math.isfinite(rate) or rate <= 0:
            raise ValueError(f"view rate must be a finite number of Hz > 0, got {rate!r}")
        self.rate = float(rate)
        self._last = -math.inf          # grid period of the latest pick

    def pick(self, t: np.ndarray) -> np.ndarray:
        """Indices of the samples of ``t`` (s, non-decreasing) to keep."""
        x = np.asarray(t, dtype=np.float64) * self.rate
        whole = np.round(x)
        period = np.floor(np.where(np.abs(x - whole) <= SNAP * np.abs(x), whole, x))
        keep = np.flatnonzero(np.diff(period, prepend=self._last) > 0)
        if keep.size:
            self._last = float(period[keep[-1]])
        return keep
