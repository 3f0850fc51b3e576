"""Incremental encoder (firmware side) and host quadrature decoding / speed estimation (drivers side)."""
import math

import numpy as np
import pytest

from drivers.encoder import (BOUND, FREQUENCY, GATE_TIME, PERIOD, QuadratureDecoder, SpeedEstimate, SpeedEstimator,
                             counts_to_angle)
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

    after = t > 0.15                           # a fixed loss after the fault: the counting goes on forward
    assert np.ptp(theta[after] / COUNT - out.count[after]) <= 2

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


# ---- speed: mixed frequency/period method on the latched edge times -----------------------------------------
Q = 1e-6                 # s, edge-time resolution of the Encoder CAN frame
READ = 1e-3              # s, 1 kHz readings as on the clutch stand


def angle_profile(kind, t):
    """Known angle θ(t) [rad] and speed ω(t) [rad/s]: constant fast/slow, ramp from rest, stop, standstill."""
    if kind == "fast":
        return 0.3 + 40.0 * t, np.full_like(t, 40.0)
    if kind == "slow":
        return 0.3 + 0.2 * t, np.full_like(t, 0.2)
    if kind == "creep":                      # the blocked clutch's drive: one count per 4.1 ms
        return 0.3 + 0.37 * t, np.full_like(t, 0.37)
    if kind == "ramp":                       # from rest through the switch-over to 40 rad/s
        return 0.3 + 200.0 * t ** 2, 400.0 * t
    if kind == "stop":                       # 5 rad/s, decelerating to rest at 0.1 s, then at rest
        tc = np.minimum(t, 0.1)
        return 0.3 + 5.0 * tc - 25.0 * tc ** 2, np.where(t < 0.1, 5.0 - 50.0 * t, 0.0)
    raise ValueError(kind)


def card_readings(kind, duration=0.2, dt=2e-5, errors=False, seed=0):
    """The counter card's latches at 1 kHz readings, as the host receives them: edge times rounded to 1 µs,
    reading times delayed by the bus (135 µs, 540 µs at every 100th reading: the device's chunk boundary)."""
    t = np.arange(dt, duration + dt / 2, dt)
    theta, omega = angle_profile(kind, t)
    r = encoder(seed, errors_enabled=errors).sample(t, theta)
    every = int(round(READ / dt))
    i = np.arange(every - 1, t.size, every)
    k = np.arange(i.size)
    t_read = t[i] + np.where(k % 100 == 99, 540e-6, 135e-6)
    edge = np.where(np.isnan(r.edge_time[i]), 0.0, np.round(r.edge_time[i] / Q) * Q)   # "no edge" sent as 0
    return t_read, r.count[i], edge, t, omega


def estimate(t_read, count, edge, chunk=37, **kw):
    est = SpeedEstimator.for_encoder(PPR, 4, **kw)
    parts = [est.update(t_read[a:a + chunk], count[a:a + chunk], edge[a:a + chunk])
             for a in range(0, t_read.size, chunk)]
    return est, SpeedEstimate(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("speed", "time", "method")))


def theory_bound(method, omega, q=Q):
    """|ω̂ − ω| for exact counts and edge times known to ±q/2 at each end of the window (rounding to Q; with
    jitter add its ±3σ): relative q/window; window ≥ gate (frequency) or ≥ one count period Δ/|ω| (period).
    The mean over the window is the speed at its midpoint for constant and linear speed."""
    w = np.abs(omega)
    return np.where(method == FREQUENCY, w * q / GATE_TIME, w * w * q / COUNT) + 1e-9


@pytest.mark.parametrize("kind", ["fast", "slow", "creep", "ramp"])
def test_speed_error_within_theory_for_each_method(kind):
    t_read, count, edge, t, omega = card_readings(kind, duration=2.0 if kind == "creep" else 0.2)
    est, s = estimate(t_read, count, edge)
    w_true = np.interp(s.time, t, omega)
    have = (s.method == FREQUENCY) | (s.method == PERIOD)
    assert have[s.time > 0.02].all()                         # an estimate at every reading after the first edges
    err = np.abs(s.speed - w_true)[have]
    assert np.all(err <= theory_bound(s.method[have], w_true[have]))
    if kind == "fast":
        assert (s.method[5:] == FREQUENCY).all()
    if kind in ("slow", "creep"):                            # one count per 7.7 / 4.1 ms: period method
        assert (s.method[have] == PERIOD).all()
        assert np.max(err) < 1e-4
    if kind == "ramp":                                       # the switch-over at ω_s = 4 counts per 2 ms gate
        ws = est.switch_speed
        assert ws == pytest.approx(4 * COUNT / 2e-3)
        assert (s.method[have & (w_true > 1.2 * ws)] == FREQUENCY).all()
        assert (s.method[have & (w_true < 0.8 * ws) & (s.time > 0.005)] == PERIOD).all()


def test_plain_frequency_method_on_reading_times_would_fail_the_bound():
    """What the report did before: Δcount/Δt over the reading times. Quantised to one count per reading (0 or
    1.53 rad/s at 0.2 rad/s) and spiking where the bus delayed a reading — the test above can tell."""
    for kind, worst in (("slow", 0.5), ("fast", 5.0)):
        t_read, count, edge, t, omega = card_readings(kind)
        w = np.gradient(count * COUNT, t_read)[5:-5]
        assert np.max(np.abs(w - omega[0])) > worst


def test_no_spikes_at_chunk_boundaries_and_any_chunking_gives_the_same_result():
    t_read, count, edge, t, omega = card_readings("ramp", errors=True)
    ref = estimate(t_read, count, edge, chunk=t_read.size)[1]
    for chunk in (1, 7, 100):
        got = estimate(t_read, count, edge, chunk=chunk)[1]
        np.testing.assert_array_equal(got.speed, ref.speed)
        np.testing.assert_array_equal(got.method, ref.method)
    # the readings the bus delayed (every 100th) are as good as the others; 50 ns rms edge jitter: ±3σ more
    w_true = np.interp(ref.time, t, omega)
    ok = (ref.method == FREQUENCY) | (ref.method == PERIOD)
    assert ok[ref.time > 0.01].all()
    assert np.all(np.abs(ref.speed - w_true)[ok] <= theory_bound(ref.method[ok], w_true[ok], Q + 6 * 50e-9))


def test_standstill_decays_within_the_one_count_bound():
    t_read, count, edge, t, omega = card_readings("stop", duration=0.4)
    _, s = estimate(t_read, count, edge)
    edge_t = edge[np.flatnonzero(np.diff(count) != 0)[-1] + 1]    # the last edge
    rest = t_read > edge_t + 2 * READ
    # |ω̂| < one count over the host-observed time without an edge, less the allowance for bus jitter
    last_reading_with_edge = t_read[np.flatnonzero(np.diff(count) != 0)[-1] + 1]
    assert np.all(np.abs(s.speed[rest]) <= COUNT / (t_read[rest] - last_reading_with_edge - 1e-3) + 1e-12)
    assert np.all(np.diff(np.abs(s.speed[rest])) <= 0) and (s.method[rest][5:] == BOUND).all()
    assert np.abs(s.speed[-1]) < COUNT / 0.25                          # 0.3 s at rest: below 6e-3 rad/s
    moving = (s.time > 0.005) & (s.time < 0.09)
    w_true = np.interp(s.time, t, omega)
    assert np.max(np.abs(s.speed - w_true)[moving]) < 0.01            # decelerating: means at their midpoints


def test_shaft_that_never_turns_reads_zero_and_placeholder_edge_times_are_ignored():
    t_read = np.arange(1, 20001) * READ                                # 20 s: the 24-bit edge time wraps at 16.8 s
    count = np.zeros(t_read.size, np.int64)
    edge = np.where(t_read > 8.4, 16.777216, 0.0)                      # the host's unwrap of a "no edge" 0
    _, s = estimate(t_read, count, edge, chunk=500)
    assert np.all(s.speed == 0.0) and (s.method == BOUND).all()


def test_speed_from_the_host_decoder_edge_times():
    """QuadratureDecoder edge times are the sample that saw the change: resolution = the sample interval."""
    dt = 2e-5
    t = np.arange(0.0, 0.1, dt)
    theta, omega = angle_profile("ramp", t)
    dec = QuadratureDecoder(PPR, 4)
    d = dec.decode(t, encoder(errors_enabled=False).measure(t, theta))
    est = SpeedEstimator.for_encoder(PPR, 4, reading_jitter=0.0)
    s = est.update(t, d.count, d.edge_time)
    ok = (s.method == FREQUENCY) | (s.method == PERIOD)
    w = np.interp(s.time, t, omega)
    bound = np.where(s.method == FREQUENCY, w * dt / GATE_TIME, w * w * dt / COUNT) + 1e-9
    assert ok[t > 0.01].all() and np.all(np.abs(s.speed - w)[ok] <= bound[ok])


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


def test_a_shaft_resting_on_a_line_edge_flickers_unless_the_disc_is_mounted_off_it():
    """At rest exactly on a whole count, rounding noise of the angle (±1 ulp) crosses the line edge back and
    forth: the count changes though the shaft does not turn (the card's dead time drops the edges that follow at
    once), as a real encoder's would. A disc mounted 0.03° off that angle holds the count."""
    t = np.arange(1, 2001) * 1e-4
    rest = 4096 * COUNT                                  # a whole turn: a line edge
    theta = rest + np.where(np.arange(t.size) % 2 == 0, 0.0, -np.spacing(rest))
    on_edge = encoder(errors_enabled=False).sample(t, theta).count
    off_edge = encoder(errors_enabled=False, mount_angle="0.03 deg").sample(t, theta).count
    assert np.unique(on_edge).size == 2
    assert np.unique(off_edge).size == 1


def test_the_counter_starts_at_power_on_for_a_shaft_already_turning():
    """The machine's first sample comes one step after power-on (t = 0): the card counts from the shaft's angle at
    t = 0, so count k's edge is where the shaft passed k counts beyond that (it counted from the first sample,
    one count late at a crank turning 0.145° in those 50 µs: the Geneva sheet's differences doubled)."""
    dt, omega = 50e-6, 50.0                                    # 20 kHz, 50 rad/s: 0.143° per sample
    t = dt * (1 + np.arange(4000))
    for start in (0.0, 0.3 * COUNT, 7 * COUNT):                # on an edge at t = 0 (the scenes' 0°), between two
        theta = start + omega * t
        out = encoder().sample(t, theta)
        changed = np.flatnonzero(np.diff(np.r_[0, out.count]) != 0)
        edge_angle = omega * out.edge_time[changed] + start
        origin = round(start / COUNT) if abs(start / COUNT - round(start / COUNT)) < 1e-9 else math.floor(start / COUNT)
        np.testing.assert_allclose(edge_angle / COUNT - origin - out.count[changed], 0.0, atol=0.05)


def test_speed_times_step_back_only_where_the_method_switches_to_the_longer_gate():
    """Each estimate is stamped at the middle of its window; with one edge seen (no estimate yet) at that edge, not at
    the reading's reception time, which lay after the next estimate's window. A step back is left only where the
    period method hands over to the frequency method, whose gate window is the longer (by at most half a gate)."""
    from drivers.encoder import NO_ESTIMATE
    t_read, count, edge, t, omega = card_readings("ramp")
    _, s = estimate(t_read, count, edge)
    assert (s.method == NO_ESTIMATE).any()
    back = np.flatnonzero(np.diff(s.time) < 0)
    assert all(s.method[i] == PERIOD and s.method[i + 1] == FREQUENCY for i in back), [(s.method[i], s.method[i + 1])
                                                                                     for i in back]
    assert np.all(np.diff(s.time)[back] >= -0.5 * GATE_TIME - 1e-12)



@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("probability", [0.01, 0.2, 0.5])
def test_missed_pulses_never_reverse_the_counting(seed, probability):
    """Whole pulses (two edges on one channel) go missing: a count offset, never a change of direction. Two draws on
    neighbouring edges dropped three edges, inverted the channel and made the card count backwards for good (a
    clutch run's encoder read -100 rad/s and 47 disengagements)."""
    t = np.arange(1, 100_001) * 1e-5                       # 1 s at 100 kHz, 15.7 rad/s: 10 240 counts/s
    theta = 15.708 * t
    enc = load_transducer("encoder_1024", np.random.default_rng(seed))
    enc.inject("missed_pulses", at=0.3, until=0.6, probability=probability)
    count = np.concatenate([enc.sample(t[k:k + 1000], theta[k:k + 1000]).count for k in range(0, t.size, 1000)])
    after = t > 0.65
    lost = theta[after] / COUNT - count[after]
    assert np.ptp(lost) <= 2 and 0 < lost.mean()              # a fixed loss, the count still follows the shaft


def test_a_shaft_accelerating_at_power_on_counts_from_the_line_it_stands_on():
    """At t = 0 the shaft stands on a line (the scenes' 0°) but is already accelerating: the angle at power-on,
    extrapolated from the first samples, must land on that line, not a hair below it (a straight line through two
    samples did, −α·t0·t1/2: the card started one count low and every later count read one high)."""
    dt, omega0, alpha = 1e-3, 2 * math.pi, 40.0                  # 1 kHz, 60 rpm, accelerating at 40 rad/s²
    t = dt * (1 + np.arange(3000))
    theta = omega0 * t + 0.5 * alpha * t * t
    out = encoder(errors_enabled=False).sample(t, theta)
    changed = np.flatnonzero(np.diff(np.r_[0, out.count]) != 0)
    te = out.edge_time[changed]
    edge_angle = omega0 * te + 0.5 * alpha * te * te
    np.testing.assert_allclose(edge_angle / COUNT - out.count[changed], 0.0, atol=0.01)   # linear between samples


@pytest.mark.parametrize("seed", range(3))
def test_any_cutting_of_the_samples_into_calls_gives_the_same_card_latches(seed):
    """Jitter, missed pulses and glitches together: one call over 0.5 s and calls of 1 ms, 37 samples and 0.1 s give
    the same counts, edge times, illegal transitions and line levels. Before, the faults drew per call (a Poisson count
    per call, the channels' draws interleaved by call) and a jittered edge could land before the last sample of the
    previous call, after its latch: the runner's chunk changed the recording."""
    t = np.arange(1, 50_001) * 1e-5                        # 0.5 s at 100 kHz
    theta = 0.3 + 12.0 * t + 3.0 * t * t                   # 1900..2200 edges per channel per second
    outs = []
    for size in (t.size, 100, 37, 10_000):
        enc = load_transducer("encoder_1024", np.random.default_rng(seed), jitter_rms="0.2 us")
        enc.inject("missed_pulses", at=0.1, until=0.3, probability=0.05)
        enc.inject("glitches", at=0.2, until=0.45, rate=300.0, width=2e-6)
        parts = [enc.sample(t[k:k + size], theta[k:k + size]) for k in range(0, t.size, size)]
        outs.append({name: np.concatenate([getattr(p, name) for p in parts])
                     for name in ("count", "edge_time", "illegal", "levels")})
    clean = load_transducer("encoder_1024", np.random.default_rng(seed), jitter_rms="0.2 us").sample(t, theta)
    glitched = (t > 0.3) & (t < 0.45)                       # pulses went missing, glitches moved the last edge times:
    assert outs[0]["count"][-1] < clean.count[-1] - 4
    only = load_transducer("encoder_1024", np.random.default_rng(seed), jitter_rms="0.2 us")
    only.inject("glitches", at=0.2, until=0.45, rate=300.0, width=2e-6)
    assert np.any(only.sample(t, theta).edge_time[glitched] != clean.edge_time[glitched])
    for out in outs[1:]:
        for name, value in out.items():
            assert np.array_equal(value, outs[0][name], equal_nan=name == "edge_time"), name
