"""LVDT: 100 Hz second-order dynamics against analytic and independent references; ripple, clipping, faults."""
import math

import numpy as np
import pytest
from scipy import signal

from firmware_sim.transducers import LowPass, frequency_response, load_transducer

ZETA = 0.7071  # burster_8740.toml; ≈ Butterworth, whose −3 dB point is the natural frequency
# natural frequency putting |H| = 1/√2 at 100 Hz for this ζ: (ω_c/ωn)² = 1 − 2ζ² + √((1 − 2ζ²)² + 1)
WN = 2 * math.pi * 100.0 / math.sqrt((1 - 2 * ZETA**2) + math.sqrt((1 - 2 * ZETA**2) ** 2 + 1))


def lvdt(**kw):
    return load_transducer("burster_8740", np.random.default_rng(0), errors_enabled=False, **kw)


def fit_sine(t, y, f):
    a = np.column_stack((np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t), np.ones_like(t)))
    c = np.linalg.lstsq(a, y, rcond=None)[0]
    return complex(c[0], c[1])  # phasor relative to sin


def test_step_response_matches_analytic_second_order():
    s = lvdt()
    dt = 1e-6
    t = np.arange(0.0, 0.03, dt)
    q = np.where(t >= 0.001, 0.05, 0.0)  # 50 mm step at 1 ms
    y = s.measure(t, q) / 2.5             # 2.5 V for 50 mm
    wn = WN
    wd = wn * math.sqrt(1 - ZETA**2)
    tau = np.clip(t - 0.001 + dt / 2, 0, None)  # the sampled step is a one-sample ramp: centre it
    ref = 1 - np.exp(-ZETA * wn * tau) * (np.cos(wd * tau) + ZETA / math.sqrt(1 - ZETA**2) * np.sin(wd * tau))
    np.testing.assert_allclose(y, ref, atol=2e-6)
    assert y.max() == pytest.approx(1 + math.exp(-math.pi * ZETA / math.sqrt(1 - ZETA**2)), abs=1e-5)  # overshoot


@pytest.mark.parametrize("f, chunk", [(100.0, 3333), (30.0, 10**6)])
def test_gain_and_phase_match_analytic_filter(f, chunk):
    s = lvdt()
    dt = 2e-5
    t = np.arange(0.0, 0.2, dt)
    q = 0.05 + 0.01 * np.sin(2 * np.pi * f * t)
    y = np.concatenate([s.measure(t[i:i + chunk], q[i:i + chunk]) for i in range(0, t.size, chunk)])
    settled = t > 0.1
    h = fit_sine(t[settled], y[settled] / 50.0, f) / 0.01   # 50 V/m
    w = 2 * np.pi * f
    h_ref = WN**2 / (WN**2 - w**2 + 2j * ZETA * WN * w)
    assert frequency_response(f, 100.0, 2, ZETA) == pytest.approx(h_ref, rel=1e-12)
    assert abs(h) == pytest.approx(abs(h_ref), rel=1e-4)
    assert np.angle(h) == pytest.approx(np.angle(h_ref), abs=1e-4)
    if f == 100.0:
        assert 20 * math.log10(abs(h)) == pytest.approx(-3.01, abs=0.01)
        assert math.degrees(np.angle(h)) == pytest.approx(-90.0, abs=0.05)


def test_filter_matches_scipy_lsim_for_piecewise_linear_input_in_chunks_and_nonuniform():
    wn, z = 2 * math.pi * 50.0, 0.3
    dt = 1e-4
    t = np.arange(0.0, 0.1, dt)
    u = np.interp(t, [0, 0.01, 0.02, 0.05, 0.1], [0, 1, -0.5, -0.5, 2])
    _, ref, _ = signal.lsim(([wn**2], [1, 2 * z * wn, wn**2]), u, t)  # linear interpolation of u
    f_c = 50.0 * math.sqrt((1 - 2 * z * z) + math.sqrt((1 - 2 * z * z) ** 2 + 1))  # −3 dB point for ωn, ζ
    f = LowPass(f_c, 2, z)
    out = np.concatenate([f(t[i:i + 137], u[i:i + 137]) for i in range(0, t.size, 137)])
    np.testing.assert_allclose(out, ref, atol=1e-9)
    # non-uniform sampling that keeps the input's breakpoints gives the same values at common times
    rng = np.random.default_rng(2)
    tn = np.unique(np.concatenate((rng.uniform(0, 0.1, 300), [0, 0.01, 0.02, 0.05], t[::50])))
    g = LowPass(f_c, 2, z)
    outn = g(tn, np.interp(tn, [0, 0.01, 0.02, 0.05, 0.1], [0, 1, -0.5, -0.5, 2]))
    common = np.isin(tn, t[::50])
    np.testing.assert_allclose(outn[common], ref[::50][np.isin(t[::50], tn[common])], atol=1e-9)


def test_first_order_filter_time_constant():
    f = LowPass(10.0, 1)
    t = np.linspace(0, 0.1, 10001)
    y = f(t, np.where(t > 0, 1.0, 0.0))
    tau = 1 / (2 * math.pi * 10.0)
    np.testing.assert_allclose(y[1:], 1 - np.exp(-(t[1:] - t[1] / 2) / tau), atol=2e-4)


def test_bad_filter_parameters_are_rejected():
    with pytest.raises(ValueError, match="order"):
        LowPass(100.0, 3)
    with pytest.raises(ValueError, match="bandwidth"):
        LowPass(-1.0, 2)
    with pytest.raises(ValueError, match="damping"):
        LowPass(100.0, 2, 1.0)
    f = LowPass(100.0, 2)
    f(np.array([0.0, 1.0]), np.array([0.0, 0.0]))
    with pytest.raises(ValueError, match="non-decreasing"):
        f(np.array([0.5]), np.array([1.0]))


def test_core_out_of_range_clips_and_supply_loss_zeroes():
    s = lvdt(dynamics_enabled=False)
    s.inject("supply_loss", at=0.3, until=0.4)
    t = np.linspace(0.0, 0.5, 6)
    q = np.array([0.05, 0.12, -0.02, 0.05, 0.05, 0.05])
    y = s.measure(t, q)
    np.testing.assert_allclose(y, [2.5, 5.25, -0.25, 0.0, 2.5, 2.5])


def test_carrier_ripple_at_12_khz():
    s = load_transducer("burster_8740", np.random.default_rng(4), noise_rms="0 V")
    dt = 1e-6
    t = np.arange(0.0, 0.01, dt)
    y = s.measure(t, np.full(t.size, 0.04))
    spec = np.abs(np.fft.rfft(y - y.mean())) * 2 / t.size
    freqs = np.fft.rfftfreq(t.size, dt)
    assert freqs[np.argmax(spec)] == pytest.approx(12e3, abs=100)
    assert spec.max() == pytest.approx(2e-3, rel=0.02)



def test_supply_outside_data_sheet_is_rejected():
    with pytest.raises(ValueError, match="supply 30.0 V"):
        load_transducer("burster_8740", np.random.default_rng(4), supply="30 V")


@pytest.mark.parametrize("order", [1, 2])
def test_the_low_pass_gives_the_same_output_however_the_samples_are_cut(order):
    """Exact sample times k/rate differ in the last bits of their spacings: the uniform path's coefficients come from
    the nominal step, not from whichever spacing a call starts with, so one call and calls of 1000, 333 or 5000
    samples filter alike to the bit (before, 1e-17..1e-13 apart: the runner's chunk changed the transducers'
    outputs)."""
    from firmware_sim.transducers.lowpass import LowPass
    t = np.arange(1, 30_001) / 10_000.0
    u = np.sin(40 * t) + 0.3 * np.cos(700 * t)
    outs = []
    for size in (t.size, 1000, 333, 5000):
        lp = LowPass(300.0, order)
        outs.append(np.concatenate([lp(t[k:k + size], u[k:k + size]) for k in range(0, t.size, size)]))
    assert all(np.array_equal(outs[0], out) for out in outs[1:])
