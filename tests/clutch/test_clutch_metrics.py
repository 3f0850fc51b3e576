"""Clutch metrics on synthetic signals with closed-form answers."""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from rig.analysis.clutch_metrics import (apex_crossings, disengagement_summary, loop_area, loop_energy,
                                         signed_loop_area, step_metrics)


def second_order_step(t, zeta, wn, initial=5.0, final=14.0):
    wd = wn * math.sqrt(1 - zeta ** 2)
    shape = 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    return initial + (final - initial) * shape


def exact_settling(zeta, wn, band):
    """Last instant with |y − final| = band·step: scan the analytic error, refine with brentq."""
    t = np.linspace(0, 20 / (zeta * wn), 400001)
    err = np.abs(second_order_step(t, zeta, wn, 0.0, 1.0) - 1.0) - band
    i = np.flatnonzero(err > 0)[-1]
    return brentq(lambda s: abs(second_order_step(np.array(s), zeta, wn, 0.0, 1.0) - 1.0) - band, t[i], t[i + 1],
                  xtol=1e-14)


def test_damped_second_order_step_matches_closed_forms():
    zeta, wn = 0.3, 40.0
    t = np.linspace(0, 1.5, 150001)
    m = step_metrics(t, second_order_step(t, zeta, wn), band=0.02, final=14.0)
    wd = wn * math.sqrt(1 - zeta ** 2)
    assert float(m.t_peak) == pytest.approx(math.pi / wd, abs=2e-5)
    overshoot = math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2))
    assert float(m.overshoot) == pytest.approx(overshoot, rel=1e-6)
    assert float(m.peak) == pytest.approx(14.0 + 9.0 * overshoot, rel=1e-8)
    assert float(m.settling_time) == pytest.approx(exact_settling(zeta, wn, 0.02), abs=1e-6)
    assert float(m.final) == 14.0


def test_step_metrics_vectorised_and_downward_steps():
    t = np.linspace(0, 2.0, 20001)
    zetas = [0.2, 0.5, 0.7]
    y = np.stack([second_order_step(t, z, 25.0, 10.0, 0.0) for z in zetas])   # steps down from 10 to 0
    m = step_metrics(t, y, band=0.05, final=0.0)
    assert m.peak.shape == (3,)
    for i, z in enumerate(zetas):
        ov = math.exp(-math.pi * z / math.sqrt(1 - z ** 2))
        assert m.overshoot[i] == pytest.approx(ov, rel=1e-5)
        assert m.peak[i] == pytest.approx(-10 * ov, rel=1e-5)
        assert m.settling_time[i] == pytest.approx(exact_settling(z, 25.0, 0.05), abs=1e-5)


def test_step_metrics_absolute_band_and_errors():
    t = np.linspace(0, 1, 101)
    y = np.where(t < 0.3, 2.0, 1.0)
    m = step_metrics(t, y, absolute_band=0.1)
    assert float(m.settling_time) == pytest.approx(0.3, abs=0.01)
    flat = step_metrics(t, np.ones_like(t), absolute_band=0.1)
    assert float(flat.settling_time) == 0.0
    with pytest.raises(ValueError, match="no step"):
        step_metrics(t, np.ones_like(t))
    with pytest.raises(ValueError, match="increasing"):
        step_metrics(t[::-1], y)
    with pytest.raises(ValueError, match="NaN"):
        step_metrics(t, np.full_like(t, np.nan))


def test_apex_crossings_of_a_ramp():
    omega = 3.0                                   # rad/s of relative slip
    t = np.linspace(0, 3, 301)                    # several apexes, some within one sample interval
    phi = omega * t
    times = apex_crossings(t, phi)
    expected = (math.pi / 3 + np.arange(4) * 2 * math.pi / 3) / omega
    expected = expected[expected <= 3.0]
    np.testing.assert_allclose(times, expected, atol=1e-12)
    np.testing.assert_allclose(apex_crossings(t, -phi), expected, atol=1e-12)   # slipping backwards
    coarse = np.array([0.0, 1.0])
    both = apex_crossings(coarse, np.radians([0.0, 200.0]))                  # 60° and 180° in one interval
    np.testing.assert_allclose(both, [0.3, 0.9], atol=1e-12)


def test_apex_dithering_counts_once():
    t = np.linspace(0, 1, 1001)
    phi = math.pi / 3 + 0.01 * np.sin(40 * t) + 0.001          # hovers around the first apex
    phi[0] = 0.0
    assert apex_crossings(t, phi).size == 1


def test_disengagement_summary():
    s = disengagement_summary(np.array([0.1, 0.5, 2.0, 2.05]), window=0.1)
    assert s.count == 4 and s.shutdown and s.first_shutdown_time == pytest.approx(2.05)
    quiet = disengagement_summary(np.array([0.1, 0.5, 2.0]), window=0.1)
    assert not quiet.shutdown and quiet.first_shutdown_time is None
    triple = disengagement_summary(np.array([0.0, 0.05, 0.3, 0.35, 0.38]), window=0.1, repeat=3)
    assert triple.shutdown and triple.first_shutdown_time == pytest.approx(0.38)
    assert disengagement_summary(np.array([]), window=1.0).count == 0
    with pytest.raises(ValueError, match="window"):
        disengagement_summary(np.array([1.0]), window=0.0)


def test_loop_areas_rectangle_ellipse_and_energy_sign():
    x = np.array([0.0, 2.0, 2.0, 0.0])
    y = np.array([0.0, 0.0, 3.0, 3.0])
    assert float(signed_loop_area(x, y)) == pytest.approx(6.0)          # counter-clockwise
    assert float(signed_loop_area(x[::-1], y[::-1])) == pytest.approx(-6.0)
    n, a, b = 720, 0.3, 5.0
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    inscribed = 0.5 * n * a * b * math.sin(2 * math.pi / n)            # exact area of the polygon
    assert float(loop_area(a * np.cos(th), b * np.sin(th))) == pytest.approx(inscribed, rel=1e-12)
    assert inscribed == pytest.approx(math.pi * a * b, rel=2e-5)
    # stacked loops; clockwise traversal in (φ, T) = loading above unloading = positive dissipation
    loops_x = np.stack([a * np.cos(-th), 2 * a * np.cos(-th)])
    loops_y = np.stack([b * np.sin(-th), b * np.sin(-th)])
    np.testing.assert_allclose(loop_energy(loops_x, loops_y), [inscribed, 2 * inscribed], rtol=1e-12)
    with pytest.raises(ValueError, match="at least 3"):
        loop_area(x[:2], y[:2])
