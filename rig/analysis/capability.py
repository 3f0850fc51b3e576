"""Descriptive statistics and process capability of one process value over a set of curves."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

MIN_SET_SIZE = 50   # fewer measurements than this: capability figures are flagged as unreliable


def index_text(value: float | None) -> str:
    """A capability index as tables print it: two decimals (Cp 3.19 beside Cpk 0.87, not 3.19 beside 0.8691), the
    infinities spelled, a dash for none."""
    if value is None or value != value:
        return "—"
    return f"{value:.2f}" if math.isfinite(value) else ("∞" if value > 0 else "-∞")


def capability(mean: float, std: float, lsl: float | None, usl: float | None) -> tuple[float | None, float | None]:
    """Cp = (USL − LSL)/6σ (needs both limits) and Cpk = min(USL − μ, μ − LSL)/3σ (either limit).

    σ = 0 gives infinite indices (or −inf for Cpk when the mean lies outside a limit).
    """
    if lsl is not None and usl is not None and usl <= lsl:
        raise ValueError(f"capability: upper limit {usl} must exceed lower limit {lsl}")
    margins = [m for m in ((usl - mean) if usl is not None else None,
                           (mean - lsl) if lsl is not None else None) if m is not None]

    def ratio(num: float, den: float) -> float:
        return num / den if den > 0 else math.copysign(math.inf, num) if num != 0 else math.nan

    cp = ratio(usl - lsl, 6 * std) if lsl is not None and usl is not None else None
    cpk = ratio(min(margins), 3 * std) if margins else None
    return cp, cpk


def describe(values: Sequence[float], limits: tuple[float | None, float | None] | None = None,
             name: str = "value") -> dict:
    """n, mean, σ (sample, ddof=1), min, max, ±3σ band, Cp/Cpk against ``limits`` and warnings.

    The ±3σ band is the natural tolerance T = ±3σ of the process; ``band_within_limits`` says whether it
    fits inside the given limits. ``spread``: σ > 0 (without it Cp/Cpk are infinite and say nothing: every value
    the same, e.g. at the resolution). NaN values (missing process values) are dropped and counted.
    """
    v = np.asarray(values, dtype=float)
    missing = int(np.count_nonzero(~np.isfinite(v)))
    v = v[np.isfinite(v)]
    n = v.size
    if n < 2:
        raise ValueError(f"{name}: need at least 2 finite values for statistics, got {n}")
    mean, std = float(v.mean()), float(v.std(ddof=1))
    lsl, usl = limits if limits is not None else (None, None)
    cp, cpk = capability(mean, std, lsl, usl)
    warnings = []
    if n < MIN_SET_SIZE:
        warnings.append(f"{name}: only {n} measurements (< {MIN_SET_SIZE}); capability figures are unreliable")
    if missing:
        warnings.append(f"{name}: {missing} missing/non-finite values ignored")
    lo, hi = mean - 3 * std, mean + 3 * std
    inside = None
    if lsl is not None or usl is not None:
        inside = (lsl is None or lo >= lsl) and (usl is None or hi <= usl)
    return {"name": name, "n": n, "mean": mean, "std": std, "min": float(v.min()), "max": float(v.max()),
            "minus_3sigma": lo, "plus_3sigma": hi, "lsl": lsl, "usl": usl, "cp": cp, "cpk": cpk, "spread": std > 0,
            "band_within_limits": inside, "warnings": warnings}
