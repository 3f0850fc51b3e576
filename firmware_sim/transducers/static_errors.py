"""Static errors of one individual transducer, drawn once from the data-sheet bounds.

Errors are fractions of the full-scale output ``FS`` (the largest |nominal output| over the range):

* zero offset ``o`` and zero temperature coefficient ``c_z`` [1/K]: ``FS·(o + c_z·ΔT)``
* gain error ``g`` and span temperature coefficient ``c_s`` [1/K]: ``(g + c_s·ΔT)·(s − s0)``
* non-linearity (terminal based, zero at the zero point and at both ends), ``|nl| ≤ A``:
  ``FS·A·(w·p2(x) + (1 − |w|)·σ·p3(x))`` with ``x = (s − s0)/FS``, ``p2 = 4|x|(1 − |x|)``,
  ``p3 = (3√3/2)·x(1 − x²)``, both of peak 1 on ``|x| ≤ 1``
* hysteresis: a play (backlash) operator of half-width ``r`` on the measured quantity, so rising and
  falling readings differ by ``2r ≤ hysteresis_max·FS`` ("relative return").

Each figure is drawn uniformly within ± its data-sheet bound (the play width within [0, bound]).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


@dataclass(frozen=True)
class StaticErrors:
    offset: float
    gain: float
    temp_zero: float
    temp_span: float
    nl_amplitude: float
    nl_weight: float
    nl_sign: float
    play_fraction: float  # play width as a fraction of FS (rising − falling difference)

    @classmethod
    def draw(cls, p: dict, rng: np.random.Generator) -> "StaticErrors":
        """Draw one unit's errors within the bounds ``*_max`` of the validated description ``p``."""
        u = rng.uniform(-1.0, 1.0, size=6)
        return cls(offset=u[0] * p["zero_offset_max"], gain=u[1] * p["gain_error_max"],
                   temp_zero=u[2] * p["temp_zero_max"], temp_span=u[3] * p["temp_span_max"],
                   nl_amplitude=abs(u[4]) * p["nonlinearity_max"], nl_weight=u[5],
                   nl_sign=1.0 if rng.uniform() < 0.5 else -1.0,
                   play_fraction=rng.uniform() * p["hysteresis_max"])

    def error(self, s: np.ndarray, s0: float, fs: float, delta_t: float) -> np.ndarray:
        """Static error [signal unit] at nominal outputs ``s`` (zero output ``s0``, full scale ``fs``)."""
        x = (s - s0) / fs
        ax = np.abs(x)
        nl = self.nl_weight * 4.0 * ax * (1.0 - ax) + \
            (1.0 - abs(self.nl_weight)) * self.nl_sign * (1.5 * math.sqrt(3.0)) * x * (1.0 - x * x)
        return fs * (self.offset + self.temp_zero * delta_t + self.nl_amplitude * nl) + \
            (self.gain + self.temp_span * delta_t) * (s - s0)


class Play:
    """Play (backlash) operator of half-width ``radius``: output follows the input within ±radius."""

    def __init__(self, radius: float) -> None:
        self.radius = float(radius)
        self.z: float | None = None

    def __call__(self, q: np.ndarray) -> np.ndarray:
        r = self.radius
        if q.size == 0:
            return q.copy()
        if self.z is None:
            self.z = float(q[0])
        if r == 0.0:
            self.z = float(q[-1])
            return q.copy()
        out = np.empty(q.shape)
        self.z = _play(np.ascontiguousarray(q, dtype=float).reshape(-1), self.z, r, out.reshape(-1))
        return out


@njit(cache=True)
def _play(q: np.ndarray, z: float, r: float, out: np.ndarray) -> float:
    """The play operator over ``q`` from state ``z`` into ``out``; returns the final state."""
    for i in range(q.size):
        v = q[i]
        if v > z + r:
            z = v - r
        elif v < z - r:
            z = v + r
        out[i] = z
    return z
