"""Oscillating flat-faced (tangential) follower (MODELS §3.6): profile by envelope and the cusp test.

Cam centre O at the origin, follower pivot P = (A, 0). The follower face is a line at distance e from P,
inclined by γ = ψ0 + ψ(φ) to P→O, with ψ0 = asin((R_b + e)/A) so that it touches the base circle R_b at
ψ = 0. The cam turns by φ counter-clockwise (``direction`` +1) or clockwise (−1). In the cam frame the face line
has the outward normal angle θ = π/2 − γ − d·φ and the support distance p = A sin γ − e; the profile is the envelope
X = p·N(θ) + (dp/dθ)·T(θ) and its radius of curvature is ρ = p + d²p/dθ². A cusp appears where ρ ≤ 0.
Lengths in m, angles in rad; ψ(φ) and its derivatives come from a callable ``law(phi) -> (ψ, ψ', ψ'')``.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import asin, degrees, tau
from typing import Callable

import numpy as np
from scipy.optimize import brentq

Law = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class FlatFollowerProfile:
    """Cam angles φ, profile points (x, y) in the cam frame (m), radius of curvature ρ (m), ψ0 (rad)."""

    phi: np.ndarray
    x: np.ndarray
    y: np.ndarray
    rho: np.ndarray
    psi0: float

    @property
    def has_cusp(self) -> bool:
        return bool(np.min(self.rho) <= 0.0)


@dataclass(frozen=True)
class FlatFollower:
    """Pivot distance ``A`` (m), face offset ``e`` (m), swing law ``law`` (ψ = 0 on the base circle), the cam's sense of
    rotation ``direction`` (+1 counter-clockwise, −1 clockwise: the same swing needs another cam)."""

    A: float
    e: float
    law: Law
    direction: float = 1.0

    def __post_init__(self) -> None:
        if not self.A > 0.0:
            raise ValueError(f"pivot distance A must be positive, got {self.A!r} m")
        if self.direction not in (1.0, -1.0):
            raise ValueError(f"direction must be +1 (counter-clockwise) or -1 (clockwise), got {self.direction!r}")

    def psi0(self, base_radius: float) -> float:
        """ψ0 = asin((R_b + e)/A) (rad)."""
        q = (base_radius + self.e) / self.A
        if not base_radius > 0.0 or not 0.0 < q < 1.0:
            raise ValueError(f"base radius {base_radius * 1e3:g} mm with offset e = {self.e * 1e3:g} mm needs "
                             f"0 < R_b + e < A = {self.A * 1e3:g} mm")
        return asin(q)

    def profile(self, base_radius: float, phi: np.ndarray | None = None) -> FlatFollowerProfile:
        """Envelope points and ρ(φ) for base radius ``base_radius`` (m) at cam angles ``phi`` (default 3600)."""
        phi = np.linspace(0.0, tau, 3600, endpoint=False) if phi is None else np.asarray(phi, dtype=float)
        psi0 = self.psi0(base_radius)
        psi, psi_p, psi_pp = (np.asarray(v, dtype=float) for v in self.law(phi))
        g = psi0 + psi
        sg, cg = np.sin(g), np.cos(g)
        p = self.A * sg - self.e
        p1 = self.A * cg * psi_p
        p2 = self.A * (cg * psi_pp - sg * psi_p ** 2)
        t1 = -(self.direction + psi_p)                  # dθ/dφ
        t2 = -psi_pp
        if np.any(t1 == 0.0):
            i = int(np.argmax(t1 == 0.0))
            raise ValueError(f"face direction stands still in the cam frame at φ = {degrees(float(phi[i])):.4g}° "
                             "(ψ' = −1): the envelope degenerates")
        p_th = p1 / t1
        p_thth = (p2 * t1 - p1 * t2) / t1 ** 3
        theta = np.pi / 2 - g - self.direction * phi
        nx, ny = np.cos(theta), np.sin(theta)
        x = p * nx - p_th * ny
        y = p * ny + p_th * nx
        return FlatFollowerProfile(phi, x, y, p + p_thth, psi0)

    def min_base_radius(self, phi: np.ndarray | None = None, tol: float = 1e-12) -> float:
        """Smallest base radius (m) whose profile has ρ > 0 everywhere (root of min ρ = 0 in R_b)."""
        hi = (self.A - self.e) * (1.0 - 1e-9)
        lo = max(-self.e, 0.0) + 1e-9 * self.A

        def margin(rb: float) -> float:
            return float(np.min(self.profile(rb, phi).rho))

        if margin(hi) <= 0.0:
            raise ValueError(f"the profile has a cusp for every base radius below A − e = {hi * 1e3:.4g} mm")
        if margin(lo) > 0.0:
            return lo
        grid = np.linspace(lo, hi, 65)
        m = np.array([margin(r) for r in grid])
        j = int(np.flatnonzero(m <= 0.0)[-1]) + 1   # the last sign change below hi
        return brentq(margin, grid[j - 1], grid[j], xtol=tol)
