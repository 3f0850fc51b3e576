"""Size of a translating roller-follower cam (MODELS §3.6): base radius (Flocke), guide length, total size
H/h and the pressure angle that minimises it.

``law`` is a normalised rise law (:mod:`rig.motion.laws`) over the cam angle Φ (rad) with stroke h (m);
s' = (h/Φ)·y'. The offset e (m) is signed so that it adds to s': tan α = (s' + e)/(sqrt(r_b² − e²) + s).
"""
from __future__ import annotations

from dataclasses import dataclass
from math import atan, cos, sin, sqrt, tan

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from rig.mechanisms.checks import finite, positive
from rig.motion.laws import MotionLaw

GRID = 4001


def _maximise(f, n: int = GRID) -> tuple[float, float]:
    """(x, f(x)) at the maximum of a scalar function of x ∈ [0, 1]: dense grid, then a bounded polish."""
    x = np.linspace(0.0, 1.0, n)
    v = f(x)
    i = int(np.argmax(v))
    lo, hi = x[max(i - 1, 0)], x[min(i + 1, n - 1)]
    res = minimize_scalar(lambda t: -float(f(np.array([t]))[0]), bounds=(lo, hi), method="bounded",
                          options={"xatol": 1e-13})
    return (float(res.x), -float(res.fun)) if -res.fun > v[i] else (float(x[i]), float(v[i]))


SMALLEST_ALPHA = np.radians(0.1) * (1.0 - 1e-12)     # rad: the least pressure angle sized for (SizeModel scans from it)


def _check(h: float, big_phi: float, alpha: float) -> None:
    positive(h, "stroke h (m)")                 # (inf read NaN, a string a TypeError; an audit)
    finite(big_phi, "rise angle Φ (rad)")
    finite(alpha, "pressure angle α (rad)")
    if not 0.0 < big_phi <= 2.0 * np.pi:
        raise ValueError(f"rise angle Φ must lie in (0, 2π] rad, got {big_phi!r} rad"
                         + (" (degrees given as rad?)" if big_phi > 2.0 * np.pi else ""))
    if not SMALLEST_ALPHA <= alpha < np.pi / 2:       # (1e-320 rad read an infinite radius; an audit)
        raise ValueError(f"pressure angle must lie in [0.1°, 90°) (below 0.1° the base radius exceeds 500 strokes), "
                         f"got {np.degrees(alpha):g}°")


def peak_velocity(law: MotionLaw) -> tuple[float, float, float]:
    """(x, y'_max, y(x)) at the largest y' of the law."""
    x, v = _maximise(lambda t: law.derivatives(t)[1])
    return x, v, float(law.y(np.array([x]))[0])


def flocke_base_radius(law: MotionLaw, h: float, big_phi: float, alpha: float, e: float = 0.0) -> float:
    """Flocke: r_b = sqrt(((s'_max + e)/tan α − s|_{s'max})² + e²) (m), evaluated at the velocity peak."""
    _check(h, big_phi, alpha)
    e = finite(e, "offset e (m)")
    _, v, y = peak_velocity(law)
    return sqrt(((h / big_phi * v + e) / tan(alpha) - h * y) ** 2 + e * e)


def centric_base_ratio(law: MotionLaw, big_phi: float, alpha: float) -> float:
    """Dimensionless centric Flocke radius r_b/h = y'_max/(Φ tan α) − y|_{y'max}."""
    _check(1.0, big_phi, alpha)
    _, v, y = peak_velocity(law)
    return v / (big_phi * tan(alpha)) - y


def exact_base_radius(law: MotionLaw, h: float, big_phi: float, alpha: float, e: float = 0.0) -> float:
    """Smallest r_b (m) keeping |pressure angle| ≤ α (rad) over the whole rise, for the offset ``e`` (m) of either
    sign: r_b = sqrt(d² + e²), d the max over x of |s' + e|/tan α − s. A negative e makes s' + e negative at the
    ends of the rise (α down to −atan(|e|/d) at x = 0), so both signs are maximised. Flocke takes the positive
    side at the velocity peak, which is slightly late: its radius is a little small."""
    _check(h, big_phi, alpha)
    e = finite(e, "offset e (m)")
    d = max(_maximise(lambda t: sign * (h / big_phi * law.derivatives(t)[1] + e) / tan(alpha) - h * law.y(t))[1]
            for sign in (1.0, -1.0))
    return sqrt(max(d, 0.0) ** 2 + e * e)


def pressure_angles(law: MotionLaw, h: float, big_phi: float, base_radius: float, e: float = 0.0,
                    x: np.ndarray | None = None) -> np.ndarray:
    """Forward check: α(x) = atan((s' + e)/(sqrt(r_b² − e²) + s)) (rad) over the rise at ``x`` (default a grid)."""
    _check(h, big_phi, np.pi / 4)
    finite(e, "offset e (m)")
    if not finite(base_radius, "base radius (m)") > abs(e):
        raise ValueError(f"base radius {base_radius * 1e3:g} mm must exceed the offset |e| = {abs(e) * 1e3:g} mm")
    x = np.linspace(0.0, 1.0, GRID) if x is None else np.asarray(x, float)
    y, y1 = law.derivatives(x)[:2]
    return np.arctan((h / big_phi * y1 + e) / (sqrt(base_radius ** 2 - e * e) + h * y))


@dataclass(frozen=True)
class TotalSize:
    """Total size of a centric translating roller-follower cam at pressure angle ``alpha`` (rad), all over h:
    base radius r_b/h, guide length b/h and H/h = 3 + 2r_b/h + b/h."""

    alpha: float
    base: float
    guide: float
    total: float


def guide_ratio(alpha: float, mu: float, base_ratio: float, load: float = 0.0) -> float:
    """b/h ≥ μ sin α/(cos α − μ sin α − Φ_L)·(1 + 2r_b/h); Φ_L = Q/F the load coefficient. Raises where the
    follower self-locks in its guide (denominator ≤ 0)."""
    if not 0.0 < finite(alpha, "pressure angle α (rad)") < np.pi / 2:      # (a negative α or μ read −0.183, an audit)
        raise ValueError(f"pressure angle α must lie in (0, 90°), got {np.degrees(alpha):g}°")
    if finite(mu, "guide friction μ") < 0.0 or finite(load, "Φ_L") < 0.0:     # (r_b/h may be: the formula's
        raise ValueError(f"guide friction μ and Φ_L must not be negative, got {mu!r}, {load!r}")   # range, said)
    finite(base_ratio, "r_b/h")
    den = cos(alpha) - mu * sin(alpha) - load
    if not den > 0.0:
        raise ValueError(f"follower self-locks in its guide at α = {np.degrees(alpha):.4g}° (μ = {mu:g}, "
                         f"Φ_L = {load:g})")
    return mu * sin(alpha) / den * (1.0 + 2.0 * base_ratio)


class SizeModel:
    """H/h(α) for a law over Φ with guide friction μ and load coefficient Φ_L; :meth:`optimum` solves
    dH/dα = 0 from the analytic derivative."""

    def __init__(self, law: MotionLaw, big_phi: float, mu: float, load: float = 0.0):
        _check(1.0, big_phi, 0.5)   # validates Φ (h and α are not parameters of the model)
        if not finite(mu, "friction coefficient μ") >= 0.0:
            raise ValueError(f"friction coefficient μ must not be negative, got {mu!r}")
        if not 0.0 <= load < 1.0:
            raise ValueError(f"load coefficient Φ_L = Q/F must lie in [0, 1), got {load!r}")
        self.big_phi, self.mu, self.load = big_phi, mu, load
        _, self.v, self.y = peak_velocity(law)

    @property
    def alpha_lock(self) -> float:
        """Pressure angle (rad) where cos α − μ sin α − Φ_L = 0 (self-locking)."""
        m = np.hypot(1.0, self.mu)
        return float(np.arccos(self.load / m) - atan(self.mu))

    def size(self, alpha: float) -> TotalSize:
        base = self.v / (self.big_phi * tan(alpha)) - self.y
        guide = guide_ratio(alpha, self.mu, base, self.load)
        return TotalSize(alpha, base, guide, 3.0 + 2.0 * base + guide)

    def derivative(self, alpha: float) -> float:
        """dH/dα (per rad, over h)."""
        s, c = sin(alpha), cos(alpha)
        base = self.v / (self.big_phi * tan(alpha)) - self.y
        base_d = -self.v / (self.big_phi * s * s)
        den = c - self.mu * s - self.load
        g = self.mu * s / den
        g_d = self.mu * (1.0 - self.load * c) / den ** 2
        return 2.0 * base_d + g_d * (1.0 + 2.0 * base) + 2.0 * g * base_d

    def scan(self, n: int = 20001) -> TotalSize:
        """The smallest H/h on ``n`` pressure angles between 0.1° and the self-locking angle (a check)."""
        sizes = [self.size(a) for a in np.linspace(np.radians(0.1), self.alpha_lock * (1.0 - 1e-6), n)]
        return min(sizes, key=lambda t: t.total)

    def optimum(self) -> TotalSize:
        """The size at the root of dH/dα = 0 between 0 and the self-locking angle."""
        hi = self.alpha_lock
        a, b = 1e-6, hi * (1.0 - 1e-9)
        if not (self.derivative(a) < 0.0 < self.derivative(b)):
            raise ValueError("H/h has no interior minimum below the self-locking angle")
        return self.size(brentq(self.derivative, a, b, xtol=1e-14, rtol=4 * np.finfo(float).eps))
