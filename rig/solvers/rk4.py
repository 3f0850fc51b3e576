"""Classical fixed-step Runge–Kutta 4 with its cubic continuous extension (compiled for a numba RHS, else
pure Python floats; compiled step: ``rig/solvers/templates/rk4.py``)."""
from __future__ import annotations

import numpy as np

from rig.solvers.base import lipschitz
from rig.solvers.stepper import FixedStepper

# continuous extension b_i(θ) = Σ_k P[i, k] θ^(k+1) (Hairer–Nørsett–Wanner II.6, 3rd order); the last row is
# f(t_new, y_new), which only serves the next step
P = np.array([[1.0, -1.5, 2 / 3], [0.0, 1.0, -2 / 3], [0.0, 1.0, -2 / 3], [0.0, -0.5, 2 / 3], [0.0, 0.0, 0.0]])


class RK4(FixedStepper):
    """Fixed step ``h`` (s), order 4 (see :class:`~rig.solvers.stepper.FixedStepper`): Hairer's stiffness test
    on stages 3 and 4 against the RK4 stability boundary 2.78 — a too-large step is reported as divergence
    (``stiffness="raise"``, default), not silently wrong."""

    order = 4
    method, label, P, limit = "rk4", "RK4", P, 2.78

    def _python_step(self) -> None:
        fun, t, y, k1 = self.fun, self.t, self.y, self.f
        h, t_new = self._fixed_h()
        hh = 0.5 * h
        k2 = tuple(fun(t + hh, tuple(a + hh * b for a, b in zip(y, k1))))
        y3 = tuple(a + hh * b for a, b in zip(y, k2))
        k3 = tuple(fun(t + hh, y3))
        y4 = tuple(a + h * b for a, b in zip(y, k3))
        k4 = tuple(fun(t + h, y4))
        y_new = tuple(a + h / 6 * (b + 2 * c + 2 * d + e) for a, b, c, d, e in zip(y, k1, k2, k3, k4))
        self.nfev += 3
        self._finish(t_new, y_new, h, (k1, k2, k3, k4), h * lipschitz(k4, k3, y4, y3))
