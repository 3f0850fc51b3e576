"""Curve memory: which input samples become stored pairs (by Δt, ΔX or ΔY) and what happens when the
memory is full ("stop": keep the first pairs, drop the rest; "decimate": halve the resolution and go on).

Rows are [t, x, y, y2]. Δt: a pair is stored at the first sample of each Δt interval counted from the
measurement start, so after a decimation the memory holds exactly what sampling with 2Δt would have
stored. ΔX/ΔY: a pair is stored when the value moved by at least the step from the last stored pair;
decimation keeps every second stored pair and doubles the step. The last sample of a measurement is
always stored when there is room (or room can be made by decimating).
"""
from __future__ import annotations

import numpy as np

_REL = 1e-9   # relative tolerance on the step, against rounding in the inputs


class CurveMemory:
    """Fixed-capacity store of one curve's pairs, with its sampling mode and overflow policy."""

    def __init__(self, capacity: int, mode: str, delta: float, policy: str) -> None:
        self.capacity, self.mode, self.policy = capacity, mode, policy
        self._base_delta = delta
        self.rows = np.empty((capacity, 4))
        self.begin(0.0)

    def begin(self, t0: float) -> None:
        """Empty the memory for a measurement starting at ``t0`` (s)."""
        self.count = 0
        self.delta = self._base_delta
        self.anchor = t0
        self.decimations = 0
        self.dropped = 0
        self.overflow = False
        self._last_cell = -np.inf
        self._ref: float | None = None
        self._last_row: np.ndarray | None = None

    def add(self, rows: np.ndarray) -> None:
        """Offer consecutive input samples (k, 4) of the running measurement."""
        if len(rows) == 0:
            return
        self._last_row = rows[-1].copy()
        if self.mode == "time":
            self._add_time(rows)
        else:
            self._add_delta(rows, 1 if self.mode == "dx" else 2)

    def finish(self) -> np.ndarray:
        """Store the measurement's last sample if missing (and there is room or it can be made by decimating)
        and return the stored pairs (n, 4)."""
        last = self._last_row
        if last is not None and (self.count == 0 or self.rows[self.count - 1, 0] != last[0]):
            if self.count == self.capacity and self.policy == "decimate":
                self._decimate()
            if self.count < self.capacity:
                self.rows[self.count] = last
                self.count += 1
        return self.rows[:self.count].copy()

    # --- Δt ---------------------------------------------------------------------------------------
    def _cells(self, t: np.ndarray) -> np.ndarray:
        """Δt interval of each time (s): the slack covers the rounding of ``t - anchor``, which grows with the
        magnitude of the times (4 ulp of them), not only with the step: without it, samples on the interval
        boundaries fall into the previous interval and are skipped once t passes ~500 s at 0.1 ms."""
        slack = _REL + 4.0 * np.finfo(float).eps * (np.abs(t) + abs(self.anchor)) / self.delta
        return np.floor((t - self.anchor) / self.delta + slack)

    def _first_in_cell(self, t: np.ndarray, last_cell: float) -> np.ndarray:
        cells = self._cells(t)
        return cells > np.concatenate([[last_cell], cells[:-1]])

    def _add_time(self, rows: np.ndarray) -> None:
        rows = rows[self._first_in_cell(rows[:, 0], self._last_cell)]
        while len(rows):
            room = self.capacity - self.count
            if len(rows) <= room or self.policy == "stop":
                self._append(rows[:room])
                if len(rows) > room:
                    self.dropped += len(rows) - room
                    self.overflow = True
                self._last_cell = self._cells(rows[-1:, 0])[0]
                return
            self._decimate()
            rows = rows[self._first_in_cell(rows[:, 0], self._last_cell)]

    # --- ΔX / ΔY ----------------------------------------------------------------------------------
    def _add_delta(self, rows: np.ndarray, col: int) -> None:
        v = rows[:, col]
        pos, n = 0, len(v)
        if self._ref is None:
            self._store_one(rows[0], col)
            pos = 1
        while pos < n:
            j, width = None, 64
            while j is None:
                hit = np.nonzero(np.abs(v[pos:pos + width] - self._ref) >= self.delta * (1 - _REL))[0]
                if hit.size:
                    j = pos + int(hit[0])
                elif pos + width >= n:
                    return
                width *= 4
            self._store_one(rows[j], col)
            pos = j + 1

    def _store_one(self, row: np.ndarray, col: int) -> None:
        if self.count == self.capacity and self.policy == "decimate":
            self._decimate()
        if self.count < self.capacity:
            self._append(row[None, :])
        else:
            self.dropped += 1
            self.overflow = True
        self._ref = float(row[col])

    # --- shared -----------------------------------------------------------------------------------
    def _append(self, rows: np.ndarray) -> None:
        k = len(rows)
        self.rows[self.count:self.count + k] = rows
        self.count += k

    def _decimate(self) -> None:
        """Halve the stored resolution: double the step and keep the pairs it would have stored."""
        self.delta *= 2.0
        self.decimations += 1                        # thinned, not cut: ``overflow`` stays for the policy "stop"
        stored = self.rows[:self.count]
        keep = self._first_in_cell(stored[:, 0], -np.inf) if self.mode == "time" else \
            np.arange(self.count) % 2 == 0
        kept = stored[keep]
        self.count = len(kept)
        self.rows[:self.count] = kept
        if self.mode == "time":
            self._last_cell = self._cells(kept[-1:, 0])[0] if self.count else -np.inf
