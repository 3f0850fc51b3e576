"""Template of the compiled step, runs of steps and event location shared by all methods
(:mod:`rig.solvers.compiled`).

Not used directly: :func:`rig.solvers.compiled.compiled_solver` copies this source into a module per method
and kernel, binding ``kernel``, ``event`` and ``act`` (the block marked below) to module-level numba functions
and inserting the method's template (``one_step`` and its continuous extension ``P``) in the second block, so
that numba can cache the compiled code on disk — it cannot cache closures or functions passed as values.

A method's ``one_step(t, h_abs, w, y, y_new, K, p, ws) -> (status, t_new, h, h_next, nfev, h·|λ|)`` advances from
(t, y) with K[0] = f(t, y) by one accepted step of size h (at most h_abs), its scratch in the rows of ``ws``
(:func:`rig.solvers.compiled.scratch_rows`), writes the new state into ``y_new``, its stage vectors into K
(rows matching the rows of P: y(t + θh) = y + h·Σ_c (Kᵀ P)[:, c]·θ^(c+1)) and f(t_new, y_new) into the last row
of K (the next step's K[0]); status 0, UNDERFLOW or NONFINITE (a fixed-step method's state became non-finite: t_new,
h are the failed step's). ``w`` holds the solver's
settings (slots of :mod:`rig.solvers.compiled`).

``run`` is compiled without numba's runtime (``_nrt=False``): no reference counting of the arrays it passes on
(every call of a method's step and of the kernel would otherwise increment and decrement counts, and the call that
does it makes the compiled code spill its registers: a fifth of a level-2 run), hence no allocation in it nor in
the helpers compiled into it: its scratch comes from the caller, and arrays are copied element by element
(:func:`put`), as numba's slice assignment between arrays needs its runtime. A kernel compiled with the runtime
still works (numba calls the version the solver's first Python-side call compiled); the plants' kernels are compiled
without it as well.
"""
import math

import numpy as np
from numba import njit

from rig.solvers.borrow import borrowed
from rig.solvers.compiled import FAIL, H, H_ABS, HL, IE, MAX_STEP, NBREAK, NEV, NFEV, T, T0, T_BOUND, scratch_rows

UNDERFLOW, NONFINITE = 1, 2


@njit(cache=True, error_model="numpy")
def never(t, y, p, k, apply):
    """``act`` for problems without compiled event actions."""
    return False


# <kernels>
kernel = event = act = None  # bound to the problem's kernels in generated copies
# </kernels>
# <method>
one_step = P = None  # the method's step and continuous extension, inserted in generated copies
ADAPTIVE = False    # the method controls its error: it lands on the roots of plain restarts (land)
# </method>


@njit(cache=True, error_model="numpy")
def fixed_step(t, h, t_bound, t0):
    """(h, t_new) of a fixed-step method on the grid t0 + k·h (t0 the time it started or restarted at: no rounding
    of t + h piles up over the steps); the last step is stretched or cut to land on t_bound."""
    t_new = t0 + (math.floor((t - t0) / h + 0.5) + 1.0) * h
    if t_bound - t_new < 1e-6 * h:
        return t_bound - t, t_bound
    return h, t_new


@njit(cache=True, error_model="numpy")
def trial(t, h_abs, t_bound):
    """(h, t_new) of an adaptive method's trial step of size h_abs from t, cut to land on t_bound."""
    t_new = t + h_abs
    if t_new >= t_bound:
        return t_bound - t, t_bound
    return h_abs, t_new


@njit(cache=True, error_model="numpy")
def min_step(t):
    """Smallest step size the time can resolve at t (10 ulp)."""
    return 10.0 * (np.nextafter(t, np.inf) - t)


@njit(cache=True, error_model="numpy")
def finite(y):
    """True when every component is finite."""
    return math.isfinite(y.sum())


@njit(cache=True, error_model="numpy")
def lipschitz(fa, fb, ya, yb):
    """‖fa − fb‖/‖ya − yb‖: Hairer's estimate of |λ| from derivatives at two nearby states (0 if equal)."""
    num = 0.0
    den = 0.0
    for i in range(ya.size):
        num += (fa[i] - fb[i]) ** 2
        den += (ya[i] - yb[i]) ** 2
    return math.sqrt(num / den) if den > 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def step(w, y, y_new, K, f, p):
    """One accepted step from (w[T], y) with first derivative f (see the module docstring); returns the status
    and sets H, NFEV, HL and, on success, T, H_ABS in w."""
    w, y, y_new, K, f, p = borrowed(w), borrowed(y), borrowed(y_new), borrowed(K), borrowed(f), borrowed(p)
    K[0] = f
    ws = np.empty((scratch_rows(y.size), y.size))
    status, t_new, h, h_next, nfev, hl = one_step(w[T], min(w[H_ABS], w[MAX_STEP]), w, y, y_new, K, p, ws)
    w[H], w[NFEV], w[HL] = h, nfev, hl
    if status == 0:
        w[T], w[H_ABS] = t_new, h_next
    return status


@njit(cache=True, error_model="numpy")
def values(t, y, p, out):
    """Every event's value at (t, y) into ``out`` (one call for the Python driver instead of one per event)."""
    y, p, out = borrowed(y), borrowed(p), borrowed(out)
    for k in range(out.size):
        out[k] = event(t, y, p, k)


@njit(cache=True, error_model="numpy")
def coeffs(K, h, Q):
    """Dense-output coefficients Q = h·(Kᵀ P) of one step."""
    for i in range(Q.shape[0]):
        for c in range(Q.shape[1]):
            acc = 0.0
            for j in range(K.shape[0]):
                acc += K[j, i] * P[j, c]
            Q[i, c] = h * acc


@njit(cache=True, error_model="numpy")
def dense_at(th, y_old, Q, y):
    """y = y_old + Σ_c Q[:, c] θ^(c+1): the dense output at θ (Horner; in Python
    :class:`~rig.solvers.dense.PolynomialDense`)."""
    for i in range(y.size):
        acc = 0.0
        for c in range(Q.shape[1] - 1, -1, -1):
            acc = acc * th + Q[i, c]
        y[i] = y_old[i] + acc * th


@njit(cache=True, error_model="numpy")
def g_dense(t, t_old, h, y_old, Q, p, k, y):
    """Event k at time t on the dense output y_old + Σ_c Q[:, c] θ^(c+1) (θ = (t − t_old)/h)."""
    dense_at((t - t_old) / h, y_old, Q, y)
    return event(t, y, p, k)


@njit(cache=True, error_model="numpy")
def sample(TE, OUT, w, t_old, t_end, h, y_old, K, Q):
    """OUT[:, i] = y(TE[i]) for the output times from w[IE] on that lie in [t_old, t_end), on the dense output of
    the step of size h from (t_old, y_old) with stages K (Q: scratch); w[IE] moved past them."""
    i = int(w[IE])
    if i >= TE.size or not TE[i] < t_end:
        return
    coeffs(K, h, Q)
    while i < TE.size and TE[i] < t_end:
        dense_at((TE[i] - t_old) / h, y_old, Q, OUT[:, i])
        i += 1
    w[IE] = i


@njit(cache=True, error_model="numpy")
def brent(t_old, t_new, y_old, Q, p, k, y):
    """Root of event k in [t_old, t_new] on the dense output (scipy's brentq.c, xtol 1e-15, rtol 4 eps); ``y``
    scratch for the states."""
    h = t_new - t_old
    xtol, rtol = 1e-15, 4.0 * 2.220446049250313e-16
    xpre, xcur = t_old, t_new
    fpre, fcur = g_dense(xpre, t_old, h, y_old, Q, p, k, y), g_dense(xcur, t_old, h, y_old, Q, p, k, y)
    if fpre == 0.0:
        return xpre
    if fcur == 0.0 or (fpre < 0.0) == (fcur < 0.0):    # no sign change on the interpolant: the end states' change lies
        return xcur                                    # within its rounding of the step's end (as integrate._root)
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


@njit(cache=True, error_model="numpy")
def locate(t_old, t_new, y_old, K, p, k):
    """Root of event k in the step [t_old, t_new] with stage vectors K (a sign change over the step)."""
    y_old, K, p = borrowed(y_old), borrowed(K), borrowed(p)
    Q = np.empty((y_old.size, P.shape[1]))
    coeffs(K, t_new - t_old, Q)
    return brent(t_old, t_new, y_old, Q, p, k, np.empty(y_old.size))


@njit(cache=True, error_model="numpy")
def put(dst, src):
    """dst[:] = src element by element (without numba's runtime)."""
    for i in range(dst.size):
        dst[i] = src[i]


@njit(cache=True, error_model="numpy")
def same(a, b):
    """Arrays equal element by element, NaN equal to NaN."""
    for i in range(a.size):
        if a[i] != b[i] and not (a[i] != a[i] and b[i] != b[i]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def land(t0, t_root, w, y0, K, yr, p, saved, y_new, ws):
    """Redo a step from (t0, y0) as a step of the method itself ending on the root t_root, its stages into K: the
    state there then carries the step's controlled error, not the interpolant's (one order lower). Returns
    (RHS calls, step size); if that step is refused (error test, underflow) step size 0, and ``yr`` (as
    interpolated) and K are left as they were. Only for restarts that change nothing in p: where an event
    switches the RHS (a new cam segment) the state must stay on the event surface (g = 0 on the interpolant), or
    the new mode starts from a state on the old side. Scratch: ``saved`` (K's shape), ``y_new``, ``ws`` (the step's)."""
    t_bound = w[T_BOUND]
    for j in range(K.shape[0]):
        put(saved[j], K[j])
    w[T_BOUND] = t_root
    status, t_end, h, _, nf, _ = one_step(t0, (t_root - t0) * (1.0 + 1e-9), w, y0, y_new, K, p, ws)
    w[T_BOUND] = t_bound
    if status != 0 or t_end != t_root:
        for j in range(K.shape[0]):
            put(K[j], saved[j])
        return nf, 0.0
    put(yr, y_new)
    return nf, h


@njit(cache=True, error_model="numpy", _nrt=False)
def run(w, Y, TT, HH, KK, HL_, EV, g, p, BR, S, GN, Q, KS, PB, TE, OUT):
    """Steps from (w[T], Y[0]) with KK[0, 0] = f there, storing step ends TT[s + 1], states Y[s + 1], step
    sizes HH[s], stage vectors KK[s] and h·|λ| HL_[s], until an event value in ``g`` (given at the start,
    updated in place) changes sign or reaches 0, t_bound is reached or the buffers are full; returns the
    number of steps, or −1 − steps on a failure (status in w[FAIL], the failed step's size in w[H]). Sign
    changes that ``act`` accepts are acted on in the run; a t_bound with further bounds BR[w[NBREAK]:] is a time
    break passed in the run (see :func:`rig.solvers.compiled.compiled_solver`). Scratch
    (:func:`~rig.solvers.compiled.run_scratch`): S (rows of the state's size: the root's state, Brent's states, the
    landing step's new state, then the method's rows), GN (event values), Q (dense-output coefficients), KS (one
    step's stages), PB (the parameter vector's size). Output times TE (may be empty) and their states OUT: every step
    samples the times from w[IE] on that it passes (:func:`sample`), but for the last one when an event's sign
    changed in it (the caller examines it)."""
    last = KK.shape[1] - 1
    g_new, yr, y_brent, y_land, ws = GN, S[0], S[1], S[2], S[3:]
    TT[0] = w[T]
    nfev = 0
    ne = 0
    m = KK.shape[0]
    restarted = False
    for s in range(m):
        if s:                                       # step s − 1 is final: its output times
            sample(TE, OUT, w, TT[s - 1], TT[s], HH[s - 1], Y[s - 1], KK[s - 1], Q)
        if s and not restarted:
            put(KK[s, 0], KK[s - 1, last])
        restarted = False
        status, t_new, h, h_next, nf, hl = one_step(TT[s], min(w[H_ABS], w[MAX_STEP]), w, Y[s], Y[s + 1], KK[s],
                                                    p, ws)
        nfev += nf
        w[NFEV], w[NEV] = nfev, ne
        if status:
            w[H], w[FAIL] = h, status
            return -1 - s
        TT[s + 1], HH[s], HL_[s] = t_new, h, hl
        w[T], w[H_ABS], w[H] = t_new, h_next, h
        crossed = False
        for k in range(g.size):                     # a zero at either end counts: leaving g = 0 may be an event
            g_new[k] = event(t_new, Y[s + 1], p, k)  # (a direction given), the driver decides; so does a NaN (the
            if g[k] == 0.0 or g_new[k] == 0.0 or (g[k] < 0.0) != (g_new[k] < 0.0) or not np.isfinite(g_new[k]):
                crossed = True                      # driver names it)
        if not crossed:
            passed = int(w[NBREAK])
            if s == m - 1 or (t_new >= w[T_BOUND] and passed == BR.size):
                sample(TE, OUT, w, TT[s], t_new, h, Y[s], KK[s], Q)   # no event in it: its output times too,
                i = int(w[IE])                                     # the one at its end its state
                if i < TE.size and TE[i] == t_new:
                    put(OUT[:, i], Y[s + 1])
                    w[IE] = i + 1
                return s + 1                        # g holds the values at the last step's start
            if t_new >= w[T_BOUND]:                 # a time break: restart one ulp past it (integrate.py)
                t_next = np.nextafter(t_new, np.inf)
                kernel(t_next, Y[s + 1], p, KK[s + 1, 0])
                nfev += 1
                w[NFEV] = nfev
                if not finite(KK[s + 1, 0]):
                    return s + 1                    # the driver's next solver reports it, with the diagnosis
                put(g, g_new)
                TT[s + 1] = t_next
                w[T], w[T0], w[T_BOUND], w[NBREAK] = t_next, t_next, BR[passed], passed + 1
                if ADAPTIVE:                        # the step that landed on it, within the next segment, as the
                    w[H_ABS] = min(h, BR[passed] - t_next)     # driver's next solver starts
                restarted = True
                continue
            put(g, g_new)
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
                    tk = brent(TT[s], t_new, Y[s], Q, p, k, y_brent)
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
        if ADAPTIVE:
            put(PB, p)
        act(t_root, yr, p, k_root, True)
        if ADAPTIVE and same(p, PB):          # a plain restart (the RHS continuous, its derivatives jump):
            nf, h_root = land(TT[s], t_root, w, Y[s], KK[s], yr, p, KS, y_land, ws)     # land on the root with a step
            nfev += nf
            if h_root > 0.0:
                HH[s] = h_root
        put(Y[s + 1], yr)
        EV[ne, 0], EV[ne, 1] = t_root, k_root
        EV[ne, 2] = 1.0 if g_new[k_root] > g[k_root] else -1.0
        put(EV[ne, 3:], Y[s + 1])
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
        w[T], w[T0], w[NFEV], w[NEV] = t_root, t_root, nfev, ne
        if ADAPTIVE:                                # within the segment, as the driver's new solver starts (a fixed
            w[H_ABS] = min(h, w[T_BOUND] - t_root)  # step keeps its h: the step that held the root may be a cut one)
        restarted = True
    return m
