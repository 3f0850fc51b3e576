"""Compiled Dormand–Prince 5(4) step (inserted into :mod:`runs` copies; same tableau, error norm and
controller as :class:`rig.solvers.dopri.DormandPrince45`'s Python step). K rows: the seven stages (the
last is f(t_new, y_new))."""
import math

import numpy as np
from numba import njit

from rig.solvers.compiled import ATOL, RTOL, T_BOUND
from rig.solvers.dopri import P, A, B, C, E, MAX_FACTOR, MIN_FACTOR, SAFETY

# <kernels>
kernel = lipschitz = min_step = trial = None  # bound in generated copies
UNDERFLOW = 1
# </kernels>
ADAPTIVE = True  # error-controlled: lands on the roots of plain restarts (runs.land)


@njit(cache=True, error_model="numpy")
def one_step(t, h_abs, w, y, y_new, K, p):
    """One accepted adaptive step (see :mod:`runs`)."""
    t_bound, rtol, atol = w[T_BOUND], w[RTOL], w[ATOL]
    n = y.size
    h_min = min_step(t)
    ys = np.empty(n)
    rejected = False
    nfev = 0
    while True:
        if h_abs < h_min:
            return UNDERFLOW, t, h_abs, h_abs, nfev, 0.0
        h, t_new = trial(t, h_abs, t_bound)
        for s in range(1, 6):
            for i in range(n):
                acc = 0.0
                for j in range(s):
                    acc += A[s, j] * K[j, i]
                ys[i] = y[i] + h * acc
            kernel(t + C[s] * h, ys, p, K[s])
        ok = True
        for i in range(n):
            acc = 0.0
            for j in range(6):
                acc += B[j] * K[j, i]
            y_new[i] = y[i] + h * acc
            ok &= math.isfinite(y_new[i])
        nfev += 5
        if not ok:
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
    return 0, t_new, h, h_abs * factor, nfev, h * lipschitz(K[6], K[5], y_new, ys)
