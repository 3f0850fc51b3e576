"""Classical fixed-step Runge–Kutta 4 with its cubic continuous extension (pure Python floats)."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from rig.solvers.base import OdeSolver, Rhs, SolverDivergence, StiffnessMonitor, all_finite
from rig.solvers.dopri import PolynomialDense

# continuous extension b_i(θ) = Σ_k P[i, k] θ^(k+1) (Hairer–Nørsett–Wanner II.6, 3rd order)
_P = np.array([[1.0, -1.5, 2 / 3], [0.0, 1.0, -2 / 3], [0.0, 1.0, -2 / 3], [0.0, -0.5, 2 / 3]])


class RK4(OdeSolver):
    """Fixed step ``h`` (s); the last step is shortened to land on ``t_bound``. No error control.

    ``first_step`` is accepted for interface compatibility with adaptive solvers and ignored.
    ``stiffness`` ('warn' | 'raise' | 'ignore'): Hairer's test on stages 3 and 4 against the RK4
    stability boundary 2.78 — a too-large fixed step on a stiff problem is reported, not silently wrong.
    """

    order = 4

    def __init__(self, fun: Rhs, t0: float, y0: Sequence[float], t_bound: float, h: float = 1e-3,
                 first_step: float | None = None, stiffness: str = "warn"):
        super().__init__(fun, t0, y0, t_bound)
        self.monitor = StiffnessMonitor("RK4", 2.78, stiffness)
        if not h > 0:
            raise ValueError(f"RK4: step h = {h!r} s must be positive")
        self.h = h
        self._K: tuple | None = None

    def _step_impl(self) -> None:
        fun, t, y = self.fun, self.t, self.y
        h = self.h
        if self.t_bound - t - h < 1e-6 * h:   # last step: land on t_bound, no round-off sliver afterwards
            h = self.t_bound - t
        if h < self._min_step():
            raise SolverDivergence(f"step size underflow (h = {h:.3g} s)", t, y)
        hh = 0.5 * h
        k1 = fun(t, y)
        k2 = fun(t + hh, tuple(a + hh * b for a, b in zip(y, k1)))
        y3 = tuple(a + hh * b for a, b in zip(y, k2))
        k3 = fun(t + hh, y3)
        y4 = tuple(a + h * b for a, b in zip(y, k3))
        k4 = fun(t + h, y4)
        self.nfev += 4
        y_new = tuple(a + h / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(y, k1, k2, k3, k4))
        if not all_finite(y_new):
            raise SolverDivergence("non-finite state", t + h, y_new)
        self.monitor.check(t + h, y_new, h, k4, k3, y4, y3)
        self.t_old, self.y_old = t, y
        self.t = self.t_bound if t + h >= self.t_bound else t + h
        self.y = y_new
        self.h_last = h
        self._K = (k1, k2, k3, k4)

    @property
    def stiff_at(self) -> float | None:
        return self.monitor.detected_at

    def dense_output(self) -> PolynomialDense:
        return PolynomialDense(self.t_old, self.t - self.t_old, self.y_old, self._K, _P)
