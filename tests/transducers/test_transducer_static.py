"""Static behaviour of the analog transducers: exact without errors, inside the data-sheet bound with."""
import math

import numpy as np
import pytest

from firmware_sim.transducers import load_transducer

ANALOG = ["burster_8411", "brake_force_2kN", "burster_8740", "torque_meter_50Nm", "potentiometer_dmm",
          "leaf_half_bridge"]


def sweep(sensor, n_per_way: int, duration: float):
    """Slow up-and-down sweep over the range; returns t, q and whether each sample is rising."""
    lo, hi = sensor.p["range_min"], sensor.p["range_max"]
    up = np.linspace(lo, hi, n_per_way)
    q = np.concatenate((up, up[::-1]))
    t = np.linspace(0.0, 2 * duration, q.size)
    rising = np.arange(q.size) < n_per_way
    return t, q, rising


@pytest.mark.parametrize("name", ANALOG)
def test_exact_without_errors(name):
    s = load_transducer(name, np.random.default_rng(0), errors_enabled=False, dynamics_enabled=False)
    lo, hi = s.p["range_min"], s.p["range_max"]
    q = np.linspace(lo, hi, 2001)
    t = np.arange(q.size) / s.p.get("reading_rate", 1.0)  # one multimeter reading per sample for the DMM
    y = s.measure(t, q)
    expect = s.p["output_at_min"] + (q - lo) * (s.p["output_at_max"] - s.p["output_at_min"]) / (hi - lo)
    step = s.p.get("resolution", 0.0)
    tol = step / 2 + 1e-12 * s.full_scale
    if "preload" in s.p:
        assert s.p["preload"] == 0.0
    np.testing.assert_allclose(y, expect, rtol=0, atol=tol)
    np.testing.assert_allclose(s.to_physical(y), q, rtol=0, atol=tol / abs(s.sensitivity) + 1e-12 * (hi - lo))


@pytest.mark.parametrize("name", ["burster_8411", "burster_8740", "torque_meter_50Nm"])
def test_exact_in_steady_state_with_dynamics(name):
    """Unity DC gain: with errors off, a held input is reproduced exactly once settled."""
    s = load_transducer(name, np.random.default_rng(0), errors_enabled=False)
    q0 = 0.37 * s.p["range_max"] + 0.63 * s.p["range_min"]
    t = np.arange(0, 0.5, 1e-4)
    y = s.measure(t, np.full(t.size, q0))
    np.testing.assert_allclose(s.to_physical(y), q0, rtol=0, atol=1e-12 * (s.p["range_max"] - s.p["range_min"]))


def datasheet_bound(s, delta_t: float, nominal: np.ndarray) -> np.ndarray:
    """|error| bound from the description's figures (sum of the worst cases), signal units."""
    p, fs = s.p, s.full_scale
    zero = p["output_at_min"] + (np.clip(0.0, p["range_min"], p["range_max"]) - p["range_min"]) * s.sensitivity
    loading = 0.0
    if "load_resistance" in p and math.isfinite(p["load_resistance"]):
        loading = p["output_resistance"] / (p["output_resistance"] + p["load_resistance"])
    fixed = fs * (p["zero_offset_max"] + p["nonlinearity_max"] + p["hysteresis_max"] / 2
                  + p["temp_zero_max"] * abs(delta_t))
    fixed += p.get("ripple_amplitude", 0.0) + 5.0 * p["noise_rms"] + p.get("resolution", 0.0) / 2
    return fixed + (p["gain_error_max"] + p["temp_span_max"] * abs(delta_t) + loading) * np.abs(nominal)  \
        + loading * abs(zero)


@pytest.mark.parametrize("name", ANALOG)
def test_static_error_inside_datasheet_bound(name):
    worst = 0.0
    for seed in range(20):
        dmm = name == "potentiometer_dmm"
        extra = {"reading_rate": "1 Hz"} if dmm else {}  # multimeter: one reading per sample
        s = load_transducer(name, np.random.default_rng(seed), temperature_delta="10 K", **extra)
        if dmm:
            t, q, _ = sweep(s, 400, 400.0)
            t = np.arange(t.size, dtype=float)
        else:                           # slow enough that the lag is < 1e-5 of the range
            t, q, _ = sweep(s, 3000, 300.0)
        y = s.measure(t, q)
        nominal = s.nominal(q)
        err = np.abs(y - nominal)
        bound = datasheet_bound(s, 10.0, nominal - s.zero_output)
        assert np.all(err <= bound), f"{name} seed {seed}: error {err.max()} exceeds bound"
        worst = max(worst, float(np.max(err / bound)))
    assert worst > 0.3, f"{name}: errors suspiciously small ({worst:.3f} of the bound)"


@pytest.mark.parametrize("name", ["burster_8411", "burster_8740", "torque_meter_50Nm"])
def test_hysteresis_relative_return(name):
    """Rising minus falling reading at the same input stays within the relative-return figure."""
    seen = 0.0
    for seed in range(10):
        quiet = {"burster_8740": {"noise_rms": "0 V", "ripple_amplitude": "0 V"},
                 "torque_meter_50Nm": {"noise_rms": "0 V"}}.get(name, {"noise_rms": 0.0})
        s = load_transducer(name, np.random.default_rng(seed), **quiet)
        t, q, rising = sweep(s, 2001, 200.0)
        y = s.measure(t, q)
        up, down = y[rising], y[~rising][::-1]
        ret = np.abs(up - down)[100:-100] / s.full_scale
        assert ret.max() <= s.p["hysteresis_max"] * (1 + 1e-9) + 1e-5
        seen = max(seen, ret.max())
    assert seen > 0.3 * s.p["hysteresis_max"]


def test_noise_is_reproducible_and_seed_dependent():
    t = np.linspace(0, 0.1, 1000)
    q = np.full(t.size, 10e-3)
    a = load_transducer("burster_8740", np.random.default_rng(5)).measure(t, q)
    b = load_transducer("burster_8740", np.random.default_rng(5)).measure(t, q)
    c = load_transducer("burster_8740", np.random.default_rng(6)).measure(t, q)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_chunked_equals_one_shot():
    t = np.linspace(0, 0.2, 4001)
    q = 400.0 * np.sin(2 * np.pi * 30 * t)
    whole = load_transducer("burster_8411", np.random.default_rng(3), noise_rms=0.0).measure(t, q)
    s = load_transducer("burster_8411", np.random.default_rng(3), noise_rms=0.0)
    parts = np.concatenate([s.measure(t[i:i + 777], q[i:i + 777]) for i in range(0, t.size, 777)])
    np.testing.assert_allclose(parts, whole, rtol=0, atol=1e-15)


def test_potentiometer_reads_a_few_times_per_second():
    s = load_transducer("potentiometer_dmm", np.random.default_rng(0), errors_enabled=False)
    t = np.arange(0.0, 2.0, 1e-3)
    q = np.radians(100.0) * t  # 100 deg/s
    y = s.measure(t[:700], q[:700])
    y = np.concatenate((y, s.measure(t[700:], q[700:])))
    changes = np.flatnonzero(np.diff(y) != 0) + 1
    np.testing.assert_allclose(t[changes], [1 / 3, 2 / 3, 1.0, 4 / 3, 5 / 3], atol=1.5e-3)
    np.testing.assert_allclose(s.to_physical(y[changes]), q[changes], atol=np.radians(340) * 1e-4 / 2 + 1e-9)


def test_temperature_effect_scales_with_delta_t():
    def zero_reading(dt_k: float) -> float:
        s = load_transducer("torque_meter_50Nm", np.random.default_rng(1), noise_rms="0 V", temperature_delta_K=dt_k)
        return float(s.measure(np.array([0.0]), np.array([0.0]))[0])
    z0, z10, z20 = zero_reading(0.0), zero_reading(10.0), zero_reading(20.0)
    assert z10 != z0
    assert z20 - z10 == pytest.approx(z10 - z0, rel=1e-9)


def test_play_operator_follows_within_its_radius_across_calls():
    """The compiled play operator equals the textbook loop, its state carried from one call to the next."""
    from firmware_sim.transducers.static_errors import Play
    q = np.cumsum(np.random.default_rng(2).normal(0.0, 0.3, 3000))
    play = Play(0.5)
    got = np.concatenate([play(part) for part in np.array_split(q, 7)])
    z, want = q[0], []
    for v in q:
        z = v - 0.5 if v > z + 0.5 else v + 0.5 if v < z - 0.5 else z
        want.append(z)
    np.testing.assert_array_equal(got, want)
    assert np.max(np.abs(got - q)) <= 0.5 * (1 + 1e-12) and play(q[:0]).size == 0     # rounding of v − r
