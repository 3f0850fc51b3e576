"""Unwrapping the device's short wrapping time stamps against a known device time."""
from __future__ import annotations


def unwrap(stamp: float, modulus: float, reference: float) -> float:
    """The device time (s) congruent to ``stamp`` modulo ``modulus`` that is closest to ``reference``.

    Exact as long as the true time is within ``modulus / 2`` of ``reference``.
    """
    return stamp + modulus * round((reference - stamp) / modulus)
