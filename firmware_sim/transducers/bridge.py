"""Strain-gauge full-bridge force transducers (Burster 8411-type load cell, brake-force transducer).

Output is the bridge ratio in V/V: bridge output voltage divided by the *nominal* excitation, so an
excitation drop shows as a proportional drop of the signal. The element sees the measured force plus
the mounting ``preload`` [N]; :meth:`to_physical` returns that element force. Overload: the output
saturates at ``clip_low``/``clip_high`` and, once the element force has exceeded
``damage_threshold``·F_FS, a permanent zero shift of ``zero_shift_per_overload``·(peak/F_FS −
threshold) of FS remains (sign of the overload direction).
"""
from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from rig.scene import Field

from .analog import AnalogTransducer, analog_schema
from .description import register


def shunt_ratio(r_bridge: float, r_shunt: float) -> float:
    """Change of a balanced full bridge's output [V/V] when ``r_shunt`` is put across one arm [Ω].

    The shunted arm becomes ``R∥Rs``; its half-bridge midpoint moves by ``−R/(2(R + 2Rs))`` of the
    excitation (negative: the shunt simulates compression on a lower arm).
    """
    if not (r_bridge > 0.0 and r_shunt > 0.0):
        raise ValueError(f"bridge and shunt resistances must be positive, got {r_bridge} Ω and {r_shunt} Ω")
    return -r_bridge / (2.0 * (r_bridge + 2.0 * r_shunt))


@register("strain_gauge_bridge")
class StrainGaugeBridge(AnalogTransducer):
    """Full-bridge strain-gauge force transducer; output in V/V of the nominal excitation."""

    QUANTITY_UNIT: ClassVar[str] = "N"
    SIGNAL_UNIT: ClassVar[str] = "1"
    SCHEMA: ClassVar[dict[str, Field]] = {
        **analog_schema(QUANTITY_UNIT, SIGNAL_UNIT),
        "excitation": Field("V", doc="bridge excitation voltage"),
        "bridge_resistance": Field("ohm", 350.0, "resistance of each bridge arm"),
        "shunt_resistance": Field("ohm", 59e3, "built-in shunt-calibration resistor"),
        "preload": Field("N", 0.0, "mounting preload the element carries with no external load"),
        "damage_threshold": Field("1", 1.5, "element force above which a permanent zero shift appears, × F_FS"),
        "zero_shift_per_overload": Field("1", 0.1, "zero shift (fraction of FS) per unit of F/F_FS above threshold"),
        "open_bridge_output": Field("1", 0.5, "output with a broken bridge arm or cable (rails), V/V"),
    }
    FAULTS: ClassVar[dict[str, dict[str, Field]]] = {
        "open_bridge": {"polarity": Field("1", 1.0, "sign of the rail (+1 or −1)", one_of=(1.0, -1.0),
                                          says="must be +1 or -1")},
        "excitation_loss": {"level": Field("1", 0.0, "remaining fraction of the excitation", minimum=0.0,
                                           maximum=1.0)},
    }

    def __init__(self, params: dict[str, Any], rng: np.random.Generator, **kw: Any) -> None:
        super().__init__(params, rng, **kw)
        self._positive("excitation", "V")
        self.force_fs = self.full_scale / abs(self.sensitivity)  # N
        self.peak_tension = 0.0      # largest element force seen, × F_FS
        self.peak_compression = 0.0  # largest element compression seen, × F_FS
        self._shift = np.zeros(0)     # zero shift per sample of the current call [V/V]

    def _shift_from_peaks(self, tension: np.ndarray | float, compression: np.ndarray | float) -> np.ndarray:
        """Permanent zero shift [V/V] left by the peak element forces seen so far (× F_FS)."""
        thr, k = self.p["damage_threshold"], self.p["zero_shift_per_overload"]
        return self.full_scale * k * (np.maximum(np.asarray(tension) - thr, 0.0)
                                      - np.maximum(np.asarray(compression) - thr, 0.0))

    @property
    def zero_shift(self) -> float:
        """Permanent zero shift from past overloads [V/V]."""
        return float(self._shift_from_peaks(self.peak_tension, self.peak_compression))

    def shunt_output(self, R_shunt: float | None = None) -> float:
        """Known output change [V/V] of switching ``R_shunt`` [Ω] (default: the built-in one) across one arm."""
        return shunt_ratio(self.p["bridge_resistance"], self.p["shunt_resistance"] if R_shunt is None else R_shunt)

    def _element(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Element force: measured force plus preload; tracks the overload history."""
        f = q + self.p["preload"]
        rel = f / self.force_fs
        # the zero shift grows from the sample at which the running peak passes the threshold
        pos = np.maximum.accumulate(np.maximum(rel, self.peak_tension))
        neg = np.maximum.accumulate(np.maximum(-rel, self.peak_compression))
        self._shift = self._shift_from_peaks(pos, neg)
        if f.size:
            self.peak_tension, self.peak_compression = float(pos[-1]), float(neg[-1])
        return f

    def _faults(self, t: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Permanent zero shift (clipped like the signal), excitation loss, open bridge (rails)."""
        s = np.clip(s + self._shift, self.p["clip_low"], self.p["clip_high"])
        for mask, par in self.faults.windows("excitation_loss", t):
            s = np.where(mask, s * par["level"], s)
        for mask, par in self.faults.windows("open_bridge", t):
            s = np.where(mask, math.copysign(self.p["open_bridge_output"], par["polarity"]), s)
        return s
