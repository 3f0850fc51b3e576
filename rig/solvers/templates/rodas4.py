"""Compiled Rodas4 step (inserted into :mod:`runs` copies; same tableau, Jacobian differences, error norm and
controller as :class:`rig.solvers.rodas.Rodas4`'s Python step). K rows: f(t, y), the six stage vectors divided
by h, f(t_new, y_new)."""
import math

from numba import njit

from rig.solvers.compiled import ATOL, RTOL, T_BOUND
from rig.solvers.control import step_factor
from rig.solvers.rodas import A, C, D, EXPONENT, GAMMA, MAX_FACTOR, MIN_FACTOR, SAFETY, SQRT_EPS, STAGE_T, P

# <kernels>
kernel = min_step = trial = None  # bound in generated copies
UNDERFLOW = 1
# </kernels>
ADAPTIVE = True  # error-controlled: lands on the roots of plain restarts (runs.land)


@njit(cache=True, error_model="numpy")
def lu_factor(W, piv):
    """In-place LU factorisation of W with partial pivoting (row swaps in piv, as floats)."""
    n = W.shape[0]
    for k in range(n):
        m = k
        for i in range(k + 1, n):
            if abs(W[i, k]) > abs(W[m, k]):
                m = i
        piv[k] = m
        if m != k:
            for j in range(n):
                W[k, j], W[m, j] = W[m, j], W[k, j]
        for i in range(k + 1, n):
            W[i, k] /= W[k, k]
            for j in range(k + 1, n):
                W[i, j] -= W[i, k] * W[k, j]


@njit(cache=True, error_model="numpy")
def lu_solve(W, piv, b):
    """Solve with the factors of :func:`lu_factor`, b overwritten by the solution."""
    n = W.shape[0]
    for k in range(n):
        m = int(piv[k])
        if m != k:
            b[k], b[m] = b[m], b[k]
    for i in range(n):
        for j in range(i):
            b[i] -= W[i, j] * b[j]
    for i in range(n - 1, -1, -1):
        for j in range(i + 1, n):
            b[i] -= W[i, j] * b[j]
        b[i] /= W[i, i]


@njit(cache=True, error_model="numpy")
def one_step(t, h_abs, w, y, y_new, K, p, ws):
    """One accepted adaptive step (see :mod:`runs`); Jacobian and ∂f/∂t by forward differences, once. Scratch in
    ws (:func:`rig.solvers.compiled.scratch_rows` rows): the Jacobian, the iteration matrix, ∂f/∂t, a stage state,
    a derivative and the pivots."""
    t_bound, rtol, atol = w[T_BOUND], w[RTOL], w[ATOL]
    n = y.size
    J, W, ft, tmp, fj, piv = ws[:n], ws[n:2 * n], ws[2 * n], ws[2 * n + 1], ws[2 * n + 2], ws[2 * n + 3]
    for i in range(n):
        tmp[i] = y[i]
    floor = max(atol / rtol, 1e-300)
    for j in range(n):
        tmp[j] = y[j] + SQRT_EPS * max(abs(y[j]), floor)
        kernel(t, tmp, p, fj)
        d = tmp[j] - y[j]
        for i in range(n):
            J[i, j] = (fj[i] - K[0, i]) / d
        tmp[j] = y[j]
    dt = SQRT_EPS * max(abs(t), h_abs, 1e-300)
    kernel(t + dt, y, p, fj)
    for i in range(n):
        ft[i] = (fj[i] - K[0, i]) / dt
    nfev = n + 1
    h_min = min_step(t)
    rejected = False
    while True:
        if not h_abs >= h_min:      # NaN too
            return UNDERFLOW, t, h_abs, h_abs, nfev, 0.0
        h, t_new = trial(t, h_abs, t_bound)
        for i in range(n):
            for j in range(n):
                W[i, j] = -J[i, j]
            W[i, i] += 1.0 / (h * GAMMA)
        lu_factor(W, piv)
        for s in range(6):
            for i in range(n):
                acc = 0.0
                for j in range(s):
                    acc += A[s, j] * K[1 + j, i]
                tmp[i] = y[i] + acc
            if s:
                kernel(t + STAGE_T[s] * h, tmp, p, fj)
            else:
                for i in range(n):
                    fj[i] = K[0, i]
            for i in range(n):
                acc = 0.0
                for j in range(s):
                    acc += C[s, j] * K[1 + j, i]
                K[1 + s, i] = fj[i] + acc / h + h * D[s] * ft[i]
            lu_solve(W, piv, K[1 + s])
        nfev += 5
        acc = 0.0
        for i in range(n):
            y_new[i] = tmp[i] + K[6, i]
            d = K[6, i] / (atol + rtol * max(abs(y[i]), abs(y_new[i])))
            acc += d * d
        err = math.sqrt(acc / n)
        if not math.isfinite(err):
            h_abs *= MIN_FACTOR
            rejected = True
            continue
        factor = step_factor(err, err <= 1.0, rejected, EXPONENT, SAFETY, MIN_FACTOR, MAX_FACTOR)
        if err <= 1.0:
            break
        h_abs *= factor
        rejected = True
    for s in range(1, 7):
        for i in range(n):
            K[s, i] /= h
    kernel(t_new, y_new, p, K[7])
    return 0, t_new, h, h_abs * factor, nfev + 1, 0.0
