"""Incremental optical encoder (A/B in quadrature + index Z) and the counter card that reads it.

Shaft angle θ [rad] is sampled at times t; between samples it is taken as linear, so every line edge
between samples gets its exact time. With ``Δ = 2π/(4·ppr)`` and ``k = floor(θ/Δ)`` the line state is
``k mod 4`` in the Gray sequence (A, B) = 00, 10, 11, 01 (A leads B for positive rotation): crossing
boundary ``mΔ`` toggles A for odd m and B for even m; Z is high for ``k ≡ 0 (mod 4·ppr)``.

Error source (``errors_enabled``): Gaussian edge-time jitter ``jitter_rms``, never moving an edge to or before the
sample preceding its crossing (the card has latched there): the result does not depend on how the samples are cut
into calls; nor do the faults', each drawn from a stream of its own in time order. Faults: ``missed_pulses``
(a pulse of A or B disappears with ``probability`` per pulse) and ``glitches`` (spurious pulses of
``width`` on A or B at a Poisson ``rate``).

Counter card: it accepts an edge only if it comes at least ``1/max_edge_frequency`` after the
previously accepted one; at each accepted edge it reads the lines and steps its ×4 count by +1/−1, or — if both A and B
differ from what it saw last — counts an *illegal transition* and leaves the count alone. The
reported ×N count (N = 1, 2, 4) is ``floor((c4 + 4/N − 1)/(4/N))`` relative to its value at power-on
(×1 steps on A rising with B low, ×2 on every A edge). At each sample time the card latches the
count, the time of the edge that last changed it, and the number of illegal transitions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from rig.scene import Field

from .base import DESCRIPTION_FIELDS, Transducer
from .description import register

A, B, Z = 0, 1, 2
_STATE_OF_LEVELS = np.array([0, 1, 3, 2])  # index A + 2B -> position in the Gray sequence 00,10,11,01


#: counts: a shaft whose angle at power-on, extrapolated to t = 0 from the first samples, lies this close to a line
#: of the disc stands on it (the extrapolation's error is the parabola's, ~jerk·t0·t1·t2/6: 1e-4 counts for a Cardan
#: output sampled at 1 kHz)
ON_LINE = 1e-6


def power_on(t: np.ndarray, q: np.ndarray, step: float) -> tuple[float, int]:
    """(angle rad, ×4 step k0 the card starts at) at power-on, t = 0, from the first samples (times ``t`` s after it,
    angles ``q`` rad, with the mount angle; ``step`` rad per ×4 count): on a line within :data:`ON_LINE` counts, that
    line (the scenes' 0°), else the step below the extrapolated angle. The lab sheets place the edges by the same rule
    from the plant's truth at the same times (rig.analysis.lab_report)."""
    q_on = _at_zero(t[:3], q[:3])
    edges = round(q_on / step)
    if abs(q_on / step - edges) < ON_LINE:
        return edges * step, edges
    return q_on, int(math.floor(q_on / step))


def _at_zero(t: np.ndarray, q: np.ndarray) -> float:
    """Angle (rad) at t = 0 extrapolated from the first samples (times s, angles rad): by the parabola through three
    (exact for a constant acceleration, as a ramp or a speed ripple's start), else the line through two."""
    if t.size < 3:
        return float(q[0] - t[0] * (q[1] - q[0]) / (t[1] - t[0]))
    (t0, t1, t2), (q0, q1, q2) = t, q               # Lagrange form at 0
    return float(q0 * t1 * t2 / ((t0 - t1) * (t0 - t2)) + q1 * t0 * t2 / ((t1 - t0) * (t1 - t2))
                 + q2 * t0 * t1 / ((t2 - t0) * (t2 - t1)))


@dataclass(frozen=True)
class EncoderSample:
    """Line levels and counter-card latches at the sample times."""

    levels: np.ndarray      # (n, 3) uint8: A, B, Z (1 = high)
    count: np.ndarray       # (n,) int64: ×N count since power-on
    edge_time: np.ndarray   # (n,) float: time of the edge that last changed the count [s] (NaN: none yet)
    illegal: np.ndarray     # (n,) int64: illegal transitions counted since power-on


@register("incremental_encoder")
class IncrementalEncoder(Transducer):
    """Shaft angle [rad] → A/B/Z logic levels, plus the latched counter-card values."""

    QUANTITY_UNIT: ClassVar[str] = "rad"
    SCHEMA: ClassVar[dict[str, Field]] = {
        **DESCRIPTION_FIELDS,
        "ppr": Field("1", doc="pulses (A periods) per revolution"),
        "multiplier": Field("1", 4.0, "counter-card decoding ×1, ×2 or ×4"),
        "max_edge_frequency": Field("Hz", math.inf, "highest edge rate the counter card follows"),
        "jitter_rms": Field("s", 0.0, "edge-time jitter (rms)"),
        "mount_angle": Field("rad", 0.0, "where the code disc's zero sits on the shaft: a shaft resting exactly "
                             "on a line edge (a rest angle that is a whole number of counts) makes the count "
                             "flicker, as a real encoder would"),
    }
    FAULTS: ClassVar[dict[str, dict[str, Field]]] = {
        "missed_pulses": {"probability": Field("1", 0.01, "chance that a pulse of A or B is lost", minimum=0.0,
                                               maximum=1.0)},
        "glitches": {"rate": Field("1/s", 100.0, "spurious pulses per second", minimum=0.0),
                     "width": Field("s", 1e-6, "duration of a spurious pulse", positive=True)},
    }

    def __init__(self, params: dict[str, Any], rng: np.random.Generator, **kw: Any) -> None:
        super().__init__(params, rng, **kw)  # dynamics_enabled: no dynamics, kept for a uniform interface
        ppr, mult = params["ppr"], params["multiplier"]
        if not (ppr >= 1 and float(ppr).is_integer()):
            raise ValueError(f"{self.name}: ppr must be a positive integer, got {ppr}")
        if mult not in (1.0, 2.0, 4.0):
            raise ValueError(f"{self.name}: multiplier must be 1, 2 or 4, got {mult}")
        self._positive("max_edge_frequency", "Hz")
        self.ppr, self.multiplier = int(ppr), int(mult)
        self.step = 2.0 * math.pi / (4 * self.ppr)   # angle per ×4 count [rad]
        self._t: float | None = None   # last sample time [s]
        self._theta = 0.0               # last sample angle [rad]
        self._line = np.zeros(3, dtype=np.uint8)       # line levels after all emitted edges
        self._pending = (np.empty(0), np.empty(0, dtype=np.int64))  # jittered edges after the last sample
        self._drop_next = np.zeros(2, dtype=bool)     # missed pulse whose second edge is still to come
        self._streams: dict[tuple[int, int], tuple[Any, np.random.Generator]] = {}    # per fault (and channel)
        self._next_glitch: dict[int, float] = {}       # per glitch fault: the start of its next pulse (s)
        self._last_edge_t = -math.inf  # time of the last edge the counter card accepted
        self._card_state = 0           # Gray position the card saw last
        self._c4 = 0
        self._c4_origin = 0
        self._illegal = 0
        self._count_edge_t = math.nan

    def to_physical(self, count: np.ndarray | float) -> np.ndarray:
        """Ideal inverse: angle turned since power-on [rad] for a ×N count."""
        return np.asarray(count, dtype=float) * 2.0 * math.pi / (self.multiplier * self.ppr)

    def _scaled(self, c4: np.ndarray | int) -> np.ndarray:
        d = 4 // self.multiplier
        return (np.asarray(c4) + d - 1) // d

    def measure(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Line levels (n, 3) uint8 [A, B, Z] at times ``t`` [s] for shaft angle ``q`` [rad]."""
        return self.sample(t, q).levels

    # --- edges -----------------------------------------------------------------------------------
    def _edges(self, tt: np.ndarray, th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Boundary crossings between consecutive samples: times, boundary indices m and the time of the sample before
        each crossing."""
        kk = np.floor(th / self.step).astype(np.int64)
        dk = np.diff(kk)
        n = np.abs(dk)
        total = int(n.sum())
        if total == 0:
            return np.empty(0), np.empty(0, dtype=np.int64), np.empty(0)
        interval = np.repeat(np.arange(dk.size), n)
        j = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
        up = dk[interval] > 0
        m = np.where(up, kk[interval] + 1 + j, kk[interval] - j)
        frac = (m * self.step - th[interval]) / (th[interval + 1] - th[interval])
        times = tt[interval] + frac * (tt[interval + 1] - tt[interval])
        return times, m, tt[interval]

    def _stream(self, fault: Any, channel: int = 0) -> np.random.Generator:
        """The random stream of one fault (and channel): a child of the transducer's generator, spawned in the order
        the faults were injected, drawn in time order — where the samples are cut into calls changes no draw."""
        key = (id(fault), channel)
        if key not in self._streams:
            for f in self.faults.faults:                   # every fault's streams at once, in injection order
                for c in (A, B):
                    self._streams.setdefault((id(f), c), (f, self.rng.spawn(1)[0]))
        return self._streams[key][1]

    def _missed(self, times: np.ndarray, chan: np.ndarray) -> np.ndarray:
        """Keep-mask after dropping whole pulses (an edge and the next one on the same channel): a pulse starts at
        an edge drawn missing that is not the second edge of the pulse before; one draw per edge in a fault's
        window, in time order."""
        keep = np.ones(times.size, dtype=bool)
        faults = [f for f in self.faults.faults if f.kind == "missed_pulses"]
        for c in (A, B):
            idx = np.flatnonzero(chan == c)
            drawn = np.zeros(idx.size, dtype=bool)
            for f in faults:
                inside = np.flatnonzero((times[idx] >= f.at) & (times[idx] < f.until))
                if inside.size:
                    drawn[inside] |= self._stream(f, c).uniform(size=inside.size) < f.params["probability"]
            last = -1 if self._drop_next[c] else -2        # -1: the edge before this call's first started a pulse
            if self._drop_next[c] and idx.size:
                keep[idx[0]] = False
            hit = []
            for i in np.flatnonzero(drawn).tolist():
                if i > last + 1:
                    hit.append(i)
                    last = i
            hit = np.asarray(hit, dtype=np.int64)
            keep[idx[hit]] = False
            second = hit + 1
            keep[idx[second[second < idx.size]]] = False
            if idx.size:
                self._drop_next[c] = bool(hit.size and hit[-1] == idx.size - 1)
        return keep

    def _glitches(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """Spurious pulses (two edges each) starting in (t0, t1]: each fault's Poisson process drawn as exponential
        gaps from its start, in time order."""
        times, chans = [], []
        for f in self.faults.faults:
            rate = f.params.get("rate", 0.0) if f.kind == "glitches" else 0.0
            if not rate > 0.0:
                continue
            stream = self._stream(f)
            nxt = self._next_glitch.get(id(f))
            if nxt is None:
                nxt = f.at + stream.exponential(1.0 / rate)
            starts, cs = [], []
            while nxt <= t1 and nxt < f.until:
                if nxt > t0:
                    starts.append(nxt)
                    cs.append(int(stream.integers(0, 2)))
                nxt += stream.exponential(1.0 / rate)
            self._next_glitch[id(f)] = nxt
            start = np.asarray(starts)
            times += [start, start + f.params["width"]]
            chans += [np.asarray(cs, dtype=np.int64)] * 2
        if not times:
            return np.empty(0), np.empty(0, dtype=np.int64)
        return np.concatenate(times), np.concatenate(chans)

    # --- sampling --------------------------------------------------------------------------------
    def sample(self, t: np.ndarray, q: np.ndarray) -> EncoderSample:
        """Levels and counter-card latches at times ``t`` [s] for shaft angle ``q`` [rad]; continues state."""
        t, q = self._samples(t, q)
        q = q + self.p["mount_angle"]
        if t.size == 0:
            return EncoderSample(np.empty((0, 3), np.uint8), np.empty(0, np.int64), np.empty(0), np.empty(0, np.int64))
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(t))):
            raise ValueError(f"{self.name}: time or angle contains NaN or inf")
        if self._t is None:
            t_on, q_on = float(t[0]), float(q[0])
            k0 = int(math.floor(q_on / self.step))
            if t.size > 1 and 0.0 < t[0] <= (t[1] - t[0]) * (1.0 + 1e-9):   # the stream's first sample after power-on
                t_on = 0.0                  # at t = 0: the card counts from the shaft's angle then (sheets align zeros)
                q_on, k0 = power_on(t, q, self.step)
            s0 = k0 % 4
            self._line[:] = (s0 in (1, 2), s0 in (2, 3), k0 % (4 * self.ppr) == 0)
            self._card_state, self._c4 = s0, k0
            self._c4_origin = int(self._scaled(k0))
            self._t, self._theta = t_on, q_on
        tt = np.concatenate(([self._t], t))
        th = np.concatenate(([self._theta], q))
        dt = np.diff(tt)
        if np.any(dt[1:] <= 0.0) or dt[0] < 0.0 or (dt[0] == 0.0 and th[1] != th[0]):
            raise ValueError(f"{self.name}: sample times must increase strictly (continuing from t={self._t} s)")
        times, m, before = self._edges(tt, th)
        chan = np.where(m % 2 == 1, A, B)
        if self.errors_enabled and self.p["jitter_rms"] > 0.0:
            # jitter never moves an edge to or before the sample preceding its crossing, whose latch is taken (it may be
            # the last sample of the previous call): where the samples are cut into calls changes no count
            times = np.maximum(times + self.rng.normal(0.0, self.p["jitter_rms"], size=times.size),
                               np.nextafter(before, np.inf))
        zsel = np.isin(m % (4 * self.ppr), (0, 1))
        z_times = times[zsel]
        keep = self._missed(times, chan)
        g_times, g_chan = self._glitches(tt[0], tt[-1])
        all_t = np.concatenate((self._pending[0], times[keep], g_times, z_times))
        all_c = np.concatenate((self._pending[1], chan[keep], g_chan, np.full(z_times.size, Z)))
        order = np.argsort(all_t, kind="stable")
        all_t, all_c = all_t[order], all_c[order]
        n_emit = int(np.searchsorted(all_t, t[-1], side="right"))
        self._pending = (all_t[n_emit:], all_c[n_emit:])
        et, ec = all_t[:n_emit], all_c[:n_emit]
        ab_before = self._line[:2].copy()
        levels = np.empty((t.size, 3), dtype=np.uint8)
        for c in (A, B, Z):
            ce = et[ec == c]
            levels[:, c] = self._line[c] ^ (np.searchsorted(ce, t, side="right") & 1)
            self._line[c] ^= ce.size & 1
        count, edge_time, illegal = self._card(et[ec != Z], ec[ec != Z], ab_before, t)
        self._t, self._theta = float(t[-1]), float(q[-1])
        return EncoderSample(levels, count, edge_time, illegal)

    def _accept(self, et: np.ndarray) -> np.ndarray:
        """Edges the card sees: each at least ``1/max_edge_frequency`` after the last accepted one."""
        tau = 1.0 / self.p["max_edge_frequency"]
        accepted = np.diff(np.concatenate(([self._last_edge_t], et))) >= tau
        if not accepted.all():  # too close somewhere: decide edge by edge
            last = self._last_edge_t
            for i, te in enumerate(et.tolist()):
                accepted[i] = te - last >= tau
                if accepted[i]:
                    last = te
        if accepted.any():
            self._last_edge_t = float(et[accepted][-1])
        return accepted

    def _card(self, et: np.ndarray, ec: np.ndarray, ab_before: np.ndarray,
              t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Counter card: filter edges, step the ×4 count, latch count/edge time/illegal count at ``t``."""
        accepted = self._accept(et)
        a = ab_before[A] ^ (np.cumsum(ec == A) & 1)
        b = ab_before[B] ^ (np.cumsum(ec == B) & 1)
        state = _STATE_OF_LEVELS[a + 2 * b][accepted]
        ta = et[accepted]
        d = np.diff(np.concatenate(([self._card_state], state))) % 4
        step = np.where(d == 1, 1, np.where(d == 3, -1, 0))
        bad = np.cumsum(d == 2)
        c4 = self._c4 + np.cumsum(step)
        scaled = self._scaled(c4) - self._c4_origin
        before = int(self._scaled(self._c4)) - self._c4_origin
        changed = scaled != np.concatenate(([before], scaled[:-1]))
        change_t = ta[changed]
        i = np.searchsorted(ta, t, side="right") - 1
        count = np.where(i >= 0, scaled[np.maximum(i, 0)] if scaled.size else before, before)
        illegal = self._illegal + np.where(i >= 0, bad[np.maximum(i, 0)] if bad.size else 0, 0)
        j = np.searchsorted(change_t, t, side="right") - 1
        edge_time = np.where(j >= 0, change_t[np.maximum(j, 0)] if change_t.size else math.nan,
                             self._count_edge_t)
        if state.size:
            self._card_state = int(state[-1])
            self._c4 = int(c4[-1])
            self._illegal += int(bad[-1])
        if change_t.size:
            self._count_edge_t = float(change_t[-1])
        return count.astype(np.int64), edge_time, illegal.astype(np.int64)
