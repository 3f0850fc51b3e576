"""Right-hand sides compiled with numba, and the Dormand–Prince step compiled around them.

A problem whose RHS is a :class:`JitRhs` (a numba kernel ``kernel(t, y, p, out)`` on float64 arrays plus
its live parameter vector) lets :class:`rig.solvers.dopri.DormandPrince45` run each step — all stages,
the error norm, rejections and the step-size controller — in machine code: the Python driver
(:func:`rig.solvers.integrate`: events, restarts, sampling) then costs one call per accepted step instead
of seven RHS calls. The compiled step is the same method (tableau, norm, controller constants of
:mod:`rig.solvers.dopri`); the tests check it against the pure-Python step.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import cache

import numpy as np
from numba import njit

from rig.solvers.base import SolverDivergence


class JitRhs:
    """A compiled RHS: ``kernel(t, y: float64[:], p: float64[:], out: float64[:])`` writing dy/dt into
    ``out``, with ``params()``
    returning its parameter vector p synchronised with the problem's discrete state (called when a
    solver segment starts and on every Python-side call), and ``diagnose()`` explaining non-finite
    derivatives (a message, or None). Callable as a plain ``fun(t, y) -> tuple`` (e.g. for scipy)."""

    def __init__(self, kernel, params: Callable[[], np.ndarray], diagnose: Callable[[], str | None] = lambda: None):
        self.kernel, self.params, self.diagnose = kernel, params, diagnose

    def __call__(self, t: float, y: Sequence[float]) -> tuple:
        out = np.empty(len(y))
        self.kernel(t, np.asarray(y, dtype=float), self.params(), out)
        dy = out.tolist()
        if not math.isfinite(sum(dy)):
            self.fail(t, y)
        return tuple(dy)

    def fail(self, t: float, y: Sequence[float], what: str = "non-finite derivatives") -> None:
        """Raise :class:`SolverDivergence` with the kernel's diagnosis when it has one."""
        why = self.diagnose()
        raise SolverDivergence(f"{what}: {why}" if why else what, t, y)


#: slots of the compiled step's work vector: T, H_ABS (in, updated to t_new, h_next), T_BOUND, RTOL,
#: ATOL, MAX_STEP (in), H, NFEV, HL (out: step taken, RHS calls, Hairer's stiffness estimate h·|λ|)
T, H_ABS, T_BOUND, RTOL, ATOL, MAX_STEP, H, NFEV, HL = range(9)


@cache
def dp45_step(kernel):
    """Compiled adaptive DP5(4) step for ``kernel`` (cached per kernel): ``step(w, y, y_new, K, f, p)``
    advances from (w[T], y) with first derivative f by one accepted step, writing the new state into
    ``y_new``, the stages into K (7, n) and T, H_ABS, H, NFEV, HL into ``w``; returns 0, or 1 on a
    step-size underflow (state untouched). Arrays in, status out: numba's call overhead grows with the
    number of arguments and returned objects, and this is called once per step."""
    from rig.solvers.dopri import A, B, C, E, MAX_FACTOR, MIN_FACTOR, SAFETY

    @njit
    def step(w, y, y_new, K, f, p):
        n = y.size
        t, h_abs, t_bound, rtol, atol = w[T], min(w[H_ABS], w[MAX_STEP]), w[T_BOUND], w[RTOL], w[ATOL]
        min_step = 10.0 * (np.nextafter(t, np.inf) - t)
        K[0] = f
        ys = np.empty(n)
        rejected = False
        nfev = 0
        while True:
            if h_abs < min_step:
                w[H], w[NFEV] = h_abs, nfev
                return 1
            h = h_abs
            t_new = t + h
            if t_new >= t_bound:
                t_new = t_bound
                h = t_new - t
            for s in range(1, 6):
                for i in range(n):
                    acc = 0.0
                    for j in range(s):
                        acc += A[s, j] * K[j, i]
                    ys[i] = y[i] + h * acc
                kernel(t + C[s] * h, ys, p, K[s])
            finite = True
            for i in range(n):
                acc = 0.0
                for j in range(6):
                    acc += B[j] * K[j, i]
                y_new[i] = y[i] + h * acc
                finite &= math.isfinite(y_new[i])
            nfev += 5
            if not finite:
                h_abs *= MIN_FACTOR
                continue
            kernel(t_new, y_new, p, K[6])
            nfev += 1
            acc = 0.0
            for i in range(n):
                e = 0.0
                for j in range(7):
                    e += E[j] * K[j, i]
                d = h * e / (atol + rtol * max(abs(y[i]), abs(y_new[i])))
                acc += d * d
            err_norm = math.sqrt(acc / n)
            if not math.isfinite(err_norm):
                h_abs *= MIN_FACTOR
                continue
            if err_norm < 1.0:
                factor = MAX_FACTOR if err_norm == 0.0 else min(MAX_FACTOR, SAFETY * err_norm ** -0.2)
                if rejected:
                    factor = min(1.0, factor)
                break
            h_abs *= max(MIN_FACTOR, SAFETY * err_norm ** -0.2)
            rejected = True
        num = 0.0
        den = 0.0
        for i in range(n):
            num += (K[6, i] - K[5, i]) ** 2
            den += (y_new[i] - ys[i]) ** 2
        w[T], w[H_ABS], w[H], w[NFEV] = t_new, h_abs * factor, h, nfev
        w[HL] = h * math.sqrt(num / den) if den > 0.0 else 0.0
        return 0

    return step
