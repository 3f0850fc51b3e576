"""Analog transducers: physical quantity (SI) → electrical signal, with errors, dynamics and faults.

Signal chain of :meth:`AnalogTransducer.measure` (each stage stateful across calls):

1. element input (subclass hook: e.g. mounting preload, overload damage)
2. dynamics: unity-gain low pass at ``bandwidth`` (order 1 or 2, :mod:`.lowpass`)
3. hysteresis (play operator), nominal linear scaling, static errors (:mod:`.static_errors`)
4. white Gaussian noise ``noise_rms`` per sample
5. clipping to the output limits ``clip_low``/``clip_high``
6. faults (subclass hook), e.g. supply loss → 0

With ``errors_enabled = False`` stages 3 (errors only) and 4 are skipped, with
``dynamics_enabled = False`` stage 2, so the output is the nominal scaling of the input, which
:meth:`to_physical` inverts.
"""
from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from rig.scene import Field

from .base import DESCRIPTION_FIELDS, Transducer
from .description import register
from .lowpass import LowPass
from .static_errors import Play, StaticErrors


def analog_schema(quantity: str, signal: str) -> dict[str, Field]:
    """Description keys shared by all analog transducers (quantity and signal SI units given)."""
    return {
        **DESCRIPTION_FIELDS,
        "range_min": Field(quantity, doc="lower end of the measuring range"),
        "range_max": Field(quantity, doc="upper end of the measuring range"),
        "output_at_min": Field(signal, doc="nominal output at range_min"),
        "output_at_max": Field(signal, doc="nominal output at range_max"),
        "zero_offset_max": Field("1", 0.0, "zero offset bound, fraction of FS"),
        "gain_error_max": Field("1", 0.0, "sensitivity tolerance, fraction"),
        "nonlinearity_max": Field("1", 0.0, "non-linearity bound, fraction of FS"),
        "hysteresis_max": Field("1", 0.0, "relative return bound (rising − falling), fraction of FS"),
        "temp_zero_max": Field("1/K", 0.0, "zero temperature coefficient bound, FS per K"),
        "temp_span_max": Field("1/K", 0.0, "span temperature coefficient bound, per K"),
        "temperature_delta": Field("K", 0.0, "ambient temperature minus the reference temperature"),
        "noise_rms": Field(signal, 0.0, "output noise per sample (rms)"),
        "bandwidth": Field("Hz", math.inf, "−3 dB frequency of the dynamics (inf: none)"),
        "filter_order": Field("1", 2.0, "order of the low pass, 1 or 2"),
        "damping": Field("1", math.sqrt(0.5), "damping ratio of the 2nd-order low pass"),
        "clip_low": Field(signal, -math.inf, "lowest output the electronics can give"),
        "clip_high": Field(signal, math.inf, "highest output the electronics can give"),
    }


@register("amplified")
class AnalogTransducer(Transducer):
    """A transducer with built-in amplifier (e.g. an in-line torque shaft with ±10 V output)."""

    QUANTITY_UNIT: ClassVar[str] = "N*m"
    SIGNAL_UNIT: ClassVar[str] = "V"
    SCHEMA: ClassVar[dict[str, Field]] = analog_schema(QUANTITY_UNIT, SIGNAL_UNIT)
    FAULTS: ClassVar[dict[str, dict[str, Field]]] = {"supply_loss": {}, "stuck": {}}

    def __init__(self, params: dict[str, Any], rng: np.random.Generator, **kw: Any) -> None:
        super().__init__(params, rng, **kw)
        lo, hi = params["range_min"], params["range_max"]
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise ValueError(f"{self.name}: range_min ({lo}) must be below range_max ({hi})")
        if params["output_at_max"] == params["output_at_min"]:
            raise ValueError(f"{self.name}: output_at_min equals output_at_max (zero sensitivity)")
        self.sensitivity = (params["output_at_max"] - params["output_at_min"]) / (hi - lo)  # signal per SI unit
        self.full_scale = max(abs(params["output_at_min"]), abs(params["output_at_max"]))  # signal
        self.zero_output = float(self.nominal(np.clip(0.0, lo, hi)))
        self.temperature_delta = params["temperature_delta"]
        self.static = StaticErrors.draw(params, rng)
        self.play = Play(self.static.play_fraction * self.full_scale / abs(self.sensitivity) / 2.0)
        self.filter: LowPass | None = None
        if math.isfinite(params["bandwidth"]):
            order = params["filter_order"]
            if order not in (1.0, 2.0):
                raise ValueError(f"{self.name}: filter_order must be 1 or 2, got {order}")
            self.filter = LowPass(params["bandwidth"], int(order), params["damping"])
        self.last_output = self.zero_output
        self._measured = False              # no output yet: a fault "stuck" from the start holds the first one

    # --- nominal scaling -------------------------------------------------------------------------
    def nominal(self, q: np.ndarray | float) -> np.ndarray:
        """Ideal output for quantity ``q`` (SI): the straight line through the range end points."""
        return self.p["output_at_min"] + (np.asarray(q, dtype=float) - self.p["range_min"]) * self.sensitivity

    def to_physical(self, signal: np.ndarray | float) -> np.ndarray:
        """Ideal inverse: the quantity (SI) a nominal transducer would have seen for ``signal``."""
        return self.p["range_min"] + (np.asarray(signal, dtype=float) - self.p["output_at_min"]) / self.sensitivity

    # --- signal chain ----------------------------------------------------------------------------
    def measure(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Electrical output at times ``t`` [s] for the physical quantity ``q`` (SI); continues state."""
        t, q = self._samples(t, q)
        if not np.all(np.isfinite(q)):
            raise ValueError(f"{self.name}: the measured quantity contains NaN or inf")
        x = self._element(t, q)
        if self.filter is not None and self.dynamics_enabled:
            x = self.filter(t, x)
        if self.errors_enabled:
            s = self.nominal(self.play(x))
            s = s + self.static.error(s, self.zero_output, self.full_scale, self.temperature_delta)
            noise = self.p["noise_rms"]
            if noise > 0.0:
                s = s + self.rng.normal(0.0, noise, size=s.shape)
            s = self._error_signals(t, s)
        else:
            s = self.nominal(x)
        s = np.clip(s, self.p["clip_low"], self.p["clip_high"])
        s = self._faults(t, s)
        if s.size:
            self.last_output = float(s[-1])
            self._measured = True
        return s

    def _element(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        """What the sensing element responds to (hook; identity here)."""
        return q

    def _error_signals(self, t: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Extra error signals added to the output (hook; none here)."""
        return s

    def _faults(self, t: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Apply scheduled faults: ``supply_loss`` → 0, ``stuck`` → output frozen at its onset value."""
        for mask, _ in self.faults.windows("supply_loss", t):
            s = np.where(mask, 0.0, s)
        for mask, _ in self.faults.windows("stuck", t):
            first = int(np.argmax(mask))
            held = s[first - 1] if first else self.last_output if self._measured else s[0]
            s = np.where(mask, held, s)
        return s


@register("strain_amplifier")
class StrainAmplifier(AnalogTransducer):
    """Strain gauges on a structural part (e.g. a clutch leaf) through a bridge amplifier: strain → V."""

    QUANTITY_UNIT: ClassVar[str] = "1"
    SCHEMA: ClassVar[dict[str, Field]] = analog_schema(QUANTITY_UNIT, AnalogTransducer.SIGNAL_UNIT)
