"""Host-side incremental-encoder decoding: sampled A/B(/Z) levels → counts → angle and speed.

Quadrature: the levels (A, B) run through the Gray sequence 00, 10, 11, 01 for positive rotation.
Between two samples the position in that sequence moves by 0 (no change), +1, −1, or 2: both
channels changed at once, the direction is unknown — an *illegal transition*, counted and never
absorbed into the position. ×N decoding (N = 1, 2, 4) reports ``floor((c4 + 4/N − 1)/(4/N))`` of the
×4 position c4 (×1 steps on A rising with B low, ×2 on every A edge), relative to the first sample.

Speed (:class:`SpeedEstimator`): by frequency — counts in the last ``gate_time`` over that time — when
the gate holds at least ``min_counts``, otherwise by period — counts between the last two count
changes over the time between them, bounded by one count over the time since the last change (so
it decays to zero when the shaft stops).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_STATE_OF_LEVELS = np.array([0, 1, 3, 2])  # index A + 2B -> position in the Gray sequence 00,10,11,01


def counts_to_angle(count: np.ndarray | int, ppr: int, multiplier: int = 4) -> np.ndarray:
    """Angle [rad] of a ×``multiplier`` count of an encoder with ``ppr`` pulses per revolution."""
    return np.asarray(count, dtype=float) * (2.0 * math.pi / (multiplier * ppr))


def _check(ppr: int, multiplier: int) -> None:
    if not (isinstance(ppr, (int, np.integer)) and ppr >= 1):
        raise ValueError(f"encoder ppr must be a positive integer, got {ppr!r}")
    if multiplier not in (1, 2, 4):
        raise ValueError(f"quadrature multiplier must be 1, 2 or 4, got {multiplier!r}")


@dataclass(frozen=True)
class Decoded:
    """Decoder output per sample of one chunk."""

    count: np.ndarray      # ×N count since the first sample (int64)
    edge_time: np.ndarray  # sample time at which the count last changed [s] (NaN: not yet)
    illegal: np.ndarray    # illegal transitions counted since the first sample (int64)
    index: np.ndarray      # sample indices of this chunk where Z rose


class QuadratureDecoder:
    """Stateful ×1/×2/×4 decoder of sampled quadrature levels (feed chunks in time order)."""

    def __init__(self, ppr: int, multiplier: int = 4) -> None:
        _check(ppr, multiplier)
        self.ppr, self.multiplier = int(ppr), int(multiplier)
        self._state: int | None = None  # Gray position of the last sample
        self._z = 0
        self._c4 = 0
        self._origin = 0
        self._illegal = 0
        self._edge_t = math.nan

    @property
    def illegal_transitions(self) -> int:
        """Illegal A/B transitions seen so far."""
        return self._illegal

    def _scaled(self, c4: np.ndarray | int) -> np.ndarray:
        d = 4 // self.multiplier
        return (np.asarray(c4) + d - 1) // d

    def angle(self, count: np.ndarray | int) -> np.ndarray:
        """Angle [rad] for a count of this decoder."""
        return counts_to_angle(count, self.ppr, self.multiplier)

    def decode(self, t: np.ndarray, levels: np.ndarray) -> Decoded:
        """Decode ``levels`` (n, 2) [A, B] or (n, 3) [A, B, Z] of 0/1 sampled at times ``t`` [s]."""
        t = np.asarray(t, dtype=float)
        lv = np.asarray(levels)
        if lv.ndim != 2 or lv.shape[1] not in (2, 3) or lv.shape[0] != t.size or t.ndim != 1:
            raise ValueError(f"quadrature levels must be (n, 2) or (n, 3) with n = len(t) = {t.size}, "
                             f"got shape {lv.shape}")
        if not np.all((lv == 0) | (lv == 1)):
            raise ValueError("quadrature levels must be 0 or 1")
        lv = lv.astype(np.int64)
        if t.size == 0:
            return Decoded(np.empty(0, np.int64), np.empty(0), np.empty(0, np.int64), np.empty(0, np.int64))
        pos = _STATE_OF_LEVELS[lv[:, 0] + 2 * lv[:, 1]]
        if self._state is None:
            self._state = self._c4 = int(pos[0])
            self._origin = int(self._scaled(self._c4))
            self._z = int(lv[0, 2]) if lv.shape[1] == 3 else 0
        d = np.diff(np.concatenate(([self._state], pos))) % 4
        c4 = self._c4 + np.cumsum(np.where(d == 1, 1, np.where(d == 3, -1, 0)))
        illegal = self._illegal + np.cumsum(d == 2)
        count = self._scaled(c4) - self._origin
        before = int(self._scaled(self._c4)) - self._origin
        changed = count != np.concatenate(([before], count[:-1]))
        last = np.maximum.accumulate(np.where(changed, np.arange(t.size), -1))
        edge_time = np.where(last >= 0, t[np.maximum(last, 0)], self._edge_t)
        index = np.empty(0, np.int64)
        if lv.shape[1] == 3:
            z = lv[:, 2]
            index = np.flatnonzero(np.diff(np.concatenate(([self._z], z))) == 1)
            self._z = int(z[-1])
        self._state, self._c4, self._illegal = int(pos[-1]), int(c4[-1]), int(illegal[-1])
        self._edge_t = float(edge_time[-1])
        return Decoded(count.astype(np.int64), edge_time, illegal.astype(np.int64), index)


class SpeedEstimator:
    """Angular speed [rad/s] from latched (time, count, last-change time), switching frequency ↔ period.

    Works on the output of :class:`QuadratureDecoder` or on a counter card's latches. ``gate_time``
    [s] is the frequency-method window; below ``min_counts`` counts in it the period method is used.
    """

    def __init__(self, ppr: int, multiplier: int = 4, gate_time: float = 0.01, min_counts: int = 10) -> None:
        _check(ppr, multiplier)
        if not gate_time > 0.0 or min_counts < 1:
            raise ValueError(f"gate_time must be > 0 s and min_counts >= 1, got {gate_time!r}, {min_counts!r}")
        self.rad_per_count = 2.0 * math.pi / (multiplier * ppr)
        self.gate_time, self.min_counts = float(gate_time), int(min_counts)
        self._hist_t = np.empty(0)
        self._hist_c = np.empty(0, np.int64)
        self._changes_t = np.full(2, math.nan)  # last two distinct count-change times
        self._changes_c = np.zeros(2, np.int64)  # counts right after them

    def update(self, t: np.ndarray, count: np.ndarray, edge_time: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Speed [rad/s] per sample and a mask of samples estimated by the period method."""
        t = np.asarray(t, dtype=float)
        count = np.asarray(count, dtype=np.int64)
        edge_time = np.asarray(edge_time, dtype=float)
        if not (t.shape == count.shape == edge_time.shape and t.ndim == 1):
            raise ValueError(f"t, count and edge_time must be 1-D of equal length, got {t.shape}, "
                             f"{count.shape}, {edge_time.shape}")
        if t.size == 0:
            return np.empty(0), np.empty(0, bool)
        # frequency method over the gate (history of earlier chunks included)
        ht = np.concatenate((self._hist_t, t))
        hc = np.concatenate((self._hist_c, count))
        n0 = self._hist_t.size
        first = np.searchsorted(ht, t - self.gate_time, side="left")
        first = np.minimum(first, np.arange(n0, ht.size))
        span = ht[n0:] - ht[first]
        dc = hc[n0:] - hc[first]
        with np.errstate(invalid="ignore", divide="ignore"):
            w_freq = np.where(span > 0.0, dc / span, 0.0)
        # period method between the last two distinct count-change times
        prev_et = np.concatenate(([self._changes_t[1]], edge_time[:-1]))
        new = np.isfinite(edge_time) & ~(edge_time == prev_et)
        rec_t = np.concatenate((self._changes_t, edge_time[new]))
        rec_c = np.concatenate((self._changes_c, count[new]))
        last = 1 + np.cumsum(new)
        t1, c1, t0, c0 = rec_t[last], rec_c[last], rec_t[last - 1], rec_c[last - 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            w_per = (c1 - c0) / (t1 - t0)
            bound = 1.0 / (t - t1)
            w_per = np.sign(w_per) * np.minimum(np.abs(w_per), bound)
        w_per = np.where(np.isfinite(w_per), w_per, 0.0)
        by_period = np.abs(dc) < self.min_counts
        keep = ht >= t[-1] - self.gate_time
        self._hist_t, self._hist_c = ht[keep], hc[keep]
        self._changes_t, self._changes_c = rec_t[-2:].copy(), rec_c[-2:].copy()
        return np.where(by_period, w_per, w_freq) * self.rad_per_count, by_period
