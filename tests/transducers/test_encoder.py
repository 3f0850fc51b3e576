"""Incremental encoder (firmware side) and host quadrature decoding / speed estimation (drivers side)."""
import math

import numpy as np
import pytest

from drivers.encoder import QuadratureDecoder, SpeedEstimator, counts_to_angle
from firmware_sim.transducers import load_transducer

PPR = 1024
COUNT = 2 * math.pi / (4 * PPR)  # rad per ×4 count


def encoder(seed=0, **kw):
    return load_transducer("encoder_1024", np.random.default_rng(seed), **kw)


def forward_and_back(dt=2e-6, duration=0.4):
    """Angle [rad]: 1.5 rev forward then back past the start, peak speed ≈ 47 rad/s."""
    t = np.arange(0.0, duration, dt)
    theta = 0.1 + 1.5 * 2 * math.pi * np.sin(math.pi * t / duration * 1.2)
    return t, theta


@pytest.mark.parametrize("errors", [False, True])
def test_x4_decoding_of_forward_and_back_motion_within_one_count(errors):
    t, theta = forward_and_back()
    enc = encoder(errors_enabled=errors)
    dec = QuadratureDecoder(PPR, 4)
    counts = []
    for i in range(0, t.size, 25_000):
        levels = enc.measure(t[i:i + 25_000], theta[i:i + 25_000])
        counts.append(dec.decode(t[i:i + 25_000], levels).count)
    angle = dec.angle(np.concatenate(counts))
    assert np.max(np.abs(angle - (theta - theta[0]))) <= COUNT
    assert dec.illegal_transitions == 0
    assert angle.min() < -0.1 and angle.max() > 9.0  # really went forward and back past the start


def test_counter_card_latches_match_the_motion_for_each_multiplier():
    t, theta = forward_and_back(dt=1e-4)
    for mult in (1, 2, 4):
        enc = encoder(multiplier=mult, errors_enabled=False)
        r = enc.sample(t, theta)
        step = 2 * math.pi / (mult * PPR)
        assert np.max(np.abs(enc.to_physical(r.count) - (theta - theta[0]))) <= step
        assert r.illegal[-1] == 0
        changed = np.flatnonzero(np.diff(r.count)) + 1
        # the latched edge time is the exact crossing of a count boundary, just before the sample
        assert np.all(r.edge_time[changed] <= t[changed]) and np.all(r.edge_time[changed] > t[changed - 1])
        edge_angle = np.interp(r.edge_time[changed], t, theta)
        frac = edge_angle / (2 * math.pi / (4 * PPR))
        np.testing.assert_allclose(frac, np.round(frac), atol=1e-3)


def test_x1_x2_relations_on_a_clean_sequence():
    """×1 steps on A rising with B low, ×2 on every A edge, both in the forward direction."""
    gray = np.array([[0, 0], [1, 0], [1, 1], [0, 1]] * 3 + [[0, 0]])
    t = np.arange(gray.shape[0], dtype=float)
    c4 = QuadratureDecoder(PPR, 4).decode(t, gray).count
    c2 = QuadratureDecoder(PPR, 2).decode(t, gray).count
    c1 = QuadratureDecoder(PPR, 1).decode(t, gray).count
    np.testing.assert_array_equal(c4, np.arange(13))
    np.testing.assert_array_equal(c1, [0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3])
    np.testing.assert_array_equal(c2, [0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6])
    back = QuadratureDecoder(PPR, 4).decode(t, gray[::-1]).count
    np.testing.assert_array_equal(back, -np.arange(13))


def test_illegal_transition_is_counted_not_absorbed():
    levels = np.array([[0, 0], [1, 0], [0, 1], [1, 1], [0, 1], [0, 0]])  # 10 -> 01 changes A and B at once
    dec = QuadratureDecoder(PPR, 4)
    out = dec.decode(np.arange(6.0), levels)
    np.testing.assert_array_equal(out.illegal, [0, 0, 1, 1, 1, 1])
    # no step on the illegal sample; then 01 -> 11 is a step back, 11 -> 01 -> 00 two steps forward
    np.testing.assert_array_equal(out.count, [0, 1, 1, 0, 1, 2])
    assert dec.illegal_transitions == 1


def test_undersampled_fast_shaft_shows_illegal_transitions():
    t = np.arange(0.0, 0.01, 1e-5)
    theta = 2 * math.pi * 30 * t  # 30 rev/s: 1.2 counts per sample
    dec = QuadratureDecoder(PPR, 4)
    dec.decode(t, encoder(errors_enabled=False).measure(t, theta))
    assert dec.illegal_transitions > 100


def test_index_pulse_once_per_revolution():
    t = np.arange(0.0, 0.5, 5e-6)
    theta = 0.05 + 2 * math.pi * 5 * t  # 2.5 rev
    dec = QuadratureDecoder(PPR, 4)
    out = dec.decode(t, encoder(errors_enabled=False).measure(t, theta))
    assert out.index.size == 2
    np.testing.assert_allclose(np.mod(theta[out.index], 2 * math.pi), 0.0, atol=2 * COUNT)


def test_counter_card_edge_rate_limit_loses_counts_and_counts_illegal():
    t = np.arange(0.0, 0.02, 1e-4)
    theta = 2 * math.pi * 300 * t  # 1.2 M edges/s: above the 1 MHz card
    r = encoder(errors_enabled=False).sample(t, theta)
    assert r.illegal[-1] > 0
    ok = encoder(errors_enabled=False, max_edge_frequency="10 MHz").sample(t, theta)
    assert ok.illegal[-1] == 0 and abs(ok.count[-1] - theta[-1] / COUNT) <= 1


def test_missed_pulses_lose_counts_and_glitches_make_illegal_transitions():
    t = np.arange(0.0, 0.2, 2e-6)
    theta = 2 * math.pi * 2 * t
    enc = encoder(errors_enabled=False)
    enc.inject("missed_pulses", at=0.05, until=0.15, probability=0.05)
    dec = QuadratureDecoder(PPR, 4)
    out = dec.decode(t, enc.measure(t, theta))
    true = theta[-1] / COUNT
    assert out.count[-1] < true - 10           # pulses went missing: the count lags
    before = t < 0.05
    assert np.max(np.abs(out.count[before] - theta[before] / COUNT)) <= 1

    enc = encoder(errors_enabled=False)
    enc.inject("glitches", at=0.0, rate="2 kHz", width="3 us")  # quantity strings or SI numbers
    assert enc.faults.faults[-1].params == {"rate": 2000.0, "width": pytest.approx(3e-6)}
    dec = QuadratureDecoder(PPR, 4)
    dec.decode(t, enc.measure(t, theta))
    assert dec.illegal_transitions > 0
    with pytest.raises(ValueError, match="unknown fault"):
        enc.inject("dust")
    with pytest.raises(ValueError, match="'width'.*wrong dimension"):
        enc.inject("glitches", width="3 mm")


def test_speed_by_frequency_at_high_and_by_period_at_low_speed():
    dt = 2e-6
    t = np.arange(0.0, 0.3, dt)
    w_true = np.where(t < 0.1, 40.0, np.where(t < 0.2, 0.2, 0.0))   # rad/s: fast, creeping, stopped
    theta = 0.3 + np.concatenate(([0.0], np.cumsum(0.5 * (w_true[1:] + w_true[:-1]) * dt)))
    enc = encoder()
    dec = QuadratureDecoder(PPR, 4)
    est = SpeedEstimator(PPR, 4, gate_time=0.005, min_counts=10)
    card_est = SpeedEstimator(PPR, 4, gate_time=0.005, min_counts=10)
    w, by_period, w_card = [], [], []
    for i in range(0, t.size, 20_000):
        sl = slice(i, i + 20_000)
        r = enc.sample(t[sl], theta[sl])
        d = dec.decode(t[sl], r.levels)
        ws, bp = est.update(t[sl], d.count, d.edge_time)
        w.append(ws), by_period.append(bp)
        w_card.append(card_est.update(t[sl], r.count, r.edge_time)[0])
    w, by_period, w_card = map(np.concatenate, (w, by_period, w_card))
    fast = (t > 0.01) & (t < 0.1)
    slow = (t > 0.16) & (t < 0.2)
    assert not by_period[fast].any() and by_period[slow].all()
    assert np.max(np.abs(w[fast] - 40.0)) < 2 * COUNT / 0.005 + 1e-9     # ±1 count over the gate (each end)
    np.testing.assert_allclose(w_card[slow], 0.2, rtol=0.01)               # exact edge times: period is sharp
    np.testing.assert_allclose(w[slow], 0.2, rtol=0.1)                      # edge times to one sample
    stopped = t > 0.28
    assert np.all(np.abs(w_card[stopped]) < COUNT / 0.07)                   # decays: ≤ 1 count / time since edge
    assert np.all(np.diff(np.abs(w_card[stopped])) <= 0)


def test_counts_to_angle_and_bad_arguments():
    assert counts_to_angle(4096, 1024, 4) == pytest.approx(2 * math.pi)
    assert counts_to_angle(1024, 1024, 1) == pytest.approx(2 * math.pi)
    with pytest.raises(ValueError, match="multiplier"):
        QuadratureDecoder(1024, 3)
    with pytest.raises(ValueError, match="0 or 1"):
        QuadratureDecoder(1024).decode(np.arange(2.0), np.array([[0, 2], [1, 1]]))
    with pytest.raises(ValueError, match="shape"):
        QuadratureDecoder(1024).decode(np.arange(3.0), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="ppr"):
        encoder(ppr=10.5)
    with pytest.raises(ValueError, match="increase"):
        enc = encoder()
        enc.measure(np.array([0.0, 1.0]), np.array([0.0, 0.1]))
        enc.measure(np.array([0.5]), np.array([0.2]))
