"""Normalised cam motion laws y(x) on x ∈ [0, 1] with y(0) = 0, y(1) = 1 (MODELS §1).

Every law gives y, y', y'', y''' (derivatives w.r.t. x) on numpy arrays, its characteristic
coefficients C_v = max|y'|, C_a = max|y''|, C_j = max|y'''| (computed, not tabulated) and the
positions where y'' jumps (soft shocks), including x = 0 and x = 1 when y'' does not vanish there.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import minimize_scalar


@dataclass(frozen=True)
class Coefficients:
    """Characteristic coefficients: C_v = max|y'|, C_a = max|y''|, C_j = max|y'''| (finite part)."""

    C_v: float
    C_a: float
    C_j: float


class MotionLaw(ABC):
    """A normalised rise law; subclasses implement :meth:`derivatives` and :meth:`breakpoints`."""

    name: str = ""

    @abstractmethod
    def derivatives(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """y, y', y'', y''' at ``x`` (array, values in [0, 1])."""

    def breakpoints(self) -> tuple[float, ...]:
        """Interior x where the law's analytic pieces change (empty for single-piece laws)."""
        return ()

    def y(self, x: np.ndarray) -> np.ndarray:
        return self.derivatives(np.asarray(x, dtype=float))[0]

    def accel_jumps(self) -> list[tuple[float, float]]:
        """(x, y''(x+) − y''(x−)) for every x in [0, 1] where y'' jumps; outside [0, 1] y'' is taken as 0."""
        jumps = []
        for x in (0.0, *self.breakpoints(), 1.0):
            eps = 1e-12
            left = 0.0 if x == 0.0 else float(self.derivatives(np.array([x - eps]))[2][0])
            right = 0.0 if x == 1.0 else float(self.derivatives(np.array([x + eps]))[2][0])
            if abs(right - left) > 1e-6 * max(1.0, abs(left), abs(right)):
                jumps.append((x, right - left))
        return jumps

    @cached_property
    def coefficients(self) -> Coefficients:
        """Maxima found on a dense grid, then polished by a bounded scalar search around the best point."""
        edges = np.unique(np.concatenate(([0.0, 1.0], self.breakpoints())))
        grid = np.unique(np.concatenate([np.linspace(a, b, 2001) for a, b in zip(edges[:-1], edges[1:])]))
        inner = grid.copy()
        inner[0] += 1e-12
        inner[-1] -= 1e-12
        values = self.derivatives(inner)
        out = []
        for order in (1, 2, 3):
            mag = np.abs(values[order])
            i = int(np.argmax(mag))
            lo, hi = inner[max(i - 1, 0)], inner[min(i + 1, len(inner) - 1)]
            res = minimize_scalar(lambda x: -abs(float(self.derivatives(np.array([x]))[order][0])),
                                  bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
            out.append(max(float(mag[i]), -float(res.fun)))
        return Coefficients(*out)

    def __repr__(self) -> str:
        return f"<MotionLaw {self.name}>"


class ReversedLaw(MotionLaw):
    """A return read backwards in cam angle, as a rise: y_r(x) = 1 − y(1 − x) of the law ``y`` a return segment
    follows (s = level − h·y over the segment). A centric follower's pressure angle depends only on |s'| and s, so
    sizing the rise y_r sizes the return."""

    def __init__(self, law: MotionLaw):
        self.law, self.name = law, f"{law.name}, reversed"

    def derivatives(self, x):
        y, y1, y2, y3 = self.law.derivatives(1.0 - np.asarray(x, dtype=float))
        return 1.0 - y, y1, -y2, y3

    def breakpoints(self) -> tuple[float, ...]:
        return tuple(sorted(1.0 - b for b in self.law.breakpoints()))


class PolynomialLaw(MotionLaw):
    """y = Σ c_n x^n (coefficients lowest power first)."""

    def __init__(self, name: str, coefficients: list[float]):
        self.name = name
        p = [np.polynomial.Polynomial(coefficients)]
        for _ in range(3):
            p.append(p[-1].deriv())
        self._coef = [q.coef for q in p]       # evaluated by polyval: Polynomial's call adds a domain map per call

    @property
    def power_coefficients(self) -> np.ndarray:
        """c_0, c_1, ... of y(x) (lowest power first)."""
        return self._coef[0].copy()

    def derivatives(self, x):
        return tuple(np.polynomial.polynomial.polyval(x, c) for c in self._coef)  # type: ignore[return-value]


@dataclass(frozen=True)
class AccelPiece:
    """On [x_start, next start): y'' ∝ c0 + c1·sin(w·(x − x_start) + theta) (w > 0)."""

    x_start: float
    c0: float = 0.0
    c1: float = 0.0
    w: float = 1.0
    theta: float = 0.0


class PiecewiseSineLaw(MotionLaw):
    """Laws built from constant and sine pieces of acceleration, integrated in closed form.

    Starting from y(0) = y'(0) = 0, the pieces are integrated analytically and scaled so that
    y(1) = 1 (the acceleration amplitude follows from the shape). Covers parabolic, cycloidal,
    simple harmonic, modified trapezoid and modified sine.
    """

    def __init__(self, name: str, pieces: list[AccelPiece]):
        if pieces[0].x_start != 0.0:
            raise ValueError(f"law {name}: the first acceleration piece must start at x = 0")
        self.name = name
        n = len(pieces)
        self._xa = np.array([p.x_start for p in pieces])
        self._c0 = np.array([p.c0 for p in pieces])
        self._c1 = np.array([p.c1 for p in pieces])
        self._w = np.array([p.w for p in pieces])
        self._th = np.array([p.theta for p in pieces])
        self._ya = np.zeros(n)
        self._va = np.zeros(n)
        ends = np.append(self._xa[1:], 1.0)
        for i in range(n):  # carry y and y' across the pieces
            y, v = self._integrate(i, np.array([ends[i] - self._xa[i]]))[:2]
            if i + 1 < n:
                self._ya[i + 1], self._va[i + 1] = y[0], v[0]
            else:
                scale = 1.0 / y[0]
        for arr in (self._c0, self._c1, self._ya, self._va):
            arr *= scale

    def _integrate(self, i, u):
        c0, c1, w, th = self._c0[i], self._c1[i], self._w[i], self._th[i]
        arg = w * u + th
        sa, ca = np.sin(arg), np.cos(arg)
        v = self._va[i] + c0 * u - (c1 / w) * (ca - np.cos(th))
        y = (self._ya[i] + self._va[i] * u + 0.5 * c0 * u * u
             - (c1 / w) * ((sa - np.sin(th)) / w - np.cos(th) * u))
        return y, v, c0 + c1 * sa, c1 * w * ca

    def breakpoints(self):
        return tuple(float(x) for x in self._xa[1:])

    def derivatives(self, x):
        i = np.searchsorted(self._xa, x, side="right") - 1
        i = np.clip(i, 0, len(self._xa) - 1)
        return self._integrate(i, x - self._xa[i])
