"""Linearly implicit Rosenbrock 2(3) method (Shampine & Reichelt 1997, MATLAB's ode23s) for stiff problems.

One LU factorisation of W = I − h·d·J per step, three stages (the third only for the error estimate, FSAL
style), L-stable 2nd-order solution with a 3rd-order error estimate and the method's quadratic continuous
extension. J = ∂f/∂y and ∂f/∂t come from forward differences (n + 1 extra RHS calls per step), so any
``fun(t, y)`` of the explicit solvers works unchanged. Written rather than adapted from scipy's Radau: the same
tuple-state interface and :class:`PolynomialDense` (batched ``fill_dense``) as DP45, no per-step array
conversions, and for the 2–5 states of the plants an n×n LU costs less than one RHS call.
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np
from scipy.linalg import lu_factor, lu_solve

from rig.solvers.base import (OdeSolver, Rhs, SolverDivergence, all_finite, check_step_options,
                              not_finite_text, rhs_not_finite)
from rig.solvers.dense import PolynomialDense
from rig.solvers.rodas import fd_jacobian
from rig.solvers.stepper import initial_step

_D = 1.0 / (2.0 + math.sqrt(2.0))
_E32 = 6.0 + math.sqrt(2.0)
# continuous extension y(t + θh) = y + h·[θ(1 − θ)/(1 − 2d)·k1 + θ(θ − 2d)/(1 − 2d)·k2]
_P = np.array([[1.0, -1.0], [-2.0 * _D, 1.0]]) / (1.0 - 2.0 * _D)
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.8, 0.2, 5.0
Jac = Callable[[float, tuple, np.ndarray], tuple[np.ndarray, np.ndarray]]


class Rosenbrock23(OdeSolver):
    """Adaptive L-stable Rosenbrock 2(3) (ode23s) with finite-difference Jacobian.

    Same interface as :class:`~rig.solvers.dopri.DormandPrince45`: ``rtol``, ``atol`` (scalar), ``first_step``,
    ``max_step`` (s); ``stiffness`` is accepted for interface compatibility — the method is stable on any
    stiff decay, so ``stiff_at`` is always None. ``njev`` counts Jacobian evaluations.
    """

    order = 2

    def __init__(self, fun: Rhs, t0: float, y0: Sequence[float], t_bound: float, rtol: float = 1e-3,
                 atol: float = 1e-6, first_step: float | None = None, max_step: float = math.inf,
                 jac: Jac | None = None, stiffness: str = "ignore"):
        super().__init__(fun, t0, y0, t_bound)
        check_step_options("Rosenbrock23", rtol, atol, first_step, max_step)
        if stiffness not in ("warn", "raise", "ignore"):
            raise ValueError(f"Rosenbrock23: stiffness = {stiffness!r} must be 'warn', 'raise' or 'ignore'")
        self.rtol, self.atol, self.max_step, self.jac = rtol, atol, max_step, jac
        self.f = np.array(fun(self.t, self.y), dtype=float)
        self.nfev, self.njev = 1, 0
        if self.f.shape != (len(self.y),):
            raise ValueError(f"Rosenbrock23: the right-hand side returned {self.f.size} components at the start for a "
                             f"state of {len(self.y)}")
        if not np.all(np.isfinite(self.f)):
            raise SolverDivergence("non-finite derivatives at the start", self.t, self.y)
        if first_step is None or not first_step > 0:
            self.h_abs = initial_step(fun, self.t, self.y, tuple(self.f), 2, rtol, atol, self.t_bound)
            self.nfev += 1
        else:
            self.h_abs = min(first_step, self.t_bound - self.t)
        self._K: tuple | None = None
        self.stiff_at: float | None = None

    def _step_impl(self) -> None:
        fun, t = self.fun, self.t
        y, f0 = np.array(self.y), self.f
        if self.jac is None:
            jac, dfdt = fd_jacobian(fun, t, y, f0, self.rtol, self.atol, self.h_abs)
            self.nfev += y.size + 1
        else:
            jac, dfdt = self.jac(t, self.y, f0)
        self.njev += 1
        eye = np.eye(y.size)
        h_abs = min(self.h_abs, self.max_step)
        min_step = self._min_step()
        while True:
            if not h_abs >= min_step:
                bad = rhs_not_finite(fun, t, self.y, (max(h_abs, min_step), 1e-7 * max(1.0, abs(t))))
                raise SolverDivergence(f"Rosenbrock23 step size underflow (h = {h_abs:.3g} s): " + (
                    not_finite_text(bad, t) if bad is not None else "the error estimate keeps rejecting the step - "
                    "the solution may blow up here (a finite-time singularity) or the right-hand side jump just "
                    "beyond it"), t, self.y)
            h = h_abs
            t_new = t + h
            if t_new >= self.t_bound:
                t_new = self.t_bound
                h = t_new - t
            lu = lu_factor(eye - h * _D * jac, check_finite=False)
            tt = h * _D * dfdt
            k1 = lu_solve(lu, f0 + tt, check_finite=False)
            f1 = np.asarray(fun(t + 0.5 * h, tuple(y + 0.5 * h * k1)), dtype=float)
            k2 = lu_solve(lu, f1 - k1, check_finite=False) + k1
            y_new = y + h * k2
            self.nfev += 1
            if not np.all(np.isfinite(y_new)):
                h_abs *= MIN_FACTOR
                continue
            f2 = np.asarray(fun(t_new, tuple(y_new)), dtype=float)
            self.nfev += 1
            k3 = lu_solve(lu, f2 - _E32 * (k2 - f1) - 2.0 * (k1 - f0) + tt, check_finite=False)
            scale = self.atol + self.rtol * np.maximum(np.abs(y), np.abs(y_new))
            err = float(np.sqrt(np.mean((h / 6.0 * (k1 - 2.0 * k2 + k3) / scale) ** 2)))
            if not math.isfinite(err):
                h_abs *= MIN_FACTOR
                continue
            if err <= 1.0:
                factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** (-1.0 / 3.0))
                break
            h_abs *= max(MIN_FACTOR, SAFETY * err ** (-1.0 / 3.0))
        new = tuple(float(v) for v in y_new)
        if not all_finite(new):
            raise SolverDivergence("non-finite state", t_new, new)
        self.t_old, self.y_old = t, self.y
        self.t, self.y, self.f = t_new, new, f2
        self.h_last = h
        self.h_abs = h_abs * factor
        self._K = (tuple(k1.tolist()), tuple(k2.tolist()))

    def dense_output(self) -> PolynomialDense:
        return PolynomialDense(self.t_old, self.t - self.t_old, self.y_old, self._K, _P)

