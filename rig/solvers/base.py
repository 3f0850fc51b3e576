"""Common parts of the ODE solvers: base class, divergence error, step-size helpers.

States are tuples of floats (pure Python is much faster than numpy for 4–6 states); right-hand sides
``fun(t, y) -> sequence of floats`` must accept tuples.
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence

Rhs = Callable[[float, tuple], Sequence[float]]


class SolverDivergence(RuntimeError):
    """The solution became non-finite or the step size underflowed; the message names time and state."""

    def __init__(self, what: str, t: float, y: Sequence[float]):
        state = ", ".join(f"{v:.6g}" for v in y)
        super().__init__(f"solver diverged: {what} at t = {t:.9g} s, state = ({state})")
        self.t = t
        self.y = tuple(y)


def all_finite(y: Sequence[float]) -> bool:
    """True when every component is finite (a sum overflowing past 1e308 also counts as divergence)."""
    return math.isfinite(sum(y))


class StiffnessWarning(RuntimeWarning):
    """An explicit solver's step size is limited by stability (h·|λ| beyond its stability boundary)."""


class StiffnessError(SolverDivergence):
    """Raised instead of :class:`StiffnessWarning` when a solver is built with ``stiffness="raise"``."""


class StiffnessMonitor:
    """Hairer's stiffness test for explicit RK: h·|λ| ≈ h·‖f(Y_a) − f(Y_b)‖/‖Y_a − Y_b‖ from two stages
    evaluated at (nearly) the same point. ``limit`` = stability boundary of the method on the negative
    real axis; 15 consecutive steps beyond it report stiffness ('warn', 'raise' or 'ignore')."""

    STEPS = 15

    def __init__(self, method: str, limit: float, policy: str = "warn"):
        if policy not in ("warn", "raise", "ignore"):
            raise ValueError(f"{method}: stiffness = {policy!r} must be 'warn', 'raise' or 'ignore'")
        self.method, self.limit, self.policy = method, limit, policy
        self.count = self.calm = 0
        self.detected_at: float | None = None

    def check(self, t: float, y: tuple, h: float, fa, fb, ya, yb) -> None:
        """Update with stage derivatives ``fa``, ``fb`` at stage states ``ya``, ``yb`` of a step of size h."""
        if self.policy == "ignore" or self.detected_at is not None:
            return
        num = sum((a - b) ** 2 for a, b in zip(fa, fb))
        den = sum((a - b) ** 2 for a, b in zip(ya, yb))
        self.update(t, y, h, h * math.sqrt(num / den) if den > 0.0 else 0.0)

    def update_many(self, t, y, h, hl) -> None:
        """:meth:`update` for consecutive steps (arrays; rows of ``y``); calm runs are skipped at once."""
        if self.policy == "ignore" or self.detected_at is not None:
            return
        if self.count == 0 and max(hl) <= self.limit:
            self.calm += len(hl)
            return
        for args in zip(t, y, h, hl):
            self.update(*args)

    def update(self, t: float, y: tuple, h: float, hl: float) -> None:
        """Update with an estimate ``hl`` of h·|λ| for a step of size h ending at (t, y)."""
        if self.policy == "ignore" or self.detected_at is not None:
            return
        if hl <= self.limit:
            self.calm += 1
            if self.calm >= 6:
                self.count = 0
            return
        self.calm = 0
        self.count += 1
        if self.count < self.STEPS:
            return
        self.detected_at = t
        msg = (f"{self.method}: problem is stiff at t = {t:.6g} s: h*|lambda| = {hl:.3g} > {self.limit} for "
               f"{self.STEPS} steps (h = {h:.3g} s, |lambda| = {hl / h:.3g} 1/s); the step size is limited by "
               f"stability, not accuracy - use an implicit method or remove the stiffness (e.g. a switched "
               f"stick-slip friction model instead of a steep regularisation)")
        if self.policy == "raise":
            raise StiffnessError(msg, t, y)
        warnings.warn(msg, StiffnessWarning, stacklevel=5)


class OdeSolver:
    """Base of the step-by-step solvers (scipy.integrate.OdeSolver style).

    Attributes: ``t``, ``y`` (tuple), ``t_old``, ``y_old``, ``t_bound``, ``status`` ('running',
    'finished', 'failed'), ``nfev``, ``nsteps``, ``h_last`` (last accepted step, s). Only forward
    integration (t_bound > t0) is supported.
    """

    order: int = 0

    def __init__(self, fun: Rhs, t0: float, y0: Sequence[float], t_bound: float):
        if not t_bound > t0:
            raise ValueError(f"solver: t_bound = {t_bound} must be greater than t0 = {t0}")
        self.fun = fun
        self.t = float(t0)
        self.y = tuple(float(v) for v in y0)
        if not all_finite(self.y):
            raise SolverDivergence("non-finite initial state", self.t, self.y)
        self.t_bound = float(t_bound)
        self.t_old: float | None = None
        self.y_old: tuple | None = None
        self.status = "running"
        self.nfev = 0
        self.nsteps = 0
        self.h_last = math.nan

    def step(self) -> None:
        """Advance one accepted step (raises :class:`SolverDivergence` on failure)."""
        if self.status != "running":
            raise RuntimeError(f"solver: step() called on a {self.status} solver")
        try:
            self._step_impl()
        except SolverDivergence:
            self.status = "failed"
            raise
        except (OverflowError, ZeroDivisionError) as exc:
            self.status = "failed"
            raise SolverDivergence(f"arithmetic error in the right-hand side ({exc})", self.t, self.y) from None
        self.nsteps += 1
        if self.t >= self.t_bound:
            self.status = "finished"

    def _step_impl(self) -> None:
        raise NotImplementedError

    def dense_output(self):
        """Interpolant over the last step [t_old, t]: callable on a float (tuple) or array (ndarray)."""
        raise NotImplementedError

    def _min_step(self) -> float:
        return 10.0 * (math.nextafter(self.t, math.inf) - self.t)
