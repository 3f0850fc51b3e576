"""Capability, normality, trend and set statistics against closed forms and numpy."""
from __future__ import annotations

import math

import numpy as np
import pytest

from rig.analysis import capability, describe, normality, runs_test, set_statistics, trend
from rig.analysis.sets import curve_verdicts, event_counts, limits_from_program, statistics_by_program


def test_cp_cpk_closed_form():
    d = describe([9.0, 10.0, 11.0], (7.0, 13.0), "F")            # mean 10, sample σ 1
    assert d["mean"] == 10.0 and d["std"] == pytest.approx(1.0)
    assert d["cp"] == pytest.approx(1.0) and d["cpk"] == pytest.approx(1.0)
    assert (d["minus_3sigma"], d["plus_3sigma"]) == pytest.approx((7.0, 13.0))
    cp, cpk = capability(10.0, 1.0, 8.0, 13.0)
    assert cp == pytest.approx(5 / 6) and cpk == pytest.approx(2 / 3)
    assert capability(10.0, 1.0, None, 16.0) == (None, pytest.approx(2.0))
    assert capability(10.0, 0.0, 8.0, 13.0) == (math.inf, math.inf)
    with pytest.raises(ValueError, match="upper limit"):
        capability(10.0, 1.0, 13.0, 8.0)


def test_describe_matches_numpy_and_warns_below_50():
    v = np.random.default_rng(0).normal(40, 2, 49)
    d = describe(v, (30.0, 52.0), "y_max")
    assert d["std"] == pytest.approx(np.std(v, ddof=1), rel=1e-12)
    assert d["cpk"] == pytest.approx(min(52 - v.mean(), v.mean() - 30) / (3 * np.std(v, ddof=1)))
    assert (d["min"], d["max"]) == (v.min(), v.max())
    assert any("only 49" in w for w in d["warnings"]) and d["band_within_limits"] is True
    assert not describe(np.append(v, 40.0), None)["warnings"]
    with pytest.raises(ValueError, match="y_max"):
        describe([1.0], None, "y_max")


def test_normality_flags_non_normal():
    rng = np.random.default_rng(1)
    skewed = normality(rng.exponential(1.0, 200))
    assert skewed["normal"] is False and skewed["shapiro_p"] < 1e-6 and skewed["anderson_p"] <= 0.01
    ok = normality(rng.normal(0, 1, 200))
    assert ok["normal"] is True and ok["shapiro_p"] > 0.05


def test_trend_flags_drift_not_noise():
    rng = np.random.default_rng(2)
    noise = rng.normal(0, 1, 100)
    drift = trend(noise + 0.03 * np.arange(100))
    assert drift["drift"] and drift["slope"] == pytest.approx(0.03, abs=0.012) and drift["slope_p"] < 0.01
    assert trend(noise)["drift"] is False


def test_runs_test_hand_computed():
    r = runs_test([1, 5, 1, 5, 1, 5, 1, 5])        # median 3: alternating -> 8 runs, n1 = n2 = 4
    assert r["runs"] == 8 and r["expected"] == 5.0
    var = 2 * 4 * 4 * (2 * 4 * 4 - 8) / (64 * 7)
    assert r["z"] == pytest.approx(3 / math.sqrt(var))
    assert runs_test([1, 1, 1, 1, 5, 5, 5, 5])["runs"] == 2


def result(n, ok=True, failed=None, **values):
    return {"number": n, "program": 1, "ok": ok,
            "elements": [{"name": failed or "W1", "kind": "window", "ok": failed is None, "reason": "r"}],
            "process_values": values}


def test_set_statistics_counts_and_limits():
    rng = np.random.default_rng(3)
    ys = rng.normal(40, 1, 60)
    results = [result(i, ok=i % 10 != 0, failed=None if i % 10 else "W1", y_max=ys[i]) for i in range(60)]
    s = set_statistics(results, limits_from_program({"limits": {"y_max": [35.0, None]}}))
    assert (s["n"], s["ok"], s["nok"], s["nok_by_element"]) == (60, 54, 6, {"W1": 6})
    v = s["values"]["y_max"]
    assert v["cpk"] == pytest.approx((ys.mean() - 35) / (3 * ys.std(ddof=1))) and v["cp"] is None
    assert s["warnings"] == [] and "normality" in v and "trend" in v
    small = statistics_by_program(results[:20], {1: {"limits": {"y_max": [35.0, 45.0]}}})[1]
    assert any("only 20 measurements" in w for w in small["warnings"])
    assert curve_verdicts(results[:1])[0]["failed"][0]["name"] == "W1"
    assert event_counts([{"kind": "gap"}, {"kind": "gap"}, {"kind": "flank"}]) == {"gap": 2, "flank": 1}
    with pytest.raises(ValueError, match="y_max"):
        limits_from_program({"limits": {"y_max": 3.0}})


def test_drift_names_the_rules_that_fired():
    rng = np.random.default_rng(3)
    steady = trend(rng.normal(0, 1, 200))
    assert steady["drift"] is False and steady["drift_why"] == []
    shifted = trend(np.r_[rng.normal(0, 0.1, 25), rng.normal(1, 0.1, 25)])
    assert shifted["drift"] and any("25 in a row on one side of the median (Nelson's 9 made 12 for a set of 50"
                                    in w for w in shifted["drift_why"])
    assert any(w.startswith("slope p") for w in shifted["drift_why"])
    skewed = trend(rng.lognormal(0.0, 1.5, 200))          # no drift, most values below the mean
    assert not any("in a row" in w for w in skewed["drift_why"]) and skewed["longest_side_run"] < 9


def test_a_stationary_set_is_called_drifting_at_most_alpha_of_the_time():
    """Nelson's 9-in-a-row is a control chart's per-point rule: a stationary set of 150 shows it with a chance of
    0.25, and the three rules together called one in three stationary sets drifting. The run limit grows with the
    set (exact chance: every sequence counted; against brute force on small sets) and each rule takes alpha/3."""
    from itertools import product

    from rig.analysis.trend import run_chance, run_limit
    for n, k in ((8, 3), (10, 4), (12, 2)):
        longest = [max(len(r) for r in "".join(map(str, bits)).replace("01", "0 1").replace("10", "1 0").split())
                   for bits in product((0, 1), repeat=n)]
        assert run_chance(n, k) == pytest.approx(np.mean(np.array(longest) >= k), abs=1e-12)
    assert run_chance(150, 9) == pytest.approx(0.2472, abs=1e-4) and run_limit(15, 0.05 / 3) == 9
    assert (run_limit(50, 0.05 / 3), run_limit(150, 0.05 / 3)) == (12, 14)
    rng = np.random.default_rng(7)
    called = np.mean([trend(rng.normal(0.0, 1.0, 150))["drift"] for _ in range(600)])
    assert called <= 0.07                                   # alpha 0.05 and the Monte-Carlo scatter (±0.009)
    drifting = np.mean([trend(rng.normal(0.0, 1.0, 150) + np.r_[np.zeros(75), np.full(75, 1.0)])["drift"]
                        for _ in range(100)])
    assert drifting > 0.97                                  # a 1 σ shift halfway is still found (≈ 0.95 at 0.8 σ)


def test_no_spread_is_not_called_capable(tmp_path):
    """σ = 0 (every value the same, e.g. at the resolution): Cp/Cpk are infinite, the report says n/a."""
    from rig.analysis import plots
    from rig.analysis.report import _capability, _indices
    stats = describe([42.0] * 5, (41.5, 42.5), "x_max")
    assert stats["std"] == 0.0 and math.isinf(stats["cp"])
    assert _indices(stats) == ["n/a", "n/a"] and _capability(stats).startswith("n/a")
    assert not stats["spread"]
    assert _capability({"cpk": 1.5, "spread": True}) == "capable"
    assert _capability({"cpk": 1.2, "spread": True}) == "marginal"
    path = plots.histograms({"x_max": np.full(5, 42.0)}, {"x_max": {**stats, "unit": "mm"}}, tmp_path / "h.png")
    assert path.stat().st_size > 0


def test_too_few_readings_get_no_drift_verdict_but_a_long_staircase_is_a_drift():
    """Three y_max readings one ADC step apart (a 3-curve run) lie exactly on a line: least squares gave slope p 9e-11
    and "drift: yes". Below MIN_TREND values there is no verdict (None, shown n/a); a staircase one step per reading over
    12 readings is a drift; otherwise the slope is ordinary least squares."""
    from scipy import stats
    from rig.analysis.trend import MIN_TREND
    q = 0.0406901
    three = trend(-6.4290366 - q * np.arange(3))
    assert three["drift"] is None and three["drift_why"] == [] and MIN_TREND == 8
    assert trend(-6.4290366 - q * np.arange(MIN_TREND))["drift"] is True
    stairs = trend(-6.4290366 - q * np.arange(12))
    assert stairs["drift"] is True and stairs["slope_p"] < 1e-6
    v = np.random.default_rng(3).normal(0.0, 1.0, 40) + 0.02 * np.arange(40)
    assert trend(v)["slope_p"] == pytest.approx(stats.linregress(np.arange(40), v).pvalue, rel=1e-12)


def test_a_small_set_is_not_called_capable():
    """Five curves read "capable" at Cpk 45 (σ the LVDT's noise): below MIN_SET_SIZE the verdict is not judged, the
    reading kept; a set that reads NOT capable is said so whatever its size, and why (a warning is not held back)."""
    from rig.analysis.capability import MIN_SET_SIZE
    from rig.analysis.report import _capability
    rng = np.random.default_rng(5)
    small = describe(42.0 + 0.0027 * rng.standard_normal(5), (41.5, 42.5), "x_max")
    assert small["cpk"] > 40 and _capability(small) == f"not judged: n = 5 < {MIN_SET_SIZE} (reads capable)"
    full = describe(42.0 + 0.0027 * rng.standard_normal(MIN_SET_SIZE), (41.5, 42.5), "x_max")
    assert _capability(full) == "capable"
    outside = describe(43.0 + 0.1 * rng.standard_normal(5), (41.5, 42.5), "x_max")
    assert _capability(outside) == (f"NOT capable (n = 5 < {MIN_SET_SIZE}: indicative only; a warning is not held "
                                    "back)")       # why it is judged when "capable" at n = 5 is not
