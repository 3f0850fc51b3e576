"""Base of the one-step methods (Euler, symplectic Euler, RK4, DP45, Tsit5, DOP853, Rodas4): Python and compiled steps,
compiled runs of steps, dense output, stiffness monitor and divergence reports.

Every method's step from (t, y) yields stage vectors K (rows) with y(t + θh) = y + h·Σ_c (Kᵀ P)[:, c]·θ^(c+1)
for the method's continuous-extension matrix P, and ends with f(t_new, y_new) as the last row of K (the next
step's first derivative). With a :class:`~rig.solvers.compiled.JitRhs` right-hand side the step runs in
machine code (:func:`~rig.solvers.compiled.compiled_solver`, one template per method) and :meth:`advance`
takes whole runs of steps in one call; otherwise the subclass's pure-Python ``_python_step`` (tuples of
floats, or numpy for the implicit method) takes the same steps.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

from rig.solvers.base import (OdeSolver, Rhs, SolverDivergence, StiffnessError, StiffnessMonitor, all_finite,
                              check_step_options, lipschitz, not_finite_text, rhs_not_finite)
from rig.solvers.amplification import Amplification
from rig.solvers.control import step_factor
from rig.solvers.compiled import (FAIL, H, H_ABS, HL, IE, NBREAK, NEV, NFEV, T, T_BOUND, JitRhs, compiled_solver,
                                  run_scratch)
from rig.solvers.dense import PolynomialDense

UNDERFLOW, NONFINITE = 1, 2          # failure codes of the compiled steps (rig/solvers/templates/runs.py)
_NO_TIMES = np.empty(0)             # no output times for a compiled run to sample


class StepEnds(NamedTuple):
    """The steps of a compiled run before its last: their start times ``T`` and states ``Y`` (rows), the first the
    run's start (views of the run's buffers)."""

    T: np.ndarray
    Y: np.ndarray


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


class Stepper(OdeSolver):
    """A one-step method (see the module docstring). Subclasses set ``method`` (the template name in
    :mod:`rig.solvers.templates`), ``label`` (name in messages), ``P`` and ``limit`` (stability boundary on
    the negative real axis of an explicit method; ``inf`` for an implicit one), implement ``_python_step``
    and call :meth:`_start` at the end of their constructor.

    ``stiffness`` ('warn' | 'raise' | 'ignore'): Hairer's stiffness test on every step (explicit methods);
    ``stiff_at`` is the time it first fired. ``compiled=False`` forces the Python step for a ``JitRhs``.
    """

    method: str = ""
    label: str = ""
    P: np.ndarray
    limit: float = math.inf
    fixed: bool = False
    #: steps a compiled run may take before it returns to Python (:meth:`advance`); 256 for the fixed-step methods:
    #: their divergence tests look at each run's steps, and longer runs would change which test reports first
    run_steps: int = 256

    def __init__(self, fun: Rhs, t0: float, y0: Sequence[float], t_bound: float, stiffness: str, compiled: bool):
        super().__init__(fun, t0, y0, t_bound)
        self.monitor = StiffnessMonitor(self.label, self.limit, stiffness, self.fixed)
        self.monitor.origin = (self.t, self.y)
        if not math.isfinite(self.limit):             # implicit: stable on any stiff decay, nothing to report
            self.monitor.policy = "ignore"
        self.f = tuple(fun(self.t, self.y))
        if len(self.f) != len(self.y):
            raise ValueError(f"{self.label}: the right-hand side returned {len(self.f)} components at the start for a "
                             f"state of {len(self.y)}")
        if not all_finite(self.f):
            if isinstance(fun, JitRhs):
                fun.fail(self.t, self.y, "non-finite derivatives at the start")
            raise SolverDivergence("non-finite derivatives at the start", self.t, self.y)
        self.nfev = 1
        self.h_abs = math.nan
        self._K = None
        self._jit = self._run = self._locate = self._values = self._scratch = self._buffers = None
        self._compiled = compiled and isinstance(fun, JitRhs)

    def _start(self, h_abs: float, rtol: float = 0.0, atol: float = 0.0, max_step: float = math.inf,
               positions: Sequence[int] = ()) -> None:
        """Set the first step size (s) and, for a compiled RHS, bind the compiled steps and their work vector."""
        self.h_abs = h_abs
        if self._compiled:
            fun = self.fun
            self._jit, self._run, self._locate, self._values = compiled_solver(self.method, fun.kernel, fun.event,
                                                                                fun.act)
            self._p = fun.params()
            self._ya, self._yb, self._fa = np.array(self.y), np.empty(len(self.y)), np.array(self.f)
            self._w = np.array([self.t, h_abs, self.t_bound, rtol, atol, max_step, float(sum(1 << i for i in positions)),
                                0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, self.t])
        self._bounds = np.empty(0)
        self.breaks_passed = 0

    # ---- steps -------------------------------------------------------------------------------------------
    def _step_impl(self) -> None:
        if self._jit is None:
            return self._python_step()
        w, K = self._w, np.empty((self.P.shape[0], len(self.y)))
        status = self._jit(w, self._ya, self._yb, K, self._fa, self._p)
        self.nfev += int(w[NFEV])
        if status:
            self._fail(status, self.t, self.y, self._yb, float(w[H]), float(w[HL]))
        y = tuple(self._yb.tolist())
        self._accept(float(w[T]), y, float(w[H]), float(w[HL]), K, float(w[H_ABS]))
        self._fa = K[-1]
        self._ya, self._yb = self._yb, self._ya

    def _python_step(self) -> None:
        raise NotImplementedError

    def _accept(self, t_new: float, y_new: tuple, h: float, hl: float, K, h_next: float) -> None:
        """Record an accepted step (stage vectors K, estimate hl of h·|λ|, next step size h_next)."""
        calls = self.monitor.calls
        try:
            self.monitor.update(t_new, y_new, h, hl)
        finally:
            self.nfev += self.monitor.calls - calls          # the amplification test's RHS calls count too
        self.t_old, self.y_old = self.t, self.y
        self.t, self.y, self.f = t_new, y_new, K[-1]
        self.h_last, self.h_abs, self._K = h, h_next, K

    def _fail(self, status: int, t: float, y: Sequence[float], y_bad: Sequence[float], h: float,
              hl: float = math.nan) -> None:
        """Raise for a failed step from (t, y) of size h: step-size underflow, or a non-finite state y_bad."""
        self.status = "failed"
        if status == UNDERFLOW:
            raise self.underflow(t, y, h)
        if math.isfinite(hl):
            self.monitor.last = hl
        raise self.diverged(t + h, y_bad, h, (t, y))

    def underflow(self, t: float, y: Sequence[float], h: float) -> SolverDivergence:
        """The error for a step size that underflowed at (t, y): the method, and why where it can tell — the right-hand
        side not finite just past t (the kernel's diagnosis when a JitRhs has one), else a solution that may blow up
        (a finite-time singularity) or a problem too stiff for the method."""
        what = f"{self.label} step size underflow (h = {h:.3g} s)"
        if isinstance(self.fun, JitRhs):
            why = self.fun.diagnose()
            if why:
                return SolverDivergence(f"{what}: {why}", t, y)
        bad = rhs_not_finite(self.fun, t, y, (max(abs(h), 4.0 * np.finfo(float).eps * max(1.0, abs(t))),
                                              1e-7 * max(1.0, abs(t))))
        if bad is not None:
            return SolverDivergence(f"{what}: {not_finite_text(bad, t)}", t, y)
        other = "" if self.label == "Rodas4" else ", or try the implicit method Rodas4"
        return SolverDivergence(f"{what}: the right-hand side is finite at the last state (|y| = "
                                f"{float(np.max(np.abs(y))):.3g}), yet no step from it passes the error test — the "
                                f"solution may blow up there (a finite-time singularity), the right-hand side may be "
                                f"non-finite or jump just beyond it (where a trial step lands), or the problem is too "
                                f"stiff for {self.label} - check the model there{other}", t, y)

    def diverged(self, t: float, y: Sequence[float], h: float, last: tuple | None = None,
                 what: str = "non-finite state after a step") -> SolverDivergence:
        """The error for a state that became non-finite (or a right-hand side that overflowed: ``what``) after a
        step of size h: names the method, the mode the step amplified (fixed-step methods: at the run's first
        state if it amplifies there — a nonlinear model linearised at a state near overflow would ask for a
        meaningless step —, else at the ``last`` finite (t, y)), or a solution that grows by itself there (a mode
        with Re λ > 0 that the step amplifies no more than the exact flow: a blow-up of the model, which a smaller h
        does not cure), or the latest h·|λ| against the stability limit, and the fix."""
        hl, lim = self.monitor.last, self.limit
        watch = self.monitor.watch
        got = grows = None
        linearised = False                  # the last finite state had a Jacobian
        for point in (self.monitor.origin, last) if watch is not None else ():
            if point is not None:
                got = watch.check(point[0], point[1], h)
                if got is not None and got[0] > 1.0 and got[0] > got[1] * (1.0 + self.monitor.EXCESS):
                    break
                if point is last and got is not None:
                    linearised = True
                    grows = (point[0], point[1], math.log(got[1]) / h) if got[1] > 1.0 + 1e-12 else None
                got = None
        if not linearised:                  # a state near overflow has no Jacobian: the latest check's growth, if any
            grows = self.monitor.growing
        if grows is not None and grows[2] * (t - grows[0]) < 1.0:    # the growth must explain the overflow (an e-fold
            grows = None                                            # or more by t; else the method, not the model)
        if got is not None:
            rho, lam = got[0], got[2]
            where = "from the run's start, " if point is self.monitor.origin else ""
            cause = (f"{self.label} unstable {where}at t = {point[0]:.6g} s: the step amplified the mode lambda = "
                     f"{lam.real:.4g}{lam.imag:+.4g}j 1/s by {rho:.4g} per step (h*|lambda| = {h * abs(lam):.3g}) - "
                     f"reduce h below {watch.largest_stable_step(point[0], point[1], h):.3g} s or use the implicit "
                     f"method Rodas4")
            hl = math.inf                    # an unstable step: reported as such
        elif last is not None and (bad := rhs_not_finite(self.fun, last[0], last[1], (0.0, 0.5 * h, h))) is not None:
            cause = not_finite_text(bad, last[0])      # no mode amplified: the model, not the method
            hl = -math.inf                   # so reported, whatever the step's h·|λ|
        elif grows is not None:
            cause = (f"the solution itself grows without bound: at t = {grows[0]:.6g} s (|y| = "
                     f"{float(np.max(np.abs(grows[1]))):.3g}) a mode with Re lambda = {grows[2]:.4g} 1/s grows, and "
                     f"the step amplifies it no more than the exact flow does - the model blows up there (a "
                     f"finite-time singularity or an unstable model), not the method: check the model")
            hl = -math.inf                   # the model, whatever the step's h·|λ|
        elif hl > lim:
            cause = (f"{self.label} unstable: h*|lambda| = {hl:.3g} > {lim:g} (its stability limit on the negative "
                     f"real axis) - reduce h below {lim * h / hl:.3g} s or use the implicit method Rodas4")
        elif math.isfinite(lim):
            cause = (f"h*|lambda| = {hl:.3g} on the last step ({self.label} is stable up to {lim:g} on the negative "
                     f"real axis, less for lightly damped oscillations): reduce h or use the implicit method "
                     f"Rodas4, unless the model itself diverges")
        else:
            cause = "the model itself diverges"
        why = self.fun.diagnose() if isinstance(self.fun, JitRhs) else None
        kind = StiffnessError if hl > lim else SolverDivergence      # unstable step: the stiffness report's class
        return kind(f"{self.label} diverged: {what} of h = {h:.3g} s; {cause}"
                    + (f" ({why})" if why else ""), t, y)

    # ---- compiled runs -----------------------------------------------------------------------------------
    @property
    def can_advance(self) -> bool:
        """True when :meth:`advance` is available (compiled RHS with an event kernel)."""
        return self._run is not None

    def advance(self, g: np.ndarray, max_steps: int | None = None, times: np.ndarray = _NO_TIMES,
                out: np.ndarray | None = None, first: int = 0) -> StepEnds | None:
        """Take accepted steps in one compiled call until an event value (``g``: at the current point, in
        the order of the RHS's event kernel; updated in place to the values at the last step's start)
        changes sign, t_bound is reached or ``max_steps`` (default :attr:`run_steps`) are taken. The solver then
        stands after the last step as after :meth:`step`; returns the steps before it (their times and states, valid
        until the next call: the buffers are reused), or None. With output ``times`` (s,
        increasing) and ``out`` (states × times), the steps fill out[:, i] for the times from index ``first`` on
        that they pass, but for the last one when an event's sign changed in it (the caller's, who examines its
        events); ``sampled`` is then the index of the first time not filled."""
        n = len(self.y)
        max_steps = self.run_steps if max_steps is None else max_steps
        if out is None:
            times, out = _NO_TIMES, np.empty((n, 0))
        elif out.shape != (n, times.size):
            raise ValueError(f"advance: out has shape {out.shape}, the states at the times need ({n}, {times.size})")
        if self._buffers is None or self._buffers[0].shape[0] != max_steps + 1 or self._scratch[1].size != g.size:
            self._buffers = (np.empty((max_steps + 1, n)), np.empty(max_steps + 1), np.empty(max_steps),
                             np.empty((max_steps, self.P.shape[0], n)), np.empty(max_steps),
                             np.empty((max_steps, 3 + n)))
            self._scratch = run_scratch(n, g.size, self.P.shape[0], self.P.shape[1], self._p.size)
        Y, TT, HH, KK, HL_, EV = self._buffers
        Y[0], KK[0, 0] = self._ya, self._fa
        self._w[IE] = first
        count = self._run(self._w, Y, TT, HH, KK, HL_, EV, g, self._p, self._bounds, *self._scratch, times, out)
        self.sampled = int(self._w[IE])
        self.nfev += int(self._w[NFEV])
        self.breaks_passed, self.t_bound = int(self._w[NBREAK]), float(self._w[T_BOUND])
        self.acted = EV[:int(self._w[NEV])].copy()
        done = count if count >= 0 else -1 - count
        calls = self.monitor.calls
        try:
            self.monitor.update_many(TT[1:done + 1], Y[1:done + 1], HH[:done], HL_[:done])
        except SolverDivergence:
            self.status = "failed"
            raise
        finally:
            self.nfev += self.monitor.calls - calls          # the amplification test's RHS calls count too
        if count < 0:
            self._fail(int(self._w[FAIL]), float(TT[done]), tuple(Y[done]), tuple(Y[done + 1]), float(self._w[H]))
        self.nsteps += count
        if TT[count] >= self.t_bound:
            self.status = "finished"
        last = count - 1
        self.t_old, self.y_old = float(TT[last]), tuple(Y[last].tolist())
        self.t, self.y = float(TT[count]), tuple(Y[count].tolist())
        self._K, self._yo = KK[last].copy(), Y[last].copy()
        self.f = self._fa = self._K[-1]
        self._ya = Y[count].copy()
        self.h_last, self.h_abs = float(self._w[H]), float(self._w[H_ABS])
        return StepEnds(TT[:count], Y[:count]) if last else None

    def pass_breaks(self, bounds: Sequence[float]) -> None:
        """Let :meth:`advance` go on past t_bound, a time break of the problem, to the later ``bounds`` (s, increasing,
        the last the span's end): each passed as :func:`rig.solvers.integrate` passes one (a restart one ulp past
        it), counted in ``breaks_passed``, ``t_bound`` the next one."""
        self._bounds = np.array(bounds, dtype=float)
        self._w[NBREAK] = 0.0
        self.breaks_passed = 0

    def locate(self, k: int) -> float:
        """Root of event k (the RHS's event kernel) in the last step taken by :meth:`advance`, which
        changes sign over it (compiled Brent search on the dense output)."""
        return self._locate(self.t_old, self.t, self._yo, self._K, self._p, k)

    def event_values(self, t: float, y: Sequence[float], n: int) -> list[float]:
        """The values of the RHS's n event kernels at (t, y), in one compiled call (with :meth:`advance`)."""
        out = np.empty(n)
        self._values(t, np.asarray(y, dtype=float), self._p, out)
        return out.tolist()

    @property
    def stiff_at(self) -> float | None:
        return self.monitor.detected_at

    def dense_output(self) -> PolynomialDense:
        return PolynomialDense(self.t_old, self.t - self.t_old, self.y_old, self._K, self.P)

    def state_at(self, t: float) -> tuple:
        """State at time t within the last step, by one step of the method (its error control on, Python or
        compiled) from the step's start landing on t: it carries the step's error, not the dense output's (one
        order lower); the dense output's value if that step is refused. Where an event acts (a restart, a mode
        switch) the state is taken this way, in the compiled runs too (``land`` in
        :mod:`rig.solvers.templates.runs`)."""
        if not t > self.t_old:
            return self.y_old
        if t >= self.t:
            return self.y
        one = type(self)(self.fun, self.t_old, self.y_old, t, first_step=(t - self.t_old) * (1.0 + 1e-9),
                         stiffness="ignore", compiled=self._compiled, **self._options())
        one.step()
        self.nfev += one.nfev
        if abs(one.t - t) <= 4.0 * np.finfo(float).eps * max(1.0, abs(t)):
            return one.y
        return tuple(self.dense_output()(t))

    def _options(self) -> dict:
        """Constructor options of a subclass beyond those of this class (error control of adaptive methods)."""
        return {"rtol": self.rtol, "atol": self.atol, "max_step": self.max_step}


class AdaptiveStepper(Stepper):
    """An error-controlled method: ``rtol``, ``atol`` (its error norm), ``first_step`` (s; default Hairer's heuristic
    for an error estimator of order ``error_order``), ``max_step`` (s); ``stiffness`` defaults to the class's
    ``default_stiffness``. Subclasses implement ``_python_step``."""

    error_order: int = 4
    run_steps = 1024            # fewer returns to Python per integration (≈ 2 % of a level-2 revolution)
    default_stiffness: str = "warn"
    #: the step-size controller (:func:`~rig.solvers.control.step_factor`), set by each method: safety factor,
    #: bounds of the factor on |h|, exponent −1/(error_order + 1); whether an error norm of exactly 1 is accepted
    safety: float
    min_factor: float
    max_factor: float
    exponent: float
    accept_one: bool = False

    def __init__(self, fun: Rhs, t0: float, y0: Sequence[float], t_bound: float, rtol: float = 1e-6,
                 atol: float = 1e-9, first_step: float | None = None, max_step: float = math.inf,
                 stiffness: str | None = None, compiled: bool = True):
        check_step_options(type(self).__name__, rtol, atol, first_step, max_step)
        super().__init__(fun, t0, y0, t_bound, self.default_stiffness if stiffness is None else stiffness, compiled)
        self.rtol, self.atol, self.max_step = rtol, atol, max_step
        if first_step is None or not first_step > 0:          # None, 0, NaN (a run's h_last before any step)
            h_abs = initial_step(fun, self.t, self.y, self.f, self.error_order, rtol, atol, self.t_bound)
            self.nfev += 1
        else:
            h_abs = min(first_step, self.t_bound - self.t)
        self._start(h_abs, rtol, atol, max_step)

    def _trial(self, h_abs: float) -> tuple[float, float]:
        """(h, t_new) of a trial step of size ``h_abs`` from ``t``, cut to land on t_bound; a step-size underflow
        raises :class:`SolverDivergence`."""
        if not h_abs >= self._min_step():                  # NaN too: it never ends a loop otherwise
            raise self.underflow(self.t, self.y, h_abs)
        t_new = self.t + h_abs
        if t_new >= self.t_bound:
            return self.t_bound - self.t, self.t_bound
        return h_abs, t_new

    def _adapt(self, attempt: Callable[[float, float], tuple[float, Any]]) -> tuple[float, float, float, Any]:
        """Trial steps until one is accepted: ``attempt(h, t_new)`` returns the trial's error norm (NaN or inf
        when its state is not finite) and what the caller keeps of it; returns (h, t_new, next |h|, that).
        A rejected or non-finite trial (one whose right-hand side raised OverflowError included) shrinks |h| (a
        non-finite one by ``min_factor``); no growth right after a rejection (as scipy)."""
        h_abs = min(self.h_abs, self.max_step)
        rejected = False
        while True:
            h, t_new = self._trial(h_abs)
            try:
                err, kept = attempt(h, t_new)
            except OverflowError:               # a Python RHS overflowing on a trial stage (x**2 of a huge x; x*x
                err, kept = math.nan, None      # gives inf): a rejected trial, as a non-finite one
            if not math.isfinite(err):
                h_abs *= self.min_factor
                rejected = True
                continue
            accepted = err <= 1.0 if self.accept_one else err < 1.0
            factor = step_factor(err, accepted, rejected, self.exponent, self.safety, self.min_factor,
                                 self.max_factor)
            if accepted:
                return h, t_new, h_abs * factor, kept
            h_abs *= factor
            rejected = True


class FixedStepper(Stepper):
    """A fixed-step method: steps ``h`` (s) on the grid t0 + k·h, the last shortened (or stretched by < 1e-6·h) to
    land on t_bound; no error control. ``first_step`` is accepted for interface compatibility and ignored. A step
    size beyond the method's stability limit is reported by the stiffness test as divergence
    (``stiffness="raise"``, the default: :class:`~rig.solvers.base.StiffnessError` naming h·|λ| and the fix)
    and a non-finite state raises :class:`~rig.solvers.base.SolverDivergence` likewise."""

    fixed = True

    def __init__(self, fun: Rhs, t0: float, y0: Sequence[float], t_bound: float, h: float = 1e-3,
                 first_step: float | None = None, stiffness: str = "raise", compiled: bool = True,
                 positions: Sequence[int] = ()):
        super().__init__(fun, t0, y0, t_bound, stiffness, compiled)
        if not 0 < h < math.inf:
            raise ValueError(f"{self.label}: step h = {h!r} s must be positive and finite")
        self.h, self.t0 = h, self.t   # steps on the grid t0 + k·h
        self._start(h, positions=positions)
        self.monitor.watch = Amplification(fun, self.method, positions)
        self.check_at_end = True        # the amplification test once more on reaching t_bound (integrate() does it
                                        # itself at the end of the whole run, over its segments)

    def step(self) -> None:
        """One step; on reaching t_bound, the amplification test over the steps since its last check (a run of fewer
        steps than the first check, driven step by step, returned RK4 at h·ω = 4 grown 25 000-fold, silently)."""
        super().step()
        if self.status == "finished" and self.check_at_end:
            calls = self.monitor.calls
            try:
                self.monitor.finish(self.t, self.y)
            finally:
                self.nfev += self.monitor.calls - calls

    def state_at(self, t: float) -> tuple:
        """State at time t within the last step, by one step of size t − t_old from its start (the same
        method, Python or compiled) — exact to the method's order even where the RHS jumps after t; in the
        compiled runs too."""
        if not t > self.t_old:
            return self.y_old
        if t - self.t_old < self._min_step(self.t_old):    # no step that short: the interpolant (an event a few ulp
            return tuple(self.dense_output()(t))            # past a time break, where the solver restarted)
        one = type(self)(self.fun, self.t_old, self.y_old, t, h=t - self.t_old,
                         stiffness="ignore", compiled=self._compiled, **self._options())
        one.step()
        self.nfev += one.nfev
        return one.y

    def _options(self) -> dict:
        """Constructor options of a subclass beyond those of :class:`FixedStepper`."""
        return {}

    def _fixed_h(self) -> tuple[float, float]:
        """(h, t_new) of the next step (as the compiled ``fixed_step``: on the grid t0 + k·h from the start)."""
        t, h, t0 = self.t, self.h, self.t0
        t_new = t0 + (math.floor((t - t0) / h + 0.5) + 1.0) * h
        if self.t_bound - t_new < 1e-6 * h:
            h, t_new = self.t_bound - t, self.t_bound
        if not h >= self._min_step():
            raise SolverDivergence(f"{self.label}: step size underflow (h = {h:.3g} s): the span to t_bound = "
                                   f"{self.t_bound!r} s is shorter than 10 ulp (two time breaks or events that "
                                   "close: merge them in the problem)", t, self.y)
        return h, t_new

    def _finish(self, t_new: float, y_new: tuple, h: float, stages: tuple, hl: float | None = None) -> None:
        """Accept a Python step with its stage vectors (all rows of K but the last, f(t_new, y_new), which is
        evaluated here) and its estimate of h·|λ| (default h·‖f_new − f‖/‖y_new − y‖), or raise
        :meth:`diverged` for a non-finite state."""
        if not all_finite(y_new):
            self._fail(NONFINITE, self.t, self.y, y_new, h, math.nan if hl is None else hl)
        f_new = tuple(self.fun(t_new, y_new))
        self.nfev += 1
        if hl is None:
            hl = h * lipschitz(f_new, self.f, y_new, self.y)
        self._accept(t_new, y_new, h, hl, (*stages, f_new), self.h)
