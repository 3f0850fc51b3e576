"""Template of the compiled DP5(4) step, runs of steps and event location (:mod:`rig.solvers.compiled`).

Not used directly: :func:`rig.solvers.compiled.dp45_step` copies this source into a module per kernel,
binding ``kernel``, ``event`` and ``act`` (the block marked below) to module-level numba functions, so
that numba can cache the compiled code on disk — it cannot cache closures or functions passed as values.
"""
import math

import numpy as np
from numba import njit

from rig.solvers.compiled import ATOL, H, H_ABS, HL, MAX_STEP, NEV, NFEV, RTOL, T, T_BOUND
from rig.solvers.dopri import _P as P
from rig.solvers.dopri import A, B, C, E, MAX_FACTOR, MIN_FACTOR, SAFETY


@njit(cache=True)
def never(t, y, p, k, apply):
    """``act`` for problems without compiled event actions."""
    return False


# <kernels>
kernel = event = act = None  # bound to the problem's kernels in generated copies
# </kernels>


@njit(cache=True)
def one_step(t, h_abs, t_bound, rtol, atol, y, y_new, K, p):
    """One accepted step from (t, y), K[0] = f(t, y): (status, t_new, h, h_next, nfev, h·|λ|)."""
    n = y.size
    min_step = 10.0 * (np.nextafter(t, np.inf) - t)
    ys = np.empty(n)
    rejected = False
    nfev = 0
    while True:
        if h_abs < min_step:
            return 1, t, h_abs, h_abs, nfev, 0.0
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
    return 0, t_new, h, h_abs * factor, nfev, (h * math.sqrt(num / den) if den > 0.0 else 0.0)

@njit(cache=True)
def step(w, y, y_new, K, f, p):
    K[0] = f
    status, t_new, h, h_next, nfev, hl = one_step(w[T], min(w[H_ABS], w[MAX_STEP]), w[T_BOUND], w[RTOL],
                                                  w[ATOL], y, y_new, K, p)
    w[H], w[NFEV] = h, nfev
    if status == 0:
        w[T], w[H_ABS], w[HL] = t_new, h_next, hl
    return status

@njit(cache=True)
def coeffs(K, h, Q):
    """Dense-output coefficients Q = h·(Kᵀ P) of one step."""
    for i in range(Q.shape[0]):
        for c in range(Q.shape[1]):
            acc = 0.0
            for j in range(K.shape[0]):
                acc += K[j, i] * P[j, c]
            Q[i, c] = h * acc

@njit(cache=True)
def g_dense(t, t_old, h, y_old, Q, p, k, y):
    """Event k at time t on the dense output y_old + Σ_c Q[:, c] θ^(c+1) (θ = (t − t_old)/h)."""
    th = (t - t_old) / h
    for i in range(y.size):
        acc = 0.0
        for c in range(Q.shape[1] - 1, -1, -1):
            acc = acc * th + Q[i, c]
        y[i] = y_old[i] + acc * th
    return event(t, y, p, k)

@njit(cache=True)
def brent(t_old, t_new, y_old, Q, p, k):
    """Root of event k in [t_old, t_new] on the dense output (scipy's brentq.c, xtol 1e-15, rtol 4 eps)."""
    h = t_new - t_old
    y = np.empty(y_old.size)
    xtol, rtol = 1e-15, 4.0 * 2.220446049250313e-16
    xpre, xcur = t_old, t_new
    fpre, fcur = g_dense(xpre, t_old, h, y_old, Q, p, k, y), g_dense(xcur, t_old, h, y_old, Q, p, k, y)
    if fpre == 0.0:
        return xpre
    if fcur == 0.0:
        return xcur
    xblk = fblk = spre = scur = 0.0
    for _ in range(100):
        if fpre != 0.0 and fcur != 0.0 and (fpre < 0.0) != (fcur < 0.0):
            xblk, fblk = xpre, fpre
            spre = scur = xcur - xpre
        if abs(fblk) < abs(fcur):
            xpre, xcur, xblk = xcur, xblk, xcur
            fpre, fcur, fblk = fcur, fblk, fcur
        delta = (xtol + rtol * abs(xcur)) / 2.0
        sbis = (xblk - xcur) / 2.0
        if fcur == 0.0 or abs(sbis) < delta:
            return xcur
        if abs(spre) > delta and abs(fcur) < abs(fpre):
            if xpre == xblk:
                stry = -fcur * (xcur - xpre) / (fcur - fpre)
            else:
                dpre = (fpre - fcur) / (xpre - xcur)
                dblk = (fblk - fcur) / (xblk - xcur)
                stry = -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre))
            if 2.0 * abs(stry) < min(abs(spre), 3.0 * abs(sbis) - delta):
                spre, scur = scur, stry
            else:
                spre, scur = sbis, sbis
        else:
            spre, scur = sbis, sbis
        xpre, fpre = xcur, fcur
        if abs(scur) > delta:
            xcur += scur
        else:
            xcur += delta if sbis > 0.0 else -delta
        fcur = g_dense(xcur, t_old, h, y_old, Q, p, k, y)
    return xcur

@njit(cache=True)
def locate(t_old, t_new, y_old, K, p, k):
    Q = np.empty((y_old.size, P.shape[1]))
    coeffs(K, t_new - t_old, Q)
    return brent(t_old, t_new, y_old, Q, p, k)

@njit(cache=True)
def run(w, Y, TT, HH, KK, HL, EV, g, p):
    n = Y.shape[1]
    g_new, yr = np.empty(g.size), np.empty(n)
    Q = np.empty((n, P.shape[1]))
    TT[0] = w[T]
    nfev = 0
    ne = 0
    m = KK.shape[0]
    restarted = False
    for s in range(m):
        if s and not restarted:
            KK[s, 0] = KK[s - 1, 6]
        restarted = False
        status, t_new, h, h_next, nf, hl = one_step(TT[s], min(w[H_ABS], w[MAX_STEP]), w[T_BOUND], w[RTOL],
                                                    w[ATOL], Y[s], Y[s + 1], KK[s], p)
        nfev += nf
        w[NFEV], w[NEV] = nfev, ne
        if status:
            w[H] = h
            return -1 - s
        TT[s + 1], HH[s], HL[s] = t_new, h, hl
        w[T], w[H_ABS], w[H] = t_new, h_next, h
        crossed = False
        for k in range(g.size):
            g_new[k] = event(t_new, Y[s + 1], p, k)
            if g_new[k] == 0.0 or (g[k] < 0.0) != (g_new[k] < 0.0):
                crossed = True
        if not crossed:
            if t_new >= w[T_BOUND] or s == m - 1:
                return s + 1                        # g holds the values at the last step's start
            g[:] = g_new
            continue
        if act is None or s == m - 1 or ne == EV.shape[0]:
            return s + 1
        t_root, k_root, ok = np.inf, -1, True       # act here only if every change is ours to act on
        coeffs(KK[s], h, Q)
        for k in range(g.size):
            if g[k] == 0.0 or g_new[k] == 0.0:
                ok = False
            elif (g[k] < 0.0) != (g_new[k] < 0.0):
                if not act(t_new, Y[s + 1], p, k, False):
                    ok = False
                else:
                    tk = brent(TT[s], t_new, Y[s], Q, p, k)
                    if tk == t_root:
                        ok = False
                    elif tk < t_root:
                        t_root, k_root = tk, k
            if not ok:
                break
        if not ok or not TT[s] < t_root < t_new:
            return s + 1
        g_dense(t_root, TT[s], h, Y[s], Q, p, k_root, yr)
        if not act(t_root, yr, p, k_root, False):
            return s + 1
        act(t_root, yr, p, k_root, True)
        Y[s + 1] = yr
        EV[ne, 0], EV[ne, 1] = t_root, k_root
        EV[ne, 2] = 1.0 if g_new[k_root] > g[k_root] else -1.0
        EV[ne, 3:] = Y[s + 1]
        ne += 1
        TT[s + 1] = t_root
        for k in range(g.size):
            if k == k_root:
                g[k] = g_new[k]
            else:
                v = event(t_root, Y[s + 1], p, k)
                if v != 0.0:
                    g[k] = v
        kernel(t_root, Y[s + 1], p, KK[s + 1, 0])
        nfev += 1
        w[T], w[H_ABS], w[NFEV], w[NEV] = t_root, h, nfev, ne
        restarted = True
    return m

