"""The flat-tappet elastic-and-safety clutch: parameters, geometry and static characteristic (§4.1–4.2)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rig.plants.clutch.geometry import GeometryError, PhaseLimits, lobe_geometry, phase_limits
from rig.plants.clutch.kernel import locate_segment, segment_geometry
from rig.scene import Field

#: Scene schema of a flat-tappet clutch ([plant] table); thesis values, assumptions marked in docs/clutch.md.
CLUTCH_SCHEMA = {
    "r0": Field("m", doc="base radius of the cam"),
    "r1": Field("m", doc="radius of the phase-I arc"),
    "r2": Field("m", 0.030, "fillet radius (assumption 30 mm)"),
    "k_a": Field("N/m", doc="tappet spring rate"),
    "F_a1": Field("N", None, "spring preload (give F_a1 or delta)"),
    "delta": Field("m", None, "initial spring deflection (give F_a1 or delta)"),
    "mu_B": Field("1", 0.10, "friction coefficient cam face / tappet"),
    "mu_C": Field("1", 0.12, "friction coefficient tappet / guide"),
    "n": Field("1", 3, "number of tappets (= lobes)", minimum=1, integer=True),
    "m_t": Field("kg", 0.2, "tappet mass (assumption)"),
    "J1": Field("kg*m^2", 0.08, "driving-side inertia (assumption)"),
    "J3": Field("kg*m^2", 0.05, "driven-side inertia (assumption)"),
    "L1": Field("m", 0.140, "radial position of the inner guide bearing"),
    "L2": Field("m", 0.160, "radial position of the outer guide bearing"),
}


@dataclass
class FlatTappetClutch:
    """Three-lobe cam with flat translating tappets (SI: m, N/m, N, kg, kg·m²).

    Give the spring preload either as ``F_a1`` (N) or as the initial deflection ``delta`` (m);
    the spring force is F_a = F_a1 + k_a·s = k_a (s + δ).
    """

    r0: float
    r1: float
    r2: float
    k_a: float
    delta: float | None = None
    F_a1: float | None = None
    mu_B: float = 0.10
    mu_C: float = 0.12
    n: int = 3
    m_t: float = 0.2
    J1: float = 0.08
    J3: float = 0.05
    L1: float = 0.140
    L2: float = 0.160
    limits: PhaseLimits = field(init=False)

    def __post_init__(self) -> None:
        if (self.delta is None) == (self.F_a1 is None):
            raise GeometryError("FlatTappetClutch: give exactly one of delta (m) or F_a1 (N) for the spring preload")
        if not self.k_a >= 0 or not math.isfinite(self.k_a):
            raise GeometryError(f"FlatTappetClutch: spring rate k_a = {self.k_a!r} N/m must be >= 0")
        if self.F_a1 is None:
            self.F_a1 = self.k_a * self.delta
        else:
            self.delta = self.F_a1 / self.k_a if self.k_a > 0 else math.inf
        if self.F_a1 < 0:
            raise GeometryError(f"FlatTappetClutch: preload F_a1 = {self.F_a1} N must be >= 0")
        for name in ("mu_B", "mu_C", "m_t"):
            if not getattr(self, name) >= 0:
                raise GeometryError(f"FlatTappetClutch: {name} = {getattr(self, name)!r} must be >= 0")
        for name in ("J1", "J3"):
            if not getattr(self, name) > 0:
                raise GeometryError(f"FlatTappetClutch: inertia {name} = {getattr(self, name)!r} kg*m^2 must be > 0")
        if int(self.n) != self.n or self.n < 1:
            raise GeometryError(f"FlatTappetClutch: number of tappets n = {self.n!r} must be a positive integer")
        if not self.L2 > self.L1 > 0:
            raise GeometryError(f"FlatTappetClutch: guide bearings need 0 < L1 < L2, got L1={self.L1}, L2={self.L2} m")
        self.n = int(self.n)
        self.limits = phase_limits(self.r0, self.r1, self.r2)

    def phase_limits(self) -> PhaseLimits:
        """φ_maxI (rad), a2 (m) and the apex angle (rad)."""
        return self.limits

    def geometry(self, phi: np.ndarray | float) -> dict[str, np.ndarray]:
        """k1 (m), k2 (m), k3 (m²), lift s (m), dk1/dφ (m) at relative angles φ (rad, any real value)."""
        return lobe_geometry(phi, self.r0, self.r1, self.r2, self.limits)

    def scalar_geometry(self):
        """Fast scalar φ ↦ (k1, k2, dk1/dφ, flank) for ODE right-hand sides: flank = +1 on the rising half-lobe
        (k1 ≥ 0, including φ = 0 and the apex), −1 on the falling one (the compiled
        :func:`rig.plants.clutch.kernel.segment_geometry` on the segment holding φ; the tests check it against
        :func:`lobe_geometry`)."""
        c1, a2, pm, r1, r2 = self.r1 - self.r0, self.limits.a2, self.limits.phi_maxI, self.r1, self.r2

        def geom(phi: float) -> tuple[float, float, float, float]:
            base, seg = locate_segment(phi, 0.0, pm)
            return segment_geometry(phi, base, seg, c1, a2, r1, r2, pm)

        return geom

    def spring_force(self, phi: np.ndarray | float) -> np.ndarray:
        """Spring force of one tappet F_a = F_a1 + k_a·s (N)."""
        return self.F_a1 + self.k_a * self.geometry(phi)["s"]

    def static_torque(self, phi: np.ndarray | float, friction: bool = True, direction: float = 1.0) -> np.ndarray:
        """Static torque T = n·F_a·(k1 + μ_B·k2·direction) (N·m).

        ``direction`` = +1 while φ increases (loading), −1 while it decreases (unloading): the friction
        term opposes the relative motion. ``friction=False`` gives the frictionless (elastic) curve.
        """
        g = self.geometry(phi)
        fa = self.F_a1 + self.k_a * g["s"]
        mu = self.mu_B * direction if friction else 0.0
        return self.n * fa * (g["k1"] + mu * g["k2"])

    def stiffness(self, phi: np.ndarray | float, friction: bool = True, direction: float = 1.0) -> np.ndarray:
        """Analytic K = dT/dφ (N·m/rad), per phase; uses ds/dφ = dk2/dφ = k1."""
        g = self.geometry(phi)
        fa = self.F_a1 + self.k_a * g["s"]
        mu = self.mu_B * direction if friction else 0.0
        return self.n * (self.k_a * g["k1"] * (g["k1"] + mu * g["k2"]) + fa * (g["dk1"] + mu * g["k1"]))
