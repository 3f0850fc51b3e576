"""DOP853: Dormand–Prince 8(5,3) adaptive explicit Runge–Kutta (Hairer, Nørsett & Wanner, *Solving ODEs I*, §II.10),
compiled for a numba RHS, else a numpy step.

The tableau, the combined 5th/3rd-order error estimate and the 7th-order dense output are scipy's
(:mod:`rig.solvers.dop853_tableau`, a copy of the coefficients of its ``DOP853``): 12 stages and f(t_new, y_new) per step,
plus 3 stages for the continuous extension — 15 RHS calls per accepted step, against DP45's 6, for an error of
order 8 instead of 5. Our stage rows: the 12 stages, the 3 extension stages, f(t_new, y_new) last (the next step's
first stage, as every method of :mod:`rig.solvers.stepper` keeps it); the dense output in the common form
y(t + θh) = y + h·Σ_c (Kᵀ P)[:, c]·θ^(c+1) (P from scipy's nested form, expanded once here). The compiled step is
``rig/solvers/templates/dop853.py``.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.polynomial import polynomial as poly

from rig.solvers import dop853_tableau as _dc
from rig.solvers.base import all_finite, lipschitz
from rig.solvers.stepper import AdaptiveStepper

N_STAGES = _dc.N_STAGES                 # 12
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0
EXPONENT = -1.0 / 8.0                   # error estimator of order 7 (scipy: −1/(order + 1))
#: our row of each of scipy's 16 stage rows (scipy: 12 stages, f_new, 3 extension stages)
_OURS = np.r_[np.arange(N_STAGES), 15, 12, 13, 14]
A = np.ascontiguousarray(_dc.A[:N_STAGES, :N_STAGES])         # stage rows 0..11 refer to stages 0..11 only
C = np.ascontiguousarray(_dc.C[:N_STAGES])
B = np.ascontiguousarray(_dc.B)
E3 = np.ascontiguousarray(_dc.E3)       # weights of the 12 stages and (last) f_new: our rows 0..11 and 15
E5 = np.ascontiguousarray(_dc.E5)
A_EXT = np.zeros((3, 16))
A_EXT[:, _OURS] = _dc.A[N_STAGES + 1:]                       # extension stages from the 12 stages and f_new
C_EXT = np.ascontiguousarray(_dc.C[N_STAGES + 1:])


def _dense_matrix() -> np.ndarray:
    """P (16 rows × 7 powers of θ) of scipy's interpolant y_old + θ(F0 + (1−θ)(F1 + θ(F2 + …))), F_j = h·Σ_i M_ji K_i."""
    m = np.zeros((7, 16))
    b = np.zeros(16)
    b[:N_STAGES] = B
    m[0] = b                                                  # Δy / h
    m[1] = -b
    m[1, 0] += 1.0                                            # f_old − Δy / h
    m[2] = 2.0 * b
    m[2, [0, 12]] -= 1.0                                      # 2Δy/h − (f_new + f_old), scipy rows
    m[3:] = _dc.D
    weights = []                                              # w_j(θ): the nested scheme with F_j = 1, others 0
    for j in range(7):
        w = np.zeros(1)
        for i, k in enumerate(reversed(range(7))):
            w = poly.polyadd(w, [1.0] if k == j else [0.0])
            w = poly.polymul(w, [0.0, 1.0] if i % 2 == 0 else [1.0, -1.0])
        weights.append(np.pad(w, (0, 8 - w.size))[1:8])      # powers θ¹..θ⁷
    p_scipy = m.T @ np.array(weights)                         # (16 scipy rows, 7)
    out = np.zeros((16, 7))
    out[_OURS] = p_scipy
    return out


P = _dense_matrix()


class DOP853(AdaptiveStepper):
    """Adaptive Dormand–Prince 8(5,3) with FSAL and 7th-order dense output (scipy's DOP853 method).

    ``rtol``, ``atol`` (error norm of scipy's DOP853), ``first_step`` (s; default Hairer's heuristic), ``max_step``
    (s). ``stiffness`` ('warn' | 'raise' | 'ignore'): Hairer's test on the last stage and f_new (both at t + h)
    against the stability boundary 6.1 (Hairer's DOP853 code). A :class:`rig.solvers.compiled.JitRhs` right-hand
    side is stepped in machine code (``compiled=False`` forces the numpy step).
    """

    order = 8
    method, label, P, limit = "dop853", "DOP853", P, 6.1

    error_order = 7
    safety, min_factor, max_factor, exponent = SAFETY, MIN_FACTOR, MAX_FACTOR, EXPONENT

    def _python_step(self) -> None:
        fun, t = self.fun, self.t
        y = np.array(self.y)
        K = np.zeros((16, y.size))
        K[0] = self.f

        def attempt(h: float, t_new: float) -> tuple[float, tuple]:
            for s in range(1, N_STAGES):
                ys = y + h * (A[s, :s] @ K[:s])
                K[s] = fun(t + C[s] * h, tuple(ys.tolist()))
            y_new = y + h * (B @ K[:N_STAGES])
            self.nfev += N_STAGES - 1
            if not all_finite(y_new):
                return math.nan, None
            K[15] = fun(t_new, tuple(y_new.tolist()))
            self.nfev += 1
            return error_norm(K, h, y, y_new, self.rtol, self.atol), (y_new, ys)

        h, t_new, h_next, (y_new, ys) = self._adapt(attempt)
        for e in range(3):                       # the continuous extension's stages (from the earlier rows only)
            K[12 + e] = fun(t + C_EXT[e] * h, tuple((y + h * (A_EXT[e] @ K)).tolist()))
        self.nfev += 3
        new = tuple(y_new.tolist())
        self._accept(t_new, new, h, h * lipschitz(tuple(K[15]), tuple(K[11]), new, tuple(ys.tolist())),
                     tuple(map(tuple, K.tolist())), h_next)


def error_norm(K: np.ndarray, h: float, y: np.ndarray, y_new: np.ndarray, rtol: float, atol: float) -> float:
    """scipy's DOP853 error norm: |h|·‖e5‖² / √((‖e5‖² + 0.01‖e3‖²)·n), e = Kᵀ E / (atol + rtol·max(|y|, |y_new|))."""
    scale = atol + rtol * np.maximum(np.abs(y), np.abs(y_new))
    rows = K[_OURS[:13]]                                     # the 12 stages and f_new
    e5, e3 = float(np.sum((E5 @ rows / scale) ** 2)), float(np.sum((E3 @ rows / scale) ** 2))
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * y.size)
