"""Per-frame-id 8-bit sequence counters: every gap is reported with the number of frames missed."""
from __future__ import annotations


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
