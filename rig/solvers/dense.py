"""Dense output of the steppers: polynomial pieces y(t_old + θh) = y_old + h·Σ_k (Kᵀ P)[:, k]·θ^(k+1) from a
step's stage vectors K and the method's continuous-extension matrix P, singly (:class:`PolynomialDense`), over
runs of steps (:class:`StepsDense`, compiled) and batched over many steps (:func:`fill_dense`)."""
from __future__ import annotations

import numpy as np
from numba import njit


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
    Q = np.empty((n, order))
    s_cur = -1
    s = max(np.searchsorted(T, t[0], side="right") - 1, 0) if t.size else 0
    h = 1.0
    for m in range(t.size):
        while s < last and T[s + 1] <= t[m]:          # sorted times: walk the steps forward
            s += 1
        if s != s_cur:                                 # coefficients of step s: h·(Kᵀ P)
            h = H[s]
            for i in range(n):
                for c in range(order):
                    acc = 0.0
                    for j in range(K.shape[1]):
                        acc += K[s, j, i] * P[j, c]
                    Q[i, c] = acc * h
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
