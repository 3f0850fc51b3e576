"""Compiled step of a seven-stage explicit 5(4) pair with FSAL and a quartic dense output from its stages (included by
the DP45 and Tsit5 templates, which import the tableau ``A``, ``B``, ``C``, ``E``, ``P`` and the controller constants).
K rows: the seven stages (the last is f(t_new, y_new))."""
import math

from numba import njit

# <kernels>
E = None  # imported by the including template (with A, B, C, P and the controller constants, for erk)
# </kernels>
N_STAGES, F_NEW = 6, 6


@njit(cache=True, error_model="numpy")
def error_norm(h, K, y, y_new, rtol, atol):
    """RMS of h·(Kᵀ E) / (atol + rtol·max(|y|, |y_new|)) (scipy's RK45)."""
    acc = 0.0
    for i in range(y.size):
        e = 0.0
        for j in range(7):
            e += E[j] * K[j, i]
        d = h * e / (atol + rtol * max(abs(y[i]), abs(y_new[i])))
        acc += d * d
    return math.sqrt(acc / y.size)


@njit(cache=True, error_model="numpy")
def extend(t, h, y, ys, K, p):
    """No extra stages: the quartic dense output uses the seven stages."""
    return 0


# <include erk>
