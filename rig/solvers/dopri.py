"""Dormand–Prince 5(4) adaptive explicit Runge–Kutta, compiled for a numba RHS, else in pure Python floats.

Same tableau, error norm (RMS of err/(atol + rtol·max|y|)) and quartic dense output as scipy's RK45. The
Python step uses tuple states and stages unrolled per state size (:mod:`rig.solvers.unrolled`); the
compiled one is ``rig/solvers/templates/dp45.py``.
"""
from __future__ import annotations

import math

import numpy as np

from rig.solvers.base import all_finite, lipschitz
from rig.solvers.stepper import AdaptiveStepper
from rig.solvers.unrolled import rk_kernels

_A21 = 1 / 5
_A31, _A32 = 3 / 40, 9 / 40
_A41, _A42, _A43 = 44 / 45, -56 / 15, 32 / 9
_A51, _A52, _A53, _A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
_A61, _A62, _A63, _A64, _A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
_B1, _B3, _B4, _B5, _B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
_E1, _E3, _E4, _E5, _E6, _E7 = -71 / 57600, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40
_C2, _C3, _C4, _C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
# quartic dense output (Shampine 1986, as in scipy RK45): rows = stages, columns = θ¹..θ⁴
P = np.array([
    [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0, 0, 0, 0],
    [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0       # the step-size controller (scipy's RK45)
EXPONENT = -0.2                                       # error estimator of order 4: −1/(order + 1)


def lower_triangle(rows: tuple[tuple[float, ...], ...]) -> np.ndarray:
    """A[s, j] of an explicit tableau from its rows below the diagonal (stage 2 on)."""
    out = np.zeros((len(rows) + 1, len(rows) + 1))
    for s, row in enumerate(rows, start=1):
        out[s, :s] = row
    return out


def python_tableau(A: np.ndarray, B: np.ndarray, C: np.ndarray, E: np.ndarray) -> tuple:
    """(rows of A below the diagonal, B, C, E) in Python floats: :func:`~rig.solvers.unrolled.rk_kernels`'s
    arguments (numpy scalars there would make the unrolled step twice as slow)."""
    rows = tuple(tuple(A[s, :s].tolist()) for s in range(1, A.shape[0]))
    return rows, tuple(B.tolist()), tuple(C.tolist()), tuple(E.tolist())


# the tableau as arrays, for the compiled step (rig.solvers.compiled): A[s, j], B, C, E (incl. FSAL stage)
A = lower_triangle(((_A21,), (_A31, _A32), (_A41, _A42, _A43), (_A51, _A52, _A53, _A54),
                    (_A61, _A62, _A63, _A64, _A65)))
B = np.array([_B1, 0.0, _B3, _B4, _B5, _B6])
C = np.array([0.0, _C2, _C3, _C4, _C5, 1.0])
E = np.array([_E1, 0.0, _E3, _E4, _E5, _E6, _E7])


class EmbeddedPair(AdaptiveStepper):
    """An explicit 5(4) pair with seven stages, FSAL and a quartic dense output (rows of ``P``): the Python step
    through :func:`~rig.solvers.unrolled.rk_kernels` on the class's ``tableau`` (rows of A below the diagonal, B,
    C, E with the FSAL stage's weight last), the compiled one through the template named by ``method``."""

    order = 5
    error_order = 4
    safety, min_factor, max_factor, exponent = SAFETY, MIN_FACTOR, MAX_FACTOR, EXPONENT
    tableau: tuple

    def _python_step(self) -> None:
        fun, t, y, k1 = self.fun, self.t, self.y, self.f
        stages, error_norm = rk_kernels(*self.tableau, len(y))

        def attempt(h: float, t_new: float) -> tuple[float, tuple]:
            y_new, y6, k2, k3, k4, k5, k6 = stages(fun, t, y, k1, h)
            self.nfev += 5
            if not all_finite(y_new):
                return math.nan, None
            k7 = tuple(fun(t_new, y_new))
            self.nfev += 1
            return (error_norm(y, y_new, k1, k2, k3, k4, k5, k6, k7, h, self.rtol, self.atol),
                    (y_new, y6, (k1, k2, k3, k4, k5, k6, k7)))

        h, t_new, h_next, (y_new, y6, K) = self._adapt(attempt)
        self._accept(t_new, y_new, h, h * lipschitz(K[6], K[5], y_new, y6), K, h_next)


class DormandPrince45(EmbeddedPair):
    """Adaptive Dormand–Prince 5(4) with FSAL, local extrapolation and quartic dense output.

    ``rtol``, ``atol`` (scipy's RMS error norm), ``first_step`` (s; default Hairer's heuristic),
    ``max_step`` (s). ``stiffness`` ('warn' | 'raise' | 'ignore'): Hairer's test on stages 6 and 7 (both
    at t + h) against the stability boundary 3.25; ``stiff_at`` is the time it first fired (None
    otherwise). A :class:`rig.solvers.compiled.JitRhs` right-hand side is stepped in machine code
    (``compiled=False`` forces the pure-Python step).
    """

    method, label, P, limit = "dp45", "DP45", P, 3.25
    tableau = python_tableau(A, B, C, E)
