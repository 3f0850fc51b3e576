"""Both framing implementations (host drivers.serial_framing, device firmware_sim.serial_protocol.framing)
against the document's examples, against each other, and on malformed input."""
from __future__ import annotations

import re
from functools import reduce
from pathlib import Path

import pytest
from hypothesis import given, settings, strategies as st

from drivers import serial_framing as host
from firmware_sim.serial_protocol import framing as dev

DOC = Path(__file__).resolve().parents[2] / "docs" / "serial-protocol.md"


def doc_examples() -> list[tuple[str, bytes]]:
    """(direction, bytes) of every example line: the hex on the indented lines under ``H→D``/``D→H``."""
    entries = re.findall(r"^(H→D|D→H) .*\n((?: {5}(?:[0-9A-F]{2} ?)+\n)+)", DOC.read_text(encoding="utf-8"), re.M)
    return [(who, bytes.fromhex(hexes)) for who, hexes in entries]


def test_doc_has_examples_of_every_kind() -> None:
    examples = doc_examples()
    assert len(examples) >= 15
    assert {raw[0] for _, raw in examples} == {host.STX, host.ACK, host.NAK}
    assert sum(raw[0] == host.STX and int(raw[-2:], 16) != reduce(lambda a, b: a ^ b, raw[1:-2])
               for _, raw in examples) == 2          # a corrupted request and a corrupted response


@pytest.mark.parametrize("who,raw", doc_examples())
def test_doc_examples_decode_identically_on_both_sides(who: str, raw: bytes) -> None:
    h, d = host.FrameParser().feed(raw), dev.Receiver().feed(raw)
    assert len(h) == len(d) == 1
    if raw[0] == host.STX and int(raw[-2:], 16) != reduce(lambda a, b: a ^ b, raw[1:-2]):
        assert isinstance(h[0], host.Corrupt) and isinstance(d[0], dev.Bad) and h[0].address == d[0].address == 1
    elif raw[0] == host.STX:
        frame, request = h[0], d[0]
        assert isinstance(frame, host.Frame) and isinstance(request, dev.Request)
        assert (frame.address, frame.seq, frame.command, frame.data) == \
               (request.address, request.seq, request.command, request.data) and frame.address == 1
        assert host.encode_frame(frame.address, frame.seq, frame.command, frame.data) == raw
        assert dev.frame(frame.address, frame.seq, frame.command, frame.data) == raw
        if who == "D→H":
            assert frame.data[:2].isdigit()
    else:
        assert (h[0].ack, h[0].address) == (d[0].ack, d[0].address) == (raw[0] == host.ACK, 1)
        assert host.encode_handshake(h[0].ack, 1) == dev.handshake(h[0].ack, 1) == raw


def test_worked_checksum_from_the_doc() -> None:
    assert host.bcc(b"011ID\x03") == dev.check(b"011ID\x03") == b"3E"
    assert 0x30 ^ 0x31 ^ 0x31 ^ 0x49 ^ 0x44 ^ 0x03 == 0x3E


printable = st.text(alphabet=st.characters(min_codepoint=0x20, max_codepoint=0x7E), max_size=300)
frames = st.tuples(st.integers(1, 254), st.integers(0, 9),
                   st.text(alphabet="ABCDEFGHIJKLMNOPQRSTUVWXYZ", min_size=2, max_size=2), printable)


@settings(max_examples=150, deadline=None)
@given(st.lists(frames, min_size=1, max_size=5), st.binary(max_size=20), st.data())
def test_both_parsers_agree_on_random_streams_cut_anywhere(items, garbage, data) -> None:
    """Frames between garbage without STX/ACK/NAK, delivered in random chunks, come out intact."""
    noise = bytes(b for b in garbage if b not in (host.STX, host.ACK, host.NAK))
    stream = b"".join(noise + host.encode_frame(*item) for item in items)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    h, d = host.FrameParser(), dev.Receiver()
    got_h, got_d = [], []
    for a, b in zip([0, *cuts], [*cuts, len(stream)]):
        got_h += h.feed(stream[a:b])
        got_d += d.feed(stream[a:b])
    assert [(f.address, f.seq, f.command, f.data) for f in got_h] == items
    assert [(r.address, r.seq, r.command, r.data) for r in got_d] == items
    assert host.encode_frame(*items[0]) == dev.frame(*items[0])


@settings(max_examples=100, deadline=None)
@given(frames, st.data())
def test_any_single_bit_flip_is_detected(item, data) -> None:
    raw = bytearray(host.encode_frame(*item))
    i = data.draw(st.integers(1, len(raw) - 1))
    raw[i] ^= 1 << data.draw(st.integers(0, 7))
    for events in (host.FrameParser().feed(bytes(raw)), dev.Receiver().feed(bytes(raw))):
        assert not any(isinstance(e, (host.Frame, dev.Request)) for e in events)


@pytest.mark.parametrize("raw,reason", [
    (b"\x02011ID\x0399", "block check"),                 # wrong check
    (b"\x02011I\x01D\x033E", "control byte 0x01"),       # control byte inside
    (b"\x020119D\x03" + dev.check(b"0119D\x03"), "malformed header"),   # command not letters
    (b"\x0201XID\x03" + dev.check(b"01XID\x03"), "malformed header"),   # seq not a digit
])
def test_invalid_frames_are_reported_with_their_address(raw: bytes, reason: str) -> None:
    for events in (host.FrameParser().feed(raw), dev.Receiver().feed(raw)):
        assert len(events) == 1 and events[0].address == 1 and reason in events[0].reason


def test_stx_restarts_and_overlong_frames_are_dropped() -> None:
    good = host.encode_frame(7, 3, "SS")
    for parser in (host.FrameParser(), dev.Receiver()):
        events = parser.feed(b"\x0201" + good)            # truncated frame, then a good one
        assert [(e.address, e.command) for e in events] == [(7, "SS")]
        events = parser.feed(b"\x02" + b"A" * (host.MAX_DATA + 10) + good)
        assert len(events) == 2 and "longer" in events[0].reason and events[1].command == "SS"


def test_host_refuses_to_encode_what_the_protocol_cannot_carry() -> None:
    with pytest.raises(ValueError, match="address 0"):
        host.encode_frame(0, 1, "ID")
    with pytest.raises(ValueError, match="sequence 10"):
        host.encode_frame(1, 10, "ID")
    with pytest.raises(ValueError, match="'id'"):
        host.encode_frame(1, 1, "id")
    with pytest.raises(ValueError, match="printable ASCII"):
        host.encode_frame(1, 1, "PW", "1,{\"name\":\"Kraft\u00e4\"}")
    with pytest.raises(ValueError, match="printable ASCII"):
        host.encode_frame(1, 1, "PW", "line\nbreak")


def test_stx_inside_a_handshake_starts_a_frame() -> None:
    good = host.encode_frame(1, 1, "ID")
    for parser in (host.FrameParser(), dev.Receiver()):
        events = parser.feed(b"\x06x" + good)
        assert [(type(e).__name__, e.address) for e in events] in ([("Frame", 1)], [("Request", 1)])


@pytest.mark.parametrize("stray", [b"\x15", b"\x06", b"\x15\x30"])
def test_a_handshake_that_lost_its_address_does_not_swallow_the_next(stray: bytes) -> None:
    """"NAK NAK 0 1" was read as NAK "\\x150" and the real NAK "01" lost (silence, then the host's timeout): a new ACK
    or NAK restarts the handshake on both sides."""
    for parser in (host.FrameParser(), dev.Receiver()):
        events = parser.feed(stray + b"\x1501")
        assert [(type(e).__name__, e.ack, e.address) for e in events] in (
            [("Handshake", False, 1)], [("Reply", False, 1)]), (parser, events)
