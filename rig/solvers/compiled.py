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
    derivatives (a message, or None). ``event(t, y, p, k)``, if given, is a compiled kernel for the value
    of event function k, in the order of ``Problem.events``: then DP45 takes runs of steps in one compiled
    call until one of them changes sign, and locates roots in compiled code (:func:`dp45_step`).
    ``act(t, y, p, k, apply)``, if given, tells whether event k (a restart without Python action) can be
    acted on in compiled code and, with ``apply``, does it by updating p: the run then restarts there
    itself. Callable as a plain ``fun(t, y) -> tuple`` (e.g. for scipy)."""

    def __init__(self, kernel, params: Callable[[], np.ndarray], diagnose: Callable[[], str | None] = lambda: None,
                 event=None, act=None):
        self.kernel, self.params, self.diagnose, self.event, self.act = kernel, params, diagnose, event, act

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
#: ATOL, MAX_STEP (in), H, NFEV, HL, NEV (out: last step taken, RHS calls, Hairer's stiffness estimate
#: h·|λ|, events acted on in a run)
T, H_ABS, T_BOUND, RTOL, ATOL, MAX_STEP, H, NFEV, HL, NEV = range(10)


@cache
def dp45_step(kernel, event=None, act=None):
    """Compiled adaptive DP5(4) for ``kernel`` (event kernels ``event``, ``act``: :class:`JitRhs`), cached:

    * ``step(w, y, y_new, K, f, p)`` advances from (w[T], y) with first derivative f by one accepted
      step, writing the new state into ``y_new``, the stages into K (7, n) and T, H_ABS, H, NFEV, HL into
      ``w``; returns 0, or 1 on a step-size underflow (state untouched);
    * ``run(w, Y, TT, HH, KK, HL, EV, g, p)`` (with ``event``) takes steps from (w[T], Y[0]) with
      KK[0, 0] the first derivative, storing step ends TT[s + 1], states Y[s + 1], step sizes HH[s],
      stages KK[s] and h·|λ| HL[s], until an event value in ``g`` (given at the start, updated in place)
      changes sign or reaches 0, t_bound is reached or the buffers are full; returns the number of steps,
      or −1 − steps on an underflow. Sign changes that ``act`` accepts (all of them in the step, none
      exactly zero) are handled in the run as the Python driver would: cut at the earliest root (the
      step then ends there, TT[s + 1] < TT[s] + HH[s]), act, record (t, k, ±1, y) in EV[w[NEV]], restart
      with the last step size; the fired event keeps its value past the root, the others are re-evaluated
      (a zero keeps the old value);
    * ``locate(t_old, t_new, y_old, K, p, k)``: root of event k on the step's quartic dense output by
      Brent's method (as scipy's ``brentq``, xtol 1e-15, rtol 4·eps), given a sign change over the step.

    Arrays in, status out: numba's call overhead grows with the number of arguments and returned
    objects. The sign test is conservative (any change stops, whatever an event's direction): the
    Python driver then examines that last step as usual."""
    from rig.solvers.dopri import _P as P
    from rig.solvers.dopri import A, B, C, E, MAX_FACTOR, MIN_FACTOR, SAFETY

    @njit
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

    @njit
    def step(w, y, y_new, K, f, p):
        K[0] = f
        status, t_new, h, h_next, nfev, hl = one_step(w[T], min(w[H_ABS], w[MAX_STEP]), w[T_BOUND], w[RTOL],
                                                      w[ATOL], y, y_new, K, p)
        w[H], w[NFEV] = h, nfev
        if status == 0:
            w[T], w[H_ABS], w[HL] = t_new, h_next, hl
        return status

    if event is None:
        return step, None, None

    @njit
    def coeffs(K, h, Q):
        """Dense-output coefficients Q = h·(Kᵀ P) of one step."""
        for i in range(Q.shape[0]):
            for c in range(Q.shape[1]):
                acc = 0.0
                for j in range(K.shape[0]):
                    acc += K[j, i] * P[j, c]
                Q[i, c] = h * acc

    @njit
    def g_dense(t, t_old, h, y_old, Q, p, k, y):
        """Event k at time t on the dense output y_old + Σ_c Q[:, c] θ^(c+1) (θ = (t − t_old)/h)."""
        th = (t - t_old) / h
        for i in range(y.size):
            acc = 0.0
            for c in range(Q.shape[1] - 1, -1, -1):
                acc = acc * th + Q[i, c]
            y[i] = y_old[i] + acc * th
        return event(t, y, p, k)

    @njit
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

    @njit
    def locate(t_old, t_new, y_old, K, p, k):
        Q = np.empty((y_old.size, P.shape[1]))
        coeffs(K, t_new - t_old, Q)
        return brent(t_old, t_new, y_old, Q, p, k)

    @njit
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

    return step, run, locate
