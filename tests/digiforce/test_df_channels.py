"""Signal chain of a channel: ADC resolution and range, scaling, low-pass, unit errors, tare, shunt check."""
import math

import numpy as np
import pytest

from firmware_sim.digiforce import DigiForce, DigiForceError, shunt_ratio


def record(dev, t, x, y, **kw):
    """One commanded curve from samples at times t (shifted to follow whatever was fed before)."""
    last = dev.status()["time"]
    if last is not None:
        t = t - t[0] + last + (t[1] - t[0])
    dev.start()
    dev.feed(t, x, y, **kw)
    return dev.stop()


def test_adc_quantises_to_stated_resolution(unit):
    lsb = 2 * 5.0 / 2 ** 16                     # Y process input ±5 V, 16-bit ADC (description)
    rng = np.random.default_rng(3)
    t = np.arange(1000) * 1e-4
    y = rng.uniform(-4.9, 4.9, t.size)
    res = record(unit, t, 0 * t, y)
    assert np.allclose(res.curve.y / lsb, np.rint(res.curve.y / lsb), atol=1e-6)
    assert np.max(np.abs(res.curve.y - y)) <= lsb / 2 + 1e-12
    assert np.max(np.abs(res.curve.y - y)) > lsb / 4          # quantisation really happens


def test_adc_range_clips_and_counts_overflow(unit):
    t = np.arange(10) * 1e-4
    y = np.array([0, 1, 6, 7, -6, 0, 0, 0, 0, 0], float)
    res = record(unit, t, 0 * t, y)
    lsb = 10 / 2 ** 16
    assert res.curve.y[2] == pytest.approx(5 - lsb) and res.curve.y[4] == pytest.approx(-5)
    assert unit.status()["adc_overflows"]["y"] == 3


def test_bridge_sensitivity_scaling():
    dev = DigiForce()                           # default program: 1.5 mV/V = 1000 N on a ±2 mV/V range
    dev.set_program(0, {"channels": {"y": {"cutoff": "off"}, "x": {"cutoff": "off"}}})
    t = np.arange(5) * 1e-4
    res = record(dev, t, np.full(5, 2.5), np.full(5, 0.75e-3))
    lsb_n = 4e-3 / 2 ** 16 / 1.5e-3 * 1000
    assert res.curve.y == pytest.approx(np.full(5, 500.0), abs=lsb_n / 2)
    assert res.curve.x == pytest.approx(np.full(5, 0.05), abs=1e-6)      # 5 V = 100 mm


def test_two_point_teach_scaling(unit):
    unit.set_program(0, {"channels": {"y": {"scaling": {"mode": "teach", "points": [[1.0, 100.0], [3.0, 500.0]]}}}})
    t = np.arange(3) * 1e-4
    res = record(unit, t, 0 * t, np.array([2.0, 1.0, 0.0]))
    assert res.curve.y == pytest.approx([300.0, 100.0, -100.0], abs=0.05)


def steady_amplitude(dev, f, fs=10_000.0, cycles=40):
    t = np.arange(int(cycles * fs / f)) / fs
    res = record(dev, t, 0 * t, np.sin(2 * np.pi * f * t))
    tail = res.curve.y[res.curve.y.size // 2:]
    return (tail.max() - tail.min()) / 2


def test_low_pass_minus_3db_at_cutoff_and_second_order_rolloff(unit):
    unit.set_program(0, {"channels": {"y": {"cutoff": "100 Hz"}}, "sampling": {"delta": 1e-4}})
    assert steady_amplitude(unit, 100.0) == pytest.approx(1 / math.sqrt(2), rel=0.01)
    assert steady_amplitude(unit, 5.0) == pytest.approx(1.0, rel=0.01)
    assert steady_amplitude(unit, 300.0) == pytest.approx(1 / math.sqrt(1 + 3 ** 4), rel=0.03)   # Butterworth


def test_cutoff_must_be_a_step(unit):
    with pytest.raises(DigiForceError, match=r"channels.y.cutoff: 300 is not one of the unit's steps"):
        unit.set_program(0, {"channels": {"y": {"cutoff": "300 Hz"}}})


def test_filter_state_continues_across_chunks(unit):
    unit.set_program(0, {"channels": {"y": {"cutoff": 50.0}}, "sampling": {"delta": 1e-4}})
    t = np.arange(3000) * 1e-4
    y = np.sign(np.sin(2 * np.pi * 7 * t))
    whole = record(unit, t, 0 * t, y).curve.y
    unit.select_program(0)                      # restart the filter from rest
    t = t + unit.status()["time"] + 1e-4
    unit.start()
    for a in range(0, 3000, 317):
        unit.feed(t[a:a + 317], 0 * t[a:a + 317], y[a:a + 317])
    assert np.array_equal(unit.stop().curve.y, whole)


def test_cutoff_above_sample_rate_bypasses_and_reports(unit):
    unit.set_program(0, {"channels": {"y": {"cutoff": "5 kHz"}}, "sampling": {"delta": 1e-3}})
    t = np.arange(20) * 1e-3
    y = np.where(t > 0.01, 1.0, 0.0)
    res = record(unit, t, 0 * t, y)
    assert unit.status()["filter_bypassed"] == ["y"]
    assert res.curve.y[11] == pytest.approx(1.0, abs=1e-3)


def test_unit_errors_within_accuracy_and_reproducible():
    fs_err = []
    for seed in range(20):
        dev = DigiForce(rng=np.random.default_rng(seed))
        dev.set_program(0, {"channels": {"y": {"cutoff": "off"}, "x": {"cutoff": "off"}}})
        t = np.arange(2000) * 1e-4
        res = record(dev, t, np.full(t.size, 4.0), np.full(t.size, 1.5e-3))
        fs_err.append((res.curve.y.mean() - 1000.0) / (2e-3 / 1.5e-3 * 1000))   # fraction of the ±2 mV/V range
    fs_err = np.abs(fs_err)
    assert fs_err.max() <= 0.005                 # bridge accuracy 0.5 % of range
    assert fs_err.max() > 0.0005                 # the errors are really drawn
    a = DigiForce(rng=np.random.default_rng(7))
    b = DigiForce(rng=np.random.default_rng(7))
    t = np.arange(100) * 1e-4
    ra, rb = (record(d, t, np.full(100, 1.0), np.full(100, 1e-3)) for d in (a, b))
    assert np.array_equal(ra.curve.y, rb.curve.y)


def test_tare_on_command(unit):
    t = np.arange(10) * 1e-4
    with pytest.raises(DigiForceError, match="tare y: no input sample yet"):
        unit.tare("y")
    unit.feed(t, np.full(10, 0.5), np.full(10, 1.25))
    unit.tare()
    res = record(unit, t + 1e-3, np.full(10, 0.75), np.full(10, 1.25))
    assert res.curve.y == pytest.approx(np.zeros(10), abs=1e-12)
    assert res.curve.x == pytest.approx(np.full(10, 0.25), abs=20 / 2 ** 16)   # two readings, each ±LSB/2
    with pytest.raises(DigiForceError, match="channel must be one of"):
        unit.tare("z")


def test_tare_at_measurement_start(unit):
    unit.set_program(0, {"channels": {"y": {"tare_at_start": True}}})
    t = np.arange(10) * 1e-4
    res = record(unit, t, 0 * t, 2.0 + t * 1000)    # 2.0 ... 2.9 V
    assert res.curve.y[0] == 0.0
    assert res.curve.y[-1] == pytest.approx(0.9, abs=2e-4)


def bridge_output(r, shunt):
    """Full bridge, four arms r, one lower arm shunted: (V_a - V_b) / V_exc by plain voltage dividers."""
    lower = r * shunt / (r + shunt)
    return 0.5 - lower / (r + lower)


def test_shunt_ratio_matches_voltage_dividers():
    assert shunt_ratio(350.0, 59e3) == pytest.approx(bridge_output(350.0, 59e3), rel=1e-12)
    assert shunt_ratio(350.0, 59e3) == pytest.approx(1.478e-3, rel=1e-3)


def test_shunt_check_passes_for_correct_gain_and_fails_for_wrong():
    dev = DigiForce()
    t = np.arange(200) * 1e-4
    dev.feed(t, 0 * t, 0 * t)
    dev.tare("y")
    expected = dev.shunt_expected("y", 59e3)
    assert expected == pytest.approx(bridge_output(350.0, 59e3) / 1.5e-3 * 1000, rel=1e-12)
    for k in (1, 2):                            # first chunk: the 1 kHz low-pass settles; then measure
        dev.feed(t + 0.02 * k, 0 * t, np.full(200, bridge_output(350.0, 59e3)))
    good = dev.shunt_check("y", expected)
    assert good["ok"] and abs(good["relative_deviation"]) < 1e-3
    for k in (3, 4):                            # gain 3 % high
        dev.feed(t + 0.02 * k, 0 * t, np.full(200, 1.03 * bridge_output(350.0, 59e3)))
    bad = dev.shunt_check("y", expected)
    assert not bad["ok"] and bad["relative_deviation"] == pytest.approx(0.03, abs=2e-3)
    assert bad["gain_correction"] == pytest.approx(1 / 1.03, rel=2e-3)


@pytest.mark.parametrize("t, x, y, message", [
    (np.arange(5) * 1e-6, np.zeros(5), np.zeros(5), "exceeds the unit's 100000 Hz"),
    (np.array([0, 1e-3, 3e-3]), np.zeros(3), np.zeros(3), "evenly spaced"),
    (np.array([0, 2e-3, 1e-3]), np.zeros(3), np.zeros(3), "must increase"),
    (np.arange(3) * 1e-3, np.array([0, np.nan, 0]), np.zeros(3), "x has a non-finite value at index 1"),
    (np.arange(3) * 1e-3, np.zeros(4), np.zeros(3), "x has shape"),
])
def test_bad_input_samples_are_refused(t, x, y, message):
    dev = DigiForce()
    with pytest.raises(DigiForceError, match=message):
        dev.feed(t, x, y)


def test_y2_channel_recorded_when_enabled(unit):
    unit.set_program(0, {"channels": {"y2": {"input": "process", "range": 5.0, "unit": "N", "cutoff": "off",
                                             "scaling": {"electrical": 1.0, "engineering": 10.0}}}})
    t = np.arange(4) * 1e-4
    with pytest.raises(DigiForceError, match="y2 is enabled"):
        unit.feed(t, 0 * t, 0 * t)
    unit.start()
    unit.feed(t, 0 * t, 0 * t, y2=np.array([0.0, 0.1, 0.2, 0.3]))
    res = unit.stop()
    assert res.curve.y2 == pytest.approx([0, 1, 2, 3], abs=2e-3)
    assert res.process_values["y2_max"] == pytest.approx(3.0, abs=2e-3)


def test_teach_two_points_from_live_input(unit):
    t = np.arange(5) * 1e-4
    unit.feed(t, 0 * t, np.full(5, 1.0))
    unit.teach("y", 0, 200.0)
    unit.feed(t + 1e-3, 0 * t, np.full(5, 3.0))
    unit.teach("y", 1, 600.0)
    sc = unit.get_program(0)["channels"]["y"]["scaling"]
    assert sc["mode"] == "teach"
    assert np.array(sc["points"]) == pytest.approx(np.array([[1.0, 200.0], [3.0, 600.0]]), abs=10 / 2 ** 16)
    res = record(unit, t, 0 * t, np.full(5, 2.0))
    assert res.curve.y == pytest.approx(np.full(5, 400.0), abs=200 * 10 / 2 ** 16)   # one LSB at 200 N/V
    with pytest.raises(DigiForceError, match="teach points must differ"):
        unit.teach("y", 0, 600.0)
