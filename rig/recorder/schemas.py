"""Topic names and JSON Schemas (encoding ``jsonschema``, messages ``json``) of the recording channels."""
from __future__ import annotations

import json
from typing import Iterable

TRUTH = "/plant/truth"
CAN_RAW = "/can/raw"
LIVE = "/device/live"
CURVE = "/device/curve"
RESULT = "/device/result"
STATISTICS = "/device/statistics"
EVENTS = "/events"
TRANSDUCERS = "/transducers/"

SCENE_ATTACHMENT = "scene.toml"
PROGRAM_ATTACHMENT = "device/program/{number}.json"
RIG_METADATA = "rig"


def _array(encoding: str, description: str) -> dict:
    if encoding == "base64":
        return {"type": "string", "contentEncoding": "base64",
                "contentMediaType": "application/x-float64-le", "description": description}
    return {"type": "array", "items": {"type": ["number", "null"]}, "description": description}


def block_schema(title: str, fields: Iterable[str], encoding: str) -> bytes:
    """Schema of a bulk block: ``t`` (s) plus one array per signal (SI), same length."""
    props = {"t": _array(encoding, "simulation time, s")}
    for name in fields:
        props[name] = _array(encoding, f"{name} (SI units)")
    return _dump({"title": title, "type": "object", "properties": props,
                  "required": list(props), "additionalProperties": False})


CAN_SCHEMA = {
    "title": "rig.CanFrames", "type": "object",
    "description": "block of raw CAN frames as seen on the bus",
    "properties": {
        "t": {"type": "array", "items": {"type": "number"}, "description": "frame time, s"},
        "id": {"type": "array", "items": {"type": "integer"}, "description": "arbitration id"},
        "is_fd": {"type": "array", "items": {"type": "boolean"}},
        "is_extended": {"type": "array", "items": {"type": "boolean"}},
        "data": {"type": "array", "items": {"type": "string"}, "description": "payload, hex"},
    },
    "required": ["t", "id", "is_fd", "is_extended", "data"],
}


def curve_schema(encoding: str) -> dict:
    """One measured curve of the device (all arrays of equal length)."""
    return {
        "title": "rig.Curve", "type": "object",
        "properties": {
            "number": {"type": "integer"}, "program": {"type": "integer"},
            "t": _array(encoding, "sample time, s"), "x": _array(encoding, "X channel, SI"),
            "y": _array(encoding, "Y channel, SI"), "angle": _array(encoding, "cam angle, rad"),
            "theory": {"type": "object", "description": "theoretical curve: t, x, y, angle arrays",
                       "additionalProperties": _array(encoding, "theory, SI")},
        },
        "required": ["number", "program", "t", "x", "y"], "additionalProperties": True,
    }


RESULT_SCHEMA = {
    "title": "rig.CurveResult", "type": "object",
    "properties": {
        "number": {"type": "integer"}, "program": {"type": "integer"}, "ok": {"type": "boolean"},
        "elements": {"type": "array", "items": {"type": "object", "properties": {
            "name": {"type": "string"}, "kind": {"type": "string"}, "ok": {"type": "boolean"},
            "reason": {"type": ["string", "null"]}}}},
        "process_values": {"type": "object", "additionalProperties": {"type": ["number", "null"]}},
    },
    "required": ["ok"], "additionalProperties": True,
}

STATISTICS_SCHEMA = {"title": "rig.DeviceStatistics", "type": "object",
                     "description": "statistics snapshot of the device (counts, per-value mean/std/min/max/cp/cpk)",
                     "additionalProperties": True}

EVENT_SCHEMA = {"title": "rig.Event", "type": "object",
                "properties": {"t": {"type": "number", "description": "s"}, "kind": {"type": "string"}},
                "required": ["t", "kind"], "additionalProperties": True}


def _dump(schema: dict) -> bytes:
    return json.dumps(schema, separators=(",", ":")).encode()


def schema_bytes(schema: dict) -> bytes:
    """Schema dict to the bytes stored in the MCAP schema record."""
    return _dump(schema)
