"""Dense output of the steppers: polynomial pieces y(t_old + θh) = y_old + h·Σ_k (Kᵀ P)[:, k]·θ^(k+1) from a
step's stage vectors K and the method's continuous-extension matrix P, singly (:class:`PolynomialDense`) and batched
over many steps (:func:`fill_dense`); the compiled runs sample theirs themselves (``sample`` in
:mod:`rig.solvers.templates.runs`)."""
from __future__ import annotations

import numpy as np


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
