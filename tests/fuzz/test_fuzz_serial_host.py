"""Fuzzing the host end of the serial protocol (docs/serial-protocol.md): random and mutated byte streams
into the host's frame parser (drivers/serial_framing.py), and fuzzed device answers into the client
(drivers/digiforce_serial.py) on a simulated line with a virtual clock.

No crash, no hang; every refused frame carries a documented reason; every call of the client either
returns a value of its documented shape or raises DigiForceError (an error status) or DigiForceLinkError
(NAKs, corrupt, stale or malformed answers, silence) naming command and port. A call whose answers were
damaged only in ways the block check detects returns exactly what it returns on a clean line.
"""
from __future__ import annotations

import copy
import re
import threading
from typing import Any, Callable
from unittest import mock

import numpy as np
from hypothesis import HealthCheck, example, given, settings, strategies as st

from drivers import digiforce_serial
from drivers import serial_framing as host
from drivers.digiforce_serial import DigiForceClient, DigiForceError, DigiForceLinkError
from firmware_sim.digiforce import DigiForce
from firmware_sim.serial_protocol import framing as dev
from firmware_sim.serial_protocol.commands import Commands

ADDRESS = 1
CORRUPT_REASONS = {"block check": r"block check b(['\"]).*\1 does not match b'..'",   # b"…" when it holds a '
                   "malformed header": r"malformed header b(['\"]).*\1",
                   "control byte": r"control byte 0x[0-9A-F]{2} inside a frame",
                   "too long": rf"frame longer than {host.MAX_DATA} data bytes"}
FUZZ = dict(derandomize=True, database=None, deadline=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
printable = st.text(alphabet=st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=60)


def _measure() -> DigiForce:
    """A unit with a curve of 130 pairs (as in docs/serial-protocol.md §6.5) and a result."""
    unit = DigiForce()
    i = np.arange(140)
    t, x_volts, y_ratio = i * 1e-4, i * 0.025, i * 7.5e-6
    unit.feed(t[:10], x_volts[:10], y_ratio[:10])
    unit.start()
    unit.feed(t[10:], x_volts[10:], y_ratio[10:])
    unit.stop()
    return unit


MEASURED = _measure()


def measured_unit() -> DigiForce:
    """A fresh copy of :data:`MEASURED` (copying is 20 times faster than loading the unit's description)."""
    return copy.deepcopy(MEASURED)


def _answers() -> list[bytes]:
    """Real device answers: one per command of a measured unit (some errors among them)."""
    commands = Commands(measured_unit(), None, threading.Lock())
    requests = [("ID", ""), ("PS", ""), ("PS", "16"), ("PG", "0"), ("CH", ""), ("CB", "1"), ("CT", "0"), ("CY", "0"),
                ("RR", ""), ("RS", ""), ("SS", ""), ("XX", ""), ("TA", "")]
    return [dev.frame(ADDRESS, k % 10, command, commands.execute(command, data))
            for k, (command, data) in enumerate(requests)]


ANSWERS = _answers()


# -- the frame parser ------------------------------------------------------------------------------
def corrupt_reason(reason: str) -> str:
    """The documented reason a refused frame carries (fails on any other text)."""
    for name, pattern in CORRUPT_REASONS.items():
        if re.fullmatch(pattern, reason, re.S):
            return name
    raise AssertionError(f"undocumented rejection reason {reason!r}")


def classify(event: host.Event, stream: bytes) -> str:
    """The outcome of one parser event; checks that an accepted frame is really in the stream."""
    if isinstance(event, host.Frame):
        assert host.encode_frame(event.address, event.seq, event.command, event.data) in stream, event
        return "frame accepted"
    if isinstance(event, host.Corrupt):
        return f"frame refused: {corrupt_reason(event.reason)}"
    return f"handshake {'ACK' if event.ack else 'NAK'} ({'readable' if event.address else 'unreadable'} address)"


answers = st.sampled_from(ANSWERS)
cut_answers = answers.flatmap(lambda f: st.one_of(st.integers(1, len(f) - 1), st.sampled_from([len(f) - 1, len(f) - 2]))
                              .map(lambda k: f[:k]))
handshakes = st.builds(lambda kind, address: kind + address, st.sampled_from([b"\x06", b"\x15"]),
                       st.one_of(st.just(b"01"), st.binary(max_size=2)))
streams = st.lists(st.one_of(answers, answers, cut_answers, handshakes, st.binary(max_size=24)),
                   min_size=1, max_size=5).map(b"".join)


@settings(max_examples=300, **FUZZ)
@given(streams, st.data())
def test_host_parser_on_random_and_mutated_streams(fuzz_cases, mutate, stream, data) -> None:
    """Device answers, handshakes, cut answers and noise, mutated and cut anywhere: the same events
    however cut, every accepted frame verbatim in the stream, every refused one with a documented reason."""
    stream = mutate.apply(stream, data.draw(st.one_of(st.just([]), mutate.mutations(len(stream)))))
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=6)))
    with fuzz_cases.example("serial host: frame parser", limit=60.0) as case:
        whole = host.FrameParser().feed(stream)
        parser, pieces = host.FrameParser(), []
        for a, b in zip([0, *cuts], [*cuts, len(stream)]):
            pieces += parser.feed(stream[a:b])
        assert pieces == whole
        for event in whole:
            case.outcome(classify(event, stream))
        if not whole:
            case.outcome("no event (no complete frame or handshake)")


# -- the client on a fuzzed line -------------------------------------------------------------------
class Clock:
    """Virtual time of the line (s): the client's ``time.monotonic``."""

    def __init__(self) -> None:
        self.now = 0.0

    def monotonic(self) -> float:
        return self.now


class FuzzedLine:
    """A pyserial-like port to a device that answers as docs §3 says (NAK for a refused frame, its stored
    answer again for a NAK or a repeated request), each transmission altered by the next of ``plans``."""

    timeout = 0.01

    def __init__(self, commands: Commands, plans: list[tuple], clock: Clock) -> None:
        self.commands, self.plans, self.clock = commands, list(plans), clock
        self.receiver = dev.Receiver()
        self.queue: list[tuple[float, bytes]] = []      # (arrival time, bytes) on the way to the host
        self.last_key: tuple | None = None
        self.last_answer: bytes | None = None
        self.used: list[str] = []                       # the plans applied, by kind

    # the device
    def write(self, data: bytes) -> int:
        """The host writes: the device receives, answers (docs §3), each transmission altered by a plan."""
        for event in self.receiver.feed(data):
            if event.address != ADDRESS:
                continue
            if isinstance(event, dev.Reply):
                if not event.ack and self.last_answer is not None:
                    self._transmit(self.last_answer)
            elif isinstance(event, dev.Bad):
                self._transmit(dev.handshake(False, ADDRESS))
            else:
                key = (event.seq, event.command, event.data)
                if key != self.last_key:
                    self.last_key = key
                    self.last_answer = dev.frame(ADDRESS, event.seq, event.command,
                                                 self.commands.execute(event.command, event.data))
                self._transmit(self.last_answer)
        return len(data)

    def _transmit(self, data: bytes) -> None:
        plan = self.plans.pop(0) if self.plans else ("clean",)
        self.used.append(plan[0])
        delay, data = alter(data, plan)
        if data:
            self.queue.append((self.clock.now + delay, data))

    # the host's port
    @property
    def in_waiting(self) -> int:
        return sum(len(d) for t, d in self.queue if t <= self.clock.now)

    def read(self, size: int = 1) -> bytes:
        """Up to ``size`` bytes that have arrived; none within the read timeout advances the clock."""
        ready = [d for t, d in self.queue if t <= self.clock.now]
        if not ready:       # nothing arrives within the port's read timeout: time passes
            later = [t for t, _ in self.queue]
            self.clock.now = min([self.clock.now + self.timeout, *later])
            return b""
        self.queue = [(t, d) for t, d in self.queue if t > self.clock.now]
        data = b"".join(ready)
        if len(data) > size:
            self.queue.insert(0, (self.clock.now, data[size:]))
        return data[:size]

    def reset_input_buffer(self) -> None:
        self.queue = [(t, d) for t, d in self.queue if t > self.clock.now]

    def close(self) -> None:
        pass


def alter(data: bytes, plan: tuple) -> tuple[float, bytes]:
    """(delay s, bytes sent) of a device transmission under ``plan``."""
    kind = plan[0]
    if kind == "silence":
        return 0.0, b""
    if kind == "late":
        return plan[1], data
    if kind == "bytes":
        return 0.0, _apply(data, plan[1])
    if kind == "garbage":
        return 0.0, plan[1]
    if data[0] != host.STX:          # a NAK: only silence, delay and byte damage apply
        return 0.0, data
    frame = host.FrameParser().feed(data)[0]
    if kind == "payload":             # a well-framed answer with a damaged data field
        return 0.0, dev.frame(ADDRESS, frame.seq, frame.command, _mutate_text(frame.data, plan[1]))
    if kind == "status":
        return 0.0, dev.frame(ADDRESS, frame.seq, frame.command, plan[1])
    if kind == "stale":
        return 0.0, dev.frame(ADDRESS, (frame.seq + 1) % 10, frame.command, frame.data)
    if kind == "other address":
        return 0.0, dev.frame(ADDRESS + 1, frame.seq, frame.command, frame.data)
    return 0.0, data


def _apply(raw: bytes, ops: list[tuple]) -> bytes:
    """``raw`` edited by ``ops``: ``(flip, at, mask)``, ``(truncate, at, None)``, ``(insert, at, bytes)``,
    ``(delete, at, n)``; offsets past the end wrap around."""
    out = bytearray(raw)
    for kind, at, arg in ops:
        at = at % (len(out) + 1)
        if kind == "flip" and at < len(out):
            out[at] ^= arg
        elif kind == "truncate":
            del out[at:]
        elif kind == "insert":
            out[at:at] = arg
        elif kind == "delete":
            del out[at:at + arg]
    return bytes(out)


def _mutate_text(text: str, ops: list[tuple]) -> str:
    """``text`` edited by ``ops``, kept printable ASCII (a device sending nonsense, well framed)."""
    out = _apply(text.encode(), ops)
    return "".join(chr(b) if 0x20 <= b <= 0x7E else "?" for b in out)


byte_ops = st.lists(st.one_of(st.tuples(st.just("flip"), st.integers(0, 4000), st.integers(1, 255)),
                              st.tuples(st.just("truncate"), st.integers(0, 4000), st.none()),
                              st.tuples(st.just("insert"), st.integers(0, 4000), st.binary(min_size=1, max_size=8)),
                              st.tuples(st.just("delete"), st.integers(0, 4000), st.integers(1, 16))),
                    min_size=1, max_size=3)
text_ops = st.lists(st.one_of(st.tuples(st.just("flip"), st.integers(0, 3000), st.integers(1, 127)),
                              st.tuples(st.just("truncate"), st.integers(0, 3000), st.none()),
                              st.tuples(st.just("insert"), st.integers(0, 3000),
                                        st.sampled_from([b",", b"{", b"}", b"[", b'"', b"=", b"-", b"9", b"NaN"])),
                              st.tuples(st.just("delete"), st.integers(0, 3000), st.integers(1, 16))),
                    min_size=1, max_size=3)
plans = st.one_of(st.just(("clean",)), st.just(("silence",)), st.just(("stale",)), st.just(("other address",)),
                  st.tuples(st.just("late"), st.floats(0.0, 0.5)),
                  st.tuples(st.just("bytes"), byte_ops),
                  st.tuples(st.just("garbage"), st.binary(min_size=1, max_size=40)),
                  st.tuples(st.just("payload"), text_ops),
                  st.tuples(st.just("status"), st.one_of(
                      st.sampled_from(["", "0", "00", "01", "09", "99", "x0", " 0", "00" + "[" * 3000, "00{}"]),
                      printable)))
CALLS: dict[str, Callable[[DigiForceClient], Any]] = {
    "identify": lambda c: c.identify(), "active_program": lambda c: c.active_program(),
    "select_program": lambda c: c.select_program(3), "get_program": lambda c: c.get_program(0),
    "status": lambda c: c.status(), "read_result": lambda c: c.read_result(),
    "read_statistics": lambda c: c.read_statistics(), "read_curve": lambda c: c.read_curve(with_time=True),
    "tare": lambda c: c.tare("x"), "start": lambda c: c.start(), "stop": lambda c: c.stop(),
}
SHAPES: dict[str, Callable[[Any], bool]] = {
    "identify": lambda v: isinstance(v, str), "select_program": lambda v: v is None,
    "active_program": lambda v: isinstance(v, tuple) and len(v) == 2 and all(type(n) is int for n in v),
    "tare": lambda v: v is None, "start": lambda v: v is None, "stop": lambda v: v is None,
    "read_curve": lambda v: len(v.x) == len(v.y) == len(v.t) == v.info["n"] and v.y2 is None,
}


def comparable(value: Any) -> Any:
    """``value`` without what differs between two runs of the same unit (the evaluation's duration)."""
    if isinstance(value, dict):
        return {k: comparable(v) for k, v in value.items() if k != "last_evaluation_time"}
    if isinstance(value, digiforce_serial.Curve):
        return [value.x.tolist(), value.y.tolist(), value.t.tolist(), value.info]
    return value


def call(name: str, plans_: list[tuple]) -> tuple[str, Any, list[str]]:
    """One client call on a fresh measured unit behind a fuzzed line: (outcome, value or exception, plans used)."""
    clock = Clock()
    line = FuzzedLine(Commands(measured_unit(), None, threading.Lock()), plans_, clock)
    with mock.patch.object(digiforce_serial.serial, "serial_for_url", return_value=line), \
            mock.patch.object(digiforce_serial, "time", clock):
        client = DigiForceClient("fuzz://line", baudrate=115200, address=ADDRESS, timeout=0.05, retries=2)
        try:
            return "ok", CALLS[name](client), line.used
        except DigiForceError as exc:
            return "error", exc, line.used
        except DigiForceLinkError as exc:
            return "link", exc, line.used


def gist(text: str) -> str:
    """``text`` with quoted values and numbers masked, cut short: one count per kind of reason."""
    masked = re.sub(r"'[^']*'|\"[^\"]*\"|b'.*|-?\d[\w.+-]*", "...", text)
    return re.split(r": |, got |\(", masked)[0][:40].strip()


def outcome(name: str, kind: str, value: Any) -> str:
    """Checks a call's outcome against its documented forms; returns its count key."""
    if kind == "ok":
        assert SHAPES.get(name, lambda v: isinstance(v, dict))(value), (name, value)
        return "returned"
    text = str(value)
    if kind == "error":
        assert f"status {value.code:02d}" in text and value.command in text, text
        return f"DigiForceError status {value.code:02d}"
    assert "fuzz://line" in text and value.command in text, text
    return f"{type(value).__name__}: {', '.join(sorted({gist(r) for r in value.reasons}))}"


UNHARMED = {"clean", "silence", "late", "stale", "other address", "garbage"}    # the answer's content intact


def detectable(plan: tuple) -> bool:
    """Whether the block check must catch ``plan``: content intact, or one flip, truncation, or one byte
    inserted or deleted (two bytes of equal XOR can cancel out: the protocol's check cannot see that)."""
    if plan[0] in UNHARMED:
        return True
    return plan[0] == "bytes" and len(plan[1]) == 1 and (
        plan[1][0][0] in ("flip", "truncate") or plan[1][0][0] == "insert" and len(plan[1][0][2]) == 1
        or plan[1][0][0] == "delete" and plan[1][0][2] == 1)


@settings(max_examples=250, **FUZZ)
@given(st.sampled_from(sorted(CALLS)), st.lists(plans, min_size=1, max_size=6))
@example("active_program", [("status", "00abc")])               # found: ValueError from unpacking
@example("read_curve", [("status", '00{"n":2}')])                 # found: KeyError 'n_blocks'
@example("read_curve", [("clean",), ("status", "001,2,1,AAAA")])  # found: ValueError from np.frombuffer
@example("status", [("status", "00" + "[" * 3000)])              # found: RecursionError in json.loads
@example("status", [("status", "00[1]")])                        # found: a list accepted as the status
def test_client_on_fuzzed_line(fuzz_cases, name, plans_) -> None:
    """Any call with its answers silenced, delayed, damaged, stale, misaddressed or nonsensical: a value of
    the documented shape or a documented exception naming what is wrong, in bounded (virtual) time."""
    with fuzz_cases.example(f"serial host: client {name}", limit=60.0) as case:
        kind, value, used = call(name, plans_)
        case.outcome(outcome(name, kind, value))
        if kind == "ok" and all(detectable(p) for p in plans_[:len(used)]):
            clean = call(name, [])
            assert clean[0] == "ok" and comparable(value) == comparable(clean[1]), f"{name} accepted a damaged answer"
