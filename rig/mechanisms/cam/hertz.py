"""Hertz line contact between roller and cam (MODELS §2).

σ_H = sqrt((F_n/(2b))·(E*/π)·(1/r_R + 1/ρ_C)) with E* = 2/((1 − ν_R²)/E_R + (1 − ν_C²)/E_C); ρ_C is the
signed radius of the cam profile at the contact (+ convex, − concave), b the contact (roller) width.
Steel (E = 210 GPa, ν = 0.3) is an assumption: the sources give no material data.
"""
from __future__ import annotations

import numpy as np

from rig.mechanisms.checks import finite_array, positive

STEEL_E = 210e9     # Pa, assumption
STEEL_NU = 0.3      # assumption


def effective_modulus(E_roller: float = STEEL_E, nu_roller: float = STEEL_NU, E_cam: float = STEEL_E,
                      nu_cam: float = STEEL_NU) -> float:
    """E* = 2/((1 − ν_R²)/E_R + (1 − ν_C²)/E_C) (Pa)."""
    for name, e in (("E_roller", E_roller), ("E_cam", E_cam)):
        positive(e, f"{name} (Pa)")                 # (inf divided by zero, an audit)
    for name, nu in (("nu_roller", nu_roller), ("nu_cam", nu_cam)):
        if not -1.0 < nu < 0.5:
            raise ValueError(f"{name} must lie in (-1, 0.5), got {nu!r}")
    return 2.0 / ((1.0 - nu_roller ** 2) / E_roller + (1.0 - nu_cam ** 2) / E_cam)


def hertz_line_stress(force: np.ndarray, width: float, roller_radius: float, profile_radius: np.ndarray,
                      e_star: float | None = None) -> np.ndarray:
    """Peak contact pressure σ_H (Pa) for normal force ``force`` (N, its magnitude is used) over ``width`` (m)
    between a roller of ``roller_radius`` (m) and a profile of signed radius ``profile_radius`` (m). Raises
    where a concave profile is tighter than the roller (1/r_R + 1/ρ_C ≤ 0: the roller does not fit)."""
    positive(width, "contact width (m)")
    positive(roller_radius, "roller radius (m)")
    e_star = effective_modulus() if e_star is None else positive(e_star, "e_star (Pa)")
    force = finite_array(force, "contact force (N)")           # (NaN, inf and a zero radius read NaN or inf, an
    radius = np.asarray(profile_radius, dtype=float)                # audit; an infinite radius is a flat: fine)
    if np.any(np.isnan(radius) | (radius == 0.0)):
        raise ValueError("profile radius (m) must be a number other than 0 (±inf: a flat), got "
                         f"{float(np.ravel(radius)[np.argmax(np.isnan(radius) | (radius == 0.0))])!r}")
    rel = 1.0 / roller_radius + 1.0 / radius
    if np.any(rel <= 0.0):
        i = int(np.argmax(rel <= 0.0))
        raise ValueError(f"concave profile radius {float(np.ravel(profile_radius)[i]) * 1e3:.4g} mm is tighter than "
                         f"the roller ({roller_radius * 1e3:g} mm): no contact")
    return np.sqrt(np.abs(force) / (2.0 * width) * e_star / np.pi * rel)
