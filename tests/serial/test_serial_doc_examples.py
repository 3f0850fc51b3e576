"""The example exchanges of docs/serial-protocol.md (section 6) replayed on the simulated device over a pty:
every request is sent as written and every response must match the document byte for byte.

Each example line is ``H→D`` or ``D→H``, the bytes as text (control bytes by name, printable runs quoted),
then the bytes in hex on the indented lines below. A response followed by the host's NAK is the device's
first transmission arriving corrupted: the test makes the device corrupt it (block check XOR 0x5A).
"""
from __future__ import annotations

import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest
import serial

from firmware_sim.digiforce import DigiForce
from firmware_sim.serial_device import SerialDevice

DOC = Path(__file__).resolve().parents[2] / "docs" / "serial-protocol.md"
NAMES = {0x02: "STX", 0x03: "ETX", 0x06: "ACK", 0x15: "NAK"}
BAUD = 1_000_000


@dataclass
class Line:
    sender: str        # "H" (host to device) or "D"
    text: str
    data: bytes


def render(data: bytes) -> str:
    """``STX "011ID" ETX "3E"``: control bytes by name, runs of printable bytes in double quotes."""
    parts = re.findall(rb"[\x20-\x7e]+|[^\x20-\x7e]", data)
    return " ".join(f'"{p.decode()}"' if p[0] >= 0x20 else NAMES.get(p[0], f"<{p[0]:02X}>") for p in parts)


def examples() -> list[tuple[str, list[Line]]]:
    """(heading, lines) of every code block in section 6."""
    section = DOC.read_text(encoding="utf-8").split("\n## 6.", 1)[1].split("\n## ", 1)[0]
    out: list[tuple[str, list[Line]]] = []
    heading, block = "", None
    for row in section.splitlines():
        if row.startswith("### "):
            heading = row[4:]
        elif row.startswith("```") and block is None:
            block = []
        elif row.startswith("```"):
            out.append((heading, block))
            block = None
        elif block is not None and row[:3] in ("H→D", "D→H"):
            block.append(Line(row[0], row[3:].strip(), b""))
        elif block is not None:
            block[-1].data += bytes.fromhex(row)
    return out


def measure_130_pairs(unit: DigiForce) -> None:
    """A measurement of 130 pairs: X 0.5 mm and Y 5 N per sample at 10 kHz (input volts and V/V)."""
    i = np.arange(140)
    t, x_volts, y_ratio = i * 1e-4, i * 0.025, i * 7.5e-6
    unit.feed(t[:10], x_volts[:10], y_ratio[:10])
    unit.start()
    unit.feed(t[10:], x_volts[10:], y_ratio[10:])
    unit.stop()


SETUP: dict[str, Callable[[DigiForce], None]] = {"6.5 Read a curve": measure_130_pairs}


def _read(port: serial.Serial, n: int) -> bytes:
    """``n`` bytes (or what came within 1 s), then whatever else arrives within 30 ms."""
    got, deadline = b"", time.monotonic() + 1.0
    while len(got) < n and time.monotonic() < deadline:
        got += port.read(n - len(got))
    time.sleep(0.03)
    return got + port.read(port.in_waiting)


def test_each_example_line_shows_its_bytes_as_text() -> None:
    blocks = examples()
    assert len(blocks) >= 6 and all(lines for _, lines in blocks)
    for heading, lines in blocks:
        for line in lines:
            assert line.text == render(line.data), f"{heading}: {line.text!r} is not {render(line.data)!r}"


def test_examples_are_what_the_device_sends() -> None:
    unit = DigiForce()
    blocks = examples()
    assert set(SETUP) <= {h for h, _ in blocks}, "a setup step names a heading the document no longer has"
    with SerialDevice(unit, "pty", baudrate=BAUD, address=1) as device, \
            serial.Serial(device.port, BAUD, timeout=0.01) as port:
        for heading, lines in blocks:
            SETUP.get(heading, lambda u: None)(unit)
            for i, line in enumerate(lines):
                if line.sender != "H":
                    continue
                rest = lines[i + 1:]
                answer = b"".join(r.data for r in rest[:next((k for k, r in enumerate(rest) if r.sender == "H"),
                                                             len(rest))])
                nak_follows = any(r.sender == "H" for r in rest) and \
                    next(r for r in rest if r.sender == "H").data[:1] == b"\x15"
                if answer[:1] == b"\x02" and nak_follows:
                    device.corrupt_next_responses(1)
                port.write(line.data)
                got = _read(port, len(answer))
                assert got == answer, f"{heading}: {line.text}\n device sent {render(got)}\n document has {render(answer)}"


@pytest.mark.parametrize("data", [b"\x02011ID\x033E", b"\x06\x30\x31", b"\x15AB", b"\x02xy\x03\x07"])
def test_render(data: bytes) -> None:
    assert render(data) == {b"\x02011ID\x033E": 'STX "011ID" ETX "3E"', b"\x06\x30\x31": 'ACK "01"',
                            b"\x15AB": 'NAK "AB"', b"\x02xy\x03\x07": 'STX "xy" ETX <07>'}[data]
