"""Simulated transducers: physical quantity (SI) → electrical signal (V, V/V or logic levels).

Behaviour lives in the classes, numbers in ``data/devices/*.toml``; build one with
:func:`load_transducer` (``type`` in the file selects the class from :data:`REGISTRY`).
"""
from .analog import AnalogTransducer, StrainAmplifier
from .base import Transducer
from .bridge import StrainGaugeBridge, shunt_ratio
from .description import REGISTRY, load_transducer
from .encoder import EncoderSample, IncrementalEncoder
from .lab import PulseCounter, SpeedIndicator, Stroboscope, Tachogenerator
from .lowpass import LowPass, frequency_response
from .lvdt import LVDT
from .potentiometer import PotentiometerDMM

__all__ = ["AnalogTransducer", "EncoderSample", "IncrementalEncoder", "LVDT", "LowPass", "PotentiometerDMM", "PulseCounter",
           "SpeedIndicator", "Stroboscope", "Tachogenerator",
           "REGISTRY", "StrainAmplifier", "StrainGaugeBridge", "Transducer", "frequency_response", "load_transducer",
           "shunt_ratio"]
