"""What an engineer reads at a glance (an audit in a browser, 2026-11-29): tables that fit, equal values that read
equal, notes said once, charts whose colours and marks mean the same on every run."""
from __future__ import annotations

import numpy as np

from rig.analysis.capability import describe
from rig.analysis.plots import truth_groups
from rig.analysis.report import _comparison_places, _values_tables
from rig.analysis.numbers import fixed
from rig.analysis.units import DisplayUnits, unit


def test_process_values_come_in_two_tables_that_fit_the_page():
    """One table of 20 columns put 'runs p' and 'drift' off the page even at 1700 px."""
    v = describe(42.0 + 0.01 * np.random.default_rng(1).standard_normal(60), (41.5, 42.5), "x_max")
    v |= {"unit": "mm", "normality": {"shapiro_p": 0.5, "anderson_p": 0.1, "normal": True},
          "trend": {"slope_p": 0.4, "runs": {"p": 0.6}, "drift": False, "drift_why": []}}
    stats, checks = _values_tables({"x_max": v})
    assert len(stats.headers) <= 14 and len(checks.headers) <= 8
    assert {"Cp", "Cpk", "±3σ in limits"} <= set(stats.headers) and {"runs p", "drift"} <= set(checks.headers)
    assert stats.rows[0][0] == checks.rows[0][0] == "x_max"


def test_host_and_device_values_that_agree_read_the_same():
    """'equal' beside mean 0.2541 and 0.254, σ 0 and 3.103e-17: each row at one precision."""
    at, sd = _comparison_places(0.25405, 7.0711e-5)
    assert fixed(0.25405, at) == fixed(float(np.float32(0.25405)), at)
    assert fixed(7.0711e-5, sd) == fixed(float(np.float32(7.0711e-5)), sd) == "0.0000707"
    at, sd = _comparison_places(0.254, 0.0)
    assert fixed(0.0, sd) == fixed(3.103e-17, sd)          # no spread, whatever the rounding noise


def test_plant_truth_axes_keep_the_recordings_order():
    """ω3 was drawn first (blue) on one run and ω1 on another: members were sorted by their range."""
    units = DisplayUnits({"x": unit("m", "mm"), "y": unit("N", "N")})
    t = np.linspace(0.0, 1.0, 50)
    data = {"omega1": 100.0 * t, "omega3": 120.0 * t, "phi1": t, "phi3": 1.2 * t}
    groups = truth_groups(data, ["omega1", "omega3", "phi1", "phi3"], units)
    assert [names for _, _, names in groups] == [["omega1", "omega3"], ["phi1", "phi3"]]
    wide = {"u_small": 0.01 * t, "u_mid": 300.0 * t, "u_big": 360.0 * t}     # one unit, split by scale: the largest
    assert [n for _, _, n in truth_groups(wide, list(wide), units)] == [["u_mid", "u_big"], ["u_small"]]   # first


def test_capability_indices_read_at_one_precision():
    """"Cp 3.19, Cpk 0.8691" and "Cp 1.717 beside Cpk 1.26": every index with two decimals, in the report's tables,
    its histograms and the console."""
    from rig.analysis.capability import index_text
    from rig.analysis.report import _indices
    assert [index_text(v) for v in (3.19, 0.869123, 1.7171, 1.26, -1307.4, float("inf"), None)] == [
        "3.19", "0.87", "1.72", "1.26", "-1307.40", "∞", "—"]
    v = describe(42.0 + 0.01 * np.random.default_rng(2).standard_normal(60), (41.5, 42.5), "x_max")
    assert _indices(v) == [index_text(v["cp"]), index_text(v["cpk"])] and len(_indices(v)[1].split(".")[1]) == 2
