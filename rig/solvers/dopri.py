"""Dormand–Prince 5(4) adaptive explicit Runge–Kutta in pure Python floats (for small systems).

Same tableau, error norm (RMS of err/(atol + rtol·max|y|)) and quartic dense output as scipy's RK45,
but with tuple states and stages unrolled per state size (:mod:`rig.solvers.unrolled`).
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from rig.solvers.base import (
    OdeSolver,
    Rhs,
    SolverDivergence,
    StiffnessMonitor,
    all_finite,
)
from rig.solvers.compiled import H, H_ABS, NEV, NFEV, JitRhs, dp45_step
from rig.solvers.unrolled import rk_kernels

_A21 = 1 / 5
_A31, _A32 = 3 / 40, 9 / 40
_A41, _A42, _A43 = 44 / 45, -56 / 15, 32 / 9
_A51, _A52, _A53, _A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
_A61, _A62, _A63, _A64, _A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
_B1, _B3, _B4, _B5, _B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
_E1, _E3, _E4, _E5, _E6, _E7 = -71 / 57600, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40
_C2, _C3, _C4, _C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
# quartic dense output (Shampine 1986, as in scipy RK45): rows = stages, columns = θ¹..θ⁴
_P = np.array([
    [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
    [0, 0, 0, 0],
    [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
    [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
    [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
    [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
    [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423]])
SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0
# the tableau as arrays, for the compiled step (rig.solvers.compiled): A[s, j], B, C, E (incl. FSAL stage)
A = np.zeros((6, 6))
for _s, _row in enumerate(((_A21,), (_A31, _A32), (_A41, _A42, _A43), (_A51, _A52, _A53, _A54),
                           (_A61, _A62, _A63, _A64, _A65)), start=1):
    A[_s, :_s] = _row
B = np.array([_B1, 0.0, _B3, _B4, _B5, _B6])
C = np.array([0.0, _C2, _C3, _C4, _C5, 1.0])
E = np.array([_E1, 0.0, _E3, _E4, _E5, _E6, _E7])


def _kernels(n: int):
    """Unrolled DP5(4) stages and error norm for n states (generated once per n)."""
    return rk_kernels(((_A21,), (_A31, _A32), (_A41, _A42, _A43), (_A51, _A52, _A53, _A54),
                       (_A61, _A62, _A63, _A64, _A65)), (_B1, 0.0, _B3, _B4, _B5, _B6),
                      (0.0, _C2, _C3, _C4, _C5, 1.0), (_E1, 0.0, _E3, _E4, _E5, _E6, _E7), n)


class PolynomialDense:
    """y(t_old + θh) = y_old + h·Σ_k (Kᵀ P)[:, k] θ^(k+1) on one step, from the stage derivatives ``K``
    and the method's continuous-extension matrix ``P`` (stages × order); call with a float or an array.
    :func:`fill_dense` evaluates many steps at once."""

    def __init__(self, t_old: float, h: float, y_old: tuple, K: tuple, P: np.ndarray):
        self.t_old, self.h, self.y_old, self.K, self.P = t_old, h, y_old, K, P
        self._rows: list[tuple] | None = None

    @property
    def Q(self) -> np.ndarray:
        return self.h * (np.array(self.K).T @ self.P)

    def __call__(self, t):
        if isinstance(t, float):
            if self._rows is None:
                self._rows = [tuple(r) for r in self.Q.tolist()]  # per component, for fast scalar evaluation
            th = (t - self.t_old) / self.h
            out = []
            for y0, q in zip(self.y_old, self._rows):
                acc = 0.0
                for c in reversed(q):
                    acc = acc * th + c
                out.append(y0 + acc * th)
            return tuple(out)
        th = (np.asarray(t, dtype=float) - self.t_old) / self.h
        powers = th[None, :] ** np.arange(1, self.P.shape[1] + 1)[:, None]
        return np.asarray(self.y_old)[:, None] + self.Q @ powers


class StepsDense:
    """Consecutive steps s = 0..m−1 of size H[s] from T[s] (ending at T[s+1] ≤ T[s] + H[s]: a step cut at
    an event keeps its polynomial), starting at Y[s] with stages K[s] (continuous extension ``P``): y(t)
    for an array of times in [T[0], T[m]] (vectorised, as :class:`PolynomialDense`)."""

    def __init__(self, T: np.ndarray, H: np.ndarray, Y: np.ndarray, K: np.ndarray, P: np.ndarray):
        self.T, self.H, self.Y, self.K, self.P = T, H, Y, K, P

    def __call__(self, t) -> np.ndarray:
        return _eval_steps(self.T, self.H, self.Y, self.K, self.P, np.asarray(t, dtype=float))


@njit(cache=True)
def _eval_steps(T, H, Y, K, P, t):
    """(n, m) states at sorted times t on consecutive polynomial steps (see :class:`StepsDense`)."""
    n, order, last = Y.shape[1], P.shape[1], K.shape[0] - 1
    out = np.empty((n, t.size))
    Q = np.zeros((n, order))
    s_cur = -1
    for m in range(t.size):
        s = min(max(np.searchsorted(T, t[m], side="right") - 1, 0), last)
        h = H[s]
        if s != s_cur:                                 # coefficients of step s: h·(Kᵀ P)
            Q[:] = 0.0
            for i in range(n):
                for c in range(order):
                    for j in range(K.shape[1]):
                        Q[i, c] += K[s, j, i] * P[j, c]
                    Q[i, c] *= h
            s_cur = s
        th = (t[m] - T[s]) / h
        for i in range(n):
            acc = 0.0
            for c in range(order - 1, -1, -1):
                acc = acc * th + Q[i, c]
            out[i, m] = Y[s, i] + acc * th
    return out


def fill_dense(out: np.ndarray, t: np.ndarray, pieces: list[tuple]) -> None:
    """out[:, i:j] = piece(t[i:j]) for all pieces: polynomial pieces in one vectorised pass per continuous
    extension, other interpolants (closed forms) called on their samples."""
    groups: dict[int, list] = {}
    for piece in pieces:
        if isinstance(piece[0], PolynomialDense):
            groups.setdefault(id(piece[0].P), []).append(piece)
        else:
            out[:, piece[1]:piece[2]] = piece[0](t[piece[1]:piece[2]])
    for group in groups.values():
        P = group[0][0].P
        lengths = np.array([j - i for _, i, j in group])
        rep = np.repeat(np.arange(len(group)), lengths)
        cols = np.concatenate([np.arange(i, j) for _, i, j in group])
        h = np.array([d.h for d, _, _ in group])
        Q = np.einsum("skn,kc->snc", np.array([d.K for d, _, _ in group]), P) * h[:, None, None]
        th = (t[cols] - np.array([d.t_old for d, _, _ in group])[rep]) / h[rep]
        powers = th[:, None] ** np.arange(1, P.shape[1] + 1)[None, :]
        y0 = np.array([d.y_old for d, _, _ in group])
        out[:, cols] = (y0[rep] + np.einsum("mnc,mc->mn", Q[rep], powers)).T


def initial_step(fun: Rhs, t0: float, y0: tuple, f0: Sequence[float], order: int, rtol: float, atol: float,
                 t_bound: float) -> float:
    """Hairer's starting-step heuristic (one extra RHS evaluation)."""
    sc = [atol + rtol * abs(v) for v in y0]
    d0 = math.sqrt(sum((v / s) ** 2 for v, s in zip(y0, sc)) / len(y0))
    d1 = math.sqrt(sum((v / s) ** 2 for v, s in zip(f0, sc)) / len(y0))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, t_bound - t0)
    y1 = tuple(v + h0 * f for v, f in zip(y0, f0))
    f1 = fun(t0 + h0, y1)
    d2 = math.sqrt(sum(((a - b) / s) ** 2 for a, b, s in zip(f1, f0, sc)) / len(y0)) / h0
    h1 = max(1e-6, h0 * 1e-3) if max(d1, d2) <= 1e-15 else (0.01 / max(d1, d2)) ** (1 / (order + 1))
    return min(100 * h0, h1, t_bound - t0)


class DormandPrince45(OdeSolver):
    """Adaptive Dormand–Prince 5(4) with FSAL, local extrapolation and quartic dense output.

    ``stiffness`` ('warn' | 'raise' | 'ignore'): Hairer's test on stages 6 and 7 (both at t + h);
    ``stiff_at`` is the time it first fired (None otherwise). A :class:`rig.solvers.compiled.JitRhs`
    right-hand side is stepped in machine code (``compiled=False`` forces the pure-Python step).
    """

    order = 5

    def __init__(self, fun: Rhs, t0: float, y0: Sequence[float], t_bound: float, rtol: float = 1e-6,
                 atol: float = 1e-9, first_step: float | None = None, max_step: float = math.inf,
                 stiffness: str = "warn", compiled: bool = True):
        super().__init__(fun, t0, y0, t_bound)
        self.monitor = StiffnessMonitor("DP45", 3.25, stiffness)
        if not (rtol > 0 and atol >= 0):
            raise ValueError(f"DormandPrince45: need rtol > 0 and atol >= 0, got rtol={rtol}, atol={atol}")
        self.rtol, self.atol, self.max_step = rtol, atol, max_step
        self.f = tuple(fun(self.t, self.y))
        self.nfev = 1
        if first_step is None or not first_step > 0:
            self.h_abs = initial_step(fun, self.t, self.y, self.f, 4, rtol, atol, self.t_bound)
            self.nfev += 1
        else:
            self.h_abs = min(first_step, self.t_bound - self.t)
        self._K: tuple | None = None
        self._jit = self._run = self._locate = None
        if compiled and isinstance(fun, JitRhs):
            (self._jit, self._run, self._locate), self._p = dp45_step(fun.kernel, fun.event, fun.act), fun.params()
            self._ya, self._yb, self._fa = np.array(self.y), np.empty(len(self.y)), np.array(self.f)
            self._w = np.array([self.t, self.h_abs, self.t_bound, rtol, atol, max_step, 0.0, 0.0, 0.0, 0.0])

    def _step_impl(self) -> None:
        if self._jit is not None:
            return self._compiled_step()
        fun, t, y, k1 = self.fun, self.t, self.y, self.f
        rtol, atol = self.rtol, self.atol
        h_abs = min(self.h_abs, self.max_step)
        min_step = self._min_step()
        stages, error_norm = _kernels(len(y))
        rejected = False
        while True:
            if h_abs < min_step:
                raise SolverDivergence(f"step size underflow (h = {h_abs:.3g} s)", t, y)
            h = h_abs
            t_new = t + h
            if t_new >= self.t_bound:
                t_new = self.t_bound
                h = t_new - t
            y_new, y6, k2, k3, k4, k5, k6 = stages(fun, t, y, k1, h)
            self.nfev += 5
            if not all_finite(y_new):
                h_abs *= MIN_FACTOR
                continue
            k7 = fun(t_new, y_new)
            self.nfev += 1
            err_norm = error_norm(y, y_new, k1, k2, k3, k4, k5, k6, k7, h, rtol, atol)
            if not math.isfinite(err_norm):
                h_abs *= MIN_FACTOR
                continue
            if err_norm < 1.0:
                factor = MAX_FACTOR if err_norm == 0 else min(MAX_FACTOR, SAFETY * err_norm ** -0.2)
                if rejected:                     # no growth right after a rejection (as scipy)
                    factor = min(1.0, factor)
                break
            h_abs *= max(MIN_FACTOR, SAFETY * err_norm ** -0.2)
            rejected = True
        self.monitor.check(t_new, y_new, h, k7, k6, y_new, y6)
        self.t_old, self.y_old = t, y
        self.t, self.y, self.f = t_new, y_new, tuple(k7)
        self.h_last = h
        self.h_abs = h_abs * factor
        self._K = (k1, k2, k3, k4, k5, k6, k7)

    def _compiled_step(self) -> None:
        w, K = self._w, np.empty((7, len(self.y)))         # w carries t and h_abs from step to step
        status = self._jit(w, self._ya, self._yb, K, self._fa, self._p)
        t_new, h_abs, _, _, _, _, h, nfev, hl, _ = w.tolist()
        self.nfev += int(nfev)
        if status:
            self.fun.fail(self.t, self.y, f"step size underflow (h = {h:.3g} s)")
        y = tuple(self._yb.tolist())
        self.monitor.update(t_new, y, h, hl)
        self.t_old, self.y_old = self.t, self.y
        self.t, self.y, self.f, self._fa = t_new, y, K[6], K[6]
        self._ya, self._yb = self._yb, self._ya
        self.h_last, self.h_abs, self._K = h, h_abs, K

    @property
    def can_advance(self) -> bool:
        """True when :meth:`advance` is available (compiled RHS with an event kernel)."""
        return self._run is not None

    def advance(self, g: np.ndarray, max_steps: int = 256) -> StepsDense | None:
        """Take accepted steps in one compiled call until an event value (``g``: at the current point, in
        the order of the RHS's event kernel; updated in place to the values at the last step's start)
        changes sign, t_bound is reached or ``max_steps`` are taken. The solver then stands after the
        last step as after :meth:`step`; returns the steps before it (interpolant with ``.T``, ``.Y`` of
        their ends), or None."""
        n = len(self.y)
        Y, TT = np.empty((max_steps + 1, n)), np.empty(max_steps + 1)
        KK, HH, HL = np.empty((max_steps, 7, n)), np.empty(max_steps), np.empty(max_steps)
        EV = np.empty((max_steps, 3 + n))
        Y[0], KK[0, 0] = self._ya, self._fa
        count = self._run(self._w, Y, TT, HH, KK, HL, EV, g, self._p)
        self.nfev += int(self._w[NFEV])
        self.acted = EV[:int(self._w[NEV])]
        if count < 0:
            self.status = "failed"
            s = -1 - count
            self.fun.fail(float(TT[s]), tuple(Y[s]), f"step size underflow (h = {self._w[H]:.3g} s)")
        self.nsteps += count
        if TT[count] >= self.t_bound:
            self.status = "finished"
        self.monitor.update_many(TT[1:count + 1], Y[1:count + 1], HH[:count], HL[:count])
        last = count - 1
        self.t_old, self.y_old = float(TT[last]), tuple(Y[last].tolist())
        self.t, self.y = float(TT[count]), tuple(Y[count].tolist())
        self._K, self.f, self._yo = KK[last], KK[last, 6], Y[last]
        self._ya, self._fa = Y[count].copy(), KK[last, 6]
        self.h_last, self.h_abs = float(self._w[H]), float(self._w[H_ABS])
        return StepsDense(TT[:count], HH[:last], Y[:count], KK[:last], _P) if last else None

    def locate(self, k: int) -> float:
        """Root of event k (the RHS's event kernel) in the last step taken by :meth:`advance`, which
        changes sign over it (compiled Brent search on the dense output)."""
        return self._locate(self.t_old, self.t, self._yo, self._K, self._p, k)

    @property
    def stiff_at(self) -> float | None:
        return self.monitor.detected_at

    def dense_output(self) -> PolynomialDense:
        return PolynomialDense(self.t_old, self.t - self.t_old, self.y_old, self._K, _P)
