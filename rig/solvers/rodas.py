"""Rodas4: L-stable, stiffly accurate Rosenbrock method of order 4 with an embedded order-3 solution and a
cubic continuous extension (Hairer & Wanner, *Solving Ordinary Differential Equations II*, §IV.7, code
RODAS; coefficients as in Hairer's rodas.f). Compiled for a numba RHS (``rig/solvers/templates/rodas4.py``),
else numpy.

One step from (t, y), W = I/(hγ) − J with J = ∂f/∂y and f_t = ∂f/∂t at (t, y) (forward differences, n + 1
RHS calls, once per step): for stages i = 1..6, W·k_i = f(t + c_i h, y + Σ_j a_ij k_j) + Σ_j (c_ij/h)·k_j
+ h·d_i·f_t; y_new = y + Σ_j a_6j k_j + k_6, and k_6 is the error estimate (difference to the embedded
order-3 solution). Dense output y(t + θh) = (1 − θ)·y + θ·(y_new + (1 − θ)·(Σ h1_j k_j + θ·Σ h2_j k_j)).
Per step: 5 RHS calls for the stages, n + 1 for the Jacobian, one for f(t_new, y_new) (the next step's
first stage).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from rig.solvers.base import Rhs
from rig.solvers.stepper import AdaptiveStepper

GAMMA = 0.25
A = np.zeros((6, 6))
A[1, 0] = 1.544
A[2, :2] = 0.9466785280815826, 0.2557011698983284
A[3, :3] = 3.314825187068521, 2.896124015972201, 0.9986419139977817
A[4, :4] = 1.221224509226641, 6.019134481288629, 12.53708332932087, -0.687886036105895
A[5, :5] = 1.221224509226641, 6.019134481288629, 12.53708332932087, -0.687886036105895, 1.0
C = np.zeros((6, 6))
C[1, 0] = -5.6688
C[2, :2] = -2.430093356833875, -0.2063599157091915
C[3, :3] = -0.1073529058151375, -9.594562251023355, -20.47028614809616
C[4, :4] = 7.496443313967647, -10.24680431464352, -33.99990352819905, 11.7089089320616
C[5, :5] = 8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136, -6.058818238834054
STAGE_T = np.array([0.0, 0.386, 0.21, 0.63, 1.0, 1.0])
D = np.array([0.25, -0.1043, 0.1035, -0.0362, 0.0, 0.0])
H_DENSE = np.array([[10.12623508344586, -7.487995877610167, -34.80091861555747, -7.992771707568823,
                     1.025137723295662, 0.0],
                    [-0.6762803392801253, 6.087714651680015, 16.43084320892478, 24.76722511418386,
                     -6.594389125716872, 0.0]])
_B = np.append(A[5, :5], 1.0)                    # y_new = y + Σ b_j k_j
# continuous extension on K rows (f(t, y), k_1/h .. k_6/h, f(t_new, y_new)): columns θ, θ², θ³
P = np.zeros((8, 3))
P[1:7, 0] = _B + H_DENSE[0]
P[1:7, 1] = H_DENSE[1] - H_DENSE[0]
P[1:7, 2] = -H_DENSE[1]
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 6.0
EXPONENT = -0.25                         # error estimator of order 3: −1/(order + 1)
SQRT_EPS = math.sqrt(np.finfo(float).eps)


def fd_jacobian(fun: Rhs, t: float, y: np.ndarray, f0: np.ndarray, rtol: float, atol: float,
                h_abs: float) -> tuple[np.ndarray, np.ndarray]:
    """∂f/∂y and ∂f/∂t at (t, y) by forward differences (steps √eps·max(|y_j|, atol/rtol) and
    √eps·max(|t|, h_abs)); n + 1 RHS calls."""
    n = y.size
    jac = np.empty((n, n))
    floor = max(atol / rtol, 1e-300)
    for j in range(n):
        yj = y.copy()
        yj[j] = y[j] + SQRT_EPS * max(abs(y[j]), floor)
        jac[:, j] = (np.asarray(fun(t, tuple(yj.tolist())), dtype=float) - f0) / (yj[j] - y[j])
    dt = SQRT_EPS * max(abs(t), h_abs, 1e-300)
    return jac, (np.asarray(fun(t + dt, tuple(y.tolist())), dtype=float) - f0) / dt


class Rodas4(AdaptiveStepper):
    """Adaptive Rodas4 (see the module docstring): ``rtol``, ``atol`` (RMS norm of k_6/(atol + rtol·max(|y|,
    |y_new|))), ``first_step``, ``max_step`` (s); step factor 0.9·err^(−1/4) within [0.2, 6], no growth right
    after a rejection. Stable on any stiff decay: ``stiffness`` is accepted for interface compatibility and
    ``stiff_at`` is always None."""

    order = 4
    method, label, P = "rodas4", "Rodas4", P

    error_order = 3
    safety, min_factor, max_factor, exponent, accept_one = SAFETY, MIN_FACTOR, MAX_FACTOR, EXPONENT, True
    default_stiffness = "ignore"

    def _python_step(self) -> None:
        fun, t, rtol, atol = self.fun, self.t, self.rtol, self.atol
        y, f0 = np.array(self.y), np.array(self.f)
        n = y.size
        jac, ft = fd_jacobian(fun, t, y, f0, rtol, atol, self.h_abs)
        self.nfev += n + 1
        k = np.zeros((6, n))

        def attempt(h: float, t_new: float) -> tuple[float, np.ndarray]:
            lu = lu_factor(np.eye(n) / (h * GAMMA) - jac, check_finite=False)
            for s in range(6):
                ys = y + A[s, :s] @ k[:s]
                fs = np.asarray(fun(t + STAGE_T[s] * h, tuple(ys.tolist())), dtype=float) if s else f0
                k[s] = lu_solve(lu, fs + C[s, :s] @ k[:s] / h + h * D[s] * ft, check_finite=False)
            self.nfev += 5
            y_new = ys + k[5]
            return float(np.sqrt(np.mean((k[5] / (atol + rtol * np.maximum(np.abs(y), np.abs(y_new)))) ** 2))), y_new

        h, t_new, h_next, y_new = self._adapt(attempt)
        new = tuple(y_new.tolist())
        f_new = tuple(fun(t_new, new))
        self.nfev += 1
        self._accept(t_new, new, h, 0.0, (self.f, *map(tuple, (k / h).tolist()), f_new), h_next)
