"""Messages of a recording read again from the file on demand, so a long run is read in bounded memory.

The reader holds what a report needs at once up to a byte budget (curves: ``rig.recorder.curves``; bulk series:
``rig.recorder.series``); of the rest it notes where each message is (its chunk and its place among the chunk's
records) in a :class:`MessageStore` and decodes it again when it is used.
"""
from __future__ import annotations

import os
import threading
from collections import OrderedDict
from pathlib import Path
from typing import Any, Callable

from mcap.reader import breakup_chunk

from rig.recorder.errors import RecordingError
from rig.recorder.salvage import chunk_at

CACHED_CHUNKS = 2           # chunks whose noted messages a store holds decoded (they are used in file order)


class MessageStore:
    """Messages of one recording file read again on demand: ``place(chunk_offset, index)`` notes a message (the chunk
    record's byte offset, the message's place among the chunk's records) and returns its key; ``get(key)`` reads it
    back, ``decode(data)`` of its bytes (its chunk read once, each message decoded when first asked for — a store shared
    by several topics decodes only the topic read —, :data:`CACHED_CHUNKS` chunks kept). ``what`` names the messages in
    errors. The file must not change after it was read: a :class:`~rig.recorder.errors.RecordingError` says so if it
    did."""

    def __init__(self, path: Path, stamp: tuple[int, int], decode: Callable[[bytes], Any], what: str):
        self.path, self.stamp = Path(os.path.abspath(path)), stamp     # absolute: a later chdir or a worker process
        #                                                               # elsewhere reads the same file; stamp: (size,
        #                                                               # mtime_ns) when it was read
        self.decode, self.what = decode, what
        self._places: list[tuple[int, int]] = []
        self._cache: OrderedDict[int, tuple[list, dict[int, Any]]] = OrderedDict()   # chunk: records, decoded
        self._lock = threading.Lock()

    def place(self, chunk: int, index: int) -> int:
        self._places.append((chunk, index))
        return len(self._places) - 1

    def get(self, key: int) -> Any:
        chunk, index = self._places[key]
        with self._lock:
            cached = self._cache.get(chunk)
            if cached is None:
                cached = self._cache[chunk] = (self._read(chunk), {})
                while len(self._cache) > CACHED_CHUNKS:
                    self._cache.popitem(last=False)
            else:
                self._cache.move_to_end(chunk)
            records, decoded = cached
            if index not in decoded:
                decoded[index] = self.decode(records[index].data)
            return decoded[index]

    def _read(self, offset: int) -> list:
        try:
            st = os.stat(self.path)
            if (st.st_size, st.st_mtime_ns) != self.stamp:
                raise RecordingError(f"{self.path}: the recording changed after it was read (its {self.what} are read "
                                     "again from the file when used): read it again")
            with open(self.path, "rb") as f:
                records = breakup_chunk(chunk_at(f, offset), validate_crc=True)
        except OSError as exc:
            raise RecordingError(f"{self.path}: cannot read the recording's {self.what} again: "
                                 f"{(exc.strerror or str(exc)).lower()}") from None
        return records

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_cache": OrderedDict(), "_lock": None}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state, _lock=threading.Lock())
