"""Flat-tappet cam geometry of the elastic-and-safety clutch (MODELS.md §4.1).

Relative angle φ = φ1 − φ3 (rad) is reduced into one lobe (period 120°) and mirrored on 60°–120°.
Phase I (arc r1): k1 = (r1 − r0) sin φ, k2 = r1 − (r1 − r0) cos φ.
Phase II (fillet r2): k1 = a2 sin(60° − φ), k2 = r2 + a2 cos(60° − φ).
k2 (m) is the distance of the tappet face from the centre, s = k2 − r0 the lift, k1 = dk2/dφ (m) the
normal-force arm and k3 = d(k1²)/dφ (m²). On the descending flank (mirrored half) k1 and k3 change sign.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LOBE = 2.0 * math.pi / 3.0      # lobe period, rad (three lobes)
APEX = math.pi / 3.0            # apex of the lobe, rad
_SIN60 = math.sin(APEX)


class GeometryError(ValueError):
    """The cam parameters describe an impossible profile."""


@dataclass(frozen=True)
class PhaseLimits:
    """End of phase I ``phi_maxI`` (rad), fillet-centre distance ``a2`` (m), apex angle ``apex`` (rad)."""

    phi_maxI: float
    a2: float
    apex: float = APEX

    @property
    def boundaries(self) -> tuple[float, float, float]:
        """Phase boundaries inside one lobe (rad): φ_maxI, apex, 120° − φ_maxI."""
        return (self.phi_maxI, self.apex, LOBE - self.phi_maxI)


def phase_limits(r0: float, r1: float, r2: float) -> PhaseLimits:
    """φ_maxI = 60° − asin((r1 − r0)/(r1 − r2)·sin 60°), a2 = (r1 − r0) sin φ_maxI / sin(60° − φ_maxI).

    Raises :class:`GeometryError` naming the parameters when the profile cannot exist.
    """
    for name, v in (("r0", r0), ("r1", r1), ("r2", r2)):
        if not (math.isfinite(v) and v > 0):
            raise GeometryError(f"clutch geometry: {name} = {v!r} m must be a positive finite length")
    if r1 <= r0:
        raise GeometryError(f"clutch geometry: r1 = {r1} m must exceed the base radius r0 = {r0} m")
    if r2 >= r1:
        raise GeometryError(f"clutch geometry: fillet radius r2 = {r2} m must be smaller than r1 = {r1} m")
    arg = (r1 - r0) / (r1 - r2) * _SIN60
    if arg > 1.0:
        raise GeometryError(f"clutch geometry: asin argument (r1 - r0)/(r1 - r2)*sin60 = {arg:.4g} > 1 "
                            f"(r0={r0}, r1={r1}, r2={r2} m)")
    phi_max = APEX - math.asin(arg)
    if phi_max <= 0.0:
        raise GeometryError(f"clutch geometry: phi_maxI = {math.degrees(phi_max):.4g} deg <= 0; the fillet "
                            f"radius r2 = {r2} m must be smaller than r0 = {r0} m")
    a2 = (r1 - r0) * math.sin(phi_max) / math.sin(APEX - phi_max)
    return PhaseLimits(phi_maxI=phi_max, a2=a2)


def reduce_angle(phi: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Reduce φ (rad) into [0, 60°]; returns (ψ, sign) with sign = −1 on the mirrored half 60°–120°."""
    psi = np.mod(np.asarray(phi, dtype=float), LOBE)
    mirrored = psi > APEX
    return np.where(mirrored, LOBE - psi, psi), np.where(mirrored, -1.0, 1.0)


def lobe_geometry(phi: np.ndarray | float, r0: float, r1: float, r2: float,
                  limits: PhaseLimits) -> dict[str, np.ndarray]:
    """Vectorised k1 (m), k2 (m), k3 (m²), lift s (m) and dk1/dφ (m) at relative angles φ (rad)."""
    psi, sign = reduce_angle(phi)
    c1, a2 = r1 - r0, limits.a2
    first = psi <= limits.phi_maxI
    k1 = np.where(first, c1 * np.sin(psi), a2 * np.sin(APEX - psi))
    k2 = np.where(first, r1 - c1 * np.cos(psi), r2 + a2 * np.cos(APEX - psi))
    dk1 = np.where(first, c1 * np.cos(psi), -a2 * np.cos(APEX - psi))
    k1 = sign * k1
    return {"k1": k1, "k2": k2, "k3": 2.0 * k1 * dk1, "s": k2 - r0, "dk1": dk1}
