"""Host-side framing of the DigiForce serial protocol (docs/serial-protocol.md, sections 2–3).

Frame: ``STX AA S CC data ETX BB`` — ``AA`` address (2 upper-case hex digits), ``S`` sequence digit,
``CC`` command (2 upper-case letters), ``data`` printable ASCII (0x20–0x7E), ``BB`` block check
character: XOR of every byte from the first address digit through ETX, as 2 upper-case hex digits.
Handshakes: ``ACK AA`` / ``NAK AA`` (3 bytes). The device keeps its own implementation of the same
document (``drivers`` and ``firmware_sim`` never import each other).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import reduce

STX, ETX, ACK, NAK = 0x02, 0x03, 0x06, 0x15
MAX_DATA = 65536
_HEX = b"0123456789ABCDEF"


def bcc(body: bytes) -> bytes:
    """Block check character of ``body`` (address … ETX): XOR of the bytes as 2 upper-case hex digits."""
    return b"%02X" % reduce(lambda a, b: a ^ b, body, 0)


def encode_frame(address: int, seq: int, command: str, data: str = "") -> bytes:
    """One frame; raises ValueError naming the field that cannot be encoded."""
    if not 1 <= address <= 0xFE:
        raise ValueError(f"serial frame: address {address} outside 1..254")
    if not 0 <= seq <= 9:
        raise ValueError(f"serial frame: sequence {seq} outside 0..9")
    if len(command) != 2 or not command.isascii() or not command.isupper() or not command.isalpha():
        raise ValueError(f"serial frame: command {command!r} is not two upper-case letters")
    if len(data) > MAX_DATA or not (data.isascii() and data.isprintable()):
        raise ValueError(f"serial frame: data for {command} must be at most {MAX_DATA} printable ASCII characters")
    body = b"%02X%d" % (address, seq) + command.encode() + data.encode() + bytes([ETX])
    return bytes([STX]) + body + bcc(body)


def encode_handshake(ack: bool, address: int) -> bytes:
    """``ACK AA`` or ``NAK AA``."""
    return bytes([ACK if ack else NAK]) + b"%02X" % address


def _address(text: bytes) -> int | None:
    return int(text, 16) if len(text) == 2 and all(c in _HEX for c in text) else None


@dataclass(frozen=True)
class Frame:
    """A frame with a valid block check character and header."""

    address: int
    seq: int
    command: str
    data: str


@dataclass(frozen=True)
class Corrupt:
    """A complete frame that failed its check; ``address`` is None when unreadable."""

    address: int | None
    reason: str


@dataclass(frozen=True)
class Handshake:
    """``ACK AA`` (ack=True) or ``NAK AA``; ``address`` is None when unreadable."""

    ack: bool
    address: int | None


Event = Frame | Corrupt | Handshake


class FrameParser:
    """Incremental receiver: feed bytes, get events. Bytes outside frames and handshakes are skipped."""

    def __init__(self) -> None:
        self._mode = "idle"   # idle | frame | bcc | handshake
        self._buf = bytearray()
        self._ack = False
        self._end = 0

    def reset(self) -> None:
        """Drop a partial frame (inter-character timeout)."""
        self._mode, self._buf = "idle", bytearray()

    def feed(self, data: bytes) -> list[Event]:
        events: list[Event] = []
        for b in data:
            event = self._byte(b)
            if event is not None:
                events.append(event)
        return events

    def _byte(self, b: int) -> Event | None:
        if b == STX:   # never inside a valid frame: (re)start
            self._mode, self._buf = "frame", bytearray()
            return None
        if self._mode == "idle":
            if b in (ACK, NAK):
                self._mode, self._ack, self._buf = "handshake", b == ACK, bytearray()
            return None
        if self._mode == "handshake" and b in (ACK, NAK):     # a new handshake: the one before lost its address
            self._ack, self._buf = b == ACK, bytearray()
            return None
        self._buf.append(b)
        if self._mode == "handshake":
            if len(self._buf) < 2:
                return None
            self._mode = "idle"
            return Handshake(self._ack, _address(bytes(self._buf)))
        if self._mode == "bcc":
            if len(self._buf) < self._end + 2:
                return None
            self._mode = "idle"
            return _decode(bytes(self._buf[:-2]), bytes(self._buf[-2:]))
        if b == ETX:
            self._mode, self._end = "bcc", len(self._buf)
        elif not 0x20 <= b <= 0x7E:
            self._mode = "idle"
            return Corrupt(_address(bytes(self._buf[:2])), f"control byte 0x{b:02X} inside a frame")
        elif len(self._buf) > MAX_DATA + 5:
            self._mode = "idle"
            return Corrupt(_address(bytes(self._buf[:2])), f"frame longer than {MAX_DATA} data bytes")
        return None


def _decode(body: bytes, check: bytes) -> Event:
    address = _address(body[:2])
    if check != bcc(body):
        return Corrupt(address, f"block check {check!r} does not match {bcc(body)!r}")
    header = body[:5]
    if len(body) < 6 or address is None or not header[2:3].isdigit() or not header[3:5].isalpha() \
            or not header[3:5].isupper():
        return Corrupt(address, f"malformed header {header!r}")
    return Frame(address, int(header[2:3]), header[3:5].decode(), body[5:-1].decode("ascii"))
