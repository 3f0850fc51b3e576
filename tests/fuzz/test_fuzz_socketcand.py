"""Fuzzing the socketcand server (firmware_sim/socketcand_server.py, docs/can-protocol.md "Across processes:
socketcand"): random and mutated ``< ... >`` command streams, cut anywhere, into its line splitting and its
``send`` parser, and into a running server on 127.0.0.1; the frame lines it sends, parsed by python-can's
socketcand client parser.

No crash, the server stays up; every command is answered as documented (``< echo >``, ``< ok >``,
``< error unknown command >``, ``< error could not open bus >`` and the connection closed) or, for data
outside ``< >`` and a ``send`` it cannot parse, logged in ``errors`` without a reply; a ``send`` it
accepts reaches the bus as exactly the frame written, and a listening client parses it back.
"""
from __future__ import annotations

import re
import socket
import time

import can
import pytest
from can.interfaces.socketcand.socketcand import convert_ascii_message_to_can_message as client_parse
from hypothesis import HealthCheck, given, settings, strategies as st

from firmware_sim.socketcand_server import SocketcandServer, frame_line, parse_send, split_commands

CHANNEL = "fuzz-socketcand"
FUZZ = dict(derandomize=True, database=None, deadline=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# -- strategies ------------------------------------------------------------------------------------
good_sends = st.one_of(
    st.builds(lambda fid, data: f"send {fid:03X} {len(data)} {' '.join(f'{b:02X}' for b in data)}".strip(),
              st.integers(0, 0x7FF), st.binary(max_size=8)),
    st.builds(lambda fid, data: f"send {fid:08X} {len(data)} {' '.join(f'{b:02x}' for b in data)}".strip(),
              st.integers(0, 0x1FFFFFFF), st.binary(max_size=8)))
fields = st.one_of(st.sampled_from(["", "-1", "+1", "0x1", "1_0", "zz", "800", "1FFFFFFF", "20000000", "9", "100",
                                    "00000000000", "-01", "7ff"]), st.text(alphabet="0123456789ABCDEFabcdefx-+_ ",
                                                                           max_size=9))
odd_sends = st.builds(lambda parts: " ".join(["send", *parts]), st.lists(fields, max_size=11))


@st.composite
def twisted_sends(draw: st.DrawFn) -> str:
    """A good send with one field twisted, its width kept: a sign, ``0x`` or ``_`` in place of digits."""
    parts = draw(good_sends).split()
    i = draw(st.integers(1, len(parts) - 1))
    field = parts[i].rjust(3, "0")
    parts[i] = draw(st.sampled_from(["+", "-", "0x", "0_", " "])) + field[2:] if len(field) > 2 else field
    return " ".join(parts)
others = st.sampled_from(["echo", f"open {CHANNEL}", "open nope", "open", "rawmode", "bcmmode", "controlmode",
                          "isotpmode", "fdsend 123 1 00", "add 1 0 123 8 11 22 33 44 55 66 77 88", "statistics 1000",
                          "frame 123 1.0 00", "ECHO", " echo ", "", "hi", "ok"])
bodies = st.one_of(good_sends, odd_sends, others, others, st.text(max_size=20))
pieces = st.one_of(bodies.map(lambda b: f"< {b} >"), bodies.map(lambda b: f"<{b}>"),
                   st.sampled_from(["<", ">", "< ", " >", "\n", "<<", ">>"]),
                   st.text(alphabet=st.characters(max_codepoint=0x7F), max_size=12))
streams = st.lists(pieces, min_size=1, max_size=8).map("".join)
opened_streams = st.tuples(st.sampled_from(["", f"< open {CHANNEL} >", f"< open {CHANNEL} >< rawmode >"]),
                           st.lists(st.one_of(pieces, good_sends.map(lambda b: f"< {b} >")), min_size=1, max_size=8)
                           ).map(lambda p: p[0] + "".join(p[1]))


# -- the line splitting and the send parser --------------------------------------------------------
@settings(max_examples=400, **FUZZ)
@given(streams, st.lists(st.integers(0, 200), max_size=6))
def test_split_commands_cut_anywhere(fuzz_cases, stream, cuts) -> None:
    """Text cut anywhere gives the same commands as whole, each the stripped text between a ``<`` and the
    next ``>`` (or None for text without ``<``), and the rest holds no ``>``."""
    with fuzz_cases.example("socketcand: line splitting", limit=60.0) as case:
        whole, rest = split_commands(stream)
        got, buffer = [], ""
        for a, b in zip([0, *sorted(cuts)], [*sorted(cuts), len(stream)]):
            new, buffer = split_commands(buffer + stream[a:b])
            got += new
        assert (got, buffer) == (whole, rest) and ">" not in rest
        expected = [None if "<" not in seg else seg.split("<", 1)[1].strip() for seg in stream.split(">")[:-1]]
        assert whole == expected
        for body in whole:
            case.outcome("outside < >" if body is None else "command")


HEX = re.compile(r"[0-9A-Fa-f]+")


@settings(max_examples=400, **FUZZ)
@given(st.one_of(good_sends, twisted_sends(), odd_sends, bodies))
def test_parse_send_accepts_exactly_the_frames_written(fuzz_cases, body) -> None:
    """A send is accepted only with hex fields, an id of 8 digits (extended, ≤ 0x1FFFFFFF) or of any other number
    (standard, ≤ 0x7FF: socketcand reads ``50`` as 0x050) and as many bytes as its length (at most 8), and gives
    exactly that frame; anything else is a ValueError naming it."""
    with fuzz_cases.example("socketcand: send parser", limit=60.0) as case:
        parts = body.split()
        try:
            msg = parse_send(body)
        except ValueError as exc:
            assert "send" in str(exc) and repr(body) in str(exc), str(exc)
            case.outcome(f"refused: {str(exc).split(':')[0]}")
            return
        assert parts[0] == "send" and all(HEX.fullmatch(p) for p in parts[1:]), body
        assert msg.is_extended_id == (len(parts[1]) == 8)
        assert msg.arbitration_id == int(parts[1], 16) <= (0x1FFFFFFF if msg.is_extended_id else 0x7FF)
        assert bytes(msg.data) == bytes(int(b, 16) for b in parts[3:]) and int(parts[2], 16) == len(msg.data) <= 8
        case.outcome("accepted")


@pytest.mark.parametrize("body", ["send -01 1 00", "send 0x1 1 00", "send 1_0 1 00", "send 123 +1 00",
                                  "send 123 1 -0"])
def test_send_fields_with_sign_prefix_or_underscore_are_refused(body) -> None:
    """Found by the fuzzing: ``int(..., 16)`` accepted ``-01`` (a frame with id -1 went on the bus), ``0x1``,
    ``1_0`` and ``+1``; socketcand's fields are hex digits."""
    with pytest.raises(ValueError, match="non-hex"):
        parse_send(body)


@settings(max_examples=300, **FUZZ)
@given(st.integers(0, 0x1FFFFFFF), st.booleans(), st.binary(max_size=8),
       st.one_of(st.floats(0, 2e9), st.integers(0, 2**31).map(float), st.floats(0, 10)))
def test_frame_lines_parse_back_in_the_python_can_client(fuzz_cases, fid, extended, data, stamp) -> None:
    """Every ``< frame ... >`` line the server sends parses back in python-can's client to the same id,
    kind of id and data, and the time stamp to within 1 µs (and a float's resolution)."""
    msg = can.Message(arbitration_id=fid if extended else fid & 0x7FF, is_extended_id=extended, data=data,
                      timestamp=stamp)
    with fuzz_cases.example("socketcand: frame lines into python-can", limit=60.0) as case:
        back = client_parse(frame_line(msg))
        assert (back.arbitration_id, back.is_extended_id, bytes(back.data)) == \
               (msg.arbitration_id, msg.is_extended_id, bytes(msg.data))
        assert abs(back.timestamp - stamp) <= 1e-6 + 4e-16 * stamp
        case.outcome(f"{'extended' if extended else 'standard'} frame, {len(data)} bytes")


# -- a running server ------------------------------------------------------------------------------
class Expected:
    """What a server must answer to ``bodies`` on a fresh connection (docs/can-protocol.md): replies in
    order, how many commands it records in ``errors``, the frames it puts on the bus, whether it closes."""

    def __init__(self, bodies: list[str | None]) -> None:
        self.replies: list[str] = []
        self.errors = 0
        self.frames: list[can.Message] = []
        self.closed = False
        opened = raw = False
        for body in bodies:
            if body is None:
                self.errors += 1
            elif body == "echo":
                self.replies.append("< echo >")
            elif body.startswith("open ") and not opened:
                opened = body[5:].strip() == CHANNEL
                self.replies.append("< ok >" if opened else "< error could not open bus >")
                if not opened:
                    self.errors += 1
                    self.closed = True
                    return
            elif body == "rawmode" and opened and not raw:
                raw = True
                self.replies.append("< ok >")
            elif body.startswith("send ") and opened:
                try:
                    self.frames.append(parse_send(body))
                except ValueError:
                    self.errors += 1
            else:
                self.replies.append("< error unknown command >")
                self.errors += 1


def read_until(sock: socket.socket, done, limit: float) -> str:
    """Text from ``sock`` until ``done(text)`` or the peer closes; fails after ``limit`` s (a hang)."""
    text, deadline = "", time.monotonic() + limit
    while not done(text):
        sock.settimeout(max(0.01, deadline - time.monotonic()))
        try:
            chunk = sock.recv(65536)
        except TimeoutError:
            raise AssertionError(f"no answer within {limit} s; got {text!r}") from None
        if not chunk:
            break
        text += chunk.decode("ascii")
    return text


def connect(port: int) -> socket.socket:
    """A client connection that got the server's ``< hi >``."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=5)
    assert read_until(sock, lambda t: ">" in t, 5.0) == "< hi >"
    return sock


@pytest.fixture(scope="module")
def server():
    """A server on 127.0.0.1 (no grace time) and a client listening in raw mode."""
    with SocketcandServer(CHANNEL, grace=0.0) as srv:
        listener = connect(srv.port)
        listener.sendall(f"< open {CHANNEL} >< rawmode >".encode())
        assert read_until(listener, lambda t: t.count(">") == 2, 5.0) == "< ok >< ok >"
        try:
            yield srv, listener
        finally:
            listener.close()


@settings(max_examples=120, **FUZZ)
@given(opened_streams, st.data())
def test_server_on_fuzzed_command_streams(fuzz_cases, mutate, server, stream, data) -> None:
    """A random, mutated command stream then ``< echo >``: the replies, recorded errors and frames on the bus
    are those the protocol gives, the listening client parses the frames back, the server stays up."""
    srv, listener = server
    raw = mutate.apply(stream.encode(), data.draw(st.one_of(st.just([]), mutate.mutations(len(stream), 2))))
    raw += b" >< echo >"          # ends a command left open, then the probe
    expected = Expected(split_commands(raw.decode("ascii", errors="replace"))[0])
    errors_before = len(srv.errors)
    with fuzz_cases.example("socketcand: served command streams", limit=60.0) as case:
        sock = connect(srv.port)
        start = time.time()
        try:
            sock.sendall(raw)
            text = read_until(sock, lambda t: t.count(">") >= len(expected.replies), 5.0)
        finally:
            sock.close()
        assert re.findall(r"<[^<>]*>", text) == expected.replies and text.count(">") == len(expected.replies)
        lines = read_until(listener, lambda t: t.count(">") >= len(expected.frames), 5.0)
        frames = [client_parse(line) for line in re.findall(r"< frame [^<>]* >", lines)]
        assert [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in frames] == \
               [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in expected.frames]
        assert all(start - 1 <= m.timestamp <= time.time() + 1 for m in frames)
        deadline = time.monotonic() + 5.0          # the server records an error just after its reply
        while len(srv.errors) - errors_before < expected.errors and time.monotonic() < deadline:
            time.sleep(0.001)
        assert len(srv.errors) - errors_before == expected.errors, srv.errors[errors_before:]
        for reply in expected.replies[:len(expected.replies) - (not expected.closed)]:   # not the final echo
            case.outcome(f"answered {reply}")
        case.outcome("logged, no reply (data outside < > or a send it cannot parse)",
                     expected.errors - expected.replies.count("< error unknown command >")
                     - expected.replies.count("< error could not open bus >"))
        case.outcome("frames sent on the bus and parsed back by python-can", len(frames))
        case.outcome("connection closed (wrong channel)" if expected.closed else "answered the final < echo >")


def test_endless_text_without_a_closing_bracket_is_discarded_counted_and_bounded(server) -> None:
    """1 MB without a ``>`` (a client gone mad) is not kept: it is dropped as it comes, the drop recorded once
    with its size, and the next command is answered as usual."""
    from firmware_sim.socketcand_server import MAX_COMMAND
    srv, _ = server
    errors_before = len(srv.errors)
    sock = connect(srv.port)
    try:
        sock.sendall(b"< send 123 1 " + b"0" * 1_000_000)
        sock.sendall(b" >< echo >")
        assert read_until(sock, lambda t: "< echo >" in t, 30.0).endswith("< echo >")
    finally:
        sock.close()
    dropped = [e for e in srv.errors[errors_before:] if "without a closing '>' discarded" in e]
    assert len(dropped) == 1 and 1_000_000 - MAX_COMMAND - 4096 <= int(dropped[0].split()[0]) <= 1_000_013
