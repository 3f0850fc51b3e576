"""Four-bar influence factors (MODELS §3.5, general tool): ∂ψ/∂l_k of the rocker angle.

Frame l1 (crank pivot at the origin, rocker pivot at (l1, 0)), crank l2 at angle φ, coupler l3, rocker l4 at
angle ψ: ``A cosψ + B sinψ + C = 0`` with A = 2l4(l1 − l2 cosφ), B = −2 l2 l4 sinφ,
C = l1² + l2² − l3² + l4² − 2 l1 l2 cosφ; ∂ψ/∂q = (A_q cosψ + B_q sinψ + C_q)/(A sinψ − B cosψ). Lengths m.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import degrees

import numpy as np

from rig.plants.cam_bar.chain import SingularPositionError

EXAMPLE_LENGTHS = (0.100, 0.030, 0.120, 0.070)     # l1..l4 (m), MODELS §3.5
EXAMPLE_TOLERANCES = (0.3e-3, 0.2e-3, 0.5e-3, 0.3e-3)


def _coefficients(l: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    l1, l2, l3, l4 = l
    cf, sf = np.cos(phi), np.sin(phi)
    return 2 * l4 * (l1 - l2 * cf), -2 * l2 * l4 * sf, l1 ** 2 + l2 ** 2 - l3 ** 2 + l4 ** 2 - 2 * l1 * l2 * cf


def rocker_angle(lengths: tuple[float, float, float, float], phi: np.ndarray, branch: float = 1.0) -> np.ndarray:
    """Rocker angle ψ (rad) at crank angles ``phi`` (rad); ``branch`` ±1 picks the assembly (+1: open)."""
    phi = np.asarray(phi, dtype=float)
    l = np.asarray(lengths, dtype=float)
    if l.shape != (4,) or np.any(l <= 0.0):
        raise ValueError(f"four-bar lengths must be four positive numbers (l1..l4, m), got {lengths!r}")
    a, b, c = _coefficients(l, phi)
    arg = -c / np.hypot(a, b)
    if np.any(np.abs(arg) > 1.0):
        i = int(np.argmax(np.abs(arg) > 1.0))
        raise SingularPositionError(f"four-bar {tuple(l)} m cannot be assembled at crank angle "
                                    f"φ = {degrees(float(phi.flat[i])):.4g}°")
    return np.arctan2(b, a) + branch * np.arccos(arg)


@dataclass(frozen=True)
class InfluenceResult:
    """ψ (rad), influence factors ∂ψ/∂l_k (rad/m, shape 4 × angles) and, for tolerances ±T_k, the worst-case
    Σ|∂ψ/∂l_k|·T_k and RSS (rad)."""

    phi: np.ndarray
    psi: np.ndarray
    factors: np.ndarray
    worst: np.ndarray
    rss: np.ndarray


def influence_factors(lengths: tuple[float, float, float, float], tolerances: tuple[float, float, float, float],
                      phi: np.ndarray, branch: float = 1.0) -> InfluenceResult:
    """Influence factors of l1..l4 on the rocker angle and the resulting worst-case/RSS angle errors."""
    phi = np.asarray(phi, dtype=float)
    psi = rocker_angle(lengths, phi, branch)
    l1, l2, l3, l4 = lengths
    a, b, _ = _coefficients(np.asarray(lengths, float), phi)
    cf, sf, cp, sp = np.cos(phi), np.sin(phi), np.cos(psi), np.sin(psi)
    den = a * sp - b * cp
    if np.any(np.abs(den) < 1e-12 * np.hypot(a, b)):
        i = int(np.argmax(np.abs(den) < 1e-12 * np.hypot(a, b)))
        raise SingularPositionError(f"four-bar at a dead centre at φ = {degrees(float(phi.flat[i])):.4g}°")
    zero = np.zeros_like(phi)
    a_q = (2 * l4 + zero, -2 * l4 * cf, zero, 2 * (l1 - l2 * cf))
    b_q = (zero, -2 * l4 * sf, zero, -2 * l2 * sf)
    c_q = (2 * l1 - 2 * l2 * cf, 2 * l2 - 2 * l1 * cf, -2 * l3 + zero, 2 * l4 + zero)
    factors = np.stack([(aq * cp + bq * sp + cq) / den for aq, bq, cq in zip(a_q, b_q, c_q)])
    contrib = factors * np.asarray(tolerances, float)[:, None]
    return InfluenceResult(phi, psi, factors, np.abs(contrib).sum(axis=0), np.sqrt((contrib ** 2).sum(axis=0)))
