"""Device curves read back from a recording, in bounded memory.

A long run holds thousands of curves (the demo's take 143 kB each as arrays: a one-hour run's would fill 1.3 GB, and a
report of it twice that). The reader keeps the arrays of the first curves up to :data:`KEPT_BYTES`; of the others it
keeps where they are in the file (the chunk and the message's place in it) and reads them again when asked, a few
chunks' curves at a time (a :class:`~rig.recorder.store.MessageStore`). A curve looks the same either way
(:class:`CurveRecord`).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from rig.recorder.encoding import decode_array, loads_message
from rig.recorder.store import MessageStore

KEPT_BYTES = 128 << 20      # curve arrays held from the reading (beyond: read again from the file when used)
ARRAYS = ("t", "x", "y", "angle", "theory")


def curve_arrays(msg: dict) -> dict[str, Any]:
    """The arrays of a decoded ``/device/curve`` message: t, x, y (SI), angle (rad, or None), theory (dict)."""
    return {"t": decode_array(msg["t"]), "x": decode_array(msg["x"]), "y": decode_array(msg["y"]),
            "angle": decode_array(msg["angle"]) if "angle" in msg else None,
            "theory": {k: decode_array(v) for k, v in msg.get("theory", {}).items()}}


def nbytes(arrays: dict[str, Any]) -> int:
    """Bytes the arrays of :func:`curve_arrays` hold."""
    return sum(v.nbytes for k, v in arrays.items() if k != "theory" and v is not None) + \
        sum(v.nbytes for v in arrays["theory"].values())


def curve_message(data: bytes) -> dict[str, Any]:
    """The arrays of an encoded ``/device/curve`` message (a curve store's decoder)."""
    return curve_arrays(loads_message(data))


class CurveRecord:
    """One device curve: ``number``, ``program``, times ``t`` (s), ``x``/``y`` (SI), optional measured cam angle
    ``angle`` (rad) and ``theory`` arrays, the message's other fields in ``extra``. Its arrays are held, or read again
    from the recording when used (a :class:`~rig.recorder.store.MessageStore` and the curve's key in it): what they hold
    is known without reading them (``samples``, ``t_start``, ``t_end``, ``has_angle``, ``theory_sizes``: what a plot or
    the reader asks of every curve before using it)."""

    __slots__ = ("number", "program", "extra", "samples", "t_start", "t_end", "has_angle", "theory_sizes", "_arrays",
                 "_store", "_key")

    def __init__(self, number: int, program: int, t: np.ndarray | None = None, x: np.ndarray | None = None,
                 y: np.ndarray | None = None, angle: np.ndarray | None = None,
                 theory: dict[str, np.ndarray] | None = None, extra: dict[str, Any] | None = None,
                 store: MessageStore | None = None, key: int = -1):
        theory = {} if theory is None else theory
        self.number, self.program, self.extra = number, program, {} if extra is None else extra
        self.samples, self.has_angle = 0 if t is None else int(np.size(t)), angle is not None
        self.t_start, self.t_end = (float(t[0]), float(t[-1])) if self.samples else (None, None)   # s: first, last
        self.theory_sizes = {k: int(np.size(v)) for k, v in theory.items()}
        self._arrays = None if store is not None else {"t": t, "x": x, "y": y, "angle": angle, "theory": theory}
        self._store, self._key = store, key

    def _get(self, name: str) -> Any:
        arrays = self._arrays if self._arrays is not None else self._store.get(self._key)
        return arrays[name]

    t = property(lambda self: self._get("t"))
    x = property(lambda self: self._get("x"))
    y = property(lambda self: self._get("y"))
    angle = property(lambda self: self._get("angle"))
    theory = property(lambda self: self._get("theory"))

    @property
    def held(self) -> bool:
        """The arrays are in memory (not read again from the file when used)."""
        return self._arrays is not None

    def __repr__(self) -> str:
        return f"CurveRecord(number={self.number}, program={self.program}{'' if self.held else ', read on demand'})"
