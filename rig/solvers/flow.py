"""Closed-form segments: a "solver" that steps along an exact flow, and the affine rotor flow.

Where a problem has an exact solution in its current mode (e.g. a stuck clutch moving as one linear
rotor), :func:`rig.solvers.integrate` asks ``Problem.flow(t, y, t_bound)`` for a :class:`ClosedForm`
and steps along it with :class:`ClosedFormSolver` instead of a Runge–Kutta method. The flow lists
``stops``: step ends chosen so that each step holds at most one zero of every event function (the flow
knows where they can be); events are then located by the driver's usual root finding on the exact
solution.
"""
from __future__ import annotations

import math
from typing import Protocol, Sequence

import numpy as np

from rig.solvers.base import OdeSolver, SolverDivergence, all_finite


class ClosedForm(Protocol):
    """Exact solution of one segment: ``flow(t)`` → state tuple for a float, (n, m) array for an array."""

    stops: Sequence[float]

    def __call__(self, t): ...


class ClosedFormSolver(OdeSolver):
    """Steps along ``flow`` from ``t0`` to ``t_bound``, ending steps at ``flow.stops``; no RHS calls."""

    def __init__(self, flow: ClosedForm, t0: float, y0: Sequence[float], t_bound: float):
        super().__init__(flow, t0, y0, t_bound)
        self.flow = flow
        self._stops = sorted(s for s in flow.stops if t0 < s < t_bound)[::-1]

    def _step_impl(self) -> None:
        t_new = self._stops.pop() if self._stops else self.t_bound
        y_new = tuple(self.flow(t_new))
        if not all_finite(y_new):
            raise SolverDivergence("non-finite closed-form state", t_new, y_new)
        self.t_old, self.y_old = self.t, self.y
        self.t, self.y = t_new, y_new
        self.h_last = t_new - self.t_old

    def dense_output(self) -> ClosedForm:
        return self.flow


class AffineRotor:
    """φ̇ = ω, J·ω̇ = a − b·ω from (t0, φ0, ω0): exact ω(t), φ(t) (rad, rad/s) and the time a speed is reached.

    With λ = b/J, α0 = (a − bω0)/J and τ = t − t0: ω = ω0 + α0 τ g1(λτ), φ = φ0 + ω0 τ + α0 τ² g2(λτ),
    g1(x) = (1 − e^(−x))/x, g2(x) = (x − 1 + e^(−x))/x² (series near x = 0; λ = 0 gives the uniformly
    accelerated rotor).
    """

    SERIES = 1e-3        # |λτ| below which g2 uses its Taylor series (cancellation otherwise)

    def __init__(self, t0: float, phi0: float, omega0: float, a: float, b: float, J: float):
        if not J > 0:
            raise ValueError(f"AffineRotor: inertia J = {J!r} kg*m^2 must be positive")
        self.t0, self.phi0, self.omega0 = t0, phi0, omega0
        self.lam = b / J
        self.alpha0 = (a - b * omega0) / J

    def state(self, t: float) -> tuple[float, float]:
        """(φ − φ0, ω) at time t (float)."""
        tau = t - self.t0
        x = self.lam * tau
        if x == 0.0:
            g1, g2 = 1.0, 0.5
        else:
            g1 = -math.expm1(-x) / x
            g2 = 0.5 - x / 6 + x * x / 24 - x ** 3 / 120 if abs(x) < self.SERIES else (x + math.expm1(-x)) / (x * x)
        return self.omega0 * tau + self.alpha0 * tau * tau * g2, self.omega0 + self.alpha0 * tau * g1

    def states(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorised :meth:`state`: (φ − φ0, ω) at times ``t`` (array)."""
        tau = np.asarray(t, dtype=float) - self.t0
        x = self.lam * tau
        xz = np.where(x == 0.0, 1.0, x)                 # avoid 0/0 in the branch not taken
        g1 = np.where(x == 0.0, 1.0, -np.expm1(-xz) / xz)
        g2 = np.where(np.abs(x) < self.SERIES, 0.5 - x / 6 + x * x / 24 - x ** 3 / 120,
                      (xz + np.expm1(-xz)) / (xz * xz))
        return self.omega0 * tau + self.alpha0 * tau * tau * g2, self.omega0 + self.alpha0 * tau * g1

    def time_of_speed(self, omega: float) -> float:
        """Time (s) at which ω reaches ``omega``; inf if it never does (moving away or at rest)."""
        dw = omega - self.omega0
        if dw == 0.0:
            return self.t0
        if self.alpha0 == 0.0 or dw / self.alpha0 < 0.0:
            return math.inf
        if self.lam == 0.0:
            return self.t0 + dw / self.alpha0
        u = -self.lam * dw / self.alpha0               # e^(−λτ) = 1 + u
        return self.t0 - math.log1p(u) / self.lam if u > -1.0 else math.inf
