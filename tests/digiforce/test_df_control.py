"""Measurement control (command, external input, X start/stop, Y threshold, time), forward/return split,
curve reference modes, evaluation through the unit and chunk independence."""
import json

import numpy as np
import pytest

from firmware_sim.digiforce import DigiForceError

from tests.digiforce.conftest import SIMPLE

DT = 1e-4


def cycles(press, n_cycles=2, gap=200):
    """Press cycles with rest between them, one time base."""
    xs, ys = [], []
    for _ in range(n_cycles):
        _, x, y = press()
        xs += [x, np.zeros(gap)]
        ys += [y, np.zeros(gap)]
    x, y = np.concatenate(xs), np.concatenate(ys)
    return np.arange(x.size) * DT, x, y


def test_command_start_and_stop_at_times(unit):
    t = np.arange(500) * DT
    unit.start(t=0.01)
    assert unit.state == "armed"
    assert unit.feed(t[:200], 0 * t[:200], 0 * t[:200]) == []
    assert unit.state == "measuring"
    assert unit.stop(t=0.03) is None                  # in the future: decided by the samples
    out = unit.feed(t[200:], 0 * t[200:], 0 * t[200:])
    assert len(out) == 1 and unit.state == "idle"
    c = out[0].curve
    assert c.t[0] == pytest.approx(0.01) and c.t[-1] == pytest.approx(0.03)
    assert c.t.size == 201


def test_start_twice_and_stop_idle_are_refused(unit):
    with pytest.raises(DigiForceError, match="stop: no measurement is running"):
        unit.stop()
    unit.start()
    with pytest.raises(DigiForceError, match="already running"):
        unit.start()
    unit.feed(np.arange(3) * DT, np.zeros(3), np.zeros(3))
    with pytest.raises(DigiForceError, match="select_program: not allowed"):
        unit.select_program(1)
    assert unit.stop().curve.t.size == 3


def test_external_input_edges(unit):
    unit.set_program(0, {"control": {"start": {"mode": "external"}, "stop": {"mode": "external"}}})
    assert unit.state == "armed"
    unit.external_input(True, t=0.005)
    unit.external_input(False, t=0.015)
    t = np.arange(300) * DT
    out = unit.feed(t, t, 0 * t)
    assert len(out) == 1
    assert out[0].curve.t[0] == pytest.approx(0.005) and out[0].curve.t[-1] == pytest.approx(0.015)
    assert unit.status()["external_input"] is False


def test_x_start_and_stop_values_give_one_curve_per_cycle(unit, press):
    unit.set_program(0, {"control": {"start": {"mode": "x", "value": 1.0, "direction": "rising"},
                                     "stop": {"mode": "x", "value": 0.5, "direction": "falling"}}})
    t, x, y = cycles(press)
    out = unit.feed(t, x, y)
    assert len(out) == 2 and unit.state == "armed"
    for r in out:
        c = r.curve
        i0 = np.searchsorted(t, c.t[0])
        assert c.x[0] >= 1.0 and x[i0 - 1] < 1.0              # first pair: first sample at/after 1.0
        assert c.x[-1] <= 0.5 + 1e-3 and c.x[-2] > 0.5         # last pair: first sample at/below 0.5
        k = c.turning_index
        assert c.x[k] == pytest.approx(4.0, abs=1e-3)
        assert np.all(np.diff(c.x[c.part("forward")]) >= -1e-3)
        assert np.all(np.diff(c.x[c.part("return")]) <= 1e-3)
    assert [r.number for r in out] == [1, 2]


def test_y_threshold_start_and_stop(unit, press):
    unit.set_program(0, {"control": {"start": {"mode": "y", "value": 0.5},
                                     "stop": {"mode": "y", "value": 0.2, "direction": "falling"}}})
    t, x, y = cycles(press, 1)
    (r,) = unit.feed(t, x, y)
    assert r.curve.y[0] >= 0.5 and r.curve.y[1] > r.curve.y[0]
    assert r.curve.y[-1] <= 0.2 and r.curve.y[-2] > 0.2


def _noisy_cycles(press, n_cycles, amplitude=0.08, seed=1):
    """Press cycles with uniform noise of ±``amplitude`` N on Y (several crossings of any level it passes)."""
    t, x, y = cycles(press, n_cycles)
    return t, x, y + np.random.default_rng(seed).uniform(-amplitude, amplitude, y.size)


@pytest.mark.parametrize("hysteresis, curves", [("0 N", None), ("0.2 N", 3)])
def test_trigger_hysteresis_keeps_noise_from_restarting_a_curve(unit, press, hysteresis, curves):
    """Start and stop on the same Y level with noise on Y: without hysteresis the noise around the level stops a
    curve and starts the next at once (short spurious curves, more than one per cycle); with a band wider than
    the noise, one curve per press cycle, each from the rise through the level to the fall through it."""
    trig = {"mode": "y", "value": "0.5 N", "hysteresis": hysteresis}
    unit.set_program(0, {"control": {"start": {**trig, "direction": "rising"},
                                     "stop": {**trig, "direction": "falling"}}})
    t, x, y = _noisy_cycles(press, 3)
    out = unit.feed(t, x, y)
    if curves is None:
        assert len(out) > 3 and min(r.curve.t.size for r in out) < 50
        return
    assert len(out) == curves
    for r in out:
        c = r.curve
        assert c.y[0] >= 0.5 and c.y[-1] <= 0.5 and c.x.max() == pytest.approx(4.0, abs=1e-3)
        i0 = int(np.searchsorted(t, c.t[0]))
        before = y[:i0][::-1]                           # back from the start: below 0.3 N before any 0.5 N
        assert np.argmax(before < 0.3) < np.argmax(before >= 0.5) or not np.any(before >= 0.5)


def test_trigger_hysteresis_carries_over_chunks(unit, press):
    """The Schmitt trigger's arming carries from one ``feed`` to the next: cutting the input anywhere gives the
    same curves."""
    trig = {"mode": "y", "value": "0.5 N", "hysteresis": "0.2 N"}
    unit.set_program(0, {"control": {"start": {**trig, "direction": "rising"},
                                     "stop": {**trig, "direction": "falling"}}})
    t, x, y = _noisy_cycles(press, 3)
    whole = [r.curve for r in unit.feed(t, x, y)]
    unit.select_program(0)
    t2 = t + t[-1] + DT
    cuts = np.sort(np.random.default_rng(3).choice(np.arange(1, t.size), 120, replace=False))
    parts = []
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, t.size]):
        parts += [r.curve for r in unit.feed(t2[a:b], x[a:b], y[a:b])]
    assert len(parts) == len(whole) == 3
    for p, w in zip(parts, whole):
        assert np.array_equal(p.y, w.y) and np.allclose(p.t - t2[0], w.t)


def test_trigger_hysteresis_is_a_quantity_of_the_channel_and_not_negative(unit):
    unit.set_program(0, {"control": {"start": {"mode": "x", "value": "1 mm", "hysteresis": "0.2 mm"}}})
    assert unit.get_program(0)["control"]["start"]["hysteresis"] == pytest.approx(2e-4)
    with pytest.raises(DigiForceError, match=r"control\.start\.hysteresis: must be >= 0"):
        unit.set_program(0, {"control": {"start": {"mode": "x", "value": "1 mm", "hysteresis": "-0.2 mm"}}})
    with pytest.raises(DigiForceError, match="hysteresis"):
        unit.set_program(0, {"control": {"start": {"mode": "x", "value": "1 mm", "hysteresis": "0.2 N"}}})
    with pytest.raises(DigiForceError, match="'hysteresis' does not apply to mode 'time'"):
        unit.set_program(0, {"control": {"stop": {"mode": "time", "duration": "1 s", "hysteresis": "1 s"}}})


def test_time_stop(unit, press):
    unit.set_program(0, {"control": {"stop": {"mode": "time", "duration": "50 ms"}}})
    unit.start()
    t, x, y = cycles(press, 1)
    (r,) = unit.feed(t, x, y)
    assert r.process_values["duration"] == pytest.approx(0.05)
    assert r.curve.t.size == 501


def test_chunking_does_not_change_curves(unit, press):
    unit.set_program(0, {"control": {"start": {"mode": "x", "value": 1.0}, "stop": {"mode": "x", "value": 0.5,
                                                                                 "direction": "falling"}},
                         "sampling": {"mode": "dx", "delta": 0.01}})
    t, x, y = cycles(press, 3)
    whole = [r.curve for r in unit.feed(t, x, y)]
    unit.select_program(0)
    t2 = t + t[-1] + DT
    rng = np.random.default_rng(0)
    cuts = np.sort(rng.choice(np.arange(1, t.size), 40, replace=False))
    parts = []
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, t.size]):
        parts += [r.curve for r in unit.feed(t2[a:b], x[a:b], y[a:b])]
    assert len(parts) == len(whole) == 3
    for p, w in zip(parts, whole):
        assert np.array_equal(p.x, w.x) and np.array_equal(p.y, w.y) and np.allclose(p.t - t2[0], w.t)


def test_reference_end_puts_turning_point_at_zero(unit, press):
    unit.set_program(0, {"reference": {"mode": "end"}})
    t, x, y = press()
    unit.start()
    unit.feed(t, x, y)
    r = unit.stop()
    assert r.curve.x[r.curve.turning_index] == 0.0
    assert r.curve.x_reference == pytest.approx(4.0, abs=1e-3)
    assert r.process_values["x_max"] == 0.0


def test_reference_y_threshold(unit, press):
    unit.set_program(0, {"reference": {"mode": "y_threshold", "y_threshold": 0.75}})
    t, x, y = press()                               # y = 3 (x/4)^2 forward: y = 0.75 at x = 2
    unit.start()
    unit.feed(t, x, y)
    r = unit.stop()
    assert r.ok and r.curve.x_reference == pytest.approx(2.0, abs=2e-3)
    assert r.process_values["x_min"] == pytest.approx(-2.0, abs=2e-3)
    unit.set_program(0, {"reference": {"y_threshold": 5.0}})
    unit.start()
    unit.feed(t + 1, x, y)
    r = unit.stop()
    assert not r.ok and r.elements[0].name == "reference"
    assert r.elements[0].reason == "Y never reaches the reference threshold 5 N from below on the forward part"


def test_evaluation_through_unit_names_failing_element(unit, press):
    elements = [
        {"kind": "window", "name": "W_mid", "part": "forward", "x_min": 1.5, "x_max": 2.5, "y_min": 0.2,
         "y_max": 1.5, "entry": "left", "exit": "right"},
        {"kind": "threshold", "name": "S_ret", "part": "return", "axis": "x", "value": 2.0, "direction": "falling"},
        {"kind": "window", "name": "W_peak", "x_min": 3.5, "x_max": 4.5, "y_min": 2.5, "y_max": 3.5,
         "entry": "ignore", "exit": "ignore", "check": "y_max"},
        {"kind": "window", "name": "W_off", "enabled": False, "x_min": 10, "x_max": 11, "y_min": 0, "y_max": 1},
    ]
    unit.set_program(0, {"elements": elements, "limits": {"y_max": [2.5, 3.5]}})
    t, x, y = press()
    unit.start()
    unit.feed(t, x, y)
    r = unit.stop()
    assert r.ok, [e.reason for e in r.elements]
    assert [e.name for e in r.elements] == ["W_mid", "S_ret", "W_peak"]       # disabled one not evaluated
    assert r.process_values["W_mid.y_entry"] == pytest.approx(3 * (1.5 / 4) ** 2, abs=2e-3)
    assert r.process_values["S_ret.at"] == pytest.approx(0.5 * 3 * (2 / 4) ** 2, abs=2e-3)
    unit.start()
    unit.feed(t + 1, x, 1.5 * y)                   # too much force: peak 4.5 and enters W_mid late
    r = unit.stop()
    assert not r.ok
    failed = {e.name: e.reason for e in r.elements if not e.ok}
    assert set(failed) == {"W_mid", "W_peak"}
    assert failed["W_peak"] == "check y_max: y max 4.49997 N at x = 3.99994 m lies above the window (y max 3.5 N)"
    d = r.to_dict()
    assert json.loads(json.dumps(d)) == d
    assert d["ok"] is False and d["curve"]["pairs"] == r.curve.t.size
    st = unit.status()
    assert st["outputs"] == {"ok": False, "nok": True}
    assert st["last_evaluation_time"] < unit.desc.evaluation_time          # within the real unit's 90 ms


def test_noisy_unit_is_reproducible_and_chunk_independent(press):
    from firmware_sim.digiforce import DigiForce
    t, x, y = press()
    y = y * 1e-3                                   # V/V on the default bridge program
    curves = []
    for chunk in (t.size, 97):
        dev = DigiForce(rng=np.random.default_rng(42))
        dev.start()
        for a in range(0, t.size, chunk):
            dev.feed(t[a:a + chunk], x[a:a + chunk], y[a:a + chunk])
        curves.append(dev.stop().curve)
    assert np.array_equal(curves[0].y, curves[1].y) and np.array_equal(curves[0].x, curves[1].x)
    assert np.std(np.diff(curves[0].y[:50])) > 0    # noise and errors really present


def test_a_hysteresis_as_wide_as_the_measuring_span_is_refused(unit):
    """Y measures ±5 V through 1 N/V: a 10 N span. A Schmitt band of 10 N could never arm (the value would have to
    swing more than the whole span), tare or not; a band inside the span is taken."""
    with pytest.raises(DigiForceError, match=r"control\.start\.hysteresis: 10 N is not below the whole measuring "
                                             r"span of channel 'y' \(10 N"):
        unit.set_program(1, {**SIMPLE, "control": {"start": {"mode": "y", "value": "0.5 N", "hysteresis": "10 N"}}})
    unit.set_program(1, {**SIMPLE, "control": {"start": {"mode": "y", "value": "0.5 N", "hysteresis": "2 N"}}})
