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


def run_chance(n: int, k: int) -> float:
    """Probability that a stationary set of ``n`` values (each independently above or below the median, even odds)
    holds a run of ``k`` or more on one side: 1 − P(longest run < k), exact by counting the sequences by the length of
    their last run."""
    if k <= 1:
        return 1.0 if n else 0.0
    if n < k:
        return 0.0
    last = np.zeros(k - 1)              # last[j]: probability of no run ≥ k so far, the last run being j + 1 long
    last[0] = 1.0
    for _ in range(n - 1):
        nxt = np.empty(k - 1)
        nxt[0] = 0.5 * last.sum()       # the next value on the other side
        nxt[1:] = 0.5 * last[:-1]       # on the same side: the run grows (a run reaching k is dropped)
        last = nxt
    return float(1.0 - last.sum())


def run_limit(n: int, alpha: float) -> int:
    """The run length on one side of the median that flags a drift in a set of ``n``: Nelson's 9, or longer where a
    stationary set of ``n`` would reach 9 with a chance above ``alpha`` (9 in a row is a per-point rule of a control
    chart: in a set of 150 a stationary process shows it 4 times in 10)."""
    k = 9
    while run_chance(n, k) > alpha:
        k += 1
    return k


#: fewer values than this get no drift verdict: with 1–5 degrees of freedom an exact fit of quantised readings (three
#: y_max values one ADC step apart lie on a line: slope p 9e-11) reads as a trend, and the run rules need 9 in a row
MIN_TREND = 8


def trend(values: Sequence[float], alpha: float = 0.05) -> dict:
    """Linear trend vs sample index (slope per sample, p of slope = 0), runs test, a run on one side of the median.

    ``drift`` is True when one of the three rules fires, each at ``alpha``/3 so that a stationary set is called
    drifting with a chance of at most ``alpha`` (Bonferroni): the slope is significant, the runs test shows too few
    runs (z < 0), or :func:`run_limit` consecutive points (9, Nelson's rule 2, in sets up to 15; 12 in a set of 50,
    14 in one of 150) lie on one side of the median; ``drift_why`` names the rules that fired (empty without drift);
    ``drift`` None (no verdict) below :data:`MIN_TREND` values.
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 3:
        raise ValueError(f"trend: need at least 3 finite values, got {v.size}")
    each = alpha / 3
    limit = run_limit(v.size, each)
    if np.ptp(v) == 0:
        return {"slope": 0.0, "slope_p": 1.0, "runs": runs_test(v), "longest_side_run": 0, "run_limit": limit,
                "drift": False if v.size >= MIN_TREND else None, "drift_why": []}
    fit = stats.linregress(np.arange(v.size), v)
    slope, slope_p = float(fit.slope), float(fit.pvalue)
    if v.size < MIN_TREND:                   # no verdict: see MIN_TREND
        return {"slope": slope, "slope_p": slope_p, "runs": runs_test(v), "longest_side_run": longest_side_run(v),
                "run_limit": limit, "drift": None, "drift_why": []}
    runs = runs_test(v)
    side = longest_side_run(v)
    why = []
    if slope_p < each:
        why.append(f"slope p {slope_p:.2g} < {each:.2g}")
    if runs["p"] is not None and runs["z"] < 0 and runs["p"] < each:
        why.append(f"too few runs (p {runs['p']:.2g})")
    if side >= limit:
        rule = "Nelson rule 2" if limit == 9 else f"Nelson's 9 made {limit} for a set of {v.size}"
        why.append(f"{side} in a row on one side of the median ({rule}; chance {run_chance(v.size, side):.2g} "
                   f"without a drift)")
    return {"slope": slope, "slope_p": slope_p, "runs": runs, "longest_side_run": side,
            "run_limit": limit, "drift": bool(why), "drift_why": why}


def drift_text(result: dict, undecided: str = "n/a (too few values)") -> str:
    """A :func:`trend` result's verdict in words: ``no``, ``yes: <the rules that fired>``, or ``undecided`` where
    the set is too small for one (the report's and the console's column)."""
    if result["drift"] is None:
        return undecided
    return f"yes: {'; '.join(result.get('drift_why') or [])}".rstrip(": ") if result["drift"] else "no"
