"""Device curves read back from a recording, in bounded memory.

A long run holds thousands of curves (the demo's take 143 kB each as arrays: a one-hour run's would fill 1.3 GB, and
a report of it twice that). The reader keeps the arrays of the first curves up to :data:`KEPT_BYTES`; of the others it
keeps where they are in the file (the chunk and the message's place in it) and reads them again when asked, a few
chunks' curves at a time (:class:`CurveStore`). A curve looks the same either way (:class:`CurveRecord`).
"""
from __future__ import annotations

import os
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np
from mcap.reader import breakup_chunk

from rig.recorder.encoding import decode_array, loads_message
from rig.recorder.errors import RecordingError
from rig.recorder.salvage import chunk_at

KEPT_BYTES = 128 << 20      # curve arrays held from the reading (beyond: read again from the file when used)
CACHED_CHUNKS = 2           # chunks whose curves a store holds decoded (curves are used in file order)
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


class CurveStore:
    """Curves of one recording file read again on demand: ``place(chunk_offset, index)`` notes a curve message (the
    chunk record's byte offset, the message's place among the chunk's records) and returns its key; ``arrays(key)``
    reads it back (the whole chunk's noted curves decoded at once, :data:`CACHED_CHUNKS` chunks kept). The file must
    not change after it was read: a :class:`~rig.recorder.errors.RecordingError` says so if it did."""

    def __init__(self, path: Path, stamp: tuple[int, int]):
        self.path, self.stamp = Path(os.path.abspath(path)), stamp     # absolute: a later chdir or a worker process
        #                                                               # elsewhere reads the same file; stamp: (size,
        #                                                               # mtime_ns) when it was read
        self._places: list[tuple[int, int]] = []
        self._in_chunk: dict[int, list[int]] = {}       # chunk offset -> indices of its noted curve messages
        self._cache: OrderedDict[int, dict[int, dict[str, Any]]] = OrderedDict()
        self._lock = threading.Lock()

    def place(self, chunk: int, index: int) -> int:
        self._places.append((chunk, index))
        self._in_chunk.setdefault(chunk, []).append(index)
        return len(self._places) - 1

    def arrays(self, key: int) -> dict[str, Any]:
        chunk, index = self._places[key]
        with self._lock:
            curves = self._cache.get(chunk)
            if curves is None:
                curves = self._cache[chunk] = self._read(chunk)
                while len(self._cache) > CACHED_CHUNKS:
                    self._cache.popitem(last=False)
            else:
                self._cache.move_to_end(chunk)
            return curves[index]

    def _read(self, offset: int) -> dict[int, dict[str, Any]]:
        try:
            st = os.stat(self.path)
            if (st.st_size, st.st_mtime_ns) != self.stamp:
                raise RecordingError(f"{self.path}: the recording changed after it was read (its curves are read "
                                     "again from the file when used): read it again")
            with open(self.path, "rb") as f:
                records = breakup_chunk(chunk_at(f, offset), validate_crc=True)
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot read the recording's curves again: "
                                 f"{(exc.strerror or str(exc)).lower()}") from None
        return {i: curve_arrays(loads_message(records[i].data)) for i in self._in_chunk[offset]}

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_cache": OrderedDict(), "_lock": None}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state, _lock=threading.Lock())


class CurveRecord:
    """One device curve: ``number``, ``program``, times ``t`` (s), ``x``/``y`` (SI), optional measured cam angle
    ``angle`` (rad) and ``theory`` arrays, the message's other fields in ``extra``. Its arrays are held, or read again
    from the recording when used (a :class:`CurveStore` and the curve's key in it): what they hold is known without
    reading them (``samples``, ``t_start``, ``t_end``, ``has_angle``, ``theory_sizes``: what a plot or the reader asks
    of every curve before using it)."""

    __slots__ = ("number", "program", "extra", "samples", "t_start", "t_end", "has_angle", "theory_sizes", "_arrays",
                 "_store", "_key")

    def __init__(self, number: int, program: int, t: np.ndarray | None = None, x: np.ndarray | None = None,
                 y: np.ndarray | None = None, angle: np.ndarray | None = None,
                 theory: dict[str, np.ndarray] | None = None, extra: dict[str, Any] | None = None,
                 store: CurveStore | None = None, key: int = -1):
        theory = {} if theory is None else theory
        self.number, self.program, self.extra = number, program, {} if extra is None else extra
        self.samples, self.has_angle = 0 if t is None else int(np.size(t)), angle is not None
        self.t_start, self.t_end = (float(t[0]), float(t[-1])) if self.samples else (None, None)   # s: first, last
        self.theory_sizes = {k: int(np.size(v)) for k, v in theory.items()}
        self._arrays = None if store is not None else {"t": t, "x": x, "y": y, "angle": angle, "theory": theory}
        self._store, self._key = store, key

    def _get(self, name: str) -> Any:
        arrays = self._arrays if self._arrays is not None else self._store.arrays(self._key)
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
