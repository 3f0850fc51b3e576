"""Fuzzing the device end of the serial protocol (docs/serial-protocol.md): random and mutated byte
streams into the frame receiver (firmware_sim/serial_protocol/framing.py), random requests into the
command dispatcher (commands.py) on a real DigiForce, and both through a running SerialDevice on TCP.

No crash, no hang; every rejection is explained: a frame the receiver refuses carries one of the
documented reasons (and is NAKed when it reads as the device's address), a request the dispatcher
refuses gets a documented error status with a printable message, and nothing the host sends makes the
device report an internal fault (status 09).
"""
from __future__ import annotations

import copy
import json
import re
import socket
import string
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings, strategies as st

from drivers import serial_framing as host
from firmware_sim.digiforce import DigiForce
from firmware_sim.digiforce.errors import DigiForceError
from firmware_sim.serial_device import SerialDevice
from firmware_sim.serial_protocol import framing as dev
from firmware_sim.serial_protocol.commands import Commands

ADDRESS = 1
COMMANDS = ["ID", "PS", "PG", "PW", "ST", "SP", "TA", "CH", "CB", "CT", "CY", "RR", "RS", "RZ", "SS"]
SCHEMAS = Path(__file__).resolve().parents[2] / "docs" / "schemas"
PAYLOAD_SCHEMAS = {"PG": "program", "CH": "curve-header", "RR": "result", "RS": "statistics", "SS": "status"}
#: a bytes repr is quoted b'…', or b"…" when it holds a single quote
BAD_REASONS = {"block check": r"block check b(['\"]).*\1 != b'..'", "malformed header": r"malformed header b(['\"]).*\1",
               "control byte": r"control byte 0x[0-9A-F]{2} inside a frame",
               "too long": rf"frame longer than {dev.MAX_DATA} data bytes"}
FUZZ = dict(derandomize=True, database=None, deadline=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.large_base_example])


# -- strategies ------------------------------------------------------------------------------------
def _schema(command: str) -> jsonschema.Draft202012Validator:
    """The validator of ``command``'s JSON payload (docs/schemas)."""
    doc = json.loads((SCHEMAS / f"serial-{PAYLOAD_SCHEMAS[command]}.schema.json").read_text(encoding="utf-8"))
    return jsonschema.Draft202012Validator(doc)


VALIDATORS = {command: _schema(command) for command in PAYLOAD_SCHEMAS}
FEATURES = {   # y2, teach scaling, a time stop, a reference threshold, every element kind, limits
    "channels": {"x": {"cutoff": 0, "scaling": {"mode": "teach", "points": [[0.0, 0.0], [5.0, 0.1]]}},
                 "y": {"cutoff": "500 Hz"}, "y2": {"input": "bridge", "range": 2e-3, "unit": "N", "cutoff": 0,
                                                  "scaling": {"electrical": 1.5e-3, "engineering": 1000.0}}},
    "control": {"stop": {"mode": "time", "duration": 1.0}},
    "reference": {"mode": "y_threshold", "y_threshold": 1.0},
    "elements": [
        {"kind": "window", "name": "W", "x_min": 0.04, "x_max": 0.06, "y_min": 0.0, "y_max": 1000.0,
         "entry": "ignore", "exit": "ignore", "check": "y_max"},
        {"kind": "trapezoid", "name": "T", "start": 0.01, "end": 0.02, "lower": [0, 0], "upper": [1000, 1000]},
        {"kind": "threshold", "name": "H", "axis": "y", "value": 100.0, "range": [None, 0.08]},
        {"kind": "envelope", "name": "E", "channel": "y2", "part": "forward",
         "references": [{"x": [0.0, 0.1], "y": [0.0, 700.0]}], "dx": 0.001, "dy": 50.0}],
    "limits": {"y_max": [0.0, 1000.0], "x_max": [None, 0.2], "W.x_entry": [0.0, 0.1]}}


def _base_program() -> dict[str, Any]:
    """Program 1 of a unit given every feature, normalised by the unit: what the fuzzed programs start from."""
    unit = DigiForce()
    unit.set_program(1, FEATURES)
    return unit.get_program(1)


BASE_PROGRAM = _base_program()
printable = st.text(alphabet=st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=40)
numbers = st.one_of(st.sampled_from(["", "0", "1", "3", "15", "16", "-1", "+3", " 3", "3 ", "1e3", "0x1", "1_0",
                                     "99999999999999999999", "abc", "x", "y", "y2", "xy"]),
                    st.integers(-10**6, 10**6).map(str))
quantities = st.one_of(st.sampled_from(["", " ", "(", "2 mm)", "1/0 Hz", "3 m / 0", "9**9**9 Hz", "2**10 Hz",
                                        "nan mm", "inf N", "1e999 Hz", "500 Hz", "-3 mm", "2 parsec", "1 \\ mm"]),
                       printable)
json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30), quantities,
              st.floats(allow_nan=False, allow_infinity=False)),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(printable, inner, max_size=3)),
    max_leaves=8)


def _paths(obj: Any, prefix: tuple = ()) -> list[tuple]:
    """Every path (keys and indices) into ``obj``, the root included."""
    out = [prefix]
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, prefix + (i,))
    return out


def _edit(program: Any, path: tuple, action: str, value: Any) -> Any:
    """``program`` with the node at ``path`` replaced, deleted or given a new key ``value[0]``."""
    if not path:
        return value if action == "replace" else program
    parent = program
    for key in path[:-1]:
        parent = parent[key]
    if action == "replace":
        parent[path[-1]] = value
    elif action == "delete":
        del parent[path[-1]]
    elif isinstance(parent[path[-1]], dict):
        parent[path[-1]][str(value)[:12]] = value
    return program


@st.composite
def program_json(draw: st.DrawFn) -> str:
    """A program object, from the unit's own with random edits (values, deletions, new keys), as JSON text;
    sometimes with a non-finite token."""
    program = json.loads(json.dumps(BASE_PROGRAM))
    for _ in range(draw(st.integers(0, 4))):
        paths = _paths(program)
        path = draw(st.sampled_from(paths))
        program = _edit(program, path, draw(st.sampled_from(["replace", "delete", "add"])), draw(json_values))
    text = json.dumps(program, separators=(",", ":"))
    if draw(st.integers(0, 3)) == 0:
        text = re.sub(r"(?<=:)-?\d+(\.\d+)?", draw(st.sampled_from(["NaN", "Infinity", "-Infinity", "1e999"])),
                      text, count=1)
    return text


program_writes = st.tuples(st.one_of(st.sampled_from("0139"), numbers), program_json()).map(",".join)
request_data = st.one_of(numbers, printable, program_writes, st.tuples(numbers, printable).map(",".join))
commands = st.one_of(st.sampled_from(COMMANDS), st.sampled_from(COMMANDS),
                     st.text(alphabet=string.ascii_uppercase, min_size=2, max_size=2))
requests = st.one_of(st.tuples(commands, request_data), st.tuples(st.just("PW"), program_writes))


def raw_frame(address: bytes, seq: bytes, command: bytes, data: bytes, good_check: bool) -> bytes:
    """``STX address seq command data ETX BB`` with any field bytes; the check right or off by one."""
    body = address + seq + command + data + b"\x03"
    check = dev.check(body) if good_check else b"%02X" % (int(dev.check(body), 16) ^ 1)
    return b"\x02" + body + check


frames = st.builds(
    raw_frame,
    st.one_of(st.just(b"01"), st.sampled_from([b"02", b"FE", b"00", b"FF", b"0a", b"1"]),
              st.binary(min_size=2, max_size=2)),
    st.one_of(st.integers(0, 9).map(lambda d: b"%d" % d), st.binary(min_size=1, max_size=1)),
    st.one_of(commands.map(str.encode), st.binary(max_size=3)),
    st.one_of(request_data.map(str.encode), st.binary(max_size=40)),
    st.integers(0, 9).map(lambda k: k > 0))
handshakes = st.builds(lambda kind, address: kind + address, st.sampled_from([b"\x06", b"\x15"]),
                       st.one_of(st.just(b"01"), st.binary(min_size=0, max_size=2)))
cut_frames = frames.flatmap(lambda f: st.one_of(st.integers(1, len(f) - 1),       # lost the rest: anywhere,
                                                st.sampled_from([len(f) - 1, len(f) - 2])   # in the check
                                                ).map(lambda k: f[:k]))
pieces = st.lists(st.one_of(frames, frames, cut_frames, handshakes, st.binary(max_size=24)),
                  min_size=1, max_size=6).map(b"".join)


# -- the receiver ----------------------------------------------------------------------------------
def bad_reason(reason: str) -> str:
    """The documented reason a refused frame carries (fails on any other text)."""
    for name, pattern in BAD_REASONS.items():
        if re.fullmatch(pattern, reason, re.S):
            return name
    raise AssertionError(f"undocumented rejection reason {reason!r}")


def classify(event: dev.Request | dev.Bad | dev.Reply, stream: bytes) -> str:
    """The outcome of one receiver event; checks that an accepted request is really in the stream."""
    own = "own address" if event.address == ADDRESS else "other/unreadable address"
    if isinstance(event, dev.Request):
        assert dev.frame(event.address, event.seq, event.command, event.data) in stream, event
        return f"request accepted ({own})"
    if isinstance(event, dev.Bad):
        return f"frame refused: {bad_reason(event.reason)} ({'NAK' if own == 'own address' else 'ignored'})"
    return f"handshake {'ACK' if event.ack else 'NAK'} ({own})"


def as_host_would(event: dev.Request | dev.Bad | dev.Reply) -> tuple:
    """``event`` in terms both receivers share (docs §2 gives one set of receiving rules for both ends)."""
    if isinstance(event, dev.Request):
        return "frame", event.address, event.seq, event.command, event.data
    if isinstance(event, dev.Bad):
        return "refused", event.address, bad_reason(event.reason)
    return "handshake", event.ack, event.address


def host_events(stream: bytes) -> list[tuple]:
    """What the host's receiver (drivers.serial_framing) makes of ``stream``, in the same terms."""
    out = []
    for e in host.FrameParser().feed(stream):
        if isinstance(e, host.Frame):
            out.append(("frame", e.address, e.seq, e.command, e.data))
        elif isinstance(e, host.Corrupt):
            reason = "block check" if e.reason.startswith("block check") else bad_reason(e.reason)
            out.append(("refused", e.address, reason))
        else:
            out.append(("handshake", e.ack, e.address))
    return out


@settings(max_examples=400, **FUZZ)
@given(pieces, st.data())
def test_receiver_on_random_and_mutated_streams(fuzz_cases, mutate, stream, data) -> None:
    """Any byte stream, cut anywhere: events only of the three kinds, the same however it is cut and the
    same as the host's receiver makes of it, every accepted request present verbatim in the stream,
    every refused frame with a documented reason."""
    ops = data.draw(st.one_of(st.just([]), mutate.mutations(len(stream))))
    stream = mutate.apply(stream, ops)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=6)))
    with fuzz_cases.example("serial device: frame receiver", limit=60.0) as case:
        whole = dev.Receiver().feed(stream)
        rx, pieces_events = dev.Receiver(), []
        for a, b in zip([0, *cuts], [*cuts, len(stream)]):
            pieces_events += rx.feed(stream[a:b])
        assert pieces_events == whole
        assert [as_host_would(e) for e in whole] == host_events(stream)
        for event in whole:
            case.outcome(classify(event, stream))
        if not whole:
            case.outcome("no event (no complete frame or handshake)")


def test_stx_in_the_check_characters_starts_a_new_frame() -> None:
    """Found by the fuzzing: the device took an STX for a check character, lost the next request and NAKed."""
    request = host.encode_frame(ADDRESS, 2, "SS")
    for cut in (b"\x02011ID\x03", b"\x02011ID\x033"):
        assert dev.Receiver().feed(cut + request) == [dev.Request(ADDRESS, 2, "SS", "")]


# -- the dispatcher --------------------------------------------------------------------------------
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


def gist(text: str) -> str:
    """``text`` with quoted values and numbers masked, cut short: one count per kind of message."""
    return re.split(r",? got | \(", re.sub(r"'[^']*'|\"[^\"]*\"|-?\d[\w.+-]*", "...", text))[0][:60]


def check_response(command: str, response: str) -> str:
    """Checks one response data field; returns its outcome (status and, when refused, why)."""
    assert re.fullmatch(r"\d\d", response[:2]), response[:40]
    status, text = int(response[:2]), response[2:]
    assert status in (0, 1, 2, 3, 4, 5), f"{command}: status {status:02d} {text!r}"
    if status:
        assert text and len(text) <= 200 and text.isascii() and text.isprintable(), (command, text)
        return f"status {status:02d}: {gist(text)}"
    if command in VALIDATORS:
        payload = json.loads(text, parse_constant=lambda token: pytest.fail(f"{command}: token {token}"))
        errors = list(VALIDATORS[command].iter_errors(payload))
        assert not errors, f"{command} payload: {errors[0].message}"
    return f"status 00 {command}"


def still_works(commands_: Commands, unit: DigiForce) -> None:
    """After any requests the unit answers status and programs, and measures with the active program (or
    refuses, explained)."""
    for command, data in (("SS", ""), ("PG", ""), ("PG", "3")):
        assert commands_.execute(command, data).startswith("00"), command
    t = 0.1 + 1e-4 * np.arange(400)          # after the 140 samples of measured_unit()
    x, y = np.linspace(0, 1, 400), np.linspace(0, 1e-3, 400)
    check_response("ST", commands_.execute("ST", ""))
    try:
        unit.feed(t, x, y, y)
    except DigiForceError:
        pass
    for command in ("SP", "RR", "CH", "RS"):
        check_response(command, commands_.execute(command, ""))


@settings(max_examples=300, **FUZZ)
@given(st.lists(requests, min_size=1, max_size=4))
@example([("PW", '0,{"channels":{"x":null}}')])        # found: AttributeError, status 09
@example([("PW", '0,{"channels":{"x":{"cutoff":"1/0 Hz"}}}'), ("PW", '0,{"name":{"x":1}}')])
def test_dispatcher_on_random_requests(fuzz_cases, requests) -> None:
    """Random commands and data (program numbers, block indices, PW programs with random edits and
    non-finite tokens) on a measured unit: a documented status for each, schema-valid JSON payloads,
    never an internal fault, and the unit keeps working."""
    unit = measured_unit()
    commands_ = Commands(unit, None, threading.Lock())
    with fuzz_cases.example("serial device: command dispatcher", limit=60.0) as case:
        for command, data in requests:
            response = case.within(case.HANG, commands_.execute, command, data)
            case.outcome(check_response(command, response))
        still_works(commands_, unit)


def test_a_power_tower_in_a_program_is_refused_at_once() -> None:
    """Found by the fuzzing: ``"9**9**9 Hz"`` kept the device busy computing a huge integer (in pint) for
    hours; now refused at once. Run in a subprocess, so that a regression fails instead of hanging."""
    code = ("import threading; from firmware_sim.digiforce import DigiForce; "
            "from firmware_sim.serial_protocol.commands import Commands; "
            "print(Commands(DigiForce(), None, threading.Lock()).execute("
            "'PW', '0,{\"channels\":{\"x\":{\"cutoff\":\"9**9**9 Hz\"}}}'))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.stdout.startswith("03") and "cutoff" in done.stdout, done.stdout + done.stderr


# -- a running device on TCP -----------------------------------------------------------------------
class Line:
    """The host's end of the device's TCP transport: raw bytes in, parsed events out."""

    def __init__(self, url: str) -> None:
        host_, port = url.removeprefix("socket://").rsplit(":", 1)
        self.sock = socket.create_connection((host_, int(port)), timeout=5)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.parser = host.FrameParser()

    def exchange(self, stream: bytes, n_events: int, limit: float) -> list[host.Event]:
        """Send ``stream``; the first ``n_events`` events the device sends back (fails after ``limit`` s)."""
        self.sock.sendall(stream)
        events: list[host.Event] = []
        deadline = time.monotonic() + limit
        while len(events) < n_events:
            self.sock.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                chunk = self.sock.recv(65536)
            except TimeoutError:
                chunk = b""
            assert chunk, f"device silent after {len(events)} of {n_events} answers (hang or lost answer)"
            events += self.parser.feed(chunk)
        assert len(events) == n_events, f"device sent {len(events)} answers, expected {n_events}"
        return events


class Expected:
    """What the device must send for the events its receiver makes of a stream (docs §2–3): NAK for a
    refused frame read as its address, the stored response again for a NAK (none before the first
    response) or for a repeated request, a response with the request's seq and command otherwise."""

    def __init__(self) -> None:
        self.last_key: tuple | None = None
        self.last_frame: host.Frame | None = None

    def answers(self, events: list) -> list[tuple]:
        """The transmissions due for the receiver events of a stream: ``(kind, request or reason)``."""
        out, last = [], self.last_frame is not None
        for e in events:
            if e.address != ADDRESS:
                continue
            if isinstance(e, dev.Reply):
                if not e.ack and last:
                    out.append(("again", None))
            elif isinstance(e, dev.Bad):
                out.append(("nak", e.reason))
            else:
                out.append(("response", e))
                last = True
        return out

    def check(self, expected: list[tuple], got: list[host.Event], case) -> None:
        """Checks what the device sent against :meth:`answers`, counting the outcomes."""
        for (kind, what), event in zip(expected, got):
            if kind == "nak":
                assert event == host.Handshake(False, ADDRESS), (what, event)
                case.outcome(f"NAK for a refused frame: {bad_reason(what)}")
                continue
            assert isinstance(event, host.Frame), (kind, what, event)
            if kind == "again":
                assert event == self.last_frame
                case.outcome("last response sent again (host NAK)")
                continue
            key = (what.seq, what.command, what.data)
            assert (event.seq, event.command) == (what.seq, what.command), (what, event)
            if key == self.last_key:
                assert event == self.last_frame
                case.outcome("repeated request answered from store")
            else:
                case.outcome(check_response(what.command, event.data))
            self.last_key, self.last_frame = key, event


@pytest.fixture(scope="module")
def served():
    """A real DigiForce served on TCP at 4 Mbaud, the host's end of the line, and the answer model."""
    device = SerialDevice(measured_unit(), "tcp://127.0.0.1:0", baudrate=4_000_000, address=ADDRESS)
    with device:
        line = Line(device.port)
        try:
            yield device, line, Expected()
        finally:
            line.sock.close()


@settings(max_examples=200, **FUZZ)
@given(pieces, st.data())
def test_served_device_on_fuzzed_line(fuzz_cases, mutate, served, stream, data) -> None:
    """A running SerialDevice answers a random, mutated stream (then a status request) exactly as the
    protocol says, stays up and never sends an internal fault."""
    device, line, model = served
    stream = mutate.apply(stream, data.draw(st.one_of(st.just([]), mutate.mutations(len(stream)))))
    probe = host.encode_frame(ADDRESS, data.draw(st.integers(0, 9)), "SS")
    events = dev.Receiver().feed(stream + probe)
    assert isinstance(events[-1], dev.Request) and events[-1].command == "SS"
    with fuzz_cases.example("serial device: served over TCP", limit=60.0) as case:
        expected = model.answers(events)
        got = line.exchange(stream + probe, len(expected), limit=60.0)
        model.check(expected, got, case)
