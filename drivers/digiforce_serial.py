"""Host client of the DigiForce serial protocol (docs/serial-protocol.md) over pyserial.

Opens a tty path (``/dev/ttyUSB0``, a pty) or any pyserial URL (``socket://``, ``rfc2217://``).
Every call is one request/response exchange: NAK or a corrupt response → retransmission, silence →
retry after ``timeout``; after ``retries`` repeats a :class:`DigiForceLinkError` names command,
port and tries. Error statuses from the device raise :class:`DigiForceError`. JSON payloads are parsed
strictly (RFC 8259: ``NaN``/``Infinity`` tokens are a link error); a non-finite value arrives as ``null``
listed in the payload's ``non_finite`` object (JSON Pointer → ``"NaN"``, ``"Infinity"``, ``"-Infinity"``).
A payload not of its documented form (a JSON object, ``active,count``, a curve block) is a
:class:`DigiForceLinkError` saying "malformed response".
"""
from __future__ import annotations

import base64
import json
import re
import socket
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import serial

try:
    import termios
    #: what pyserial passes on unwrapped from a port whose device is gone (a closed pty: its buffer flush)
    PORT_GONE: tuple[type[BaseException], ...] = (OSError, termios.error)
except ImportError:                 # not POSIX
    PORT_GONE = (OSError,)

from drivers.serial_framing import Corrupt, Frame, FrameParser, Handshake, encode_frame, encode_handshake

BITS_PER_BYTE = 10      # 8N1
MIN_GAP = 0.1           # s, inter-character timeout floor

COMMANDS = {
    "ID": "identify", "PS": "select program", "PG": "get program", "PW": "write program",
    "ST": "start", "SP": "stop", "TA": "tare", "CH": "latch curve", "CB": "read curve block",
    "CT": "read curve time block", "CY": "read curve y2 block", "RR": "read result", "RS": "read statistics",
    "RZ": "reset statistics", "SS": "status",
}


class DigiForceError(RuntimeError):
    """The device answered a command with an error status."""

    def __init__(self, command: str, code: int, message: str) -> None:
        super().__init__(f"DigiForce {command} ({COMMANDS.get(command, '?')}) failed with status {code:02d}: {message}")
        self.command, self.code, self.message = command, code, message


class DigiForceLinkError(IOError):
    """No valid response after all tries (NAKs, corrupt responses, timeouts)."""

    def __init__(self, command: str, port: str, tries: int, reasons: list[str]) -> None:
        super().__init__(f"DigiForce at {port}: command {command} ({COMMANDS.get(command, '?')}) got no valid "
                         f"response after {tries} tries ({', '.join(reasons)})")
        self.command, self.port, self.tries, self.reasons = command, port, tries, reasons


class DigiForceTimeout(DigiForceLinkError):
    """The last try ended in silence (no response within the timeout)."""


@dataclass(frozen=True)
class Curve:
    """The last curve: X and Y value pairs (engineering units, SI), the sample times (s) if read, the
    second Y channel if the curve has one, and the header (turning_index, x_reference, sampling, flags)."""

    x: np.ndarray
    y: np.ndarray
    t: np.ndarray | None
    y2: np.ndarray | None
    info: dict[str, Any]


class DigiForceClient:
    """Talk to the DigiForce at ``address`` on ``port_or_url``.

    ``timeout`` (s) is the wait for a response after the request has left the line; ``retries`` the
    number of repeats after the first try.
    """

    def __init__(self, port_or_url: str, baudrate: int = 115200, address: int = 1,
                 timeout: float = 0.5, retries: int = 3) -> None:
        if not 1 <= address <= 0xFE:
            raise ValueError(f"DigiForce client: address must be in 1..254, got {address}")
        if timeout <= 0 or retries < 0:
            raise ValueError(f"DigiForce client: need timeout > 0 and retries >= 0, got {timeout}, {retries}")
        try:
            self._port = serial.serial_for_url(port_or_url, baudrate=baudrate, timeout=0.01)
        except (serial.SerialException, ValueError) as e:
            raise DigiForceLinkError("--", port_or_url, 0, [f"cannot open: {e}"]) from e
        self.port, self.address, self.timeout, self.retries = port_or_url, address, timeout, retries
        sock = getattr(self._port, "_socket", None)      # socket:// : no Nagle delay on ACK + next request
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._char = BITS_PER_BYTE / baudrate
        self._gap = max(MIN_GAP, 20 * self._char)
        self._parser = FrameParser()
        self._seq = 0
        self.bytes_sent = self.bytes_received = 0

    def close(self) -> None:
        self._port.close()

    def __enter__(self) -> DigiForceClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- commands ---------------------------------------------------------------------------------
    def identify(self) -> str:
        return self._transact("ID")

    def select_program(self, n: int) -> None:
        self._transact("PS", str(int(n)))

    def active_program(self) -> tuple[int, int]:
        """(active program, number of programs)."""
        text = self._transact("PS")
        match = re.fullmatch(r"(\d+),(\d+)", text)
        if match is None:
            raise self._malformed("PS", f"{text[:40]!r} is not 'active,count'")
        return int(match[1]), int(match[2])

    def get_program(self, n: int | None = None) -> dict[str, Any]:
        """Configuration of program ``n`` (default: the active one)."""
        return self._json("PG", "" if n is None else str(int(n)))

    def set_program(self, n: int, config: dict[str, Any]) -> None:
        """Store ``config`` (channels, sampling, control, evaluation) as program ``n``."""
        try:
            text = json.dumps(config, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
        except ValueError as e:
            raise ValueError(f"DigiForce PW: program {n} configuration is not strict JSON ({e})") from None
        self._transact("PW", f"{int(n)},{text}")

    def configure(self, n: int, changes: dict[str, Any]) -> dict[str, Any]:
        """Read program ``n``, merge ``changes`` into it (dicts key by key, lists and values replace),
        write it back; returns the configuration sent."""
        config = _merge(self.get_program(n), changes)
        self.set_program(n, config)
        return config

    def configure_channel(self, n: int, channel: str, **settings: Any) -> dict[str, Any]:
        """E.g. ``configure_channel(1, "y", cutoff=500.0, scaling={"engineering": 2000.0})``."""
        return self.configure(n, {"channels": {channel: settings}})

    def configure_sampling(self, n: int, **settings: Any) -> dict[str, Any]:
        """E.g. ``configure_sampling(1, mode="dx", delta=1e-5, overflow="decimate")``."""
        return self.configure(n, {"sampling": settings})

    def configure_control(self, n: int, **triggers: Any) -> dict[str, Any]:
        """E.g. ``configure_control(1, start={"mode": "x", "value": 0.002})``."""
        return self.configure(n, {"control": triggers})

    def configure_evaluation(self, n: int, elements: list[dict[str, Any]],
                             limits: dict[str, Any] | None = None) -> dict[str, Any]:
        """Replace the evaluation elements (and the statistics limits, if given) of program ``n``."""
        return self.configure(n, {"elements": elements} | ({} if limits is None else {"limits": limits}))

    def start(self) -> None:
        self._transact("ST")

    def stop(self) -> None:
        self._transact("SP")

    def tare(self, channel: str | None = None) -> None:
        """Zero ``channel`` (``"x"``, ``"y"``, ``"y2"``; None: the device's default set)."""
        self._transact("TA", channel or "")

    def read_curve(self, with_time: bool = False) -> Curve:
        """Latch the last curve and read it block by block: pairs, times (``with_time``), y2 if present."""
        header = self._json("CH")
        n, n_blocks = header.get("n"), header.get("n_blocks")
        if not all(type(v) is int and v >= 0 for v in (n, n_blocks)):
            raise self._malformed("CH", f"curve header without counts n and n_blocks: n {n!r}, n_blocks {n_blocks!r}")
        xy = self._read_blocks("CB", n_blocks, 2).reshape(-1, 2)
        t = self._read_blocks("CT", n_blocks, 1) if with_time else None
        y2 = self._read_blocks("CY", n_blocks, 1) if header.get("y2") else None
        if any(a is not None and len(a) != n for a in (xy, t, y2)):
            raise DigiForceLinkError("CB", self.port, 1, [f"curve blocks hold {len(xy)} pairs, header says {n}"])
        return Curve(xy[:, 0].copy(), xy[:, 1].copy(), t, y2, header)

    def read_result(self) -> dict[str, Any]:
        return self._json("RR")

    def read_statistics(self, program: int | None = None) -> dict[str, Any]:
        return self._json("RS", "" if program is None else str(int(program)))

    def reset_statistics(self, program: int | None = None) -> None:
        self._transact("RZ", "" if program is None else str(int(program)))

    def status(self) -> dict[str, Any]:
        return self._json("SS")

    # -- helpers ----------------------------------------------------------------------------------
    def _malformed(self, command: str, why: str) -> DigiForceLinkError:
        """The error for a well-framed response whose payload is not what the protocol says."""
        return DigiForceLinkError(command, self.port, 1, [f"malformed response: {why}"])

    def _json(self, command: str, data: str = "") -> dict[str, Any]:
        """The payload of ``command``: a JSON object, strict JSON."""
        text = self._transact(command, data)

        def reject(token: str) -> None:
            raise DigiForceLinkError(command, self.port, 1, [f"response holds the non-JSON token {token}"])
        try:
            value = json.loads(text, parse_constant=reject)
        except (json.JSONDecodeError, RecursionError) as e:     # nested too deep: RecursionError
            raise DigiForceLinkError(command, self.port, 1, [f"response is not JSON: {e}"]) from None
        if not isinstance(value, dict):
            raise self._malformed(command, f"expected a JSON object, got {type(value).__name__}")
        return value

    def _read_blocks(self, command: str, n_blocks: int, width: int) -> np.ndarray:
        parts = []
        for i in range(n_blocks):
            text = self._transact(command, str(i))
            try:
                index, total, count, payload = text.split(",", 3)
                values = np.frombuffer(base64.b64decode(payload, validate=True), dtype="<f8")
                index, total, count = int(index), int(total), int(count)
            except ValueError as e:          # binascii.Error too
                raise self._malformed(command, f"block {i} {text[:40]!r}: {e}") from None
            if (index, total) != (i, n_blocks) or len(values) != count * width:
                raise DigiForceLinkError(command, self.port, 1, [
                    f"block {index}/{total} with {len(values)} values, expected block {i}/{n_blocks} "
                    f"with {count}x{width}"])
            parts.append(values)
        return np.concatenate(parts) if parts else np.empty(0)

    def _write(self, data: bytes) -> None:
        self._port.write(data)
        self.bytes_sent += len(data)

    def _transact(self, command: str, data: str = "") -> str:
        """One exchange; returns the payload of a ``00`` response. A port whose device is gone is pyserial's
        :class:`serial.SerialException` naming it, whichever call found it."""
        try:
            return self._exchange(command, data)
        except (serial.SerialException, DigiForceLinkError):    # (both OSErrors) already named
            raise
        except PORT_GONE as exc:        # pyserial's flush and in_waiting pass the OS's error on unwrapped
            raise serial.SerialException(f"{self.port}: {exc}") from None

    def _exchange(self, command: str, data: str) -> str:
        self._seq = (self._seq + 1) % 10
        request = encode_frame(self.address, self._seq, command, data)
        self._port.reset_input_buffer()
        self._parser.reset()
        reasons: list[str] = []
        outgoing = request
        while True:
            self._write(outgoing)
            outcome = self._await(command, time.monotonic() + len(outgoing) * self._char + self.timeout)
            if isinstance(outcome, Frame):
                self._write(encode_handshake(True, self.address))
                return self._payload(command, outcome.data)
            reasons.append(outcome)
            if len(reasons) > self.retries:
                error = DigiForceTimeout if outcome == "timeout" else DigiForceLinkError
                raise error(command, self.port, len(reasons), reasons)
            # a corrupt response is asked for again with NAK; NAK or silence → send the request again
            outgoing = encode_handshake(False, self.address) if outcome.startswith("corrupt") else request

    def _await(self, command: str, deadline: float) -> Frame | str:
        """The response to the current request, or why there is none (``"timeout"``, ``"NAK"``, ``"corrupt …"``)."""
        while time.monotonic() < deadline:
            chunk = self._port.read(self._port.in_waiting or 1)
            if not chunk:
                continue
            self.bytes_received += len(chunk)
            deadline = max(deadline, time.monotonic() + self._gap)
            for event in self._parser.feed(chunk):
                if event.address not in (self.address, None):
                    continue
                if isinstance(event, Handshake) and not event.ack:
                    return "NAK"
                if isinstance(event, Corrupt):
                    return f"corrupt response ({event.reason})"
                if isinstance(event, Frame) and (event.seq, event.command) == (self._seq, command):
                    return event
        return "timeout"

    def _payload(self, command: str, data: str) -> str:
        if len(data) < 2 or not data[:2].isdigit():
            raise DigiForceLinkError(command, self.port, 1, [f"response {data[:20]!r} has no 2-digit status"])
        if data[:2] != "00":
            raise DigiForceError(command, int(data[:2]), data[2:])
        return data[2:]


def _merge(base: dict[str, Any], update: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in update.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out
