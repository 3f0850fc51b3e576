"""Compiled step of an embedded explicit Runge–Kutta pair with FSAL (included by ``pair45.py`` — DP45, Tsit5 — and
the DOP853 template, which define the tableau ``A``, ``B``, ``C`` with ``N_STAGES`` stages, ``F_NEW`` — the row of f(t_new, y_new) in
K —, the controller constants, ``error_norm(h, K, y, y_new, rtol, atol)`` and ``extend(t, h, y, ys, K, p)``: the
stages of the continuous extension, returning their RHS calls)."""
import math

from numba import njit

from rig.solvers.compiled import ATOL, RTOL, T_BOUND
from rig.solvers.control import step_factor

# <kernels>
kernel = lipschitz = min_step = trial = error_norm = extend = None  # bound in generated copies
A = B = C = N_STAGES = F_NEW = EXPONENT = SAFETY = MIN_FACTOR = MAX_FACTOR = None
UNDERFLOW = 1
# </kernels>
ADAPTIVE = True  # error-controlled: lands on the roots of plain restarts (runs.land)


@njit(cache=True, error_model="numpy")
def one_step(t, h_abs, w, y, y_new, K, p, ws):
    """One accepted adaptive step (see :mod:`runs`); the stage states in ws[0]."""
    t_bound, rtol, atol = w[T_BOUND], w[RTOL], w[ATOL]
    n = y.size
    h_min = min_step(t)
    ys = ws[0]
    rejected = False
    nfev = 0
    while True:
        if not h_abs >= h_min:      # NaN too
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
            rejected = True
            continue
        kernel(t_new, y_new, p, K[F_NEW])
        nfev += 1
        err = error_norm(h, K, y, y_new, rtol, atol)
        if not math.isfinite(err):
            h_abs *= MIN_FACTOR
            rejected = True
            continue
        factor = step_factor(err, err < 1.0, rejected, EXPONENT, SAFETY, MIN_FACTOR, MAX_FACTOR)
        if err < 1.0:
            break
        h_abs *= factor
        rejected = True
    hl = h * lipschitz(K[F_NEW], K[N_STAGES - 1], y_new, ys)
    nfev += extend(t, h, y, ys, K, p)
    return 0, t_new, h, h_abs * factor, nfev, hl
