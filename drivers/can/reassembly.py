"""Curve reassembly from CurveHeader / CurveBlock(FD) / CurveEnd frames.

Pairs arrive as raw 20-bit counts; the end frame's count and CRC-16/CCITT-FALSE (over the raw pairs
as little-endian int32, X then Y) are checked before a curve is declared complete. Anything that
does not add up becomes a problem string and the (partial) curve is kept, never silently dropped.
"""
from __future__ import annotations

import binascii
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Curve:
    """One transferred curve: pairs in SI (X m, Y N) at device times ``t`` (s; None if they did not
    arrive); ``received`` marks the pairs that arrived."""

    number: int
    program: int
    t: np.ndarray | None
    x: np.ndarray
    y: np.ndarray
    received: np.ndarray
    clipped: int = 0
    complete: bool = False
    problems: list[str] = field(default_factory=list)


def crc_of(raw_x: np.ndarray, raw_y: np.ndarray) -> int:
    """CRC-16/CCITT-FALSE of raw pairs packed as little-endian int32, X then Y of each pair."""
    return binascii.crc_hqx(np.column_stack([raw_x, raw_y]).astype("<i4").tobytes(), 0xFFFF)


class CurveAssembler:
    """Collects the blocks of one curve at a time; finished curves (complete or not) go to ``done``."""

    def __init__(self, x_lsb: float, y_lsb: float, pairs_per_fd_block: int) -> None:
        self.x_lsb, self.y_lsb, self.per_block = x_lsb, y_lsb, pairs_per_fd_block
        self.done: list[Curve] = []
        self._number: int | None = None
        self._program = 0
        self._raw: np.ndarray = np.zeros((0, 2), dtype=np.int64)
        self._got: np.ndarray = np.zeros(0, dtype=bool)
        self._t_start: float | None = None
        self._dt = 0.0
        self._offsets: np.ndarray = np.zeros(0)

    def header(self, number: int, count: int, program: int) -> list[str]:
        """A new curve starts; an unfinished previous one is closed as incomplete."""
        problems = self.abandon(f"header of curve {number} arrived before its end frame")
        self._number, self._program = number, program
        self._raw = np.zeros((count, 2), dtype=np.int64)
        self._got = np.zeros(count, dtype=bool)
        self._t_start, self._dt, self._offsets = None, 0.0, np.full(count, np.nan)
        return problems

    def timing(self, number_low8: int, t_start: float, dt: float) -> list[str]:
        """Pair i was sampled at ``t_start + i * dt`` (s); ``dt == 0``: offsets follow (:meth:`times`)."""
        if self._number is None or self._number % 256 != number_low8:
            return [f"curve timing (curve {number_low8} mod 256) without its header"]
        self._t_start, self._dt = t_start, dt
        return []

    def times(self, number_low4: int, first: int, offsets: np.ndarray) -> list[str]:
        """Sample times (s after the start) of pairs ``first, first + 1, ...``."""
        if self._number is None or self._number % 16 != number_low4:
            return [f"curve times (curve {number_low4} mod 16, pair {first}) without their header"]
        n = max(0, min(len(offsets), len(self._offsets) - first))
        self._offsets[first:first + n] = offsets[:n]
        return []

    def pairs(self, number_bits: np.ndarray, number_mod: int, first: np.ndarray, count: np.ndarray,
                   raw: np.ndarray) -> list[tuple[int, str]]:
        """Store the raw pairs of consecutive blocks: block ``i`` holds ``count[i]`` pairs ``raw[i, :count[i]]``
        (``raw`` of shape (n, k, 2)) from pair index ``first[i]`` of the curve whose number modulo
        ``number_mod`` is ``number_bits[i]``. Returns the problems as (block index, text)."""
        number_bits, first, count = (np.asarray(a, dtype=np.int64) for a in (number_bits, first, count))
        size = len(self._got)
        ours = (number_bits == self._number % number_mod) if self._number is not None else np.zeros(len(first), bool)
        fits = first + count <= size
        problems = [(i, f"curve block (curve {number_bits[i]} mod {number_mod}, pair {first[i]}) without its header")
                    if not ours[i] else
                    (i, f"curve {self._number}: block at pair {first[i]} (+{count[i]}) beyond the announced {size} pairs")
                    for i in np.flatnonzero(~(ours & fits)).tolist()]
        keep = np.flatnonzero(ours & fits)
        if keep.size:
            n = count[keep]
            slot = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
            rows = np.repeat(keep, n)
            at = first[rows] + slot
            self._raw[at] = raw[rows, slot]
            self._got[at] = True
        return problems

    def pair_run(self, number_bits: int, number_mod: int, first: int, xs: list[int], ys: list[int]) -> str | None:
        """Store the raw pairs of one block (pairs ``first, first + 1, ...``) of the curve whose number
        modulo ``number_mod`` is ``number_bits``; returns the problem, if any."""
        if self._number is None or self._number % number_mod != number_bits:
            return f"curve block (curve {number_bits} mod {number_mod}, pair {first}) without its header"
        if first + len(xs) > len(self._got):
            return f"curve {self._number}: block at pair {first} (+{len(xs)}) beyond the announced {len(self._got)} pairs"
        if len(xs) == 1:                     # a classic frame's one pair: scalar stores are 3x faster
            self._raw[first] = xs[0], ys[0]
            self._got[first] = True
        else:
            stop = first + len(xs)
            self._raw[first:stop, 0], self._raw[first:stop, 1] = xs, ys
            self._got[first:stop] = True
        return None

    def end(self, number_low16: int, count: int, crc: int, clipped: int) -> list[str]:
        """Close the curve: check number (its low 16 bits, as the end frame carries it), count, missing pairs and
        CRC."""
        if self._number is None or self._number % 65536 != number_low16:
            return [f"end frame of curve {number_low16} (mod 65536) without its header"]
        number = self._number
        problems = []
        if count != len(self._got):
            problems.append(f"curve {number}: end frame says {count} pairs, header said {len(self._got)}")
        missing = int(np.count_nonzero(~self._got))
        if missing:
            problems.append(f"curve {number}: {missing} of {len(self._got)} pairs missing")
        elif crc_of(self._raw[:, 0], self._raw[:, 1]) != crc:
            problems.append(f"curve {number}: checksum mismatch (got 0x{crc:04X})")
        if self._sample_times() is None:
            problems.append(f"curve {number}: sample times missing")
        self._finish(clipped, problems)
        return problems

    @property
    def in_transfer(self) -> bool:
        """Whether a curve's header has arrived and its end has not."""
        return self._number is not None

    def abandon(self, why: str) -> list[str]:
        """End the curve being assembled, if any, as incomplete (``why``: what cut it); its problems."""
        if self._number is None:
            return []
        problems = [f"curve {self._number}: {why}"]
        self._finish(0, problems)
        return problems

    def _sample_times(self) -> np.ndarray | None:
        if self._t_start is None:
            return None
        if self._dt > 0:
            return self._t_start + np.arange(len(self._got)) * self._dt
        return None if np.isnan(self._offsets).any() else self._t_start + self._offsets

    def _finish(self, clipped: int, problems: list[str]) -> None:
        self.done.append(Curve(self._number, self._program, self._sample_times(), self._raw[:, 0] * self.x_lsb,
                               self._raw[:, 1] * self.y_lsb, self._got, clipped, not problems, problems))
        self._number = None
