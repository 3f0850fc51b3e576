"""Clutch metrics on synthetic signals with closed-form answers."""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from rig.analysis.clutch_metrics import (StandRecord, Stimulus, apex_crossings, disengagement_summary, loop_area,
                                         loop_energy, signed_loop_area, stand_metrics, step_metrics)


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
    assert float(m.overshoot_pct) == pytest.approx(100 * overshoot, rel=1e-6)
    assert bool(m.settled)
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
        assert m.overshoot_pct[i] == pytest.approx(100 * ov, rel=1e-5)
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


def test_no_settling_time_for_a_trace_that_does_not_settle_inside_the_record():
    """The old definition (final = last sample, last exit from its band) gave ≈ the record length here."""
    t = np.linspace(0, 1.0, 1001)
    rng = np.random.default_rng(0)
    ringing = 5 + 9 * (1 - np.exp(-0.5 * t) * np.cos(60 * t))           # decays too slowly for 1 s
    m = step_metrics(t, ringing, band=0.05, initial=5.0, dwell=0.05)
    assert not bool(m.settled) and np.isnan(m.settling_time) and np.isnan(m.overshoot_pct)
    noisy = second_order_step(t, 0.3, 40.0) + rng.normal(0, 0.5, t.size)  # noise beyond a ±0.45 band
    m = step_metrics(t, noisy, band=0.05, initial=5.0, dwell=0.05)
    assert not bool(m.settled) and np.isnan(m.settling_time)
    late = np.where(t < 0.98, 5.0, 14.0)                                # steps only in the last 20 ms
    assert not bool(step_metrics(t, late, band=0.05, initial=5.0, final=14.0, dwell=0.05).settled)
    quiet = second_order_step(t, 0.3, 40.0) + rng.normal(0, 0.05, t.size)
    m = step_metrics(t, quiet, band=0.05, initial=5.0, dwell=0.05)
    assert bool(m.settled) and float(m.settling_time) == pytest.approx(exact_settling(0.3, 40.0, 0.05), abs=0.01)
    assert float(m.settling_time) < 0.3


def stand(t, torque, angle=None, end=None, last_edge=None):
    return StandRecord(t, torque, t if angle is not None else None, angle, {}, last_edge,
                       float(t[-1]) if end is None else end)


def by_name(metrics):
    return {m.name: m for m in metrics}


def test_start_up_overshoot_in_percent_of_the_step_from_rest():
    t = np.arange(1, 801) * 1e-3
    y = second_order_step(t, 0.3, 40.0, initial=0.0, final=50.0)
    m = by_name(stand_metrics(stand(t, y), [Stimulus(0.0, "start", "motor on", 0.0, 50.0)], 4, 0.1))
    ov = 100 * math.exp(-math.pi * 0.3 / math.sqrt(1 - 0.3 ** 2))
    assert m["start-up: overshoot"].value == pytest.approx(ov, rel=1e-3)
    assert m["start-up: overshoot"].unit == "%" and "initial 0 N·m" in m["start-up: overshoot"].reference
    assert m["start-up: settling time"].value == pytest.approx(exact_settling(0.3, 40.0, 0.05), abs=2e-3)
    assert "5 % of the 50 N·m step" in m["start-up: settling time"].reference
    assert m["start-up: final torque"].value == pytest.approx(50.0, abs=0.01)


def test_shock_has_no_overshoot_but_peak_over_the_pre_shock_level_and_a_recovery_time():
    t = np.arange(1, 601) * 1e-3
    y = 10.0 + np.where(t >= 0.1, 200.0 * np.exp(-(t - 0.1) / 0.03), 0.0)      # back to 10 N·m
    shock = Stimulus(0.1, "shock", "brake shock +165 N·m for 55 ms", after=165.0, duration=0.055)
    m = by_name(stand_metrics(stand(t, y), [shock], 4, 0.1))
    assert m["shock at 0.1 s: overshoot"].value is None
    assert "pulse, not a step" in m["shock at 0.1 s: overshoot"].reference
    assert m["shock at 0.1 s: peak torque"].value == pytest.approx(210.0)
    assert "over the pre-shock 10 N·m" in m["shock at 0.1 s: peak torque"].reference
    # back within ±5 % of 165 N·m = 8.25 N·m: 200 exp(−τ/0.03) = 8.25
    assert m["shock at 0.1 s: recovery time"].value == pytest.approx(0.03 * math.log(200 / 8.25), abs=1e-3)
    flat = 10.0 + np.where(t >= 0.1, 200.0 * np.exp(-(t - 0.1) / 0.3), 0.0)     # still far out at the end
    m = by_name(stand_metrics(stand(t, flat), [shock], 4, 0.1))
    assert m["shock at 0.1 s: recovery time"].value is None
    assert "not back within" in m["shock at 0.1 s: recovery time"].reference


def test_step_after_an_unsteady_torque_has_no_overshoot_but_a_settling_time():
    t = np.arange(1, 1001) * 1e-3
    y = np.where(t < 0.4, 50.0 + 100.0 * np.sin(2 * np.pi * 40 * t), 10.0 + 30.0 * np.exp(-(t - 0.4) / 0.05))
    step = Stimulus(0.4, "step", "load 50 → 10 N·m", 50.0, 10.0)
    m = by_name(stand_metrics(stand(t, y), [step], 4, 0.1))
    assert m["step at 0.4 s: overshoot"].value is None and "not steady" in m["step at 0.4 s: overshoot"].reference
    assert m["step at 0.4 s: settling time"].value > 0.05
    # no measured initial level: the scene's 40 N·m step sets the band (±2 N·m), 30 exp(−τ/0.05) = 2
    settle = m["step at 0.4 s: settling time"]
    assert "5 % of the 40 N·m step" in settle.reference and settle.value == pytest.approx(0.05 * math.log(15), abs=2e-3)
    assert "step of the scene, 50 → 10 N·m" in m["step at 0.4 s: peak torque"].reference
    steady = np.where(t < 0.4, 50.0, 10.0 - 8.0 * np.exp(-(t - 0.4) / 0.05))    # 50 → 10, dips to 2: 20 %
    m = by_name(stand_metrics(stand(t, steady), [step], 4, 0.1))
    assert m["step at 0.4 s: overshoot"].value == pytest.approx(20.0, rel=1e-3)


def test_stop_standstill_from_the_last_encoder_edge_and_sweep_without_step_figures():
    t = np.arange(1, 1001) * 1e-3
    y = np.where(t < 0.1, 100.0, np.where(t < 0.5, 150.0 * (0.5 - t) / 0.4, 0.0))
    stop = Stimulus(0.1, "stop", "motor off", 100.0, None)
    m = by_name(stand_metrics(stand(t, y, last_edge=0.6), [stop], 4, 0.1))
    assert m["stop at 0.1 s: standstill"].value == pytest.approx(0.5) and m["stop at 0.1 s: standstill"].at == 0.6
    assert m["stop at 0.1 s: torque rise"].value == pytest.approx(150.0, abs=0.5)
    m = by_name(stand_metrics(stand(t, y, last_edge=0.98), [stop], 4, 0.1))
    assert m["stop at 0.1 s: standstill"].value is None
    phi = np.radians(240.0) * t / t[-1]
    m = by_name(stand_metrics(stand(t, 100 * np.sin(3 * phi), phi), [Stimulus(0.0, "sweep", "blocked")], 4, 0.1))
    assert m["overshoot"].value is None and m["settling time"].value is None
    assert "quasi-static" in m["overshoot"].reference
    assert m["disengagements"].value.startswith("2,") and m["shutdown"].value == "not required"


def test_disengagements_and_the_shutdown_rule_from_the_relative_angle():
    t = np.arange(1, 601) * 1e-3
    phi = np.radians(2.0) + np.clip(t - 0.1, 0, 0.1) * 80.0          # 8 rad of slip in 0.1 s: 3.8 lobes
    m = by_name(stand_metrics(stand(t, np.full_like(t, 10.0), phi), [], 4, 0.1, model_disengagements=4))
    assert m["disengagements"].value.startswith("4, at ") and "model: 4" in m["disengagements"].reference
    fourth = 0.1 + (np.pi / 3 + 3 * 2 * np.pi / 3 - np.radians(2.0)) / 80
    assert m["shutdown"].value == "required" and m["shutdown"].at == pytest.approx(fourth, abs=1e-3)
    assert m["slip ended"].value == pytest.approx(0.2, abs=2e-3)
    assert m["relative slip"].value == pytest.approx(np.degrees(8.0), abs=0.01)
    m = by_name(stand_metrics(stand(t, np.full_like(t, 10.0), phi), [], 5, 0.1))
    assert m["shutdown"].value == "not required" and "at most 4" in m["shutdown"].reference


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


def test_without_a_scene_there_is_no_shutdown_rule_and_no_step_figures():
    t = np.arange(1, 601) * 1e-3
    phi = np.radians(2.0) + np.clip(t - 0.1, 0, 0.1) * 80.0
    m = by_name(stand_metrics(stand(t, np.full_like(t, 10.0), phi), [], None, None))
    assert m["shutdown"].value is None and "no scene" in m["shutdown"].reference
    assert not any("overshoot" in k or "settling" in k for k in m)
    assert m["relative slip"].value == pytest.approx(np.degrees(8.0), abs=0.01)
    still = by_name(stand_metrics(stand(t, np.full_like(t, 10.0), np.full_like(t, 0.3)), [], 4, 0.1))
    assert "relative angle change" in still and "slip ended" not in still and still["disengagements"].value == "0"


def test_a_torque_still_falling_when_the_record_ends_has_no_peak_but_a_settled_one_keeps_its_extreme():
    """After a stop the torque still fell at the run's end: the "peak torque" was the last reading (0.928 N·m at
    0.9 s in clutch_leaf_shock_short). The last reading is no peak when it lies beyond the level the record ends at;
    in a settled record whose noise happens to end on its lowest reading it is the extreme as before."""
    t = np.arange(1, 901) * 1e-3
    falling = np.where(t < 0.5, 5.0, 5.0 * np.exp(-(t - 0.5) / 0.4))
    stop = Stimulus(0.5, "stop", "motor off", 5.0, None)
    m = by_name(stand_metrics(stand(t, falling), [stop], 4, 0.1))
    peak = m["stop at 0.5 s: peak torque"]
    assert peak.value is None and "still falling at the end" in peak.reference and "no peak" in peak.reference
    settled = np.where(t < 0.5, 5.0, 2.0 + 3.0 * np.exp(-(t - 0.5) / 0.02))
    settled = settled + 0.002 * np.sin(2 * np.pi * 37 * t)
    settled[-1] = settled.min() - 1e-4                # the noise's lowest reading is the last one
    m = by_name(stand_metrics(stand(t, settled), [stop], 4, 0.1))
    assert m["stop at 0.5 s: peak torque"].value == pytest.approx(settled[-1])


def test_a_noisy_torque_still_rising_at_the_end_has_no_peak_even_if_its_highest_reading_is_not_the_last():
    """A meter's noise puts the highest reading of a rising torque a sample or two before the end: it was a "peak"
    in 10 of 20 seeds. The trend over the last dwell decides wherever in it the extreme lies."""
    t = np.arange(1, 501) * 1e-3
    start = Stimulus(0.0, "start", "motor on", 0.0, 20.0)
    peaks = 0
    for seed in range(20):
        y = 20.0 * t + np.random.default_rng(seed).normal(0.0, 0.05, t.size)
        peaks += by_name(stand_metrics(stand(t, y), [start], 4, 0.1))["start-up: peak torque"].value is not None
    assert peaks == 0
