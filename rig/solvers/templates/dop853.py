"""Compiled DOP853 step (inserted into :mod:`runs` copies; same tableau, error norm and controller as
:class:`rig.solvers.dop853.DOP853`'s numpy step). K rows: the 12 stages, the 3 stages of the continuous extension,
f(t_new, y_new) last."""
import math

import numpy as np
from numba import njit

from rig.solvers.compiled import ATOL, RTOL, T_BOUND
from rig.solvers.dop853 import (A, A_EXT, B, C, C_EXT, E3, E5, EXPONENT, MAX_FACTOR, MIN_FACTOR, N_STAGES, SAFETY,
                                P)

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
        for s in range(1, N_STAGES):
            for i in range(n):
                acc = 0.0
                for j in range(s):
                    acc += A[s, j] * K[j, i]
                ys[i] = y[i] + h * acc
            kernel(t + C[s] * h, ys, p, K[s])
        ok = True
        for i in range(n):
            acc = 0.0
            for j in range(N_STAGES):
                acc += B[j] * K[j, i]
            y_new[i] = y[i] + h * acc
            ok &= math.isfinite(y_new[i])
        nfev += N_STAGES - 1
        if not ok:
            h_abs *= MIN_FACTOR
            continue
        kernel(t_new, y_new, p, K[15])
        nfev += 1
        e5 = 0.0
        e3 = 0.0
        for i in range(n):
            a5 = 0.0
            a3 = 0.0
            for j in range(N_STAGES):
                a5 += E5[j] * K[j, i]
                a3 += E3[j] * K[j, i]
            a5 += E5[N_STAGES] * K[15, i]
            a3 += E3[N_STAGES] * K[15, i]
            scale = atol + rtol * max(abs(y[i]), abs(y_new[i]))
            e5 += (a5 / scale) ** 2
            e3 += (a3 / scale) ** 2
        if e5 == 0.0 and e3 == 0.0:
            err_norm = 0.0
        else:
            err_norm = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)
        if not math.isfinite(err_norm):
            h_abs *= MIN_FACTOR
            continue
        if err_norm < 1.0:
            factor = MAX_FACTOR if err_norm == 0.0 else min(MAX_FACTOR, SAFETY * err_norm ** EXPONENT)
            if rejected:
                factor = min(1.0, factor)
            break
        h_abs *= max(MIN_FACTOR, SAFETY * err_norm ** EXPONENT)
        rejected = True
    hl = h * lipschitz(K[15], K[N_STAGES - 1], y_new, ys)
    for e in range(3):                        # the continuous extension's stages (rows 12..14: the earlier ones only)
        for i in range(n):
            acc = A_EXT[e, 15] * K[15, i]
            for j in range(N_STAGES + e):
                acc += A_EXT[e, j] * K[j, i]
            ys[i] = y[i] + h * acc
        kernel(t + C_EXT[e] * h, ys, p, K[N_STAGES + e])
    nfev += 3
    return 0, t_new, h, h_abs * factor, nfev, hl
