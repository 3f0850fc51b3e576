"""Sampling by Δt, ΔX, ΔY and the curve-memory overflow policies (stop / decimate), never silent."""
import numpy as np
import pytest


def record(dev, t, x, y):
    dev.start()
    dev.feed(t, x, y)
    return dev.stop()


def sequential_delta(v, delta):
    """Reference rule: store a pair when the value moved by >= delta from the last stored pair."""
    idx, ref = [0], v[0]
    for i in range(1, len(v)):
        if abs(v[i] - ref) >= delta * (1 - 1e-9):
            idx.append(i)
            ref = v[i]
    if idx[-1] != len(v) - 1:
        idx.append(len(v) - 1)          # the last sample of a measurement is always stored
    return np.array(idx)


def test_time_sampling_stores_every_delta(unit):
    unit.set_program(0, {"sampling": {"mode": "time", "delta": "1 ms"}})
    t = np.arange(1001) * 1e-4
    res = record(unit, t, 0 * t, 0 * t)
    assert res.curve.t.size == 101
    assert np.allclose(np.diff(res.curve.t), 1e-3)
    assert not res.curve.overflow and res.process_values["duration"] == pytest.approx(0.1)


@pytest.mark.parametrize("mode, col", [("dx", "x"), ("dy", "y")])
def test_delta_sampling_matches_sequential_rule(unit, mode, col):
    unit.set_program(0, {"sampling": {"mode": mode, "delta": 0.05}})
    t = np.arange(5000) * 1e-4
    x = 2 * np.sin(2 * np.pi * 1.3 * t) ** 2          # slow and steep regions, reversals
    y = np.cumsum(np.abs(np.sin(40 * t))) * 1e-3 - 1.0
    res = record(unit, t, x, y)
    quantised = {"x": res.curve.x, "y": res.curve.y}
    raw = {"x": x, "y": y}[col]
    # compare against the rule applied to the quantised input the unit really saw
    lsb = {"x": 20 / 2 ** 16, "y": 10 / 2 ** 16}[col]
    seen = np.rint(raw / lsb) * lsb
    expected = sequential_delta(seen, 0.05)
    assert np.array_equal(res.curve.t, t[expected])
    assert np.allclose(quantised[col], seen[expected])
    assert 10 < res.curve.t.size < 1000                 # really compressed


def test_overflow_stop_keeps_first_pairs_and_flags(unit):
    unit.set_program(0, {"sampling": {"mode": "time", "delta": 1e-4, "overflow": "stop"}})
    t = np.arange(10000) * 1e-4
    res = record(unit, t, np.sin(t), 0 * t)
    c = res.curve
    assert c.t.size == 4000 and np.array_equal(c.t, t[:4000])
    assert c.overflow and c.decimations == 0 and c.dropped == 6000
    st = unit.status()
    assert st["overflow_curves"] == 1 and st["dropped_pairs"] == 6000
    assert "memory overflow" in st["errors"][-1]
    assert res.to_dict(include_curve=False)["overflow"] is True


def test_overflow_decimate_equals_coarser_sampling(unit):
    unit.set_program(0, {"sampling": {"mode": "time", "delta": 1e-4, "overflow": "decimate"}})
    t = np.arange(10000) * 1e-4
    x = np.sin(7 * t)
    res = record(unit, t, x, 0 * t)
    dec = res.curve
    assert dec.decimations == 2 and dec.sampling["delta"] == pytest.approx(4e-4)
    assert not dec.overflow and dec.dropped == 0            # thinned, not cut (MemoryFull means cut, policy stop)
    flags = res.to_dict(include_curve=False)
    assert flags["overflow"] is False and flags["decimated"] is True
    assert not any("memory overflow" in e for e in unit.status()["errors"])
    assert dec.t.size <= 4000
    unit.set_program(0, {"sampling": {"delta": 4e-4, "overflow": "stop"}})
    ref = record(unit, t + 1.0, x, 0 * t).curve
    assert not ref.overflow
    assert np.allclose(dec.t, ref.t - 1.0) and np.array_equal(dec.x, ref.x)
    assert unit.status()["decimated_curves"] == 1


@pytest.mark.parametrize("policy", ["stop", "decimate"])
def test_a_full_memory_shows_in_the_status_while_measuring(unit, policy):
    """A cut or thinned curve was seen only when it ended (overflow_curves, decimated_curves): while it runs the status
    says so (memory_full with the stop policy, decimations with decimate), and both clear when it ends."""
    unit.set_program(0, {"sampling": {"mode": "time", "delta": 1e-4, "overflow": policy}})
    t = np.arange(10000) * 1e-4
    unit.start()
    unit.feed(t[:3000], np.sin(t[:3000]), 0 * t[:3000])
    before = unit.status()
    unit.feed(t[3000:], np.sin(t[3000:]), 0 * t[3000:])
    during = unit.status()
    unit.stop()
    after = unit.status()
    assert before["state"] == during["state"] == "measuring"
    assert (before["memory_full"], before["decimations"]) == (False, 0)
    assert (during["memory_full"], during["decimations"]) == ((True, 0) if policy == "stop" else (False, 2))
    assert (after["memory_full"], after["decimations"]) == (False, 0)


def test_overflow_decimate_in_dx_mode_keeps_whole_stroke(unit):
    unit.set_program(0, {"sampling": {"mode": "dx", "delta": 1e-3, "overflow": "decimate"}})
    t = np.arange(20000) * 1e-4
    x = np.linspace(0, 9.0, t.size)                     # 9000 steps of 1 mm
    c = record(unit, t, x, 0 * t).curve
    assert c.decimations >= 1 and c.t.size <= 4000
    assert c.x[0] == pytest.approx(0, abs=2e-4) and c.x[-1] == pytest.approx(9.0, abs=2e-4)
    assert np.all(np.diff(c.x)[:-1] >= c.sampling["delta"] * (1 - 1e-9))


def test_time_delta_faster_than_unit_refused(unit):
    from firmware_sim.digiforce import DigiForceError
    with pytest.raises(DigiForceError, match="faster than the unit's 100000 pairs/s"):
        unit.set_program(0, {"sampling": {"delta": "5 us"}})
