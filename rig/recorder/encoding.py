"""Payload encoding for MCAP messages: JSON with plain numbers, or base64 float64 blocks.

Bulk blocks are ``{"t": [...], "<signal>": [...]}`` (times in s, values SI). Two encodings:

* ``"json"``: plain JSON number arrays, plottable by any JSON-aware MCAP viewer. Non-finite values
  are written as ``null`` (JSON has no NaN/inf) and read back as NaN.
* ``"base64"``: every array is the base64 text of its little-endian float64 bytes (JSON Schema
  ``contentEncoding: base64``); exact and ~10x faster, but viewers cannot plot it directly.

JSON text is written by ``orjson`` (shortest round-trip float digits, like Python's ``repr``, at about
1/10 of the ``json`` module's cost per number) and read back by ``orjson`` too; any JSON parser reads it.
"""
from __future__ import annotations

import base64
import math
from typing import Any, Mapping

import numpy as np
import orjson

ENCODINGS = ("json", "base64")


_PLAIN = (str, int, type(None))
_PLAIN_ITEMS = frozenset({str, int, bool, float, type(None)})   # list items orjson writes as they are
                                                                 # (non-finite floats as null)


def to_jsonable(value: Any) -> Any:
    """Turn numpy scalars/arrays and non-finite floats into plain JSON values (NaN/inf -> None)."""
    kind = type(value)
    if kind in _PLAIN or kind is bool:
        return value
    if kind is float:
        return value if math.isfinite(value) else None
    if kind is list and _PLAIN_ITEMS.issuperset(map(type, value)):
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
    return orjson.dumps(to_jsonable(obj))


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
    """Serialise one bulk block (time + signals) to message bytes. JSON arrays go to orjson as float64
    arrays (it writes non-finite values as null, like :func:`encode_array`)."""
    arrays = {"t": t, **signals}
    if encoding == "json":
        return orjson.dumps({k: np.ascontiguousarray(v, dtype=np.float64) for k, v in arrays.items()},
                            option=orjson.OPT_SERIALIZE_NUMPY)
    return orjson.dumps({k: encode_array(v, encoding) for k, v in arrays.items()})


def decode_block(data: bytes) -> dict[str, np.ndarray]:
    """Parse one bulk block back to float arrays."""
    return {k: decode_array(v) for k, v in orjson.loads(data).items()}
