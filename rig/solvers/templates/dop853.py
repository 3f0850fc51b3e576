"""Compiled DOP853 step (inserted into :mod:`runs` copies; same tableau, error norm and controller as
:class:`rig.solvers.dop853.DOP853`'s numpy step). K rows: the 12 stages, the 3 stages of the continuous extension,
f(t_new, y_new) last."""
import math

from numba import njit

from rig.solvers.dop853 import (A, A_EXT, B, C, C_EXT, E3, E5, EXPONENT, MAX_FACTOR, MIN_FACTOR, N_STAGES, SAFETY,
                                P)

# <kernels>
kernel = None  # bound in generated copies
# </kernels>
F_NEW = 15


@njit(cache=True, error_model="numpy")
def error_norm(h, K, y, y_new, rtol, atol):
    """scipy's DOP853 norm: |h|·‖e5‖² / √((‖e5‖² + 0.01‖e3‖²)·n), e = Kᵀ E / (atol + rtol·max(|y|, |y_new|))."""
    n = y.size
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        a5 = 0.0
        a3 = 0.0
        for j in range(N_STAGES):
            a5 += E5[j] * K[j, i]
            a3 += E3[j] * K[j, i]
        a5 += E5[N_STAGES] * K[F_NEW, i]
        a3 += E3[N_STAGES] * K[F_NEW, i]
        scale = atol + rtol * max(abs(y[i]), abs(y_new[i]))
        e5 += (a5 / scale) ** 2
        e3 += (a3 / scale) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)


@njit(cache=True, error_model="numpy")
def extend(t, h, y, ys, K, p):
    """The continuous extension's 3 stages (rows 12..14, from the earlier rows and f_new only)."""
    for e in range(3):
        for i in range(y.size):
            acc = A_EXT[e, F_NEW] * K[F_NEW, i]
            for j in range(N_STAGES + e):
                acc += A_EXT[e, j] * K[j, i]
            ys[i] = y[i] + h * acc
        kernel(t + C_EXT[e] * h, ys, p, K[N_STAGES + e])
    return 3


# <include erk>
