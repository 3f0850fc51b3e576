"""Course-lab speed instruments (DEVICES §1 "lab instruments"): each gives a shaft-speed reading.

* ``pulse_counter`` — a slotted disc with ``holes`` holes in front of a photodiode and a counter that counts
  the pulses over a ``gate_time``: the reading is the count N of the last completed gate (held; 0 before the
  first gate ends), n = N / (holes · gate_time). Gates start at power-on (t = 0); the shaft angle is taken
  as linear between samples, so a gate boundary between two samples gets its exact count.
* ``speed_indicator`` — a reading in rad/s (a mechanical tachometer, ±5 % in the lab sheet): the analog
  chain (:mod:`.analog`: gain error, dynamics of the pointer, noise) and the dial's ``resolution``.
* ``tachogenerator`` — a DC tachogenerator: speed → V (the analog chain).
* ``stroboscope`` — the flash frequency (Hz) at which the mark stands still. It also stands still at
  f_x = f_i / k for an integer ``divisor`` k (the classic mistake the lab teaches to avoid; 1 by default),
  read to the dial's ``resolution``.
"""
from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from rig.scene import Field

from .analog import AnalogTransducer, analog_schema
from .base import DESCRIPTION_FIELDS, Transducer
from .description import register


@register("pulse_counter")
class PulseCounter(Transducer):
    """Slotted disc + photodiode + gated pulse counter: shaft angle (rad) → pulses in the last gate."""

    QUANTITY_UNIT: ClassVar[str] = "rad"
    SCHEMA: ClassVar[dict[str, Field]] = {
        **DESCRIPTION_FIELDS,
        "holes": Field("1", doc="holes (pulses) per revolution of the disc"),
        "gate_time": Field("s", doc="counting time of the counter"),
    }
    FAULTS: ClassVar[dict[str, dict[str, Field]]] = {}

    def __init__(self, params: dict[str, Any], rng: np.random.Generator, **kw: Any) -> None:
        super().__init__(params, rng, **kw)
        holes = params["holes"]
        if not (holes >= 1 and float(holes).is_integer()):
            raise ValueError(f"{self.name}: holes must be a positive integer, got {holes}")
        self.holes = int(holes)
        self.gate_time = self._positive("gate_time", "s")
        self._t, self._theta = 0.0, None         # last sample (the counter starts at t = 0)
        self._gates = 0                           # gates completed
        self._at_gate = 0.0                       # pulses at the start of the running gate
        self.reading = 0.0                        # pulses of the last completed gate

    def _pulses(self, theta: np.ndarray) -> np.ndarray:
        return np.floor(np.asarray(theta) * self.holes / (2.0 * math.pi))

    def measure(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Pulses of the last completed gate at times ``t`` (s) for shaft angles ``q`` (rad); continues state."""
        t, q = self._samples(t, q)
        if self._theta is None:                   # power-on: the count starts from the first sample
            self._theta = float(q[0])
            self._at_gate = float(self._pulses(self._theta))
        tt, qq = np.concatenate([[self._t], t]), np.concatenate([[self._theta], q])
        out = np.empty(t.size)
        start = 0
        while (end_t := (self._gates + 1) * self.gate_time) <= t[-1]:
            stop = int(np.searchsorted(t, end_t, side="left"))
            out[start:stop] = self.reading
            pulses = float(self._pulses(np.interp(end_t, tt, qq)))
            self.reading, self._at_gate = pulses - self._at_gate, pulses
            self._gates += 1
            start = stop
        out[start:] = self.reading
        self._t, self._theta = float(t[-1]), float(q[-1])
        return out

    def to_physical(self, signal: np.ndarray | float) -> np.ndarray:
        """The counter shows the pulses themselves."""
        return np.asarray(signal, dtype=float)


class _Dial(AnalogTransducer):
    """An analog speed reading shown on a dial read to ``resolution`` (0: exact)."""

    def measure(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        s = super().measure(t, q)
        res = self.p["resolution"]
        return np.round(s / res) * res if res > 0.0 else s


@register("speed_indicator")
class SpeedIndicator(_Dial):
    """Mechanical tachometer: shaft speed (rad/s) → the speed it shows (rad/s)."""

    QUANTITY_UNIT: ClassVar[str] = "rad/s"
    SIGNAL_UNIT: ClassVar[str] = "rad/s"
    SCHEMA: ClassVar[dict[str, Field]] = {**analog_schema(QUANTITY_UNIT, SIGNAL_UNIT),
                                          "resolution": Field("rad/s", 0.0, "smallest step read on the dial")}


@register("tachogenerator")
class Tachogenerator(AnalogTransducer):
    """DC tachogenerator: shaft speed (rad/s) → V."""

    QUANTITY_UNIT: ClassVar[str] = "rad/s"
    SIGNAL_UNIT: ClassVar[str] = "V"
    SCHEMA: ClassVar[dict[str, Field]] = analog_schema(QUANTITY_UNIT, SIGNAL_UNIT)


@register("stroboscope")
class Stroboscope(_Dial):
    """Stroboscope: shaft speed (rad/s) → flash frequency (Hz) at which the mark stands still (f_i / k)."""

    QUANTITY_UNIT: ClassVar[str] = "rad/s"
    SIGNAL_UNIT: ClassVar[str] = "Hz"
    SCHEMA: ClassVar[dict[str, Field]] = {**analog_schema(QUANTITY_UNIT, SIGNAL_UNIT),
                                          "resolution": Field("Hz", 0.0, "smallest step read on the dial"),
                                          "divisor": Field("1", 1.0, "k: the image also stands at f_i / k")}

    def __init__(self, params: dict[str, Any], rng: np.random.Generator, **kw: Any) -> None:
        super().__init__(params, rng, **kw)
        k = params["divisor"]
        if not (k >= 1 and float(k).is_integer()):
            raise ValueError(f"{self.name}: divisor must be a positive integer, got {k}")

    def _element(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        return q / self.p["divisor"]
