"""Payload encoding for MCAP messages: JSON with plain numbers, or base64 float64 blocks.

Bulk blocks are ``{"t": [...], "<signal>": [...]}`` (times in s, values SI). Two encodings:

* ``"json"``: plain JSON number arrays, plottable by any JSON-aware MCAP viewer. Non-finite values
  are written as ``null`` (JSON has no NaN/inf) and read back as NaN.
* ``"base64"``: every array is the base64 text of its little-endian float64 bytes (JSON Schema
  ``contentEncoding: base64``); exact and ~10x faster, but viewers cannot plot it directly.
"""
from __future__ import annotations

import base64
import json
import math
from typing import Any, Mapping

import numpy as np

ENCODINGS = ("json", "base64")


_PLAIN = (str, int, type(None))


def to_jsonable(value: Any) -> Any:
    """Turn numpy scalars/arrays and non-finite floats into plain JSON values (NaN/inf -> None)."""
    kind = type(value)
    if kind in _PLAIN or kind is bool:
        return value
    if kind is float:
        return value if math.isfinite(value) else None
    if kind is list and all(type(v) in _PLAIN for v in value):
        return value
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return encode_array(value, "json") if value.dtype.kind == "f" else value.tolist()
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).hex()
    return value


def dumps(obj: Any) -> bytes:
    """Compact JSON bytes of ``obj`` (numpy values converted, NaN forbidden)."""
    return json.dumps(to_jsonable(obj), separators=(",", ":"), allow_nan=False).encode()


def encode_array(a: np.ndarray, encoding: str) -> list | str:
    """Encode one float array as a JSON list (non-finite -> None) or base64 float64 LE text."""
    a = np.asarray(a, dtype=np.float64)
    if encoding == "base64":
        return base64.b64encode(a.astype("<f8", copy=False).tobytes()).decode("ascii")
    if np.isfinite(a).all():
        return a.tolist()
    return [float(v) if math.isfinite(v) else None for v in a.tolist()]


def decode_array(value: list | str) -> np.ndarray:
    """Inverse of :func:`encode_array` (either encoding; ``None`` entries become NaN)."""
    if isinstance(value, str):
        return np.frombuffer(base64.b64decode(value), dtype="<f8").astype(np.float64)
    return np.array(value, dtype=np.float64)


def encode_block(t: np.ndarray, signals: Mapping[str, np.ndarray], encoding: str) -> bytes:
    """Serialise one bulk block (time + signals) to message bytes."""
    body = {"t": encode_array(t, encoding)}
    for name, values in signals.items():
        body[name] = encode_array(values, encoding)
    return json.dumps(body, separators=(",", ":"), allow_nan=False).encode()


def decode_block(data: bytes) -> dict[str, np.ndarray]:
    """Parse one bulk block back to float arrays."""
    return {k: decode_array(v) for k, v in json.loads(data).items()}
