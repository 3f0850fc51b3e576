"""Trend and run checks of a measurement sequence (in production order)."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np
from scipy import stats


def runs_test(values: Sequence[float]) -> dict:
    """Wald–Wolfowitz runs test about the median (values equal to the median are dropped).

    Too few runs = drift/clustering, too many = oscillation. Returns runs, expected, z, two-sided p.
    """
    v = np.asarray(values, dtype=float)
    above = v[v != np.median(v)] > np.median(v)
    n1, n2 = int(above.sum()), int((~above).sum())
    if n1 == 0 or n2 == 0:
        return {"runs": 1 if above.size else 0, "expected": None, "z": None, "p": None}
    runs = 1 + int(np.count_nonzero(above[1:] != above[:-1]))
    n = n1 + n2
    expected = 2 * n1 * n2 / n + 1
    var = 2 * n1 * n2 * (2 * n1 * n2 - n) / (n * n * (n - 1))
    z = (runs - expected) / math.sqrt(var) if var > 0 else 0.0
    return {"runs": runs, "expected": expected, "z": z, "p": float(2 * stats.norm.sf(abs(z)))}


def longest_side_run(values: Sequence[float]) -> int:
    """Longest run of consecutive values on one side of the median (Nelson rule 2 fires at 9). Nelson's centre
    line is the mean of a normal process; the median keeps the rule's false-alarm rate (2·0.5⁹ per start) for a
    skewed set too, where most values lie on one side of the mean without any drift."""
    v = np.asarray(values, dtype=float)
    side = np.sign(v - np.median(v))
    best = cur = 0
    prev = 0.0
    for s in side:
        cur = cur + 1 if s == prev and s != 0 else (1 if s != 0 else 0)
        prev = s
        best = max(best, cur)
    return best


def trend(values: Sequence[float], alpha: float = 0.05) -> dict:
    """Linear trend vs sample index (slope per sample, p of slope = 0), runs test, Nelson rule 2.

    ``drift`` is True when the slope is significant at ``alpha``, the runs test shows too few runs
    (z < 0, p < alpha), or 9+ consecutive points lie on one side of the median; ``drift_why`` names the rules
    that fired (empty without drift).
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 3:
        raise ValueError(f"trend: need at least 3 finite values, got {v.size}")
    if np.ptp(v) == 0:
        return {"slope": 0.0, "slope_p": 1.0, "runs": runs_test(v), "longest_side_run": 0, "drift": False,
                "drift_why": []}
    fit = stats.linregress(np.arange(v.size), v)
    runs = runs_test(v)
    side = longest_side_run(v)
    why = []
    if fit.pvalue < alpha:
        why.append(f"slope p {fit.pvalue:.2g} < {alpha:g}")
    if runs["p"] is not None and runs["z"] < 0 and runs["p"] < alpha:
        why.append(f"too few runs (p {runs['p']:.2g})")
    if side >= 9:
        why.append(f"{side} in a row on one side of the median (Nelson rule 2: 9)")
    return {"slope": float(fit.slope), "slope_p": float(fit.pvalue), "runs": runs,
            "longest_side_run": side, "drift": bool(why), "drift_why": why}
