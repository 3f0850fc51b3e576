"""Normality checks of a set of measurements (Shapiro–Wilk and Anderson–Darling, scipy.stats)."""
from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy import stats


ANDERSON_P = (0.01, 0.15)      # the range of the tabulated Anderson–Darling p-values (bounds outside it)


def _anderson_p(v: np.ndarray) -> tuple[float, float]:
    """Anderson–Darling A² and its p-value (tabulated, clipped by scipy to 0.01…0.15)."""
    try:
        res = stats.anderson(v, dist="norm", method="interpolate")   # scipy >= 1.17
        return float(res.statistic), float(res.pvalue)
    except TypeError:                                                 # older scipy: critical values only
        res = stats.anderson(v, dist="norm")
        passed = [lvl / 100 for lvl, c in zip(res.significance_level, res.critical_values) if res.statistic < c]
        return float(res.statistic), max(passed) if passed else 0.01


def normality(values: Sequence[float], alpha: float = 0.05) -> dict:
    """Shapiro–Wilk W and p, Anderson–Darling A² and p; ``normal`` is False if either p < ``alpha``."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 3:
        raise ValueError(f"normality: need at least 3 finite values, got {v.size}")
    if np.ptp(v) == 0:
        return {"n": int(v.size), "shapiro_W": None, "shapiro_p": None, "anderson_A2": None,
                "anderson_p": None, "alpha": alpha, "normal": None, "note": "all values equal"}
    sw = stats.shapiro(v)
    a2, ap = _anderson_p(v)
    return {"n": int(v.size), "shapiro_W": float(sw.statistic), "shapiro_p": float(sw.pvalue),
            "anderson_A2": a2, "anderson_p": ap, "alpha": alpha,
            "normal": bool(sw.pvalue >= alpha and ap >= alpha)}
