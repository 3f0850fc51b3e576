"""Fuzzing the CAN host (drivers/can/host.py) with random frames: every id of data/can/rig.dbc, unknown
and extended ids, classic and FD, random lengths 0..64 (invalid FD lengths too), random bytes, error and
remote frames; and with the demo's real trace damaged frame by frame.

No exception; every bad frame (error frame, unknown or extended id, wrong length) becomes exactly one
LinkEvent of its kind (documented in ``LinkEvent``), a frame of the right length only events of the
kinds a decoded frame can raise; and ``CanHost.receive`` frame by frame and ``CanHost.receive_block``
on the same frames cut into random blocks end in the same state (events, results, curves, live data,
readings, counters).
"""
from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any
from unittest import mock

import can
import cantools
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from drivers.can.host import DBC_PATH, CanHost, LinkEvent
from rig.blockbus import FrameBlock
from rig.recorder import read_recording

DB = cantools.database.load_file(str(DBC_PATH))
DEVICE_IDS = {m.frame_id: m.length for m in DB.messages if "DEVICE" in m.senders}
COMMAND_ID = DB.get_message_by_name("HostCommand").frame_id
DOCUMENTED_KINDS = set(re.search(r"``kind`` is one of ([\w,\s]+);", LinkEvent.__doc__)[1].replace(",", " ").split())
#: what a frame of the right length may raise (run_stopped: a TxStatus whose RunEnded names a cause, any of 16)
DECODED_KINDS = {"sequence_gap", "decode_error", "curve", "result", "run_stopped"}
FUZZ = dict(derandomize=True, database=None, deadline=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


# -- strategies ------------------------------------------------------------------------------------
payload_bytes = st.one_of(st.sampled_from([0, 1, 2, 0x7F, 0x80, 0xFF]), st.integers(0, 255))


@st.composite
def frames(draw: st.DrawFn) -> dict[str, Any]:
    """One frame's fields: a DBC id (often), an unknown or an extended id; the DBC length (often), an FD
    length or any 0..64; bytes biased to 0/1/0xFF so that counters and curve numbers meet; flags."""
    extended = draw(st.integers(0, 9)) == 0
    fid = draw(st.one_of(st.sampled_from(sorted(DEVICE_IDS) + [COMMAND_ID]), st.integers(0, 0x7FF),
                         st.integers(0, 0x1FFFFFFF if extended else 0x7FF)))
    length = draw(st.one_of(st.just(DEVICE_IDS.get(fid, 8)), st.sampled_from(FD_LENGTHS), st.integers(0, 64)))
    kind = draw(st.sampled_from(["data"] * 12 + ["error", "remote"]))
    data = b"" if kind == "remote" else bytes(draw(st.lists(payload_bytes, min_size=length, max_size=length)))
    return {"arbitration_id": fid, "is_extended_id": extended, "data": data, "dlc": len(data) if data else length,
            "is_fd": draw(st.booleans()), "bitrate_switch": draw(st.booleans()),
            "is_error_frame": kind == "error", "is_remote_frame": kind == "remote"}


steps = st.sampled_from([0.0, 1e-4, 1e-4, 1e-3, 0.05, 0.6, 1.5])


def messages(fields: list[dict[str, Any]], gaps: list[float]) -> list[can.Message]:
    """python-can messages of ``fields`` at increasing times (steps ``gaps``, cycled)."""
    t, out = 0.0, []
    for i, f in enumerate(fields):
        t += gaps[i % len(gaps)]
        out.append(can.Message(timestamp=t, channel="fuzz", is_rx=True, **f))
    return out


# -- two hosts, one frame by frame and one by blocks -----------------------------------------------
@pytest.fixture(scope="module")
def make_host():
    """A factory of CanHosts sharing one loaded DBC (loading it per host would dominate the run time)."""
    bus = can.Bus(interface="virtual", channel="fuzz-can-host")
    with mock.patch.object(cantools.database, "load_file", return_value=DB):
        yield lambda: CanHost(bus)
    bus.shutdown()


def _array(a: np.ndarray | None) -> Any:
    """``a`` comparable bit for bit (NaN equal to NaN)."""
    return None if a is None else (a.dtype.str, a.shape, a.tobytes())


def _readings(taken: dict[str, Any]) -> dict[str, Any]:
    """``take_readings``' counters and readings, arrays compared bit for bit."""
    return {"counters": taken["counters"],
            "readings": {name: (_array(t), {k: _array(v) for k, v in values.items()})
                         for name, (t, values) in taken["readings"].items()}}


def state(host: CanHost) -> dict[str, Any]:
    """Everything the host holds after reception (flushed), arrays compared bit for bit."""
    host.flush()
    t, x, y = host.take_live()
    return {"events": host.take_events(), "results": [vars(r) for r in host.take_results()],
            "curves": [{**vars(c), **{k: _array(getattr(c, k)) for k in ("t", "x", "y", "received")}}
                       for c in host.take_curves()],
            "live": [_array(a) for a in (t, x, y)], "readings": _readings(host.take_readings()), "acks": host.acks,
            "drops": host.take_drop_reports(), "status": host.status, "counters": host.counters,
            "missed": host.sequence.missed, "frames": host.frames_received,
            "device_time": host.device_time, "run_ended": host.run_ended}


def expected_kind(msg: can.Message) -> str | None:
    """The one event kind a bad frame must raise (None: a frame the host decodes or ignores)."""
    if msg.is_error_frame:
        return "error_frame"
    if msg.is_extended_id or msg.arbitration_id not in DEVICE_IDS:
        return None if (msg.arbitration_id, msg.is_extended_id) == (COMMAND_ID, False) else "unknown_frame"
    return "bad_length" if len(msg.data) != DEVICE_IDS[msg.arbitration_id] or (len(msg.data) > 8 and not msg.is_fd) \
        else None


def receive_one_by_one(host: CanHost, msgs: list[can.Message], case) -> None:
    """``host.receive`` on each frame; checks the events each one raises and counts them."""
    for msg in msgs:
        before = len(host.events)
        host.receive(msg)
        new = [e for e in host.events[before:]
               if not (e.kind == "result" and "bus time passed" in e.detail)]   # a result timing out
        kind = expected_kind(msg)
        if kind is not None:
            assert [e.kind for e in new] == [kind], (msg, new)
            case.outcome(f"bad frame: {kind}")
        elif (msg.arbitration_id, msg.is_extended_id) == (COMMAND_ID, False):
            assert not new, (msg, new)
            case.outcome("ignored: a HostCommand (the host's own frame)")
        else:
            assert {e.kind for e in new} <= DECODED_KINDS, (msg, new)
            case.outcome("decoded" + "".join(sorted({f", {e.kind}" for e in new})))


def receive_in_blocks(host: CanHost, msgs: list[can.Message], cuts: list[int]) -> None:
    """``host.receive_block`` on ``msgs`` cut into blocks at ``cuts``."""
    bounds = [0, *sorted(cuts), len(msgs)]
    for a, b in zip(bounds, bounds[1:]):
        host.receive_block(FrameBlock.of_messages(msgs[a:b]))


def check_both_ways(make_host, msgs: list[can.Message], cuts: list[int], case) -> None:
    """Frame by frame and in blocks cut at ``cuts``: the same state, events only of documented kinds."""
    one, block = make_host(), make_host()
    receive_one_by_one(one, msgs, case)
    receive_in_blocks(block, msgs, cuts)
    got = state(one)
    assert state(block) == got
    assert {e.kind for e in got["events"]} <= DOCUMENTED_KINDS


@settings(max_examples=150, **FUZZ)
@given(st.lists(frames(), min_size=1, max_size=40), st.lists(steps, min_size=1, max_size=5), st.data())
def test_random_frames(fuzz_cases, make_host, fields, gaps, data) -> None:
    """Random frames of every kind: each bad one exactly one event of its kind, and the same state frame by
    frame as in blocks cut anywhere."""
    msgs = messages(fields, gaps)
    cuts = data.draw(st.lists(st.integers(0, len(msgs)), max_size=5))
    with fuzz_cases.example("CAN host: random frames", limit=60.0) as case:
        check_both_ways(make_host, msgs, cuts, case)


def test_extended_ids_are_unknown_frames(make_host) -> None:
    """Found by the fuzzing: an extended frame with a DBC id (0x51: CommandAck, 0x200: LiveXY) was decoded
    as that 11-bit frame."""
    msgs = [can.Message(timestamp=0.1 * k, arbitration_id=fid, is_extended_id=True, data=bytes(8))
            for k, fid in enumerate((0x051, 0x200, 0x200))]
    one, block = make_host(), make_host()
    for msg in msgs:
        one.receive(msg)
    block.receive_many(msgs)
    for host in (one, block):
        assert [(e.kind, e.frame_id) for e in host.events] == [("unknown_frame", 0x051), ("unknown_frame", 0x200),
                                                              ("unknown_frame", 0x200)]
        assert host.acks == [] and host.take_live()[0].size == 0


@pytest.mark.parametrize("between", [0x7AB, 0x200, 0x302])     # a frame decoded alone, live data, a curve block
def test_a_result_timing_out_inside_a_block_is_released_as_frame_by_frame(make_host, between) -> None:
    """Found by the fuzzing: ``receive_block`` checked the result timeout only at the end of the block, so a
    result whose end marker came late inside one block was complete there and incomplete frame by frame."""
    msgs = [can.Message(timestamp=0.0, arbitration_id=0x310, data=bytes(8), is_extended_id=False),
            can.Message(timestamp=1.5, arbitration_id=between, data=bytes(8), is_extended_id=False),
            can.Message(timestamp=1.6, arbitration_id=0x311, data=bytes([0, 0, 255, 0, 0, 0, 0, 0]),
                        is_extended_id=False)]
    check_both_ways(make_host, msgs, [], SimpleNamespace(outcome=lambda *a: None))
    host = make_host()
    host.receive_many(msgs)
    assert [r.complete for r in host.take_results()] == [False]


@pytest.mark.parametrize("fd", [False, True])
def test_counter_frames_in_a_live_run_unwrap_as_frame_by_frame(make_host, fd) -> None:
    """Counter frames are decoded in bulk with the live data around them; each edge time is unwrapped against the
    device time the live frames before it left, as frame by frame — also when those frames move it by more than
    half the 16.8 s wrap of the edge stamp within one run (ticks of 3.2 s steps, near the live stamp's half wrap)."""
    layout = {m.name: m for m in DB.messages}
    live = layout["LiveXYFD" if fd else "LiveXY"]
    fields = {"Seq": 0, "Tick": 0, **({"Dt": 100, "NPairs": 1} if fd else {}),
              **{s.name: 0 for s in live.signals if s.name[0] in "XY"}}
    msgs, t = [], 0.0
    for k in range(12):
        t += 0.01
        if k % 3 == 2:
            data = layout["Encoder1"].encode({"Seq": k, "Count": 100 * k, "Illegal": 0,
                                              "EdgeTime": round(k * 3.19e6) % 2 ** 24},
                                             scaling=False)
            msgs.append(can.Message(timestamp=t, arbitration_id=layout["Encoder1"].frame_id, data=data,
                                    is_extended_id=False))
        else:
            data = live.encode({**fields, "Seq": k, "Tick": round(k * 3.2e4) % 65536}, scaling=False)
            msgs.append(can.Message(timestamp=t, arbitration_id=live.frame_id, data=data, is_extended_id=False,
                                    is_fd=fd))
    check_both_ways(make_host, msgs, [], SimpleNamespace(outcome=lambda *a: None))
    host = make_host()
    host.receive_block(FrameBlock.of_messages(msgs))
    edges = [row[3] for row in host.take_readings()["counters"]]
    assert len(edges) == 4 and edges[-1] > 16.777216          # unwrapped past the stamp's wrap

# -- the demo's trace, damaged ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def trace(demo_recording: Path) -> list[dict[str, Any]]:
    """The frames of the demo recording's /can/raw (a whole measurement: live data, one curve, its result)."""
    c = read_recording(demo_recording).can_frames
    return [{"timestamp": float(c["t"][i]), "arbitration_id": int(c["id"][i]), "data": c["data"][i],
             "is_extended_id": bool(c["is_extended"][i]), "is_fd": bool(c["is_fd"][i]),
             "is_error_frame": bool(c["error"][i]), "is_rx": c["dir"][i] == "rx"} for i in range(len(c["t"]))]


damage = st.tuples(st.sampled_from(["flip", "length", "error", "id", "extended", "drop", "repeat", "swap"]),
                   st.integers(0, 10**6), st.integers(0, 255))


def damaged(trace: list[dict[str, Any]], edits: list[tuple[str, int, int]]) -> list[can.Message]:
    """The trace with frames damaged: a byte flipped, the length changed, turned into an error frame, the
    id changed or made extended, dropped, repeated or swapped with the next one."""
    frames_ = [dict(f) for f in trace]
    for kind, at, value in edits:
        i = at % len(frames_)
        f = frames_[i]
        if kind == "flip" and f["data"]:
            data = bytearray(f["data"])
            data[value % len(data)] ^= value or 1
            f["data"] = bytes(data)
        elif kind == "length":
            f["data"] = (f["data"] + bytes(64))[:value % 65]
        elif kind == "error":
            f["is_error_frame"] = True
        elif kind == "id":
            f["arbitration_id"] = sorted(DEVICE_IDS)[value % len(DEVICE_IDS)]
        elif kind == "extended":
            f["is_extended_id"] = True
        elif kind == "drop":
            del frames_[i]
        elif kind == "repeat":
            frames_.insert(i, dict(f))
        elif kind == "swap" and i + 1 < len(frames_):
            frames_[i], frames_[i + 1] = frames_[i + 1], frames_[i]
    t = 0.0
    out = []
    for f in frames_:                    # times never go back (a swap or repeat keeps the order of time)
        t = max(t, f["timestamp"])
        out.append(can.Message(channel="fuzz", **{**f, "timestamp": t}))
    return out


@settings(max_examples=30, **FUZZ)
@given(st.lists(damage, max_size=12), st.lists(st.integers(0, 4000), max_size=8))
def test_damaged_demo_trace(fuzz_cases, make_host, trace, edits, cuts) -> None:
    """A real measurement's frames with a few damaged: each bad frame one event, the rest decoded (the curve
    reassembled, or kept incomplete with its problems), the same frame by frame as in blocks."""
    msgs = damaged(trace, edits)
    with fuzz_cases.example("CAN host: damaged demo trace", limit=60.0) as case:
        check_both_ways(make_host, msgs, [min(c, len(msgs)) for c in cuts], case)
