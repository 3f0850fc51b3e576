"""Explicit Euler and semi-implicit (symplectic) Euler, fixed step, order 1 (compiled for a numba RHS, else
pure Python floats; compiled steps: ``rig/solvers/templates/euler.py``, ``symplectic_euler.py``).

Both interpolate linearly between steps: y(t + θh) = y + θ·(y_new − y).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rig.solvers.base import Rhs
from rig.solvers.stepper import FixedStepper

#: continuous extensions: K rows (f(t, y), f(t_new, y_new)) and (f(t, y), (y_new − y)/h, f(t_new, y_new))
EULER_P = np.array([[1.0], [0.0]])
SYMPLECTIC_P = np.array([[0.0], [1.0], [0.0]])


class Euler(FixedStepper):
    """Explicit (forward) Euler y_new = y + h·f(t, y) with fixed step ``h`` (s) (see
    :class:`~rig.solvers.stepper.FixedStepper`): stable for |1 + hλ| ≤ 1, i.e. h·|λ| ≤ 2 on the negative real
    axis and h·ω_n < 2ζ for a damped oscillation (never for an undamped one); Hairer's stiffness test on
    f(t, y), f(t_new, y_new) reports h·|λ| > 2 as divergence."""

    order = 1
    method, label, P, limit = "euler", "explicit Euler", EULER_P, 2.0

    def _python_step(self) -> None:
        y, f0 = self.y, self.f
        h, t_new = self._fixed_h()
        y_new = tuple(a + h * b for a, b in zip(y, f0))
        self._finish(t_new, y_new, h, (f0,))


MASK_BITS = 53       # components the compiled step's position mask holds (a float64 holds whole numbers below 2^53)


class SymplecticEuler(FixedStepper):
    """Semi-implicit (symplectic) Euler for a second-order system with positions q and velocities v: ``positions``
    the indices of q in the state (in any order, e.g. (e, τė, φ, ω) → (0, 2)), or ``nq`` for the first nq
    components (default: the first half): kick v_new = v + h·f_v(t, q, v), then drift
    q_new = q + h·f_q(t, q, v_new) — explicit, two RHS calls per step, order 1; for a Hamiltonian system
    with q̇ = v its energy error stays bounded instead of drifting (Hairer–Lubich–Wanner, *Geometric
    Numerical Integration*, §VI.3). Fixed step ``h`` (s), stability boundary h·ω ≤ 2 for an undamped
    oscillation (see :class:`~rig.solvers.stepper.FixedStepper`)."""

    order = 1
    method, label, P, limit = "symplectic_euler", "symplectic Euler", SYMPLECTIC_P, 2.0

    def __init__(self, fun: Rhs, t0: float, y0: Sequence[float], t_bound: float, h: float = 1e-3,
                 first_step: float | None = None, stiffness: str = "raise", compiled: bool = True,
                 nq: int | None = None, positions: Sequence[int] | None = None):
        n = len(y0)
        if n < 2:
            raise ValueError(f"symplectic Euler needs positions and velocities (at least 2 states), got {n}")
        if positions is not None and nq is not None:
            raise ValueError("symplectic Euler: give the positions either as nq or as positions, not both")
        if positions is None:
            nq = n // 2 if nq is None else nq
            if not 1 <= nq < n:
                raise ValueError(f"symplectic Euler: nq = {nq!r} positions must be in 1..{n - 1} for {n} states")
            positions = range(nq)
        self.positions = tuple(sorted({int(i) for i in positions}))
        if not 1 <= len(self.positions) < n or not 0 <= self.positions[0] <= self.positions[-1] < n:
            raise ValueError(f"symplectic Euler: positions {tuple(positions)!r} must name 1..{n - 1} of the {n} "
                             f"state components (indices 0..{n - 1}), leaving at least one velocity")
        self._is_q = tuple(i in self.positions for i in range(n))
        compiled = compiled and n <= MASK_BITS       # the compiled step keeps the positions as a float's bit mask
        super().__init__(fun, t0, y0, t_bound, h, first_step, stiffness, compiled, self.positions)

    def _options(self) -> dict:
        return {"positions": self.positions}

    def _python_step(self) -> None:
        t, y, f0, q = self.t, self.y, self.f, self._is_q
        h, t_new = self._fixed_h()
        kicked = tuple(a if is_q else a + h * b for a, b, is_q in zip(y, f0, q))
        f1 = tuple(self.fun(t, kicked))
        self.nfev += 1
        y_new = tuple(a + h * b if is_q else k for a, b, k, is_q in zip(y, f1, kicked, q))
        self._finish(t_new, y_new, h, (f0, tuple(b if is_q else a for a, b, is_q in zip(f0, f1, q))))
