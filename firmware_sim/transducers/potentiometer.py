"""Potentiometric angle transducer read by a digital multimeter (static clutch rig).

The wiper voltage follows the nominal chain of :mod:`.analog`; the multimeter takes a reading every
``1/reading_rate`` seconds (counted from the first sample it ever saw), quantises it to
``resolution`` and shows it until the next reading: the output is a staircase a few steps per second.
"""
from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from rig.scene import Field

from .analog import AnalogTransducer, analog_schema
from .description import register


@register("potentiometer_dmm")
class PotentiometerDMM(AnalogTransducer):
    """Angle [rad] → multimeter reading [V], held between readings."""

    QUANTITY_UNIT: ClassVar[str] = "rad"
    SIGNAL_UNIT: ClassVar[str] = "V"
    SCHEMA: ClassVar[dict[str, Field]] = {
        **analog_schema(QUANTITY_UNIT, SIGNAL_UNIT),
        "reading_rate": Field("Hz", doc="multimeter readings per second"),
        "resolution": Field("V", 0.0, "multimeter display step (0: none)"),
    }
    FAULTS: ClassVar[dict[str, dict[str, Field]]] = {"supply_loss": {}, "stuck": {}}

    def __init__(self, params: dict[str, Any], rng: np.random.Generator, **kw: Any) -> None:
        super().__init__(params, rng, **kw)
        self._positive("reading_rate", "Hz")
        self.t0: float | None = None
        self.reading_index = -1
        self.reading = 0.0

    def quantise(self, v: np.ndarray) -> np.ndarray:
        """Round to the display resolution."""
        step = self.p["resolution"]
        return v if step == 0.0 else np.round(v / step) * step

    def measure(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Displayed reading [V] at times ``t`` [s] for wiper angle ``q`` [rad]."""
        s = super().measure(t, q)
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if s.size == 0:
            return s
        if self.t0 is None:
            self.t0 = float(t[0])
        k = np.floor((t - self.t0) * self.p["reading_rate"] + 1e-9).astype(np.int64)
        new = np.concatenate(([k[0] != self.reading_index], k[1:] != k[:-1]))
        idx = np.maximum.accumulate(np.where(new, np.arange(s.size), -1))
        values = self.quantise(s)
        out = np.where(idx >= 0, values[np.maximum(idx, 0)], self.reading)
        self.reading_index, self.reading = int(k[-1]), float(out[-1])
        return out
