"""A serial client written from docs/serial-protocol.md alone (no project code), against the simulated unit
over a pty: identify, select a program, read a result and statistics; the same answers as the project's
client (drivers/digiforce_serial.py)."""
from __future__ import annotations

import json
import threading
import time

import numpy as np
import serial

from drivers.digiforce_serial import DigiForceClient
from firmware_sim.digiforce import DigiForce
from firmware_sim.serial_device import SerialDevice


class DocClient:
    """§2: STX, address as 2 hex digits, seq digit, 2-letter command, data, ETX, XOR check of address…ETX
    as 2 hex digits. §3: ACK after a good response, a new seq per request. §5: 2-digit status first."""

    def __init__(self, path: str, baud: int, address: int) -> None:
        self.port = serial.Serial(path, baud, timeout=0.05)
        self.address, self.seq = b"%02X" % address, 0

    def ask(self, command: str, data: str = "") -> str:
        self.seq = (self.seq + 1) % 10
        body = self.address + str(self.seq).encode() + command.encode() + data.encode() + b"\x03"
        check = 0
        for b in body:
            check ^= b
        self.port.write(b"\x02" + body + b"%02X" % check)
        reply, deadline = b"", time.monotonic() + 2.0
        while not (b"\x03" in reply and len(reply) >= reply.index(b"\x03") + 3):
            assert time.monotonic() < deadline, f"no response to {command}"
            reply += self.port.read(4096)
        frame = reply[reply.index(b"\x02") + 1:]
        end = frame.index(b"\x03")
        check = 0
        for b in frame[:end + 1]:
            check ^= b
        assert frame[end + 1:end + 3] == b"%02X" % check, "bad block check"
        assert frame[:5] == self.address + str(self.seq).encode() + command.encode()
        self.port.write(b"\x06" + self.address)
        text = frame[5:end].decode("ascii")
        assert text[:2] == "00", f"{command} failed: status {text[:2]} {text[2:]}"
        return text[2:]

    def ask_json(self, command: str, data: str = "") -> dict:
        def refuse(token: str) -> None:
            raise ValueError(f"not strict JSON: {token}")
        return json.loads(self.ask(command, data), parse_constant=refuse)


def test_client_written_from_the_document_alone() -> None:
    unit, lock = DigiForce(rng=np.random.default_rng(11)), threading.Lock()
    i = np.arange(2000)
    x_volts, y_ratio = 2.5 * (1 - np.cos(2 * np.pi * i / 1999)), 1e-3 * np.sin(np.pi * i / 1999) ** 2
    with SerialDevice(unit, "pty", baudrate=460_800, address=7, lock=lock) as device:
        doc = DocClient(device.port, 460_800, 7)
        ident = doc.ask("ID")
        assert doc.ask("PS", "4") == f"4,{unit.n_programs}" and unit.active_program == 4
        for k in range(2):
            t = (2000 * k + i) * 1e-4
            doc.ask("ST")
            with lock:
                unit.feed(t, x_volts, y_ratio * (1 + 0.02 * k))
            doc.ask("SP")
        result, stats = doc.ask_json("RR"), doc.ask_json("RS")
        doc.port.close()
        with DigiForceClient(device.port, baudrate=460_800, address=7) as client:
            assert client.identify() == ident
            assert client.active_program() == (4, unit.n_programs)
            assert client.read_result() == result and client.read_statistics() == stats
    assert result["number"] == 2 and result["program"] == 4 and stats["total"] == 2
    assert stats["values"]["y_max"]["n"] == 2 and stats["values"]["y_max"]["std"] > 0
