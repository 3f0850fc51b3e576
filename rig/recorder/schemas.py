"""Topic names and JSON Schemas (encoding ``jsonschema``, messages ``json``) of the recording channels.

Every schema keeps to what Foxglove's JSON-schema parser accepts: one string per ``type`` (no unions),
``properties`` on every object (dynamic keys are ``additionalProperties`` beside them), ``items`` on every
array. Undefined values are listed in each message's ``nulls`` (rig.recorder.encoding).
"""
from __future__ import annotations

import json
import re
from typing import Iterable, Mapping

from drivers.can.process_values import PROCESS_VALUES
from rig.recorder.encoding import NULLS


def snake(name: str) -> str:
    """A DBC name in snake case: ``BrakeForce`` → ``brake_force``, ``Encoder1`` → ``encoder1``."""
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def stand_topic(message: str) -> str:
    """The recording topic of a CAN reading message: ``/stand/`` and its name in snake case; its columns are the
    message's signals in snake case."""
    return f"/stand/{snake(message)}"


def measuring(transducers: Mapping[str, Mapping], signal: str) -> tuple[str, str] | None:
    """(``to``, recording topic) of the scene's transducer that measures the plant ``signal`` into a CAN reading
    (``[transducers.*]`` tables as written; ``phi_out`` → ``("can.Encoder2", "/stand/encoder2")`` when the scene
    wires it so); None when none does. Reports find their channels by what is measured, not by a message name."""
    for table in transducers.values():
        to = str(table.get("to", ""))
        if table.get("signal") == signal and to.startswith("can."):
            return to, stand_topic(to.split(".")[1])
    return None

TRUTH = "/plant/truth"
CAN_RAW = "/can/raw"
LIVE = "/device/live"
CURVE = "/device/curve"
RESULT = "/device/result"
STATISTICS = "/device/statistics"
EVENTS = "/events"
LOG = "/log"
VIEW_DEVICE = "/view/device"
VIEW_PLANT = "/view/plant"
VIEWS = (VIEW_DEVICE, VIEW_PLANT)

RIG_TOPICS = ("plant", "can", "device", "stand", "view", "events", "log")     # the first parts of the rig's topics


def is_rig_topic(topic: str) -> bool:
    """Whether ``topic`` is one the rig writes (``/plant/truth``, ``/stand/encoder1`` …); a file written by another
    tool holds others, which the reader counts and does not decode."""
    parts = topic.split("/")
    return len(parts) > 1 and parts[0] == "" and parts[1] in RIG_TOPICS


REPAIRED = "repaired by rig repair"     # the start of a rewritten file's rig.end reason (rig.recorder.repair)


def is_repaired(reason: str) -> bool:
    """Whether a recording's end ``reason`` says :func:`rig.recorder.repair.repair` rewrote it."""
    return reason.startswith(REPAIRED)


SCENE_ATTACHMENT = "scene.toml"
PROGRAM_ATTACHMENT = "device/program/{number}.json"
RIG_METADATA = "rig"
END_METADATA = "rig.end"

NUMBER = {"type": "number"}
INTEGER = {"type": "integer"}
BOOLEAN = {"type": "boolean"}
STRING = {"type": "string"}


def array_of(item: dict, description: str = "") -> dict:
    return {"type": "array", "items": item, **({"description": description} if description else {})}


def message_schema(title: str, properties: dict, required: Iterable[str] = (), description: str = "",
                   extra: bool = True) -> dict:
    """A top-level message schema: ``properties`` plus ``nulls``; ``extra``: further keys allowed."""
    props = {**properties, NULLS: array_of(STRING, "JSON Pointers of undefined values (null: NaN, inf or None), "
                                                    "left out of their object, 0 in their array")}
    schema = {"title": title, "type": "object", "properties": props, "required": list(required),
              "additionalProperties": extra}
    if description:
        schema["description"] = description
    return schema


def _array(encoding: str, description: str) -> dict:
    if encoding == "base64":
        return {"type": "string", "contentEncoding": "base64",
                "contentMediaType": "application/x-float64-le", "description": description}
    return array_of(NUMBER, description)


def described(name: str, unit: str | None) -> str:
    """A signal's description with its unit: "phi, rad"; "count (a count or code, no unit)" for "1"; "(SI units)"
    where the unit is not known."""
    if unit is None:
        return f"{name} (SI units)"
    return f"{name} (a count or code, no unit)" if unit in ("1", "") else f"{name}, {unit}"


def block_schema(title: str, fields: Iterable[str], encoding: str, units: Mapping[str, str] | None = None) -> dict:
    """Schema of a bulk block: ``t`` (s) plus one array per signal (SI, ``units`` by name where known), same
    length."""
    props = {"t": _array(encoding, "simulation time, s")}
    for name in fields:
        props[name] = _array(encoding, described(name, (units or {}).get(name)))
    return message_schema(title, props, required=props, extra=False)


def view_schema(title: str, fields: Iterable[str], description: str, units: Mapping[str, str] | None = None) -> dict:
    """Schema of a view channel: one sample per message, ``t`` (s) and one number per signal (SI, ``units`` by name
    where known)."""
    props = {"t": {"type": "number", "description": "simulation time, s"}}
    props.update({name: {"type": "number", "description": described(name, (units or {}).get(name))}
                  for name in fields})
    return message_schema(title, props, required=["t"], description=description, extra=False)


CAN_SCHEMA = message_schema("rig.CanFrames", {
    "t": array_of(NUMBER, "frame time, s (simulation time)"),
    "id": array_of(INTEGER, "arbitration id"),
    "dir": array_of(STRING, "'rx': received by the host, 'tx': sent by the host"),
    "channel": array_of(STRING, "CAN channel name"),
    "is_fd": array_of(BOOLEAN, "CAN FD frame"),
    "brs": array_of(BOOLEAN, "CAN FD bit rate switch"),
    "esi": array_of(BOOLEAN, "CAN FD error state indicator"),
    "is_extended": array_of(BOOLEAN, "29-bit identifier"),
    "error": array_of(BOOLEAN, "error frame"),
    "data": array_of(STRING, "payload, hex"),
}, required=("t", "id", "dir", "channel", "is_fd", "brs", "esi", "is_extended", "error", "data"),
    description="block of raw CAN frames on the bus, the host's own included", extra=False)


def _value_unit(name: str, units: Mapping[str, str]) -> str:
    """The unit of a process value by its name: an X value's (``x_…``) and a Y value's (``y_…``) the channel's as
    wired (``units`` x, y), a duration's s; "SI" where not known (an element's value, named by the program)."""
    if name == "duration":
        return "s"
    return units.get(name[0], "SI") if name[:2] in ("x_", "y_") else "SI"


def curve_schema(encoding: str, units: Mapping[str, str] | None = None) -> dict:
    """One measured curve of the device (all arrays of equal length); ``units`` of x and y where known."""
    units = units or {}
    shown = {"t": "s", "x": units.get("x", "SI"), "y": units.get("y", "SI"), "angle": "rad"}
    return message_schema("rig.Curve", {
        "number": INTEGER, "program": INTEGER,
        "t": _array(encoding, "sample time, s"), "x": _array(encoding, f"X channel, {shown['x']}"),
        "y": _array(encoding, f"Y channel, {shown['y']}"), "angle": _array(encoding, "cam angle, rad"),
        "theory": {"type": "object", "description": "theoretical curve (arrays, SI); without t it shares the "
                                                    "curve's times",
                   "properties": {k: _array(encoding, f"theory {k}, {u}") for k, u in shown.items()},
                   "additionalProperties": _array(encoding, "theory, SI")},
        "complete": {"type": "boolean", "description": "every block of the curve arrived"},
        "problems": array_of(STRING, "what was wrong with an incomplete curve"),
    }, required=("number", "program", "t", "x", "y"))


_VALUE = {"type": "number", "description": "process value, SI"}


_RESULT_FLAGS = {
    "complete": {"type": "boolean", "description": "every announced process value arrived"},
    "missing": array_of(STRING, "process values that did not arrive"),
    "memory_full": {"type": "boolean", "description": "the curve filled the unit's curve memory and was cut there "
                                                      "(overflow policy stop): elements beyond the cut saw no data"},
    "decimated": {"type": "boolean", "description": "the curve was thinned to fit the unit's memory (policy decimate)"},
}


def result_schema(units: Mapping[str, str] | None = None) -> dict:
    """A curve's result; its process values' units from the X and Y channels' (``units`` x, y) where known."""
    units = units or {}
    return message_schema("rig.CurveResult", {
        "number": INTEGER, "program": INTEGER, "ok": BOOLEAN,
        "elements": array_of({"type": "object", "properties": {
            "name": STRING, "kind": STRING, "ok": BOOLEAN, "reason": STRING}}),
        "process_values": {"type": "object", "description": "process values by name (SI); an undefined one is in "
                                                            "nulls",
                           "properties": {name: {"type": "number",
                                                 "description": f"{name}, {_value_unit(name, units)}"}
                                          for name in PROCESS_VALUES.values()},
                           "additionalProperties": _VALUE},
        **_RESULT_FLAGS}, required=("ok",))




def _value_statistics(unit: str) -> dict:
    """One process value's statistics: n, mean, σ, min, max and limits in ``unit``, Cp and Cpk (no unit)."""
    def number(what: str) -> dict:
        return {"type": "number", "description": f"{what}, {unit}"}
    return {"type": "object", "properties": {
        "n": INTEGER, "mean": number("mean"), "std": number("σ"), "min": number("min"), "max": number("max"),
        "lower": number("lower limit"), "upper": number("upper limit"),
        "cp": {"type": "number", "description": "Cp (no unit)"},
        "cpk": {"type": "number", "description": "Cpk (no unit)"}},
            "description": "per process value: n, mean, σ, min, max, limits, Cp, Cpk (an undefined one is in nulls)"}


def statistics_schema(units: Mapping[str, str] | None = None) -> dict:
    """The device's statistics snapshot; the values' units from the X and Y channels' (``units`` x, y) where known."""
    units = units or {}
    return message_schema("rig.DeviceStatistics", {
        "program": INTEGER, "total": INTEGER, "ok": INTEGER, "nok": INTEGER,
        "elements": {"type": "object", "description": "OK/NOK counts by element name (the program's names)",
                     "properties": {},
                     "additionalProperties": {"type": "object", "properties": {"ok": INTEGER, "nok": INTEGER}}},
        "values": {"type": "object", "description": "statistics by process value name (element values are named by "
                                                    "the program: additional properties)",
                   "properties": {name: _value_statistics(_value_unit(name, units))
                                  for name in PROCESS_VALUES.values()},
                   "additionalProperties": _value_statistics("SI")},
    }, description="statistics snapshot of the device (counts, per-value mean/std/min/max/cp/cpk)")

EVENT_SCHEMA = message_schema("rig.Event", {"t": {"type": "number", "description": "simulation time, s"},
                                            "kind": STRING}, required=("t", "kind"))

LOG_SCHEMA = {    # Foxglove's well-known foxglove.Log (https://docs.foxglove.dev), as Foxglove publishes it
    "title": "foxglove.Log", "description": "A log message", "type": "object",
    "properties": {
        "timestamp": {"type": "object", "title": "time", "description": "Timestamp of log message",
                      "properties": {"sec": {"type": "integer", "minimum": 0},
                                     "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
        "level": {"title": "foxglove.LogLevel", "description": "Log level", "oneOf": [
            {"title": title, "const": value} for value, title in enumerate(
                ("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL"))]},
        "message": {"type": "string", "description": "Log message"},
        "name": {"type": "string", "description": "Process or node name"},
        "file": {"type": "string", "description": "Filename"},
        "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"},
    },
    "required": ["timestamp", "level", "message", "name", "file", "line"],
}


def schema_bytes(schema: dict) -> bytes:
    """Schema dict to the bytes stored in the MCAP schema record."""
    return json.dumps(schema, separators=(",", ":"), ensure_ascii=False).encode()
