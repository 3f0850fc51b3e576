"""LVDT with built-in carrier electronics (Burster 8740-type): core position [m] → output [V].

Beyond the nominal chain (:mod:`.analog`) it has: a residual carrier ripple
``ripple_amplitude·sin(2π f_c t + φ)`` (random phase φ, an error source), the loading of its output
resistance by the input resistance it drives (``R_in/(R_in + R_out)``, a gain error), clipping of the
output when the core leaves the range (``clip_low``/``clip_high``) and the fault ``supply_loss``.
"""
from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from rig.scene import Field

from .analog import AnalogTransducer, analog_schema
from .description import register


@register("lvdt")
class LVDT(AnalogTransducer):
    """Inductive displacement transducer with DC output."""

    QUANTITY_UNIT: ClassVar[str] = "m"
    SIGNAL_UNIT: ClassVar[str] = "V"
    SCHEMA: ClassVar[dict[str, Field]] = {
        **analog_schema(QUANTITY_UNIT, SIGNAL_UNIT),
        "supply": Field("V", doc="supply voltage (9…25 V)"),
        "carrier_frequency": Field("Hz", 12e3, "internal carrier frequency"),
        "ripple_amplitude": Field("V", 0.0, "residual carrier ripple on the output (amplitude)"),
        "output_resistance": Field("ohm", 0.0, "output resistance of the electronics"),
        "load_resistance": Field("ohm", math.inf, "input resistance of the acquisition channel"),
    }
    FAULTS: ClassVar[dict[str, dict[str, Field]]] = {"supply_loss": {}}

    def __init__(self, params: dict[str, Any], rng: np.random.Generator, **kw: Any) -> None:
        super().__init__(params, rng, **kw)
        if not 9.0 <= params["supply"] <= 25.0:
            raise ValueError(f"{self.name}: supply {params['supply']} V is outside the allowed 9…25 V")
        self.ripple_phase = rng.uniform(0.0, 2.0 * math.pi)
        r_out, r_in = params["output_resistance"], params["load_resistance"]
        self.loading = 1.0 if math.isinf(r_in) else r_in / (r_in + r_out)

    def _error_signals(self, t: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Output loading and carrier ripple."""
        ripple = self.p["ripple_amplitude"] * np.sin(2.0 * math.pi * self.p["carrier_frequency"] * t
                                                     + self.ripple_phase)
        return s * self.loading + ripple
