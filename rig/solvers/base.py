"""Common parts of the ODE solvers: base class, divergence error, step-size helpers.

States are tuples of floats (pure Python is much faster than numpy for 4–6 states); right-hand sides
``fun(t, y) -> sequence of floats`` must accept tuples.
"""
from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Callable, Sequence
from numbers import Real
from typing import Any

import numpy as np

Rhs = Callable[[float, tuple], Sequence[float]]


class SolverDivergence(RuntimeError):
    """The solution became non-finite or the step size underflowed; the message names time and state."""

    def __init__(self, what: str, t: float, y: Sequence[float]):
        state = ", ".join(f"{v:.6g}" for v in y)
        super().__init__(f"solver diverged: {what}; state at t = {t:.9g} s: ({state})")
        self.t = t
        self.y = tuple(y)


RTOL_MIN = 100.0 * np.finfo(float).eps      # the tightest relative tolerance taken (scipy's floor)


def check_step_options(name: str, rtol: Any, atol: Any, first_step: Any, max_step: Any) -> None:
    """An adaptive method's options named when they cannot work (scipy's words where it has them): ``rtol`` and
    ``atol`` real scalars, rtol > 0 and finite, atol > 0 and finite (with atol = 0 a component at 0 has no error scale);
    ``max_step`` > 0 (inf: no limit); ``first_step`` None, 0 or NaN (chosen by Hairer's heuristic) or positive and
    finite."""
    def real(value: Any) -> bool:
        return isinstance(value, Real) and not isinstance(value, bool)

    for key, value in (("rtol", rtol), ("atol", atol), ("max_step", max_step)):
        if not real(value):
            raise ValueError(f"{name}: {key} = {value!r} must be a real number (one for every component)")
    if not RTOL_MIN <= rtol < math.inf:
        raise ValueError(f"{name}: rtol = {rtol!r} must be finite and at least {RTOL_MIN:.3g} (100 ulp: no step meets "
                         "a tighter one in double precision)")
    if not 0.0 < atol < math.inf:
        raise ValueError(f"{name}: atol = {atol!r} must be positive and finite (with atol = 0 a state component at 0 "
                         "has no error scale)")
    if not max_step > 0:
        raise ValueError(f"{name}: max_step = {max_step!r} s must be positive (inf: no limit)")
    if first_step is not None and (not real(first_step) or first_step < 0 or first_step == math.inf):
        raise ValueError(f"{name}: first_step = {first_step!r} s must be positive and finite (None, 0 or NaN: chosen "
                         "by Hairer's heuristic)")


def rhs_not_finite(fun: Callable, t: float, y: Sequence[float], ahead: Sequence[float]) -> float | None:
    """The first time t + a (a in ``ahead``, s) where the right-hand side at the state ``y`` is not finite or raises an
    arithmetic error, the state being of moderate size (|y| < 1e100: NaN or inf from a state near the float range —
    inf/inf — is the solution's growth); else None: a step that failed there failed on the model, not the method."""
    if not float(np.max(np.abs(y))) < 1e100:
        return None
    for a in ahead:
        try:
            if not all_finite(fun(t + a, tuple(y))):
                return t + a
        except (ArithmeticError, SolverDivergence):
            return t + a
    return None


def not_finite_text(bad: float, t: float) -> str:
    """What a failed step from ``t`` (an underflow, a non-finite state) is when the right-hand side is not finite at
    ``bad``, just past it (or at it)."""
    return (f"the right-hand side is not finite at t = {bad:.9g} s, just past t = {t:.9g} s (NaN or inf from the "
            f"model there: outside its range, or a singularity) - check the model there")


def all_finite(y: Sequence[float]) -> bool:
    """True when every component is finite (a sum overflowing past 1e308 also counts as divergence)."""
    return math.isfinite(sum(y))


class StiffnessWarning(RuntimeWarning):
    """An explicit solver's step size is limited by stability (h·|λ| beyond its stability boundary)."""


class StiffnessError(SolverDivergence):
    """Raised instead of :class:`StiffnessWarning` when a solver is built with ``stiffness="raise"``."""


class ResolutionWarning(RuntimeWarning):
    """A fixed-step method, stable, steps a persistent mode so coarsely that its error there has grown to a large
    share of the mode (a heavily damped, phase-shifted or decayed oscillation): the answer may be wrong."""


#: order in h of the fixed-step methods' error on a mode per step (the accuracy warning's suggested step): explicit
#: Euler h², symplectic Euler's phase h³, RK4 h⁵
STEP_ORDERS = {"euler": 2, "symplectic_euler": 3, "rk4": 5}


#: what keeps a fixed-step method stable on a lightly damped mode ω_n, ζ (for the amplification report)
STABLE_WHEN = {"explicit Euler": "explicit Euler needs h*omega_n < 2*zeta",
               "symplectic Euler": "symplectic Euler needs h*omega_n < 2 on an undamped mode",
               "RK4": "RK4 needs h*|lambda| inside its stability region, 2.78 on the negative real axis, 2.83 on "
                      "the imaginary one"}


class StiffnessMonitor:
    """Hairer's stiffness test for explicit RK: h·|λ| ≈ h·‖f(Y_a) − f(Y_b)‖/‖Y_a − Y_b‖ from two stages
    evaluated at (nearly) the same point. ``limit`` = stability boundary of the method on the negative
    real axis; 15 consecutive steps beyond it report stiffness ('warn', 'raise' or 'ignore'). For a
    ``fixed``-step method that means the solution diverges: the report says so and how to fix it; such a
    method is also watched for exponential growth of its step increments max|y_new − y| (doubling over
    each of ``GROWTH_WINDOWS`` consecutive windows of ``GROWTH_STEPS`` steps), the signature of an
    oscillatory mode outside its stability region (explicit Euler: h·ω_n > 2ζ, although h·|λ| < 2).
    ``last`` is the latest estimate of h·|λ| (for the messages of a diverged step)."""

    STEPS = 15
    GROWTH_STEPS, GROWTH_WINDOWS = 50, 6
    #: amplification test of a fixed-step method (``watch``, :class:`rig.solvers.amplification.Amplification`):
    #: every SPARSE steps, every DENSE steps after a positive check; a report at a spurious growth of SPURIOUS (2-fold:
    #: at 10 % the test's own estimate on the worn-pins level 2 — symplectic Euler at 5 µs, which converges — summed to
    #: 1.18 in 0.2 s and stopped the run; explicit Euler on an undamped mode at h·ω = 0.1 thus grows 1.65-fold over ten
    #: periods unreported)
    SPARSE, DENSE, SPURIOUS = 100, 10, 2.0
    #: growth per step beyond the exact flow's that counts (1e-4: +10 % in 1000 steps; explicit Euler on an
    #: undamped oscillation at a small h·ω grows by (h·ω)²/2 per step, which convergence studies accept)
    EXCESS = 1e-4
    #: accuracy test at the same checks, on the persistent modes the method does not amplify
    #: (:func:`rig.solvers.amplification.mode_errors`): one :class:`ResolutionWarning` per run where the error per step
    #: reaches STEP_ERROR of the mode (RK4 at h·ω ≳ 1.45, symplectic Euler ≳ 1.05), or where, over the mode's life
    #: (its lifetime, at most the steps so far), the method's spurious decay has halved it (SPURIOUS) or its phase
    #: error reached PHASE rad, a fifth of a radian (RK4 at h·ω = 1 damps an undamped mode by 0.6 % per step: to 1e-3 in 1000 steps;
    #: symplectic Euler at 0.1 turns 4e-5 rad per step too many: 0.4 rad in 10 000). Not the plain error summed
    #: over the life (tried): on level 2 that flagged every converged run, the contact mode (ζ ≈ 0.16) being barely
    #: excited — the linearisation cannot tell how much of a mode the answer holds. The suggested step takes each
    #: fault of the mode to TARGET_ERROR / STEP_ERROR (a tenth) of its limit, with the fault's order in h, the summed
    #: ones extrapolated to the run's end (``horizon``, set by :func:`rig.solvers.integrate`)
    STEP_ERROR, PHASE, TARGET_ERROR = 0.05, 0.2, 0.005
    #: relative error on modes the exact flow grows, summed over the steps between the checks that find one (the
    #: method's error compounds while the mode grows): one :class:`ResolutionWarning` at GROWN_ERROR (5 %, half of
    #: where the stability map calls a run's error silent: an inverted pendulum falling from 1e-8 rad under explicit
    #: Euler at 1 ms reaches it at t ≈ 1.1 s, and its speed is later 20 % off); the suggested step takes it to a tenth.
    #: Summed per episode of growth: a check that finds none ends it, and an episode's first check counts at most
    #: DENSE steps (of the up to SPARSE since the check before: it may start late in them)
    GROWN_ERROR = 0.05

    def __init__(self, method: str, limit: float, policy: str = "warn", fixed: bool = False):
        if policy not in ("warn", "raise", "ignore"):
            raise ValueError(f"{method}: stiffness = {policy!r} must be 'warn', 'raise' or 'ignore'")
        self.method, self.limit, self.policy, self.fixed = method, limit, policy, fixed
        self.count = self.calm = 0
        self._recent: list[float] = []               # the latest estimates beyond the limit
        self.detected_at: float | None = None
        self.last = math.nan
        self._y: np.ndarray | None = None            # growth test: last state, current window, growing windows
        self._window = [0, 0.0, 0.0, 0]               # steps, max increment, previous window's max, growing
        self.watch = None                              # amplification test (fixed-step methods)
        self.origin: tuple | None = None               # the run's first (t, y), for the divergence report
        self.horizon = math.nan                        # the run's end (s), when known: the accuracy advice's span
        self._steps, self._next_check, self._last_check = 0, self.DENSE, -1    # index of the step checked last
        self._h_since = 0.0                            # the largest step taken since the last check (s)
        self._hot: list[int] = []                      # steps of the current batch whose h·|λ| passed the limit
        self._hits = [0, 0, 0.0]                       # positive and negative checks, summed spurious log-growth
        self._slow = 0.0                               # net spurious log-growth however small per step (see below)
        self._drift = 0.0                              # summed relative error on a growing mode (GROWN_ERROR)
        self._grew = False                             # whether the latest check found a mode growing
        self.calls = 0                                 # RHS calls the amplification test made
        self.growing = None                            # (t, y, Re λ) of the latest check if a mode grew by itself
        self.coarse: str | None = None                 # the accuracy warning, once given

    def update_many(self, t, y, h, hl) -> None:
        """:meth:`update` for consecutive steps (arrays; rows of ``y``); calm runs are skipped at once."""
        hl = np.asarray(hl, dtype=float)
        known = hl[np.isfinite(hl)]
        if known.size:
            self.last = float(known[-1])
        if self.policy == "ignore" or self.detected_at is not None:
            return
        if self.fixed and len(t):
            self._amplification(t, y, h, hl)        # first: its checks say whether a mode grows by itself
            if self.detected_at is None:
                self._growth(t, np.asarray(y, dtype=float), h)
            return
        if self.count == 0 and (known.size == 0 or known.max() <= self.limit):
            self.calm += len(hl)
            return
        k = self._stiffness_many(hl)
        if k is not None:                         # the step that reports (once per run)
            self._stiffness(float(t[k]), tuple(y[k]), float(h[k]), float(hl[k]))

    def update(self, t: float, y: tuple, h: float, hl: float) -> None:
        """Update with an estimate ``hl`` of h·|λ| for a step of size h ending at (t, y); a non-finite estimate
        (states near overflow) carries no information."""
        if math.isfinite(hl):
            self.last = hl
        if self.policy == "ignore" or self.detected_at is not None:
            return
        if self.fixed:
            self._amplification([t], [y], [h], [hl])
            if self.detected_at is None:
                self._growth([t], np.array([y], dtype=float), [h])
            return
        self._stiffness(t, y, h, hl)

    def _stiffness_many(self, hl: np.ndarray) -> int | None:
        """:meth:`_stiffness` over a batch of estimates at once: the state it leaves after the batch, or, when a step
        of the batch reports, the state before that step and its index (the caller then takes it by
        :meth:`_stiffness`). Non-finite estimates are skipped, as there; an estimate above the limit counts, six
        calm ones in a row reset the count."""
        where = np.flatnonzero(np.isfinite(hl))
        v = hl[where]
        if not v.size:
            return None
        pos = np.arange(v.size)
        above = v > self.limit
        last_above = np.maximum.accumulate(np.where(above, pos, -1))
        calm = np.where(last_above >= 0, pos - last_above, self.calm + pos + 1)      # calm estimates in a row
        reset = ~above & (calm >= 6)
        last_reset = np.maximum.accumulate(np.where(reset, pos, -1))
        counted = np.cumsum(above)
        count = np.where(last_reset >= 0, counted - counted[np.maximum(last_reset, 0)], self.count + counted)
        hits = np.flatnonzero(above & (count >= self.STEPS))
        end = int(hits[0]) if hits.size else v.size       # the state is taken before this estimate
        if end == 0:
            return int(where[0])
        i = end - 1
        start = int(last_reset[i]) + 1                     # the estimates counted since the last reset
        carried = self._recent if last_reset[i] < 0 else []
        self._recent = (carried + v[start:end][above[start:end]].tolist())[-self.STEPS:]
        self.count = int(count[i])
        self.calm = 0 if above[i] else int(calm[i])
        if reset[i]:
            self.count, self._recent = 0, []
        return int(where[end]) if hits.size else None

    def _stiffness(self, t: float, y: tuple, h: float, hl: float) -> None:
        if not math.isfinite(hl):
            return
        if hl <= self.limit:
            self.calm += 1
            if self.calm >= 6:
                self.count, self._recent = 0, []
            return
        self.calm = 0
        self.count += 1
        self._recent = (self._recent + [hl])[-self.STEPS:]
        if self.count < self.STEPS:
            return
        lam = hl / h
        self._report(t, y, f"{self.method}: problem is stiff at t = {t:.6g} s: h*|lambda| above {self.limit} for "
                           f"{self.STEPS} steps ({min(self._recent):.4f} … {max(self._recent):.4f}; h = {h:.3g} s, "
                           f"|lambda| = {lam:.3g} 1/s); the "
                           f"step size is limited by stability, not accuracy - use the implicit method Rodas4 or "
                           f"remove the stiffness (e.g. a switched stick-slip friction model instead of a steep "
                           f"regularisation)")

    def _amplification(self, t, y, h, hl=()) -> None:
        """Run the amplification test on the steps due among these (ends t, states y, sizes h, Hairer's estimates hl
        of h·|λ|): every SPARSE steps, every DENSE after a positive check, and at a step whose estimate passed the
        method's limit (at most every DENSE steps: a stiff mode that acts only part of the time — a contact between
        flights across a clearance — is looked at while it acts, not only where a schedule happens to fall). The spurious
        growth log(ρ(M)/ρ(exp(hJ))) is summed over the steps between positive checks; a report once it reaches
        a factor ``SPURIOUS`` over at least two positive checks (more checks where the method damps than positive
        ones since the first positive one start over; neutral states, e.g. no stiff mode, do not count). Growth
        below ``EXCESS`` per step is also summed, net of where the method damps (ρ < 1), and reported once it has
        amplified the mode by ``SPURIOUS`` — explicit Euler on an undamped oscillation at a small h·ω grows by only
        (h·ω)²/2 per step, but over enough steps that too is a wrong answer."""
        if self.watch is None or self.detected_at is not None:
            return
        first = self._steps
        self._steps += len(t)
        over = np.asarray(hl, dtype=float) > self.limit
        self._hot = (first + np.flatnonzero(over)).tolist() if over.any() else []
        self._pull_check()
        if self._next_check >= self._steps:            # no check due among these steps (most calls): the largest
            self._h_since = max(self._h_since, _largest(h))     # step since the last one, for finish()
            return
        checked = self._last_check
        try:
            self._check_due(first, t, y, h)
        finally:                                       # the steps after the last check: what finish() tests
            after = max(0, self._last_check + 1 - first) if self._last_check != checked else 0
            largest = _largest(h[after:])
            self._h_since = largest if self._last_check != checked else max(self._h_since, largest)

    def _check_due(self, first: int, t, y, h) -> None:
        """The checks due among the steps ``first``… (see :meth:`_amplification`)."""
        while self._next_check < self._steps:
            k = self._next_check - first
            after = self._last_check - first + 1       # the steps since the last check: tested at the largest (a
            h_k = max(_largest(h[max(after, 0):k + 1]), self._h_since if after <= 0 else 0.0)   # check landing on a
            got = self.watch.check(float(t[k]), tuple(y[k]), h_k,    # run's cut last step missed the full ones);
                                   self._steps_by_end(float(t[k]), self._next_check + 1)
                                   if math.isfinite(self.horizon) else math.inf)
            #                                                         the run's length unknown: no short-run test
            self.calls += len(y[k]) + 1
            self._note_growth(float(t[k]), tuple(y[k]), h_k, got)
            since, self._last_check = self._next_check - self._last_check, self._next_check
            self._accuracy(float(t[k]), h_k, got, self._next_check + 1, since)    # the steps up to the checked one
            if got is not None and got[0] > 1.0 + 1e-12 and got[0] > got[1]:
                self._slow += since * math.log(got[0] / got[1])
            elif got is not None and 0.0 < got[0] < 1.0:
                self._slow = max(0.0, self._slow + since * math.log(got[0]))
            if self._slow >= math.log(self.SPURIOUS):
                self._report_amplification(float(t[k]), tuple(y[k]), h_k, got, self._slow)
                return
            if got is not None and got[0] > 1.0 + 1e-12 and got[0] > got[1] * (1.0 + self.EXCESS):
                self._hits[0] += 1
                self._hits[2] += since * math.log(got[0] / got[1])
                if self._hits[0] >= 2 and self._hits[2] >= math.log(self.SPURIOUS):
                    self._report_amplification(float(t[k]), tuple(y[k]), h_k, got)
                    return
            elif self._hits[0] and got is not None and got[0] < 1.0:    # the method damps here (free flight
                self._hits[1] += 1                                       # between contacts is neutral)
                if self._hits[1] > self._hits[0]:
                    self._hits = [0, 0, 0.0]
            self._next_check += self.DENSE if self._hits[0] else self.SPARSE
            self._pull_check()

    def _pull_check(self) -> None:
        """Bring the next check forward to the first step of :attr:`_hot` (estimates beyond the limit) at least DENSE
        steps after the last check."""
        hot = self._hot
        while hot and hot[0] < self._last_check + self.DENSE:
            hot.pop(0)
        if hot and hot[0] < self._next_check:
            self._next_check = hot[0]

    def finish(self, t: float, y: Sequence[float]) -> None:
        """End of a run at (t, y): the amplification test of a fixed-step method once more over the steps since its
        last check, at the largest step among them (the steps a run takes, cut at time breaks or shorter than h, not
        the nominal h). A run shorter than the first check (10 steps) or than the next one was otherwise never
        tested: RK4 at h·|λ| = 5 returned 2e11 for a decay to 2e-22 after 10 steps, silently."""
        if not self.fixed or self.watch is None or self.detected_at is not None or self.policy == "ignore":
            return
        since, h = self._steps - 1 - self._last_check, self._h_since     # the steps after the one checked last
        if since <= 0 or not h > 0.0:
            return
        got = self.watch.check(float(t), tuple(y), float(h), self._steps)
        self.calls += len(y) + 1
        self._accuracy(float(t), float(h), got, self._steps, since)
        self._last_check = self._steps - 1
        if got is not None and got[0] > 1.0 + 1e-12 and got[0] > got[1]:
            grown = self._slow + since * math.log(got[0] / got[1])
            if grown >= math.log(self.SPURIOUS):
                self._report_amplification(float(t), tuple(y), float(h), got, grown)

    def _note_growth(self, t: float, y: tuple, h: float, got) -> None:
        """Note in :attr:`growing` whether the latest check (at (t, y), step h) found a mode the exact flow grows: (t,
        y, its largest Re λ in 1/s) — the solution grows by itself there
        (:meth:`rig.solvers.stepper.Stepper.diverged` names it if the run then overflows) —, else None."""
        self.growing = (t, y, math.log(got[1]) / h) if got is not None and got[1] > 1.0 + 1e-12 \
            and got[0] <= got[1] * (1.0 + self.EXCESS) else None

    def _steps_by_end(self, t: float, steps: int) -> float:
        """The steps the run will have taken by its end (:attr:`horizon`) at the pace of the ``steps`` it took up to
        time ``t``."""
        t0 = self.origin[0] if self.origin is not None else t
        return steps * (self.horizon - t0) / (t - t0) if self.horizon > t > t0 else steps

    def _accuracy(self, t: float, h: float, got, steps: int, since: int) -> None:
        """The accuracy test on a check's persistent modes (see :data:`STEP_ERROR`) and on the modes it finds growing
        (:data:`GROWN_ERROR`, their error summed per episode of growth: over the ``since`` steps since the last check,
        at most DENSE of them at an episode's first check; a check without one ends it): one warning per run
        naming the mode, its steps per period, what the method does to it, and a step that takes each of its faults to
        a tenth of its limit by the run's end."""
        if got is None or self.coarse is not None:
            return
        err, decay, phase, growth, life, lam, drift = got[3]
        if not err.size:
            return
        grown = int(np.argmax(drift)) if drift.max() > 0.0 else None
        if grown is None:                  # an episode of growth is over: a model that damps between them (a
            self._drift = 0.0              # two-well oscillator crossing its saddle) does not sum its episodes
        else:                              # a new episode counts from at most DENSE steps before its first check
            self._drift += (since if self._grew else min(since, self.DENSE)) * float(drift[grown])
        self._grew = grown is not None
        span = np.minimum(life, steps)
        order = STEP_ORDERS.get(self.watch.method, 2)
        # (values, limit, exponent in h — an error summed over the mode's life in a given time has one order
        # fewer —, wording)
        faults = [(err, self.STEP_ERROR, order, lambda v, n: f"an error of {v:.2g} of the mode per step"),
                  (decay * span, math.log(self.SPURIOUS), order - 1,
                   lambda v, n: f"a spurious decay to {math.exp(-v):.2g} of the mode over the {n:.0f} steps it has lived"),
                  (phase * span, self.PHASE, order - 1,
                   lambda v, n: f"a phase error of {v:.2g} rad over the {n:.0f} steps it has lived"),
                  # a growth short of the amplification test's report (SPURIOUS): that one says "unstable"
                  (np.where(growth * span < math.log(self.SPURIOUS), growth * span, 0.0), self.PHASE, order - 1,
                   lambda v, n: f"a spurious growth to {math.exp(v):.3g} times the mode over the {n:.0f} steps it has "
                                f"lived (short of the {self.SPURIOUS:g}-fold the instability report needs)")]
        for k, (values, limit, power, said) in enumerate(faults):
            if np.nanmax(values) >= limit:
                i = int(np.nanargmax(values))
                how = said(values[i], span[i])
                break
        else:
            if grown is not None and self._drift >= self.GROWN_ERROR:
                self._warn_grown(t, h, complex(lam[grown]), float(drift[grown]), steps)
            return
        # the advice: the step that takes every fault of that mode to a tenth of its limit (TARGET_ERROR /
        # STEP_ERROR), the summed ones as they will have grown by the run's end (horizon) at this step
        steps_end = self._steps_by_end(t, steps)
        grow = [1.0] + [min(life[i], steps_end) / span[i] if span[i] > 0 else 1.0] * 3
        fix = min(h * (self.TARGET_ERROR / self.STEP_ERROR * limit / (values[i] * g)) ** (1.0 / power)
                  for (values, limit, power, _), g in zip(faults, grow) if values[i] * g > 0.0)
        mode = complex(lam[i])
        growth_per_step = math.exp(min(h * mode.real, 700.0))
        if k == 3:                                   # the spurious-growth fault says what it is itself
            qualifier = ""
        elif growth_per_step > 1.0 + 1e-3:
            qualifier = (f"the mode grows by {growth_per_step:.3g} per step, faster than the step resolves (a blow-up "
                         "ahead?): ")
        else:
            qualifier = "stable, but "
        period = (f" (period {2 * math.pi / abs(mode.imag):.3g} s: {2 * math.pi / (h * abs(mode.imag)):.3g} steps "
                  f"per period)") if mode.imag else ""
        self.coarse = (f"{self.method} may be inaccurate from t = {t:.6g} s: at h = {h:.3g} s it steps the mode lambda "
                       f"= {mode.real:.4g}{mode.imag:+.4g}j 1/s{period} with {how}: {qualifier}the answer is wrong "
                       f"wherever that mode shows - reduce h to about {fix:.2g} s or use an adaptive method (DP45, "
                       f"Tsit5)")
        warnings.warn(self.coarse, ResolutionWarning, stacklevel=6)

    def _warn_grown(self, t: float, h: float, mode: complex, per_step: float, steps: int) -> None:
        """The accuracy warning for a growing mode (:data:`GROWN_ERROR`), with the step that takes the error summed by
        the run's end to a tenth of it (a summed error has the method's global order, one fewer than its step's)."""
        order = STEP_ORDERS.get(self.watch.method, 2) - 1
        by_end = self._drift * max(self._steps_by_end(t, steps) / steps, 1.0) if steps else self._drift
        fix = h * (0.1 * self.GROWN_ERROR / by_end) ** (1.0 / order)
        self.coarse = (f"{self.method} may be inaccurate from t = {t:.6g} s: at h = {h:.3g} s it steps the mode lambda "
                       f"= {mode.real:.4g}{mode.imag:+.4g}j 1/s, which grows by "
                       f"{math.exp(min(h * mode.real, 700.0)):.4g} per step, with an error of {per_step:.2g} of it per "
                       f"step, {self._drift:.2g} summed while it grew: the answer is wrong wherever that mode shows - "
                       f"reduce h to about {fix:.2g} s or use an adaptive method (DP45, Tsit5)")
        warnings.warn(self.coarse, ResolutionWarning, stacklevel=7)

    def _report_amplification(self, t: float, y: tuple, h: float, got, accumulated: float | None = None) -> None:
        rho, exact, lam = got[:3] if got is not None else (math.nan, math.nan, complex(math.nan))
        zeta = -lam.real / abs(lam) + 0.0 if abs(lam) > 0 else math.nan       # + 0.0: no "-0"
        h_ok = self.watch.largest_stable_step(t, y, h)
        fix = (f"reduce h below {h_ok:.3g} s or use the implicit method Rodas4" if h_ok > 1e-3 * h else
               "no practical step keeps this method from amplifying a mode this lightly damped: use symplectic "
               "Euler, RK4 or the implicit method Rodas4")
        slow = rho <= exact * (1.0 + self.EXCESS)
        fold = f"{math.exp(accumulated):.3g}" if accumulated is not None and accumulated < 700.0 else \
            f"10^{accumulated / math.log(10.0):.0f}" if accumulated is not None else ""    # exp overflows past ~709
        grown = "" if accumulated is None else f"; {'slowly, but ' if slow else ''}{fold}-fold since the run began"
        self._report(t, y, f"{self.method} unstable at t = {t:.6g} s: at h = {h:.3g} s the step amplifies the "
                           f"mode lambda = {lam.real:.4g}{lam.imag:+.4g}j 1/s (|lambda| = {abs(lam):.4g} 1/s, damping "
                           f"ratio {zeta:.3g}) by {rho:.6g} per step while the exact flow changes it by {exact:.6g} "
                           f"(h*|lambda| = {h * abs(lam):.3g}; {STABLE_WHEN.get(self.method, 'outside its stability region')}"
                           f"){grown}: the solution grows without physical cause - {fix}")

    def _growth(self, t, y: np.ndarray, h) -> None:
        """Feed the step ends ``y`` (rows) to the growth test."""
        rows = y if self._y is None else np.vstack([self._y, y])
        self._y = y[-1].copy()
        inc = np.max(np.abs(np.diff(rows, axis=0)), axis=1) if len(rows) > 1 else np.zeros(0)
        off = len(t) - len(inc)                       # the very first state has no increment
        w = self._window
        i = 0
        while i < len(inc):
            take = min(self.GROWTH_STEPS - w[0], len(inc) - i)
            w[0], w[1] = w[0] + take, max(w[1], float(np.max(inc[i:i + take])))
            i += take
            if w[0] < self.GROWTH_STEPS:
                break
            w[3] = w[3] + 1 if w[2] > 0.0 and w[1] >= 2.0 * w[2] else 0
            ratio = w[1] / w[2] if w[2] > 0.0 else math.inf
            w[:3] = [0, 0.0, w[1]]
            if w[3] >= self.GROWTH_WINDOWS and self._grows_by_itself(ratio, float(h[i - 1 + off])):
                w[3] = 0                              # the model grows: the amplification test judges the method
            if w[3] >= self.GROWTH_WINDOWS:
                k = i - 1 + off
                self._report(float(t[k]), tuple(y[k]), f"{self.method} unstable at t = {float(t[k]):.6g} s: the step "
                             f"increments grow exponentially (x{ratio:.3g} per {self.GROWTH_STEPS} steps for "
                             f"{self.GROWTH_WINDOWS * self.GROWTH_STEPS} steps, h = {float(h[k]):.3g} s, h*|lambda| = "
                             f"{self.last:.3g}): a lightly damped mode outside the method's stability region "
                             f"(explicit Euler: h*omega_n > 2*zeta) - reduce h or use the implicit method Rodas4 "
                             f"(stiffness='ignore' if the model itself grows)")
                return

    def _grows_by_itself(self, ratio: float, h: float) -> bool:
        """Whether the step increments' growth ``ratio`` per window of :data:`GROWTH_STEPS` steps of ``h`` (s) is a mode
        the exact flow grows (the latest amplification check found one, :attr:`growing`, not amplified beyond it) at a
        rate that explains it (within a factor 2): y' = 10y under RK4 at h = 5 ms grows ×12.2 per window, e^2.5, and was
        stopped as unstable though 2.5e-6 from e^50."""
        return self.growing is not None and ratio <= 2.0 * math.exp(min(self.growing[2] * self.GROWTH_STEPS * h, 700.0))

    def _report(self, t: float, y, msg: str) -> None:
        self.detected_at = t
        if self.policy == "raise":
            raise StiffnessError(msg, t, y)
        warnings.warn(msg, StiffnessWarning, stacklevel=6)


def _largest(h) -> float:
    """The largest of step sizes ``h`` (one Python step's list, or a compiled run's array; 0 for none)."""
    if len(h) == 0:
        return 0.0
    return float(h.max() if isinstance(h, np.ndarray) else max(h))

def lipschitz(fa: Sequence[float], fb: Sequence[float], ya: Sequence[float], yb: Sequence[float]) -> float:
    """‖fa − fb‖/‖ya − yb‖: estimate of |λ| from derivatives at two nearby states (0 if they coincide)."""
    num = sum((a - b) * (a - b) for a, b in zip(fa, fb))      # products: no OverflowError near overflow
    den = sum((a - b) * (a - b) for a, b in zip(ya, yb))
    return math.sqrt(num / den) if den > 0.0 else 0.0


class OdeSolver:
    """Base of the step-by-step solvers (scipy.integrate.OdeSolver style).

    Attributes: ``t``, ``y`` (tuple), ``t_old``, ``y_old``, ``t_bound``, ``status`` ('running',
    'finished', 'failed'), ``nfev``, ``nsteps``, ``h_last`` (last accepted step, s). Only forward
    integration (t_bound > t0) is supported.
    """

    order: int = 0

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """A method's own ``dense_output`` asked before its first step says so (it failed on a None ``t_old``)."""
        super().__init_subclass__(**kwargs)
        own = cls.__dict__.get("dense_output")
        if own is None:
            return

        @functools.wraps(own)
        def dense_output(self: "OdeSolver", *args: Any, **kw: Any) -> Any:
            if self.t_old is None:
                raise RuntimeError(f"{type(self).__name__}: dense_output() interpolates over the last step: call "
                                   "step() first")
            return own(self, *args, **kw)
        cls.dense_output = dense_output

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
            h = getattr(self, "h_abs", math.nan)
            if isinstance(exc, OverflowError) and hasattr(self, "diverged"):   # the state grew past the floats
                raise self.diverged(self.t, self.y, h, (self.t, self.y),
                                    f"the right-hand side overflowed ({exc}) in the step") from None
            raise SolverDivergence(f"{getattr(self, 'label', '') or type(self).__name__}: arithmetic error in the "
                                   f"right-hand side ({exc}) in a step of h = {h:.3g} s", self.t, self.y) from None
        self.nsteps += 1
        if self.t >= self.t_bound:
            self.status = "finished"

    def _step_impl(self) -> None:
        raise NotImplementedError

    def dense_output(self):
        """Interpolant over the last step [t_old, t]: callable on a float (tuple) or array (ndarray)."""
        raise NotImplementedError

    def _min_step(self, at: float | None = None) -> float:
        """The smallest step (s) from ``at`` (default: the current time): 10 ulp."""
        at = self.t if at is None else at
        return 10.0 * (math.nextafter(at, math.inf) - at)
