"""DigiForce-style acquisition unit: records one X-Y curve per cycle, evaluates it, keeps statistics.

Public API: :class:`DigiForce`; results :class:`CurveResult`, :class:`ElementResult`, :class:`Curve`;
errors :class:`DigiForceError`. See docs/digiforce.md.
"""
from .channel import shunt_ratio
from .curve import Curve
from .device import DigiForce
from .elements import ELEMENT_KINDS, envelope_band
from .errors import DigiForceError
from .results import CurveResult, ElementResult

__all__ = ["DigiForce", "Curve", "CurveResult", "ElementResult", "DigiForceError", "ELEMENT_KINDS",
           "envelope_band", "shunt_ratio"]
