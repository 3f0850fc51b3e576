"""Host-side incremental-encoder decoding: sampled A/B(/Z) levels → counts → angle and speed.

Quadrature: the levels (A, B) run through the Gray sequence 00, 10, 11, 01 for positive rotation.
Between two samples the position in that sequence moves by 0 (no change), +1, −1, or 2: both
channels changed at once, the direction is unknown — an *illegal transition*, counted and never
absorbed into the position. ×N decoding (N = 1, 2, 4) reports ``floor((c4 + 4/N − 1)/(4/N))`` of the
×4 position c4 (×1 steps on A rising with B low, ×2 on every A edge), relative to the first sample.

Speed (:class:`SpeedEstimator`): mixed frequency/period method timed by the latched edge times — edges
counted over a gate at high speed, the time between the last two edges at low speed, a decaying bound
at standstill; the switch-over speed, the windows and the error bounds are in the class docstring.
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


NO_ESTIMATE, FREQUENCY, PERIOD, BOUND = 0, 1, 2, 3
METHOD_NAMES = {NO_ESTIMATE: "none", FREQUENCY: "frequency", PERIOD: "period", BOUND: "standstill bound"}
GATE_TIME = 2e-3       # s, frequency-method gate (default)
MIN_COUNTS = 4         # counts in the gate below which the period method is used (default)
EDGE_TOLERANCE = 1e-3  # s an edge time may lie after its reading's time; later ones are stale (wrapped) stamps
READING_JITTER = 1e-3  # s by which the reading times may scatter (bus delays): allowance of the standstill bound


@dataclass(frozen=True)
class SpeedEstimate:
    """Speed estimates, one per reading."""

    speed: np.ndarray   # rad/s: mean speed over the estimate's window (BOUND: an upper bound of it; NaN: none)
    time: np.ndarray    # s: midpoint of that window, the instant the mean belongs to (device time; NO_ESTIMATE: the
    #                     one edge seen, so that the times never go back to the next estimate's window)
    method: np.ndarray  # int8: NO_ESTIMATE, FREQUENCY, PERIOD or BOUND (METHOD_NAMES)


class SpeedEstimator:
    """Angular speed from latched encoder readings (reading time, count, time of the count's last edge):
    mixed frequency/period method, timed by the latched edge times.

    Every reading k carries the count c_k and the time e_k of the edge that made it c_k, so the shaft
    was *exactly* on a count boundary at each distinct edge time. A speed is therefore taken between two
    such edges, ``(c_b − c_a)·Δ/(e_b − e_a)`` with ``Δ = rad_per_count``: the mean speed over
    [e_a, e_b], stamped at the window's midpoint (exact for constant and linearly changing speed).
    The windows:

    * **frequency method** (high speed): edges counted over the gate — e_a is the latest edge at least
      ``gate_time`` before e_b. Used while the gate holds at least ``min_counts`` counts, i.e. above the
      switch-over speed ``ω_s = min_counts·Δ/gate_time`` (1024 PPR ×4, 2 ms, 4 counts: 3.07 rad/s).
    * **period method** (low speed, below ω_s): the time between the last two distinct edges the host has
      seen (usually one count apart at low speed; at most one reading interval at higher speed).
    * **standstill bound**: when no edge arrived for longer than the chosen estimate allows, the shaft
      has moved less than one count since the last edge, so |ω| < Δ/(time without an edge) and the
      estimate is clipped to that: it decays to 0 at standstill instead of holding the last period.
      The time without an edge is measured by the host (reading times), less ``reading_jitter`` so that
      a reading the bus delayed cannot clip a steady speed.
    * edge times count only once the count has left ``initial_count`` (its power-on value: a card
      that has seen no edge sends a placeholder stamp). Until then the shaft has not turned a count:
      speed 0 (BOUND). With one edge seen there is no estimate yet: NaN (NO_ESTIMATE).

    The reading times ``t`` (the host's reception times, delayed and jittered by the bus) serve only to
    measure the time without an edge and the staleness check; they never time a window. Counting edges
    per reading interval instead (Δcount/Δt, the plain frequency method) is quantised to ±Δ/Δt — at
    1 kHz readings ±1.53 rad/s: a shaft at 0.5 rad/s reads 0 or 1.53 — and a reading delayed by the bus
    shows as a spike.

    Error bounds (monotone motion; edge times rounded to q, 1 µs in the CAN frame, ±q/2 at each end):
    |ω̂ − ω̄| ≤ |ω̄|·q/(e_b − e_a) — relative ≤ q/gate_time for the frequency method, ≤ q·|ω|/Δ for one
    count in the period method (0.2 % at ω_s). A reversal inside the window adds up to Δ/(e_b − e_a)
    (a count boundary is passed at kΔ going up, (k+1)Δ going down). ω̄ differs from the speed at the
    stamp by at most max|ω̈|·(e_b − e_a)²/24.

    Works on the output of :class:`QuadratureDecoder` (edge time = the sample that saw the change) or on
    a counter card's latches (exact edge times). Feed readings in time order, in chunks of any size.
    """

    def __init__(self, rad_per_count: float, gate_time: float = GATE_TIME, min_counts: int = MIN_COUNTS,
                 initial_count: int = 0, reading_jitter: float = READING_JITTER) -> None:
        if not (rad_per_count > 0.0 and math.isfinite(rad_per_count)):
            raise ValueError(f"rad_per_count must be a positive angle (rad), got {rad_per_count!r}")
        if not gate_time > 0.0 or min_counts < 1:
            raise ValueError(f"gate_time must be > 0 s and min_counts >= 1, got {gate_time!r}, {min_counts!r}")
        self.rad_per_count = float(rad_per_count)
        self.gate_time, self.min_counts = float(gate_time), int(min_counts)
        if not reading_jitter >= 0.0:
            raise ValueError(f"reading_jitter must be >= 0 s, got {reading_jitter!r}")
        self.reading_jitter = float(reading_jitter)
        self._rec_e = np.empty(0)                 # distinct edge times seen (s) ...
        self._rec_c = np.empty(0, np.int64)       # ... the counts they made ...
        self._rec_t = np.empty(0)                 # ... and the reading time that brought each
        self.initial_count = int(initial_count)
        self._armed = False                       # the count has left its power-on value
        self._last_e = -math.inf

    @classmethod
    def for_encoder(cls, ppr: int, multiplier: int = 4, **kw: float) -> "SpeedEstimator":
        """Estimator for an encoder of ``ppr`` pulses per revolution read with ×``multiplier`` decoding."""
        _check(ppr, multiplier)
        return cls(float(counts_to_angle(1, ppr, multiplier)), **kw)

    @property
    def switch_speed(self) -> float:
        """Speed (rad/s) above which the frequency method is used: ``min_counts`` counts per gate."""
        return self.min_counts * self.rad_per_count / self.gate_time

    def update(self, t: np.ndarray, count: np.ndarray, edge_time: np.ndarray) -> SpeedEstimate:
        """Estimates for readings at times ``t`` [s] with latched ``count`` and ``edge_time`` [s] (NaN, a
        stamp while the count is still at ``initial_count``, or one later than the reading: no new edge)."""
        t = np.asarray(t, dtype=float)
        count = np.asarray(count, dtype=np.int64)
        edge_time = np.asarray(edge_time, dtype=float)
        if not (t.shape == count.shape == edge_time.shape and t.ndim == 1):
            raise ValueError(f"t, count and edge_time must be 1-D of equal length, got {t.shape}, "
                             f"{count.shape}, {edge_time.shape}")
        n = t.size
        speed, stamp, method = np.zeros(n), t.copy(), np.full(n, BOUND, np.int8)    # no edge yet: at rest
        if n == 0:
            return SpeedEstimate(speed, stamp, method)
        armed = np.ones(n, bool)
        if not self._armed:
            moved = np.flatnonzero(count != self.initial_count)
            armed = np.arange(n) >= (moved[0] if moved.size else n)
            self._armed = bool(moved.size)
        ok = armed & np.isfinite(edge_time) & (edge_time <= t + EDGE_TOLERANCE)
        ev = np.where(ok, edge_time, -np.inf)
        new = ev > np.maximum.accumulate(np.concatenate(([self._last_e], ev)))[:-1]
        rec_e = np.concatenate((self._rec_e, edge_time[new]))
        rec_c = np.concatenate((self._rec_c, count[new]))
        rec_t = np.concatenate((self._rec_t, t[new]))
        if rec_e.size:
            k = self._rec_e.size - 1 + np.cumsum(new)          # latest edge seen at each reading (-1: none)
            two = k >= 1
            kk, p = np.maximum(k, 0), np.maximum(k - 1, 0)
            e_k, c_k = rec_e[kk], rec_c[kk]
            j = np.maximum(np.searchsorted(rec_e, e_k - self.gate_time, side="right") - 1, 0)
            dc_f, de_f = c_k - rec_c[j], e_k - rec_e[j]
            since = t - rec_t[kk] - self.reading_jitter   # at least this long without a new edge (≤ 0: unknown)
            with np.errstate(invalid="ignore", divide="ignore"):
                w_f = np.where(de_f > 0.0, dc_f / np.where(de_f > 0.0, de_f, 1.0), 0.0)
                w_p = np.where(two, (c_k - rec_c[p]) / np.where(two, e_k - rec_e[p], 1.0), 0.0)
                bound = np.where(since > 0.0, 1.0 / np.where(since > 0.0, since, 1.0), np.inf)
            freq = two & (np.abs(dc_f) >= self.min_counts) & (np.abs(w_f) * self.gate_time >= self.min_counts)
            w = np.where(freq, w_f, w_p)
            bounded = two & (np.abs(w) > bound)
            freq &= ~bounded
            per = two & ~freq & ~bounded
            w = np.where(bounded, np.sign(w) * np.where(bounded, bound, 0.0), w)
            speed = np.where(two, w * self.rad_per_count, np.where(k >= 0, np.nan, 0.0))
            stamp = np.select([freq, per, bounded, k >= 0], [0.5 * (rec_e[j] + e_k), 0.5 * (rec_e[p] + e_k),
                                                              0.5 * (e_k + t), e_k], t)     # one edge: its time
            method = np.select([freq, per, bounded, k < 0], [FREQUENCY, PERIOD, BOUND, BOUND],
                               NO_ESTIMATE).astype(np.int8)
            keep = max(0, min(rec_e.size - 2,
                              int(np.searchsorted(rec_e, rec_e[-1] - self.gate_time, side="right")) - 1))
            self._rec_e, self._rec_c, self._rec_t = rec_e[keep:], rec_c[keep:], rec_t[keep:]
            self._last_e = float(rec_e[-1])
        return SpeedEstimate(speed, stamp, method)
