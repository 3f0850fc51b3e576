"""Device-side framing (docs/serial-protocol.md, sections 2–3), written against the document.

Frame ``STX AA S CC data ETX BB``; handshakes ``ACK AA`` / ``NAK AA``. The check ``BB`` is the XOR of
the bytes from the first address digit through ETX, as 2 upper-case hex digits. The host keeps its own
implementation (``drivers`` and ``firmware_sim`` never import each other).
"""
from __future__ import annotations

import re
from dataclasses import dataclass

STX, ETX, ACK, NAK = 0x02, 0x03, 0x06, 0x15
MAX_DATA = 65536
_CONTROL = re.compile(rb"[^\x20-\x7e]")
_START = re.compile(rb"[\x02\x06\x15]")
_STARTS = (STX, ACK, NAK)
_HEADER = re.compile(rb"([0-9A-F]{2})([0-9])([A-Z]{2})")


def check(body: bytes) -> bytes:
    """XOR of ``body`` as 2 upper-case hex digits."""
    x = 0
    for b in body:
        x ^= b
    return b"%02X" % x


def frame(address: int, seq: int, command: str, data: str) -> bytes:
    """Encode one frame (device responses: ``data`` = 2-digit status + payload)."""
    body = b"%02X%d%s%s\x03" % (address, seq, command.encode("ascii"), data.encode("ascii"))
    return b"\x02" + body + check(body)


def handshake(ack: bool, address: int) -> bytes:
    return (b"\x06" if ack else b"\x15") + b"%02X" % address


def _addr(text: bytes) -> int | None:
    return int(text, 16) if re.fullmatch(rb"[0-9A-F]{2}", text) else None


@dataclass(frozen=True)
class Request:
    address: int
    seq: int
    command: str
    data: str


@dataclass(frozen=True)
class Bad:
    """A complete but unusable frame; ``address`` None when unreadable."""

    address: int | None
    reason: str


@dataclass(frozen=True)
class Reply:
    """A handshake from the host: ``ack`` True for ACK, False for NAK."""

    ack: bool
    address: int | None


class Receiver:
    """Buffer received bytes and cut them into Request / Bad / Reply events."""

    def __init__(self) -> None:
        self._buf = b""

    @property
    def pending(self) -> bool:
        """True while a frame or handshake is partly received."""
        return bool(self._buf)

    def reset(self) -> None:
        self._buf = b""

    def feed(self, data: bytes) -> list[Request | Bad | Reply]:
        self._buf += data
        events: list[Request | Bad | Reply] = []
        while True:
            m = _START.search(self._buf)
            if m is None:
                self._buf = b""
                return events
            buf = self._buf = self._buf[m.start():]
            if buf[0] != STX:
                cut = next((k for k in (1, 2) if k < len(buf) and buf[k] in _STARTS), None)
                if cut is not None:          # STX, ACK or NAK starts anew, even inside a handshake: "NAK NAK 0 1" is
                    self._buf = buf[cut:]    # a stray byte, then NAK "01" (it read NAK "\x150" and swallowed the NAK)
                    continue
                if len(buf) < 3:
                    return events
                events.append(Reply(buf[0] == ACK, _addr(buf[1:3])))
                self._buf = buf[3:]
                continue
            end = _CONTROL.search(buf, 1)
            j = len(buf) if end is None else end.start()
            if j - 1 > MAX_DATA + 5:        # header (5) + data so far
                events.append(Bad(_addr(buf[1:3]), f"frame longer than {MAX_DATA} data bytes"))
                self._buf = buf[j:]
                continue
            if end is None:
                return events
            if buf[j] == STX:
                self._buf = buf[j:]
                continue
            if buf[j] != ETX:
                events.append(Bad(_addr(buf[1:3]), f"control byte 0x{buf[j]:02X} inside a frame"))
                self._buf = buf[j + 1:]
                continue
            if STX in buf[j + 1:j + 3]:     # STX starts a frame, even where a check character is due
                self._buf = buf[buf.index(STX, j + 1):]
                continue
            if len(buf) < j + 3:
                return events
            events.append(_decode(buf[1:j + 1], buf[j + 1:j + 3]))
            self._buf = buf[j + 3:]


def _decode(body: bytes, bcc: bytes) -> Request | Bad:
    if bcc != check(body):
        return Bad(_addr(body[:2]), f"block check {bcc!r} != {check(body)!r}")
    m = _HEADER.match(body)
    if m is None:
        return Bad(_addr(body[:2]), f"malformed header {body[:5]!r}")
    return Request(int(m[1], 16), int(m[2]), m[3].decode(), body[5:-1].decode("ascii"))
