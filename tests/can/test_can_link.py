"""Device node -> host over python-can's virtual bus: curves, results, live budget, gaps, commands."""
from __future__ import annotations

import itertools

import can
import numpy as np
import pytest

from drivers.can import CanHost
from firmware_sim.can_budget import BusTiming
from firmware_sim.can_node import CanNode, X_LSB, Y_LSB

_channels = itertools.count()


@pytest.fixture
def buses():
    channel = f"can-test-{next(_channels)}"
    dev = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
    host = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
    yield dev, host
    dev.shutdown()
    host.shutdown()


def run(node: CanNode, host: CanHost, t_end: float, step: float = 0.05) -> list[can.Message]:
    """Advance the node in steps, feeding every frame to the host; returns the frames."""
    frames = []
    t = node.now
    while t < t_end - 1e-12:
        t = min(t + step, t_end)
        node.advance_to(t)
        while (m := host.bus.recv(0)) is not None:
            frames.append(m)
            host.receive(m)
    return frames


@pytest.fixture
def elements(fakes):
    E = fakes.ElementResult
    return [E("W1", "window", True), E("T1", "threshold", False, "not crossed"), E("E1", "envelope", False, "left band")]


@pytest.fixture
def make_curve(fakes):
    return fakes.make_curve


PV = {"x_max": 0.04, "x_min": 0.0, "y_max": 775.125, "y_min": -31.5, "x_at_y_max": 0.039, "duration": 0.4}


@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_curve_of_4000_pairs_and_result(buses, device, rng, fd, elements, make_curve):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, fd=fd, data_bitrate=2_000_000 if fd else None,
                   heartbeat_period=100.0)
    host = CanHost(host_bus)
    t, x, y = make_curve(rng)
    node.advance_to(0.5)                       # heartbeat at 0, then idle
    device.finish(t, x, y, elements, PV)
    node.advance_to(0.5)                       # the node sees the new result at t = 0.5
    frames = run(node, host, 3.0)
    assert host.events == []
    (curve,) = host.curves()
    assert curve.number == 1 and curve.program == 0 and curve.complete
    np.testing.assert_allclose(curve.x, x, rtol=0, atol=X_LSB / 2 + 1e-15)
    np.testing.assert_allclose(curve.y, y, rtol=0, atol=Y_LSB / 2 + 1e-12)
    np.testing.assert_array_equal(curve.x, np.rint(x / X_LSB) * X_LSB)
    np.testing.assert_allclose(curve.t, t, rtol=0, atol=5e-6)          # uniform: start + i * step
    res = host.results[1]
    assert (res.ok, res.first_fail, res.fail_mask) == (False, 1, 0b110)
    assert res.process_values == pytest.approx(PV, rel=1e-6)      # float32 on the wire
    # the transfer takes exactly the bit budget: the bus is busy back to back from t = 0.5
    timing = BusTiming(500_000, fd=fd, data_bitrate=2e6 if fd else None)
    if fd:
        blocks = -(-4000 // 11)
        expected = blocks * timing.frame_time(0x303, bytes(64), True) + 11 * 135 / 500e3
    else:
        expected = (4000 + 11) * 135 / 500e3    # header, timing, blocks, end, result, 6 process values, end marker
    assert max(m.timestamp for m in frames) == pytest.approx(0.5 + expected, abs=0.5e-6)   # stamps in whole µs
    assert node.pending_frames == 0


def test_curve_transfer_time_from_received_timestamps(buses, device, rng, elements, make_curve):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=100.0)
    t, x, y = make_curve(rng, 1000)
    node.advance_to(0.2)
    device.finish(t, x, y, elements[:1], {})
    node.advance_to(0.2)
    stamps = []
    for t_end in np.arange(0.25, 1.5, 0.05):
        node.advance_to(t_end)
        while (m := host_bus.recv(0)) is not None:
            stamps.append((m.arbitration_id, m.timestamp))
    curve_stamps = [s for fid, s in stamps if fid >= 0x300]
    # header + timing + 1000 blocks + end + result + end marker = 1005 frames of 135 bits at 1 Mbit/s, back to back
    assert len(curve_stamps) == 1005
    np.testing.assert_allclose(np.diff(curve_stamps), 135e-6, rtol=1e-9)
    assert curve_stamps[-1] == pytest.approx(0.2 + 1005 * 135e-6, abs=1e-9)


def test_live_stream_is_decimated_to_fit_500k(buses, device, rng):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, live_share=0.5, heartbeat_period=0.1)
    host = CanHost(host_bus)
    fs, chunk = 10_000.0, 0.1
    frames = []
    sent_t, sent_x, sent_y = [], [], []
    for k in range(10):
        t = (np.arange(1000) + k * 1000) / fs
        x, y = 0.01 * np.sin(2 * np.pi * 5 * t), 500 * np.cos(2 * np.pi * 3 * t) + rng.normal(0, 1, t.size)
        factor = node.publish_live(t, x, y)
        sent_t.append(t[::factor]), sent_x.append(x[::factor]), sent_y.append(y[::factor])
        node.advance_to((k + 1) * chunk)
        while (m := host_bus.recv(0)) is not None:
            frames.append(m)
            host.receive(m)
    node.advance_to(1.1)                               # the last queued frames and a status frame
    while (m := host_bus.recv(0)) is not None:
        frames.append(m)
        host.receive(m)
    # 0.5 x 0.1 s / 270 us = 185 frames per chunk -> every 6th of 1000 samples: 167 kept per chunk
    assert factor == 6
    lt, lx, ly = host.take_live()
    assert lt.size == sum(m.arbitration_id == 0x200 for m in frames) == node.live_sent == 1670
    assert node.live_dropped == 10_000 - 1670
    # what arrived is the decimated stream, to the quantisation and the 100 us tick
    st, sx, sy = (np.concatenate(a) for a in (sent_t, sent_x, sent_y))
    np.testing.assert_allclose(lt, st, atol=1e-9)
    np.testing.assert_allclose(lx, sx, atol=X_LSB / 2 + 1e-15)
    np.testing.assert_allclose(ly, sy, atol=Y_LSB / 2 + 1e-12)
    # the device reports its drops in the status frame
    assert host.counters["live_dropped"] == node.live_dropped
    # never more bits than the wire carries: frames do not overlap and the load is <= 1
    timing = BusTiming(500_000)
    ends = np.array([m.timestamp for m in frames])
    durations = np.array([timing.frame_time(m.arbitration_id, bytes(m.data)) for m in frames])
    assert np.all(np.diff(ends) >= durations[1:] - 1e-12)
    assert durations.sum() <= ends[-1] - (ends[0] - durations[0]) + 1e-12
    assert host.events == []


def test_fd_live_carries_11_pairs_per_frame(buses, device):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, fd=True, data_bitrate=2_000_000, heartbeat_period=1.0)
    host = CanHost(host_bus)
    t = np.arange(2000) / 10_000.0
    x, y = 1e-3 * np.arange(2000) % 0.3, np.linspace(-900, 900, 2000)
    assert node.publish_live(t, x, y) == 1           # 10 kHz fits at 2 Mbit/s data phase
    run(node, host, 0.25)
    lt, lx, ly = host.take_live()
    assert node.live_dropped == 0 and lt.size == 2000
    np.testing.assert_allclose(lt, t, atol=1e-9)
    np.testing.assert_allclose(ly, y, atol=Y_LSB / 2 + 1e-12)


@pytest.mark.parametrize("fd", [False, True])
def test_live_above_the_tick_rate_goes_out_on_the_tick_grid_with_exact_stamps(buses, device, fd):
    """At 20 kHz (pairs 50 µs apart) only the samples on the 100 µs Tick grid are sent: every stamp exact and
    increasing across frames and chunks (CAN FD stamped every frame's first pair to the nearest tick, which put it
    before the previous frame's last pair and stopped the run); the others are counted as not sent."""
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, fd=fd, data_bitrate=4_000_000 if fd else None,
                   heartbeat_period=1.0, live_share=1.0)
    host = CanHost(host_bus)
    fs, sent = 20_000.0, []
    for k in range(4):
        t = (1 + np.arange(2000) + k * 2000) / fs
        factor = node.publish_live(t, 1e-3 * np.sin(t), 100 * np.cos(t))
        assert factor % 2 == 0                          # a whole number of grid steps
        sent.append(t[np.abs(t / 1e-4 - np.rint(t / 1e-4)) < 1e-9][::factor // 2])
        run(node, host, 0.1 * (k + 1))
    run(node, host, 0.6)
    lt, _, _ = host.take_live()
    np.testing.assert_allclose(lt, np.concatenate(sent), rtol=0, atol=1e-9)
    assert np.all(np.diff(lt) > 0) and lt.size == node.live_sent and node.live_dropped == 8000 - lt.size


def test_dropped_frame_is_a_sequence_gap(buses, device, rng, elements, make_curve):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=100.0)
    host = CanHost(host_bus)
    t, x, y = make_curve(rng, 500)
    device.finish(t, x, y, elements[:1], {})
    node.advance_to(0.0)                                # the node picks up the result at t = 0
    node.advance_to(1.0)
    frames = []
    while (m := host_bus.recv(0)) is not None:
        frames.append(m)
    blocks = [i for i, m in enumerate(frames) if m.arbitration_id == 0x302]
    lost = frames.pop(blocks[100])                      # the wire loses block 100
    for m in frames:
        host.receive(m)
    (gap,) = host.events_of("sequence_gap")
    assert (gap.frame_id, gap.count) == (0x302, 1) and gap.time == pytest.approx(frames[blocks[100]].timestamp)
    assert host.sequence.missed == {0x302: 1}
    assert host.curves() == []
    (bad,) = host.incomplete_curves()
    assert not bad.received[100] and bad.received.sum() == 499
    assert any("1 of 500 pairs missing" in e.detail for e in host.events_of("curve"))
    assert lost.data[0] == 100 % 256
    assert host.results[1].ok                            # the result after the curve still arrived


def test_malformed_frames_are_reported_and_nothing_is_lost(buses, device, rng, elements, make_curve):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=100.0)
    host = CanHost(host_bus)
    t, x, y = make_curve(rng, 300)
    device.finish(t, x, y, elements[:1], {"y_max": 1.5})
    node.advance_to(0.0)                                # the node picks up the result at t = 0
    node.advance_to(1.0)
    frames = []
    while (m := host_bus.recv(0)) is not None:
        frames.append(m)
    frames.insert(50, can.Message(arbitration_id=0x7A5, data=b"\x01\x02", is_extended_id=False))
    frames.insert(80, can.Message(arbitration_id=0x302, data=b"\x00\x01\x02", is_extended_id=False))
    frames.insert(90, can.Message(arbitration_id=0x311, data=bytes([0, 1, 200, 0, 0, 0, 0, 0]), is_extended_id=False))
    frames.insert(95, can.Message(is_error_frame=True))
    for m in frames:
        host.receive(m)
    kinds = sorted(e.kind for e in host.events)
    assert kinds == ["bad_length", "decode_error", "error_frame", "unknown_frame"]
    assert "0x7A5" in host.events_of("unknown_frame")[0].detail
    assert "3 data bytes" in host.events_of("bad_length")[0].detail
    (curve,) = host.curves()
    np.testing.assert_allclose(curve.y, y, atol=Y_LSB / 2 + 1e-12)
    assert host.results[1].process_values == {"y_max": 1.5}


def test_commands_reach_the_device(buses, device):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, heartbeat_period=0.1)
    host = CanHost(host_bus)
    node.advance_to(0.01)
    host.select_program(3)
    host.tare("y")
    host.start()
    node.advance_to(0.2)
    host.stop()
    host.reset_statistics()
    host.select_program(40)                       # the device refuses
    host.send_command("identify")
    node.advance_to(0.3)
    node.advance_to(0.31)                         # acks queued at 0.3 go out after it
    host.poll()
    assert device.calls == [("select_program", 3), ("tare", "y"), ("start", 0.2), ("stop", 0.3),
                            ("reset_statistics",), ("identify",)]
    assert [(a["host_seq"], a["status"]) for a in host.acks] == [(0, "done"), (1, "done"), (2, "done"), (3, "done"),
                                                                 (4, "done"), (5, "rejected"), (6, "done")]
    assert host.status["program"] == 3 and host.status["state"] == "idle" and host.status["errors"] == 0
    assert "program 40" in node.rx_errors[0]
    with pytest.raises(ValueError, match="tare channel 'z'"):
        host.tare("z")
    with pytest.raises(ValueError, match="unknown CAN host command"):
        host.send_command("explode")


def test_encoders_and_torque(buses, device):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, heartbeat_period=0.1)
    host = CanHost(host_bus)
    node.advance_to(20.0)                              # heartbeats bring the host to device time ~20 s
    host.poll()
    node.publish_reading("Encoder1", 20.0, {"Count": 123456, "EdgeTime": 19.9871234})   # wraps at 16.78 s
    node.publish_reading("Encoder2", 20.0, {"Count": -42, "EdgeTime": 18.5})
    node.publish_reading("Torque", 20.0005, {"Torque": 212.3456, "BrakeForce": 1503.2})  # 1 mN·m steps, ±524 N·m
    node.publish_reading("StaticRig", 20.0005, {"Angle": 99.0})             # beyond ±10.49 rad: clipped, counted
    node.advance_to(20.01)
    host.poll()
    readings = host.take_readings()
    (e1, e2) = readings["counters"]
    assert (e1[0], e1[2], e2[0], e2[2]) == ("Encoder1", 123456, "Encoder2", -42)
    assert e1[3] == pytest.approx(19.987123, abs=1e-6) and e2[3] == pytest.approx(18.5, abs=1e-6)
    assert list(readings["readings"]) == ["Torque", "StaticRig"]
    (tq_t, tq), (st_t, st) = readings["readings"]["Torque"], readings["readings"]["StaticRig"]
    assert tq_t == pytest.approx([20.0005], abs=1e-4) and st_t == pytest.approx([20.0005], abs=1e-4)
    assert {k: v.item() for k, v in tq.items()} == pytest.approx({"Torque": 212.3456, "BrakeForce": 1503.2}, abs=5e-3)
    assert {k: v.item() for k, v in st.items()} == pytest.approx({"Angle": 10.48574, "Strain": 0.0})
    assert node.clipped == 1
    assert host.events == []


def test_edge_time_of_a_shaft_at_rest_stays_past_half_a_wrap(buses, device):
    """An encoder whose shaft stands still keeps sending the time of its last edge, however old: past half of the
    16.78 s EdgeTime wrap the host must not move it a wrap into the future (it keeps the edge's time while the raw
    stamp is unchanged); a new edge after the long rest is unwrapped against the device time as before."""
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, heartbeat_period=0.1)
    host = CanHost(host_bus)
    for t in np.arange(0.5, 30.0, 0.5):               # at rest since 0.2 s: 29.8 s, beyond one whole wrap
        node.advance_to(t)
        node.publish_reading("Encoder1", t, {"Count": 7, "EdgeTime": 0.2})
        host.poll()
    node.advance_to(30.5)
    node.publish_reading("Encoder1", 30.5, {"Count": 8, "EdgeTime": 30.4})          # moves again
    node.advance_to(31.0)
    host.poll()
    edges = np.array([row[3] for row in host.take_readings()["counters"]])
    assert edges.size == 60
    assert np.all(edges[:-1] == pytest.approx(0.2, abs=1e-6)) and edges[-1] == pytest.approx(30.4, abs=1e-6)
    assert host.events == []


def test_bad_calls_are_named(buses, device):
    node = CanNode(buses[0], device)
    with pytest.raises(ValueError, match="uniformly spaced"):
        node.publish_live(np.array([0.0, 0.1, 0.3]), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match=">= 2 samples"):
        node.publish_live(np.array([0.0]), np.zeros(1), np.zeros(1))
    with pytest.raises(ValueError, match="not a device reading message"):
        node.publish_reading("CurveBlock", 0.0, {"X0": 1.0})
    with pytest.raises(ValueError, match="Torque has no signal 'Torq'.*Torque, BrakeForce"):
        node.publish_reading("Torque", 0.0, {"Torq": 1.0})
    node.advance_to(1.0)
    with pytest.raises(ValueError, match="back in time"):
        node.advance_to(0.5)
    with pytest.raises(ValueError, match="live_share"):
        CanNode(buses[0], device, live_share=0)


def test_live_frames_stuck_behind_higher_priority_traffic_go_stale(buses, device):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, live_max_age=0.05, heartbeat_period=100.0)
    t = np.arange(1000) / 10_000.0
    factor = node.publish_live(t, np.zeros(1000), np.zeros(1000))
    for _ in range(300):                       # then 600 encoder frames = 162 ms of wire time from t = 0
        for encoder in ("Encoder1", "Encoder2"):
            node.publish_reading(encoder, 0.0, {"Count": 1, "EdgeTime": 0.0})
    node.advance_to(0.5)
    ids = []
    while (m := host_bus.recv(0)) is not None:
        ids.append(m.arbitration_id)
    # every live frame was ready before 0.1 s and could not start before 0.162 s > 0.1 + 0.05
    assert factor == 6 and ids.count(0x200) == 0 and node.live_sent == 0
    assert node.live_dropped == 1000 and node.live_stale == 167     # 833 decimated, 167 sent as frames went stale
    assert ids.count(0x180) == ids.count(0x181) == 300


def test_explicitly_published_result_is_not_sent_twice(buses, device, rng, elements, make_curve):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=100.0)
    host = CanHost(host_bus)
    t, x, y = make_curve(rng, 200)
    node.publish_measurement(0.0, device.finish(t, x, y, elements[:1], {}))
    run(node, host, 1.0)
    assert len(host.curves()) == 1 and node.curves_measured == 1 and host.events == []


def test_non_uniform_sample_times_are_sent_per_pair(buses, device, rng, elements):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=0.1)
    host = CanHost(host_bus)
    run(node, host, 30.0, step=0.5)                    # device time past one TStart wrap (16.8 s)
    t = 29.0 + np.cumsum(rng.uniform(1e-5, 5e-4, 1001))      # e.g. sampling by delta-X
    x, y = np.linspace(0, 0.01, t.size), np.linspace(0, 100, t.size)
    node.publish_measurement(30.0, device.finish(t, x, y, elements[:1], {}))
    frames = run(node, host, 31.0)
    assert sum(m.arbitration_id == 0x304 for m in frames) == 501
    (curve,) = host.curves()
    np.testing.assert_allclose(curve.t, t, rtol=0, atol=5e-6)
    assert host.events == []


def _frames_until(node: CanNode, host_bus, t_end: float) -> list[can.Message]:
    """Frames on the wire up to ``t_end`` (s); a new result is picked up at the node's present time."""
    node.advance_to(node.now)
    node.advance_to(t_end)
    frames = []
    while (m := host_bus.recv(0)) is not None:
        frames.append(m)
    return frames


def test_result_is_complete_only_with_its_end_marker_and_every_value(buses, device, rng, elements, make_curve):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=100.0)
    t, x, y = make_curve(rng, 100)
    device.finish(t, x, y, elements[:1], PV)
    frames = _frames_until(node, host_bus, 1.0)
    values = [m for m in frames if m.arbitration_id == 0x311]
    assert len(values) == len(PV) + 1 and values[-1].data[2] == 255      # the values, then the end marker
    whole = CanHost(None)
    for m in frames:
        whole.receive(m)
    assert whole.results[1].complete and whole.results[1].missing == [] and whole.events == []
    # the wire loses the y_min and duration frames: the result is released, marked incomplete, naming them
    lost = {values[3].data[2], values[5].data[2]}
    host = CanHost(None)
    host.receive_many([m for m in frames if not (m.arbitration_id == 0x311 and m.data[2] in lost)])
    res = host.results[1]
    assert not res.complete and sorted(res.missing) == ["duration", "y_min"]
    assert set(res.process_values) == set(PV) - {"y_min", "duration"}
    (event,) = host.events_of("result")
    assert event.count == 2 and "duration, y_min" in event.detail or "y_min, duration" in event.detail


def test_result_without_end_marker_is_released_incomplete_never_silently(buses, device, rng, elements, make_curve):
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=0.1)
    t, x, y = make_curve(rng, 100)
    device.finish(t, x, y, elements[:1], PV)
    first = _frames_until(node, host_bus, 0.5)
    device.finish(t + 0.5, x, y, elements[:1], PV)
    second = _frames_until(node, host_bus, 5.0)
    is_end = lambda m: m.arbitration_id == 0x311 and m.data[2] == 255      # noqa: E731
    # (a) the next curve's header arrives first: released at once, all values kept, marked incomplete
    host = CanHost(None)
    for m in [m for m in first if not is_end(m)] + second:
        host.receive(m)
    taken = host.take_results()
    assert [r.number for r in taken] == [1, 2] and not taken[0].complete and taken[1].complete
    from drivers.can.host import PROCESS_VALUES
    assert taken[0].process_values == pytest.approx(PV, rel=1e-6)
    assert set(taken[0].missing) == set(PROCESS_VALUES.values()) - set(PV)    # unknown which were sent: all absent
    assert "no end marker before the header of curve 2" in host.events_of("result")[0].detail
    # (b) nothing follows: released after result_timeout s of bus time (heartbeats keep coming) ...
    host = CanHost(None, result_timeout=1.0)
    for m in [m for m in first + second if not is_end(m) or m.data[1] != 1]:
        if m.arbitration_id in (0x300, 0x301, 0x302, 0x305, 0x310, 0x311) and m.timestamp > 0.5:
            continue                                         # the second curve never comes
        host.receive(m)
    (late,) = host.take_results()
    assert late.number == 1 and not late.complete and "1 s of bus time passed" in host.events_of("result")[0].detail
    # (c) ... or at the end of reception
    host = CanHost(None, result_timeout=100.0)
    for m in [m for m in first if not is_end(m)]:
        host.receive(m)
    assert host.take_results() == []
    host.flush()
    (last,) = host.take_results()
    assert last.number == 1 and not last.complete
    (event,) = host.events_of("result")                 # named by the Result frame (it said HostCommand, 0x050)
    assert event.frame_id == 0x310 and event.count == len(last.missing)
    assert f"{len(last.missing)} of {len(PROCESS_VALUES)} process values missing" in event.detail


def test_curve_start_is_exact_for_a_backlog_longer_than_a_counter_wrap(buses, device, rng, elements, make_curve):
    """A curve measured at 1 s reaches the host at ~30 s (device time from heartbeats): 29 s of backlog is
    more than the 16.78 s wrap of the 24-bit TStart, yet the 40-bit start (TStartHigh) places it exactly."""
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=0.1)
    host = CanHost(host_bus)
    run(node, host, 30.0, step=0.5)
    t, x, y = make_curve(rng, 500)
    node.publish_measurement(30.0, device.finish(t + 1.0, x, y, elements[:1], {}))
    run(node, host, 31.0)
    (curve,) = host.curves()
    assert host.device_time > 30.0
    np.testing.assert_allclose(curve.t, t + 1.0, rtol=0, atol=5e-6)
    # ... and far beyond: 5 days of device time (the 32-bit heartbeat stamp in ms and 40-bit start hold it)
    late = 5 * 86_400.0 + 0.25
    node2 = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=0.1, t0=late - 1.0)
    host2 = CanHost(host_bus)
    node2.publish_measurement(late, device.finish(t + late - 0.2, x, y, elements[:1], {}))
    run(node2, host2, late + 1.0)
    (curve2,) = host2.curves()
    np.testing.assert_allclose(curve2.t, t + late - 0.2, rtol=0, atol=5e-6)


@pytest.mark.parametrize("one_by_one", [True, False])
def test_more_than_8_bytes_in_a_classic_frame_is_malformed_not_decoded(buses, one_by_one):
    """A CurveBlockFD of the DBC's 64 bytes sent as a classic frame (is_fd false) cannot exist on a CAN bus:
    reported as bad_length naming CAN FD, never decoded, in the frame-by-frame and the block path alike."""
    from rig.blockbus import FrameBlock
    _, host_bus = buses
    host = CanHost(host_bus)
    bad = can.Message(arbitration_id=0x303, data=bytes(64), is_extended_id=False, is_fd=False, timestamp=0.1)
    if one_by_one:
        host.receive(bad)
    else:
        host.receive_block(FrameBlock.of_messages([bad, bad]))
    events = host.events_of("bad_length")
    assert events and all("classic (non-FD) frame; more than 8 need CAN FD" in e.detail for e in events)
    assert len(events) == (1 if one_by_one else 2) and host.counters.get("curve", 0) == 0


def test_curve_numbers_count_on_past_the_16_bit_wrap(buses, device, rng, elements, make_curve):
    """CurveNo is 16-bit on the wire: curves 65535, 65536, 65537 (after 7.3 h at 150 rpm) arrive as 65535, 0, 1
    and the host counts on, curves and results alike, so the recording's numbers stay unique and increasing."""
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=100.0)
    host = CanHost(host_bus)
    device.number = 65534
    for k in range(3):
        t, x, y = make_curve(rng, 100)
        node.publish_measurement(float(k), device.finish(t + k, x, y, elements[:1], {}))
        run(node, host, k + 1.0)
    assert [c.number for c in host.curves()] == [65535, 65536, 65537]
    assert [r.number for r in host.take_results()] == [65535, 65536, 65537]
    assert host.events == []


def test_a_curve_longer_than_the_time_field_is_counted_as_clipped(buses, device, rng, elements):
    """A non-uniformly sampled curve of 11 s: its CurveTimes offsets past 10.48575 s go out saturated; CurveEnd's
    Clipped counts them (it counted only values: the host took the curve as whole, times up to 0.5 s off)."""
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=100.0)
    host = CanHost(host_bus)
    t = np.sort(rng.uniform(0.2, 11.2, 300))                  # non-uniform: the times go in CurveTimes
    x, y = np.linspace(0.0, 0.04, t.size), np.zeros(t.size)
    node.advance_to(11.3)
    device.finish(t, x, y, elements[:1], {})
    node.advance_to(11.3)
    run(node, host, 12.0)
    (curve,) = host.curves()
    late = int(np.count_nonzero(t - t[0] > 10.48575 + 5e-6))
    assert late > 0 and curve.clipped == late
    np.testing.assert_allclose(curve.t[t - t[0] <= 10.48], t[t - t[0] <= 10.48], atol=6e-6)


def test_encoder_counts_unwrap_past_24_bits_and_carry_the_cards_illegal_transitions(buses, device):
    """Count is 24 bits on the wire (room for the card's 8-bit illegal-transition count): the host unwraps it by the
    change from the reading before — through 2^24 and through negative counts; the illegal count comes as sent (the
    unit saturates it at 255: a wrap could hide any number)."""
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=500_000, heartbeat_period=0.1)
    host = CanHost(host_bus)
    counts = [-5, 1_000, 8_000_000, 16_000_000, 16_777_300, 17_000_000, 25_000_000]   # 2^24 = 16 777 216
    illegal = [0, 0, 3, 200, 255, 255, 255]
    for k, (c, n) in enumerate(zip(counts, illegal)):
        t = 0.1 * (k + 1)
        node.advance_to(t)
        node.publish_reading("Encoder1", t, {"Count": c, "Illegal": n, "EdgeTime": t})
        node.advance_to(t + 0.01)
        host.poll()
    rows = host.take_readings()["counters"]
    assert [r[2] for r in rows] == counts and [r[4] for r in rows] == illegal


def test_a_stopped_run_discards_its_queue_and_its_last_status_says_why(buses, device, rng, elements, make_curve):
    """abort(): the unit stops sending what it has queued (counted, its wire time in the final Backlog) and sends
    its final status at once: RunEnded with the StopCause named, read with cantools and the DBC alone; the host
    makes it a run_stopped event naming the cause. Nothing follows, and a second stop or an unknown cause is not
    sent."""
    import cantools
    from firmware_sim.can_node import DBC_PATH
    db = cantools.database.load_file(str(DBC_PATH))
    dev_bus, host_bus = buses
    node = CanNode(dev_bus, device, bitrate=1_000_000, heartbeat_period=100.0)
    host = CanHost(host_bus)
    node.advance_to(0.2)
    device.finish(*make_curve(rng, 4000), elements[:1], {})
    run(node, host, 0.25)                             # a 4000-pair curve takes about 0.55 s of wire: mid-transfer
    queued, backlog = node.pending_frames, node.backlog_time
    assert queued > 1000 and backlog > 0.1
    with pytest.raises(ValueError, match="unknown stop cause 'Lunch'.*HostStalled"):
        node.abort("Lunch")
    assert node.abort("HostStalled") == 3 and node.frames_discarded == queued and node.pending_frames == 0
    frames = []
    while (m := host_bus.recv(0)) is not None:
        frames.append(m)
        host.receive(m)
    assert [db.get_message_by_frame_id(m.arbitration_id).name for m in frames] == \
        ["Heartbeat", "StatusCounters", "TxStatus"]
    status = db.decode_message(frames[-1].arbitration_id, frames[-1].data)
    assert status["RunEnded"] == 1 and str(status["StopCause"]) == "HostStalled"
    assert status["Backlog"] == pytest.approx(backlog, abs=1e-3)
    assert host.run_ended and host.stop_cause == "HostStalled"
    assert host.events_of("sequence_gap") == []        # discarded frames took no Seq numbers
    stopped = host.events_of("run_stopped")
    assert len(stopped) == 1 and stopped[0].detail.startswith("HostStalled: the host stopped reading")
    assert node.abort("Fault") == 0 and host_bus.recv(0) is None            # the run has ended: nothing more
    node.advance_to(1.0)
    assert host_bus.recv(0) is None
