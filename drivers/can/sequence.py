"""Per-frame-id 8-bit sequence counters: every gap is reported with the number of frames missed."""
from __future__ import annotations

import numpy as np


class SequenceChecker:
    """Tracks the ``Seq`` counter of each frame id (modulo ``modulus``).

    :meth:`check` returns how many frames were missed before this one (0 if none). A repeated
    counter reads as ``modulus - 1`` missed frames, and a loss of a multiple of ``modulus`` frames
    is invisible: an 8-bit counter cannot tell.
    """

    def __init__(self, modulus: int = 256) -> None:
        self.modulus = modulus
        self._last: dict[int, int] = {}
        self.missed: dict[int, int] = {}   # frame id -> total frames missed

    def check(self, frame_id: int, seq: int) -> int:
        last = self._last.get(frame_id)
        self._last[frame_id] = seq
        if last is None:
            return 0
        gap = (seq - last - 1) % self.modulus
        if gap:
            self.missed[frame_id] = self.missed.get(frame_id, 0) + gap
        return gap

    def check_many(self, frame_id: int, seqs: np.ndarray) -> np.ndarray:
        """:meth:`check` for consecutive frames of one id; returns the frames missed before each."""
        seqs = np.asarray(seqs, dtype=np.int64)
        if seqs.size == 0:
            return np.zeros(0, dtype=np.int64)
        last = self._last.get(frame_id)
        previous = np.concatenate([[seqs[0] - 1 if last is None else last], seqs[:-1]])
        gaps = (seqs - previous - 1) % self.modulus
        self._last[frame_id] = int(seqs[-1])
        if gaps.any():
            self.missed[frame_id] = self.missed.get(frame_id, 0) + int(gaps.sum())
        return gaps
