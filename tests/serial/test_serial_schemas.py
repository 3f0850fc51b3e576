"""The JSON payloads the device sends (PG, CH, RR, RS, SS) against docs/schemas/serial-*.schema.json, read
over a pty and parsed strictly; non-finite numbers travel as null plus the ``non_finite`` flag."""
from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest

from drivers.digiforce_serial import DigiForceClient, DigiForceError, DigiForceLinkError
from firmware_sim.digiforce import DigiForce
from firmware_sim.serial_device import SerialDevice
from firmware_sim.serial_protocol.commands import Commands

SCHEMAS = Path(__file__).resolve().parents[2] / "docs" / "schemas"
PAYLOADS = {"PG": "program", "CH": "curve-header", "RR": "result", "RS": "statistics", "SS": "status"}


def schema(command: str) -> jsonschema.Draft202012Validator:
    doc = json.loads((SCHEMAS / f"serial-{PAYLOADS[command]}.schema.json").read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(doc)
    return jsonschema.Draft202012Validator(doc)


def valid(command: str, payload: Any) -> Any:
    errors = sorted(schema(command).iter_errors(payload), key=str)
    assert not errors, f"{command}: " + "; ".join(f"{'/'.join(map(str, e.path))}: {e.message}" for e in errors[:5])
    return payload


def strict(text: str) -> Any:
    def reject(token: str) -> None:
        raise AssertionError(f"non-JSON token {token} on the wire")
    return json.loads(text, parse_constant=reject)


def every_feature_program(unit: DigiForce) -> dict[str, Any]:
    """A program with y2, teach scaling, a time stop, a reference threshold, every element kind, limits."""
    y = unit.get_program(0)["channels"]["y"]
    return {"channels": {"x": {"cutoff": 0, "scaling": {"mode": "teach", "points": [[0.0, 0.0], [5.0, 0.1]]}},
                         "y": {"cutoff": "500 Hz"}, "y2": dict(y, cutoff=0)},
            "control": {"stop": {"mode": "time", "duration": 1.0}},
            "reference": {"mode": "y_threshold", "y_threshold": 1.0},
            "elements": [
                {"kind": "window", "name": "W", "x_min": 0.04, "x_max": 0.06, "y_min": 0.0, "y_max": 1000.0,
                 "entry": "ignore", "exit": "ignore", "check": "y_max"},
                {"kind": "window", "name": "never", "x_min": 0.5, "x_max": 0.6, "y_min": 0.0, "y_max": 1.0},
                {"kind": "trapezoid", "name": "T", "start": 0.01, "end": 0.02, "lower": [0, 0], "upper": [1000, 1000]},
                {"kind": "threshold", "name": "H", "axis": "y", "value": 100.0, "range": [None, 0.08]},
                {"kind": "envelope", "name": "E", "channel": "y2", "part": "forward",
                 "references": [{"x": [0.0, 0.1], "y": [0.0, 700.0]}], "dx": 0.001, "dy": 50.0}],
            "limits": {"y_max": [0.0, 1000.0], "x_max": [None, 0.2], "W.x_entry": [0.0, 0.1]}}


def measure(unit: DigiForce, lock: threading.Lock, client: DigiForceClient, k: int) -> None:
    """Curve ``k``: X out and back, Y a hump; 3000 samples at 10 kHz, continuing the previous curve's time."""
    i = np.arange(3000)
    t = (3000 * k + i) * 1e-4
    x_volts = 2.5 * (1 - np.cos(2 * np.pi * i / 2999))
    y_ratio = 1e-3 * (1 + 0.01 * k) * np.sin(np.pi * i / 2999) ** 2
    with lock:
        unit.feed(t[:10], x_volts[:10], y_ratio[:10], y_ratio[:10])
    client.start()
    with lock:
        unit.feed(t[10:], x_volts[10:], y_ratio[10:], y_ratio[10:])
    client.stop()


def test_every_json_payload_matches_its_schema() -> None:
    unit, lock = DigiForce(rng=np.random.default_rng(3)), threading.Lock()
    with SerialDevice(unit, "pty", baudrate=1_000_000, lock=lock) as device, \
            DigiForceClient(device.port, baudrate=1_000_000) as client:
        fresh = valid("SS", client.status())
        assert fresh["time"] is None and fresh["last_ok"] is None
        for n in range(unit.n_programs):
            valid("PG", client.get_program(n))
        valid("RS", client.read_statistics())
        for command in ("RR", "CH"):
            with pytest.raises(DigiForceError, match="status 04"):
                client._json(command)
        client.set_program(2, every_feature_program(unit))
        client.select_program(2)
        program = valid("PG", client.get_program())
        assert {e["kind"] for e in program["elements"]} == {"window", "trapezoid", "threshold", "envelope"}
        client.set_program(2, program)                              # PG's object is a valid PW request
        for k in range(3):
            measure(unit, lock, client, k)
        result = valid("RR", client.read_result())
        assert result["process_values"]["never.x_entry"] is None and "non_finite" not in result
        stats = valid("RS", client.read_statistics())
        assert stats["total"] == 3 and stats["values"]["y_max"]["cpk"] is not None
        valid("SS", client.status())
        header = valid("CH", client._json("CH"))
        assert header["y2"] and header["n"] == len(unit.last_curve.t)
        client.select_program(3)
        client.set_program(3, {"reference": {"mode": "end"}, "control": {"start": {"mode": "x", "value": 0.01},
                                                                         "stop": {"mode": "external"}}})
        valid("PG", client.get_program())
        valid("SS", client.status())


class Overflowing:
    """A unit whose statistics and status hold values that are not finite numbers."""

    active_program, n_programs = 0, 1

    def statistics(self, program: int) -> dict[str, Any]:
        value = {"n": 2, "mean": float("inf"), "std": float("nan"), "min": -float("inf"), "max": np.float64("inf"),
                 "lower": None, "upper": None, "cp": None, "cpk": None}
        return {"program": program, "total": 2, "ok": 2, "nok": 0, "elements": {}, "values": {"a/b~c": value}}


def test_non_finite_values_travel_as_null_with_a_flag() -> None:
    data = Commands(Overflowing(), None, threading.Lock()).execute("RS", "")
    assert data.startswith("00")
    stats = valid("RS", strict(data[2:]))
    assert stats["values"]["a/b~c"]["mean"] is None and stats["values"]["a/b~c"]["std"] is None
    assert stats["non_finite"] == {"/values/a~1b~0c/mean": "Infinity", "/values/a~1b~0c/std": "NaN",
                                   "/values/a~1b~0c/min": "-Infinity", "/values/a~1b~0c/max": "Infinity"}


def test_the_client_refuses_non_json_tokens(monkeypatch) -> None:
    client = DigiForceClient("loop://")
    monkeypatch.setattr(client, "_transact", lambda command, data="": '{"std": NaN}')
    with pytest.raises(DigiForceLinkError, match="RS .*non-JSON token NaN"):
        client.read_statistics()
    monkeypatch.setattr(client, "_transact", lambda command, data="": '{"std": 1,}')
    with pytest.raises(DigiForceLinkError, match="not JSON"):
        client.status()
    with pytest.raises(ValueError, match="not strict JSON"):
        client.set_program(1, {"limits": {"y_max": [float("nan"), 1.0]}})


class Unserialisable(Overflowing):
    def status(self) -> dict[str, Any]:
        return {"state": object()}


def test_a_payload_json_cannot_carry_is_an_internal_fault() -> None:
    data = Commands(Unserialisable(), None, threading.Lock()).execute("SS", "")
    assert data.startswith("09payload is not JSON-serialisable: Object of type object")
