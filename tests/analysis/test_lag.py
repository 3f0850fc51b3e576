"""Lag estimation recovers known shifts to sub-sample accuracy, in time and in cam angle."""
from __future__ import annotations

import numpy as np
import pytest

from rig.analysis import compare_theory, estimate_lag

OMEGA = 2 * np.pi * 150 / 60          # 150 rpm, rad/s


def force(s):
    """A smooth insertion-like force pulse over a periodic background (N)."""
    return 40 * np.exp(-((s - 0.2) / 0.05) ** 2) + 8 * np.sin(OMEGA * s) + 3 * np.cos(3 * OMEGA * s)


@pytest.mark.parametrize("lag", [0.1037, 0.0012, -0.0421])
def test_time_lag_sub_sample(lag):
    dt = 1e-3
    t = np.arange(0, 0.6, dt)
    t_th = np.arange(0, 0.6, 2.5e-3)                # theory sampled more coarsely
    est = estimate_lag(t_th, force(t_th), t, force(t - lag))
    assert abs(est - lag) < 1e-3 * dt


def test_angle_lag_and_rms():
    dt, lag = 1e-3, 0.1037
    t = np.arange(0, 0.6, dt)
    theory = {"t": t, "y": force(t), "angle": OMEGA * t}
    meas = force(t - lag)
    res = compare_theory(t, meas, theory, "y", angle=OMEGA * t)
    assert abs(res["lag_time"] - lag) < 0.05 * dt
    assert res["angle_method"] == "xcorr"
    assert abs(res["lag_angle"] - OMEGA * lag) < 0.05 * OMEGA * dt      # ≈ 93° at 150 rpm
    assert np.degrees(res["lag_angle"]) == pytest.approx(93.33, abs=0.1)
    assert res["rms_after"] < 1e-3 * res["rms_before"]
    assert res["rms_before"] == pytest.approx(np.sqrt(np.mean((meas - force(t)) ** 2)), rel=1e-6)
    assert res["peak_difference"] == pytest.approx(meas.max() - force(t).max())
    derived = compare_theory(t, meas, {"t": t, "y": force(t)}, "y", angle=OMEGA * t)   # no theory angle
    assert derived["angle_method"] == "derived"
    assert derived["lag_angle"] == pytest.approx(OMEGA * derived["lag_time"])
    assert compare_theory(t, meas, {"t": t, "y": force(t)}, "y")["lag_angle"] is None


@pytest.mark.parametrize("lag", [0.0025, 0.0123, -0.0031])
def test_lag_of_a_stroke_window_is_the_least_squares_shift(lag):
    """A window of a stroke (a monotone ramp, as a curve's displacement) delayed by many samples: the correlation of
    such a window peaks near zero lag whatever the delay (it held the demo's displacement lag at 1.1 ms, the
    edge of the old rescan, where the LVDT's filter delays it by 2.47 ms); the least mean square finds it."""
    dt = 1e-4
    t = np.arange(0.09, 0.34, dt)
    stroke = lambda s: 0.02 * (1 - np.cos(np.pi * np.clip((s - 0.05) / 0.4, 0, 1)))   # m, rising through the window
    res = compare_theory(t, stroke(t - lag), {"y": stroke(t)}, "y")
    assert abs(res["lag_time"] - lag) < 0.01 * dt
    assert res["rms_after"] < 1e-3 * res["rms_before"]


def test_lag_bad_input():
    t = np.arange(0, 1, 0.01)
    with pytest.raises(ValueError, match="do not overlap"):
        estimate_lag(t, force(t), t + 5, force(t))
    with pytest.raises(ValueError, match="strictly increasing"):
        estimate_lag(t[::-1], force(t), t, force(t))
    with pytest.raises(KeyError, match="'x'"):
        compare_theory(t, force(t), {"y": force(t)}, "x")
