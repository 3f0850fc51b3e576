"""Unwrapping the device's short wrapping time stamps against a known device time."""
from __future__ import annotations

import numpy as np


def unwrap(stamp: float | np.ndarray, modulus: float, reference: float | np.ndarray) -> float | np.ndarray:
    """The device time (s) congruent to ``stamp`` (a number or an array) modulo ``modulus`` that is closest to
    ``reference`` (a number, or an array beside an array of stamps). Exact as long as the true time is within
    ``modulus / 2`` of ``reference``."""
    if isinstance(stamp, np.ndarray):
        return stamp + modulus * np.round((reference - stamp) / modulus)
    return stamp + modulus * round((reference - stamp) / modulus)
