"""Bulk series (plant truth, live data, stand readings) read back in bounded memory.

The demo's plant truth takes 32 kB per machine cycle as arrays: a one-hour run's would hold 290 MB, and a report of
it that again. The reader holds every topic's samples up to one common time — where the first topic's arrays reach
:data:`KEPT_BYTES` — as ``Recording.series`` (what the charts and analyses use, so a join of two topics sees the same
span); of the later blocks it keeps where they are in the file and what span they cover (:class:`Beyond`), so an
export still writes every sample, reading them again a chunk at a time.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Iterator

import numpy as np

if TYPE_CHECKING:
    from rig.recorder.store import MessageStore

KEPT_BYTES = 64 << 20       # bytes of one topic's arrays held from the reading (beyond: read again when exported)


def block_bytes(block: dict[str, np.ndarray]) -> int:
    return sum(v.nbytes for v in block.values())


@dataclass
class Beyond:
    """A topic's samples not held: the ``tail`` of its held blocks past the common cut (arrays kept, at most a block's),
    then its blocks' keys in the recording's series store; samples and time span (s)."""

    keys: list[int] = field(default_factory=list)
    samples: int = 0
    t_first: float = float("nan")
    t_last: float = float("nan")
    tail: dict[str, np.ndarray] | None = None

    def set_tail(self, tail: dict[str, np.ndarray]) -> None:
        t = tail["t"]
        self.tail, self.samples = tail, self.samples + int(t.size)
        self.t_first = float(t[0])
        if self.t_last != self.t_last:                  # NaN: no stored block after it
            self.t_last = float(t[-1])

    def add(self, key: int, block: dict[str, np.ndarray]) -> None:
        t = block.get("t")
        self.keys.append(key)
        if t is not None and t.size:
            self.samples += int(t.size)
            self.t_last = float(t[-1])
            if self.t_first != self.t_first:            # NaN: the first block with samples
                self.t_first = float(t[0])


def blocks(held: dict[str, np.ndarray], beyond: Beyond | None,
           store: MessageStore | None) -> Iterator[dict[str, np.ndarray]]:
    """A topic's samples in file order, a block at a time: the held arrays, then each block read again."""
    if held:
        yield held
    if beyond is not None and beyond.tail is not None:
        yield beyond.tail
    for key in beyond.keys if beyond is not None else ():
        yield store.get(key)


def held_text(topic: str, held: dict[str, np.ndarray], beyond: Beyond, exported: str | None) -> str:
    """'/plant/truth: 0.001–838 s held (838000 samples), 838.001–2000 s (1162000 samples) not held; not exported' (or
    'exported in full: NAME')."""
    t = held.get("t", np.empty(0))
    span = f"{t[0]:.6g}–{t[-1]:.6g} s held ({t.size} samples)" if t.size else "nothing held"
    return (f"{topic}: {span}, {beyond.t_first:.6g}–{beyond.t_last:.6g} s ({beyond.samples} samples) not held; "
            + (f"exported in full: {exported}" if exported else "not exported"))
