"""One input channel's signal chain: unit error, noise, low-pass, ADC, scaling, tare, shunt check.

electrical input (V/V or V) -> offset and gain error of the unit (drawn once, within the accuracy
figure) + noise -> Butterworth low-pass (cut-off from the unit's steps) -> ADC (clipped to the
range, quantised to ``adc_bits``) -> engineering unit (sensitivity or two-point teach) -> minus tare.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np
from scipy import signal

from .description import Description, InputType
from .errors import DigiForceError
from .program import scaling_line

BYPASS_FRACTION = 0.45   # a cut-off at or above this fraction of the sample rate leaves the filter out
RATE_TOL = 1e-6          # relative change of the sample rate still treated as the same rate


def shunt_ratio(bridge_resistance: float, shunt_resistance: float) -> float:
    """Bridge output (V/V) when ``shunt_resistance`` is switched across one arm of a full bridge of
    four equal arms ``bridge_resistance``: R / (2 (R + 2 R_s))."""
    if bridge_resistance <= 0 or shunt_resistance <= 0:
        raise DigiForceError("shunt_ratio: resistances must be > 0 ohm")
    return bridge_resistance / (2.0 * (bridge_resistance + 2.0 * shunt_resistance))


class InputChain:
    """Signal chain of one channel under one program. ``unit_error`` = (gain, offset) as fractions in
    [-0.5, 0.5] of the input's accuracy figure (together at most the full accuracy); None = ideal."""

    def __init__(self, cfg: Mapping[str, Any], inp: InputType, desc: Description,
                 unit_error: tuple[float, float] | None, rng: np.random.Generator | None) -> None:
        self.cfg = cfg
        self.input = inp
        self.range = cfg["range"]
        self.lsb = 2.0 * self.range / 2 ** desc.adc_bits
        self._code_max = 2 ** (desc.adc_bits - 1) - 1
        self._order = desc.filter_order
        g, o = unit_error if unit_error is not None else (0.0, 0.0)
        self.gain_error = g * inp.accuracy
        self.offset_error = o * inp.accuracy * self.range
        self._noise = desc.noise_lsb * self.lsb if rng is not None else 0.0
        self._rng = rng
        self.scale, self.zero = scaling_line(cfg["scaling"])
        self.tare_value = 0.0
        self.adc_overflows = 0
        self.bypassed = False
        self._fs: float | None = None
        self._sos: np.ndarray | None = None
        self._zi: np.ndarray | None = None

    @property
    def full_scale(self) -> float:
        """The range in engineering units (magnitude)."""
        return abs(self.range * self.scale)

    def to_engineering(self, electrical: np.ndarray) -> np.ndarray:
        """Electrical value (V/V or V) to engineering units, before tare."""
        return (np.asarray(electrical) - self.zero) * self.scale

    def _filter(self, v: np.ndarray, fs: float | None) -> np.ndarray:
        fc = self.cfg["cutoff"]
        if fc <= 0 or fs is None:
            return v
        if self._fs is None or abs(fs - self._fs) > RATE_TOL * fs:    # new rate: the filter restarts
            self._fs = fs
            self.bypassed = fc >= BYPASS_FRACTION * fs
            self._sos = None if self.bypassed else signal.butter(self._order, fc, fs=fs, output="sos")
            self._zi = None if self.bypassed else signal.sosfilt_zi(self._sos) * v[0]
        if self.bypassed:
            return v
        out, self._zi = signal.sosfilt(self._sos, v, zi=self._zi)
        return out

    def convert(self, v: np.ndarray, fs: float | None) -> np.ndarray:
        """Electrical samples at rate ``fs`` (None: filter not applied) to engineering units before tare."""
        v = v * (1.0 + self.gain_error) + self.offset_error
        if self._noise:
            v = v + self._rng.normal(0.0, self._noise, v.shape)
        v = self._filter(v, fs)
        code = np.rint(v / self.lsb)
        over = (code > self._code_max) | (code < -self._code_max - 1)
        self.adc_overflows += int(over.sum())
        code = np.clip(code, -self._code_max - 1, self._code_max)
        return self.to_engineering(code * self.lsb)
