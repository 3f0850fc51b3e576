"""The fast CAN paths against their references: layout decoding and packed encoding against cantools,
batch reception against frame-by-frame reception, bulk draining against ``recv``."""
from __future__ import annotations

import copy
import itertools

import can
import cantools
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from drivers.can import CanHost
from drivers.can.drain import drain, drain_block
from drivers.can.host import DBC_PATH
from drivers.can.layout import FrameLayout, supports
from firmware_sim.can_node import CanNode, _Packing
from rig.blockbus import FrameBlock

DB = cantools.database.load_file(str(DBC_PATH))
LAYOUT_MESSAGES = [m for m in DB.messages if supports(m)]
_channels = itertools.count()


def test_every_frame_but_the_multiplexed_float_one_has_a_layout():
    assert {m.name for m in DB.messages} - {m.name for m in LAYOUT_MESSAGES} == {"ResultValue"}
    with pytest.raises(ValueError, match="ResultValue"):
        FrameLayout(DB.get_message_by_name("ResultValue"))


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(LAYOUT_MESSAGES), st.data())
def test_layout_decoding_equals_cantools_for_random_payloads(message, data):
    rows = data.draw(st.lists(st.binary(min_size=message.length, max_size=message.length), min_size=1, max_size=6))
    layout = FrameLayout(message)
    batch = layout.decode(np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(len(rows), -1))
    for i, row in enumerate(rows):
        expected = message.decode(row, decode_choices=False, scaling=False)
        assert layout.decode_one(row) == expected
        assert {k: int(v[i]) for k, v in batch.items()} == expected


def test_layout_rejects_wrong_lengths():
    layout = FrameLayout(DB.get_message_by_name("LiveXY"))
    with pytest.raises(ValueError, match="LiveXY.*7 data bytes"):
        layout.decode_one(bytes(7))
    with pytest.raises(ValueError, match=r"LiveXY.*\(n, 8\)"):
        layout.decode(np.zeros((3, 7), dtype=np.uint8))


class _Idle:
    last_result = None


@pytest.fixture(scope="module")
def node():
    """One idle FD node; tests clear its queue before use."""
    bus = can.Bus(interface="virtual", channel=f"fast-{next(_channels)}", preserve_timestamps=True)
    yield CanNode(bus, _Idle(), bitrate=1_000_000, fd=True)
    bus.shutdown()


@settings(max_examples=30, deadline=None)
@given(st.sampled_from(["LiveXY", "CurveBlock", "LiveXYFD", "CurveBlockFD", "CurveTimes", "Torque"]),
       st.integers(1, 5), st.data())
def test_packed_encoding_equals_cantools_classic_and_fd(node, name, n, data):
    message = node._msg[name]
    cols = {}
    for sig in message.signals:
        if sig.name == "Seq":
            continue
        lo, hi = (-(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1) if sig.is_signed else (0, (1 << sig.length) - 1)
        cols[sig.name] = np.array(data.draw(st.lists(st.integers(lo, hi), min_size=n, max_size=n)), dtype=np.int64)
    rows = _Packing(message).pack(cols, n)
    assert rows.shape == (n, message.length)
    for i in range(n):
        expected = message.encode({"Seq": 0, **{k: int(v[i]) for k, v in cols.items()}}, scaling=False, strict=True)
        assert rows[i].tobytes() == expected


def test_frame_blocks_round_trip_python_can_messages():
    msgs = [can.Message(timestamp=1.5, arbitration_id=0x302, is_extended_id=False, data=b"\x01\x02"),
            can.Message(timestamp=1.6, arbitration_id=0x18FF0001, is_extended_id=True, data=bytes(range(64)),
                        is_fd=True, bitrate_switch=True, error_state_indicator=True),
            can.Message(timestamp=1.7, is_error_frame=True)]
    block = FrameBlock.of_messages(msgs)
    back = block.messages()
    assert all(a.equals(b, timestamp_delta=0.0) for a, b in zip(msgs, back)) and len(back) == 3
    assert FrameBlock.concat([block.take(slice(0, 1)), block.take(slice(1, None))]).messages()[1].equals(msgs[1])


def test_block_bus_delivers_blocks_and_single_frames_to_every_other_bus():
    channel = f"blockbus-{next(_channels)}"
    with can.Bus(interface="blockbus", channel=channel) as tx, can.Bus(interface="blockbus", channel=channel) as a, \
            can.Bus(interface="blockbus", channel=channel) as b:
        msgs = [can.Message(timestamp=0.1 * i, arbitration_id=i, data=[i], is_extended_id=False) for i in range(5)]
        tx.send_block(FrameBlock.of_messages(msgs[:3]))
        tx.send(msgs[3])
        tx.send(msgs[4])
        assert tx.recv(0) is None                                  # a sender does not hear itself
        first = a.recv(0)
        assert first.equals(msgs[0], timestamp_delta=0.0, check_channel=False)
        rest = drain_block(a)                                      # the rest of the first block, then the singles
        assert [m.arbitration_id for m in rest.messages()] == [1, 2, 3, 4]
        assert [m.arbitration_id for m in drain(b)] == [0, 1, 2, 3, 4] and a.recv(0) is None


def test_a_block_bus_that_is_not_read_drops_its_oldest_blocks_beyond_what_it_keeps():
    """overflow(): a receiver that does not read keeps at most about ``keep`` frames (whole blocks, the newest), the
    rest counted as dropped; what it then reads is the newest frames in order."""
    channel = f"blockbus-{next(_channels)}"
    with can.Bus(interface="blockbus", channel=channel) as tx, can.Bus(interface="blockbus", channel=channel) as rx:
        for k in range(10):                       # ten blocks of 100 frames, ids 100k..100k+99
            tx.send_block(FrameBlock.of_messages([can.Message(timestamp=k + i * 1e-3, arbitration_id=100 * k + i,
                                                              is_extended_id=True) for i in range(100)]))
        first = rx.recv(0)                        # one frame of the first block taken: its rest waits
        assert first.arbitration_id == 0 and rx.pending == 999
        assert rx.overflow(1000) == 0 and rx.overflow(250) == 699 and rx.dropped == 699 and rx.pending == 300
        assert rx.overflow(300) == 0              # 300 - 100 < 300: the oldest block stays
        ids = [m.arbitration_id for m in drain(rx)]
        assert ids == list(range(700, 1000)) and rx.pending == 0


def _frames(fd: bool, seed: int) -> list[can.Message]:
    """Traffic of a node: live data, two curves, heartbeats, with damage: a lost frame, a wrong length, an
    error frame, an unknown id, a curve block without its header."""
    from types import SimpleNamespace
    rng = np.random.default_rng(seed)
    channel = f"fast-traffic-{next(_channels)}"
    with can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as dev, \
            can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as rx:
        device = SimpleNamespace(last_result=None, status=lambda: {"state": "measuring", "program": 1})
        device.state_at = lambda t: ("measuring", device.last_result)
        node = CanNode(dev, device, bitrate=500_000, fd=fd, data_bitrate=2_000_000 if fd else None)
        for k in range(2):
            t = node.now + (1 + np.arange(400)) * 1e-4
            node.publish_live(t, rng.normal(0, 0.01, 400), rng.normal(0, 50, 400))
            device.last_result = SimpleNamespace(
                number=k + 1, program=1, ok=bool(k), elements=[SimpleNamespace(ok=bool(k))],
                process_values={"x_max": 0.04}, curve=SimpleNamespace(t=t[:300], x=rng.normal(0, 0.01, 300),
                                                                       y=rng.normal(0, 50, 300)))
            node.advance_to(float(t[-1]))
        node.advance_to(node.now + 0.5)
        frames = drain(rx)
    live = [i for i, m in enumerate(frames) if m.arbitration_id in (0x200, 0x201)]
    del frames[live[len(live) // 2]]                              # a lost live frame: sequence gap
    frames[60] = can.Message(arbitration_id=frames[60].arbitration_id, data=bytes(3), is_extended_id=False,
                             timestamp=frames[60].timestamp)       # wrong length
    frames.insert(80, can.Message(is_error_frame=True, timestamp=frames[80].timestamp))
    frames.insert(90, can.Message(arbitration_id=0x7AB, data=bytes(8), is_extended_id=False,
                                  timestamp=frames[90].timestamp))
    block = next(m for m in frames if m.arbitration_id in (0x302, 0x303))
    frames.insert(5, copy.deepcopy(block))                        # before its header, and a repeated Seq
    return frames


def _state(host: CanHost):
    t, x, y = host.take_live()
    return (t.tolist(), x.tolist(), y.tolist(), host.events, host.frames_received, host.device_time,
            dict(host.sequence.missed), host.status, host.counters,
            [(c.number, c.complete, c.problems, c.x.tolist(), c.y.tolist(), None if c.t is None else c.t.tolist(),
              c.received.tolist()) for c in host.assembler.done],
            {k: vars(v) for k, v in host.results.items()})


@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_batch_reception_equals_frame_by_frame(fd):
    frames = _frames(fd, seed=4)
    one, many = CanHost(None), CanHost(None)
    for m in frames:
        one.receive(m)
    for i in range(0, len(frames), 97):                          # batches cut anywhere
        many.receive_many(frames[i:i + 97])
    a, b = _state(one), _state(many)
    assert a == b
    kinds = {e.kind for e in one.events}
    assert {"sequence_gap", "bad_length", "error_frame", "unknown_frame", "curve"} <= kinds
    assert len(one.assembler.done) >= 2 and len(a[0]) > 50


def test_drain_takes_everything_in_order_and_respects_limit_and_filters():
    channel = f"fast-drain-{next(_channels)}"
    with can.Bus(interface="virtual", channel=channel) as tx, can.Bus(interface="virtual", channel=channel) as rx, \
            can.Bus(interface="virtual", channel=channel) as ref:
        assert drain(rx) == []
        for i in range(10):
            tx.send(can.Message(arbitration_id=i, data=[i], is_extended_id=False))
        assert [m.arbitration_id for m in drain(rx, limit=4)] == [0, 1, 2, 3]
        assert [m.arbitration_id for m in drain(rx)] == list(range(4, 10))
        while ref.recv(0) is not None:
            pass
        for bus in (rx, ref):                                   # filtered: python-can's own recv semantics
            bus.set_filters([{"can_id": 0, "can_mask": 0x7F8, "extended": False}])
        for i in range(10):
            tx.send(can.Message(arbitration_id=i, data=[i], is_extended_id=False))
        expected = []
        while (m := ref.recv(0)) is not None:
            expected.append(m.arbitration_id)
        assert [m.arbitration_id for m in drain(rx)] == expected == list(range(8))


def test_drain_block_of_a_streaming_bus_ends():
    """A bus read frame by frame whose frames keep coming (a served run's socketcand stream, faster than the host
    reads) is drained in bounded pieces: one drain took 96 % of a run, nothing recorded meanwhile (an audit)."""
    from drivers.can.drain import DRAIN_LIMIT

    class Streaming(can.BusABC):
        def __init__(self):
            super().__init__(channel="stream")
            self.sent = 0

        def _recv_internal(self, timeout):
            self.sent += 1
            return can.Message(arbitration_id=0x100, data=bytes(8), timestamp=self.sent * 1e-4), False

        def send(self, msg, timeout=None):
            pass

    bus = Streaming()
    first, second = drain_block(bus), drain_block(bus)
    assert len(first) == len(second) == DRAIN_LIMIT == bus.sent // 2
    assert first.timestamp[-1] < second.timestamp[0]             # in order, nothing lost between the pieces
