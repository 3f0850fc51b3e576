"""Radius of curvature of a plane curve given by its derivatives w.r.t. any parameter (MODELS §2)."""
from __future__ import annotations

import numpy as np


def curvature_radius(dx: np.ndarray, dy: np.ndarray, ddx: np.ndarray, ddy: np.ndarray) -> np.ndarray:
    """ρ = (x'² + y'²)^{3/2}/(x'y'' − x''y') (units of x); positive where the curve turns counter-clockwise
    as the parameter grows, ±inf on straight stretches."""
    num = (np.asarray(dx) ** 2 + np.asarray(dy) ** 2) ** 1.5
    den = np.asarray(dx) * ddy - np.asarray(ddx) * dy
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den != 0.0, num / np.where(den != 0.0, den, 1.0), np.copysign(np.inf, num))
