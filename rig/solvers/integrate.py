"""Problem-independent integration driver: sampling, event location, restarts at discontinuities.

A *problem* is a right-hand side plus event functions (and optional times where the RHS jumps);
a *method* is a solver class. ``integrate`` drives one with the other:

* events are located by root finding (Brent) on the step's dense output and recorded; for a fixed-step
  method on states stepped from the step's start instead (``state_at``): it has no error control, and its
  stages past a jump of the RHS at the event would spoil the interpolant. At a plain restart (no action,
  not mode-dependent, a problem without ``reset``: the RHS continuous there, its derivatives jumping, e.g. a
  contact onset) the state is
  one step of the method from the step's start landing on the root (``state_at``; error-controlled for the
  adaptive methods, whose dense output is an order lower), as the compiled runs do at the restarts they take;
  where an event switches the RHS the state stays on the event surface (the interpolant's, g = 0);
* at an event flagged ``restart`` (RHS discontinuous there, e.g. a cam phase boundary) or whose
  ``action`` reports a change of the problem, the step is cut at the event and the solver restarted;
* ``time_breaks`` (load steps in time) are hit exactly by bounding the solver there and restarting
  one ulp later; the RHS must be left-continuous there (value at t_b = value before the break); for a problem
  without ``reset`` (no mode to re-select) nor ``flow`` the compiled runs pass them the same way without returning
  here (the state at a break then sampled from the step's interpolant at its end, and a step ending there recorded at
  the restart time, one ulp on);
* terminal events stop the integration;
* hybrid (switched) problems keep a discrete mode outside the state: an event ``action`` may switch it
  and return a projected state to restart from, ``Problem.reset`` re-selects it at the start and after
  every restart, and ``mode_dependent`` event functions are re-evaluated after a switch;
* where the problem has a closed-form solution in its current mode (``Problem.flow`` returns one),
  the segment is stepped along it exactly (:class:`ClosedFormSolver`) instead of by the method;
* a diverging solver raises :class:`SolverDivergence` naming time and state, and so does event
  chattering (more than ``MAX_STALLED`` restarts without the time advancing by more than
  ``STALL_SPAN``·max(1, |t|): a Zeno point).
"""
from __future__ import annotations

import bisect
import inspect
import math
from dataclasses import dataclass, field
from functools import cache
from typing import Any, Callable, Sequence

import numpy as np
from scipy.optimize import brentq

from rig.solvers.base import OdeSolver, Rhs, SolverDivergence
from rig.solvers.dense import fill_dense
from rig.solvers.dop853 import DOP853
from rig.solvers.dopri import DormandPrince45
from rig.solvers.euler import Euler, SymplecticEuler
from rig.solvers.flow import ClosedForm, ClosedFormSolver
from rig.solvers.implicit import Rosenbrock23
from rig.solvers.rk4 import RK4
from rig.solvers.rodas import Rodas4
from rig.solvers.stepper import FixedStepper
from rig.solvers.tsit5 import Tsitouras45

METHODS: dict[str, type[OdeSolver]] = {"Euler": Euler, "SymplecticEuler": SymplecticEuler, "RK4": RK4,
                                       "DP45": DormandPrince45, "Tsit5": Tsitouras45, "DOP853": DOP853, "Rodas4": Rodas4,
                                       "Rosenbrock23": Rosenbrock23}
MAX_STALLED = 50
STALL_SPAN = 1e-12     # restarts closer than this (relative to max(1, |t|)) do not count as progress


@dataclass(frozen=True)
class EventRecord:
    """An event found at time ``t`` (s) with state ``y``; ``sign`` = +1 if g went − → +, else −1."""

    t: float
    name: str
    y: tuple
    sign: float


@dataclass(frozen=True)
class Event:
    """Event function g(t, y) whose zeros are located.

    ``direction`` > 0 / < 0 keeps only rising / falling crossings (leaving g = 0 in that direction counts, and so does
    reaching it at the span's end, as in scipy); without one, a sign change or reaching g = 0 counts, leaving g = 0 does
    not (a root exactly at the span's start, or where a restart left g, is not recorded: give a direction to count it —
    unlike scipy, which records it). Two roots inside one step (g of one sign at both ends) are not seen, as in scipy:
    bound the step (``max_step``) where such pairs matter; ``terminal`` stops the integration; ``restart`` restarts the
    solver at the event (RHS discontinuous there); ``action(record)`` is called for each recorded event and returns True
    when it changed the problem, or a new state tuple to restart from (then the solver is restarted too);
    ``mode_dependent`` marks a g that changes with the problem's discrete mode (re-evaluated after a restart).
    """

    fun: Callable[[float, tuple], float]
    name: str
    direction: float = 0.0
    terminal: bool = False
    restart: bool = False
    action: Callable[[EventRecord], bool | tuple] | None = None
    mode_dependent: bool = False


@dataclass
class Problem:
    """Right-hand side ``fun(t, y)``, initial state, events, times where the RHS or its derivatives jump
    (a sequence, or a function ``(t0, tf) -> sequence`` of those in a span) and
    ``reset(t, y) -> bool`` (re-selects a discrete mode at the start and after restarts; True if changed);
    ``flow(t, y, t_bound)`` returns the exact solution from (t, y) in the current mode, or None
    (asked at the start of every solver segment); ``positions`` the indices of the state's positions (the others
    velocities: symplectic Euler's kick–drift split; empty: the first half)."""

    fun: Rhs
    y0: Sequence[float]
    events: Sequence[Event] = ()
    time_breaks: Sequence[float] | Callable[[float, float], Sequence[float]] = ()
    reset: Callable[[float, tuple], bool] | None = None
    flow: Callable[[float, tuple, float], ClosedForm | None] | None = None
    positions: Sequence[int] = ()


@dataclass
class Solution:
    """Samples ``t`` (m,), ``y`` (n, m); events; final time/state; work counters; last step size;
    ``stiff_at``: first time a solver's stiffness test fired (None if never)."""

    t: np.ndarray
    y: np.ndarray
    events: list[EventRecord]
    status: str
    t_final: float
    y_final: tuple
    nfev: int = 0
    nsteps: int = 0
    h_last: float = math.nan
    restarts: int = 0
    stiff_at: float | None = None
    t_events: dict[str, list[float]] = field(default_factory=dict)


#: ulp: time breaks closer than this to either end of a span or to the break before are dropped (a solver restarts one
#: ulp past a break and refuses steps below 10 ulp)
BREAK_ULPS = 16


def breaks_in(problem: Problem, t0: float, tf: float) -> list[float]:
    """The problem's time breaks inside (t0, tf), sorted (s), less those within :data:`BREAK_ULPS` ulp of either end
    or of the break kept before them: a solver restarts one ulp past a break, which for a break one ulp before tf
    would leave it an empty span (a break computed as 1.4 s from the cam angle at the end of a chunk ending at
    1.4000000000000001 s stopped a level-2 run) and for two breaks 5 ulp apart (a segment end and a law-piece end
    computed from different angles, 1.4999999999999998 and 1.500000000000001 s) a span no fixed step fits."""
    known = problem.time_breaks(t0, tf) if callable(problem.time_breaks) else problem.time_breaks
    near = BREAK_ULPS * np.finfo(float).eps * max(1.0, abs(t0), abs(tf))
    kept: list[float] = []
    for b in sorted(b for b in known if t0 + near < b < tf - near):
        if not kept or b - kept[-1] > near:
            kept.append(b)
    return kept


@cache
def _options_of(cls) -> tuple[str, ...] | None:
    """The options a method's constructor takes (None: any, it takes ``**kwargs``); once per class (inspecting the
    signature costs ~15 µs, on a path called per chunk of a run)."""
    params = inspect.signature(cls.__init__).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return None
    return tuple(p for p in params if p not in ("self", "fun", "t0", "y0", "t_bound"))


def _check_options(cls, options: dict) -> None:
    """A ValueError naming an option the method does not take (``rtol`` for a fixed-step method, ``h`` for an
    adaptive one: a TypeError from deep inside before) and the ones it does."""
    taken = _options_of(cls)
    if taken is None:
        return
    unknown = sorted(set(options) - set(taken))
    if unknown:
        kind = "a fixed-step method (give h)" if "h" in taken else "an adaptive method (give rtol, atol)"
        raise ValueError(f"integrate: {getattr(cls, 'label', cls.__name__)} is {kind} and takes no option "
                         f"{', '.join(map(repr, unknown))} (its options: {', '.join(taken)})")


def _make_solver(cls, fun, t, y, t_bound, options):
    return cls(fun, t, y, t_bound, **options)


def _past_root(g: Callable[[float, tuple], float], dense: Callable, t_root: float, t_new: float,
               rising: bool) -> float:
    """First time ≥ ``t_root`` in the step where ``g`` is strictly past zero: a mode switch acts where the
    old mode is already invalid, so a root located a rounding error early cannot chatter (Zeno)."""
    dt = 4 * np.finfo(float).eps * max(1.0, abs(t_root))
    while t_root < t_new:
        v = g(t_root, dense(t_root))
        if (v > 0.0) if rising else (v < 0.0):
            return t_root
        t_root, dt = min(t_new, t_root + dt), 2 * dt
    return t_new


def _before_root(g: Callable[[float, tuple], float], states: Callable, t_root: float, t_old: float,
                 rising: bool) -> float:
    """Last time ≤ ``t_root`` in the step where ``g`` still has its sign before the crossing: a fixed-step
    method stepping to the root must not evaluate the RHS of the new side (a jump there would enter its last
    stage)."""
    dt = 4 * np.finfo(float).eps * max(1.0, abs(t_root))
    while t_root > t_old:
        v = g(t_root, states(t_root))
        if (v < 0.0) if rising else (v > 0.0):
            return t_root
        t_root, dt = max(t_old, t_root - dt), 2 * dt
    return t_old


def _root(g_at: Callable[[float], float], t_a: float, t_new: float) -> float:
    """The root of ``g_at`` (the event on the step's interpolant) in [t_a, t_new], given that the event's values at the
    step's states changed sign; ``t_new`` when the interpolant shows no sign change over the step: the end state is
    then on the other side, but the interpolant at the step's end misses it by its rounding (DOP853's by ≈ 1e-13·h·|y'|)
    — the root lies within that of the step's end, and brentq would refuse the bracket."""
    g_a, g_b = g_at(t_a), g_at(t_new)
    if g_a == 0.0:
        return t_a
    if g_b == 0.0 or (g_a < 0.0) == (g_b < 0.0):
        return t_new
    return brentq(g_at, t_a, t_new, xtol=1e-15, rtol=4 * np.finfo(float).eps)


def _left_zero(g: Callable[[float, tuple], float], dense: Callable, t_old: float, t_new: float,
               b: float) -> tuple[float, float]:
    """For an event an action left on its surface (g = 0 at ``t_old``) and found at ``b`` ≠ 0 at the step's end:
    the last of 16 points in the step where g is on the other side of zero, and g there (the bracket of the new
    crossing: a bounce whose whole flight fits in one step); (``t_old``, 0) if g went straight to ``b``'s side."""
    for t in np.linspace(t_new, t_old, 17)[1:-1]:
        v = g(float(t), dense(float(t)))
        if v != 0.0 and (v < 0.0) != (b < 0.0):
            return float(t), v
    return t_old, 0.0


def _finite(events: Sequence[Event], g: Sequence[float], t: float, y: tuple) -> Sequence[float]:
    """The event values ``g`` at (t, y), or a :class:`SolverDivergence` naming an event whose value is not finite (its
    zeros are found by sign changes: a NaN would hide every one)."""
    for e, v in zip(events, g):
        if not math.isfinite(v):
            raise SolverDivergence(f"event {e.name!r} returned {v} at t = {t:.9g} s: an event function must be finite "
                                   "(its zeros are found by sign changes)", t, y)
    return g


def _state(y0: Any) -> tuple[float, ...]:
    """An initial state as a tuple of floats: a non-empty sequence of real numbers, named when it is not."""
    arr = np.asarray(y0, dtype=float) if not isinstance(y0, (str, bytes)) else np.empty((0, 0))
    if arr.ndim != 1 or not arr.size:
        raise ValueError(f"integrate: y0 = {y0!r} must be a non-empty sequence of numbers (one per state component)")
    return tuple(float(v) for v in arr)


def integrate(problem: Problem, t_span: tuple[float, float], method: str | type[OdeSolver] = "DP45",
              events: Sequence[Event] | None = None, t_eval: Sequence[float] | None = None,
              y0: Sequence[float] | None = None, **options) -> Solution:
    """Integrate ``problem`` over ``t_span`` with ``method`` (a name of :data:`METHODS` or a solver class).

    ``options`` go to the solver (rtol, atol, first_step, max_step, stiffness, compiled for DP45 and Rodas4;
    h, stiffness, compiled for Euler, SymplecticEuler (and nq or positions; default the problem's) and RK4).
    ``t_eval`` (increasing, inside t_span) selects output times, otherwise every step is returned.
    """
    if isinstance(method, str) and method not in METHODS:
        raise ValueError(f"integrate: unknown method {method!r} (known: {', '.join(METHODS)})")
    t0, tf = float(t_span[0]), float(t_span[1])
    if not (math.isfinite(t0) and math.isfinite(tf) and tf > t0):
        raise ValueError(f"integrate: t_span = ({t0}, {tf}) must be two finite times, the end after the start (s)")
    fun = problem.fun
    y = _state(problem.y0 if y0 is None else y0)
    if y0 is not None and len(y) != len(problem.y0):        # a compiled kernel would read and write past it
        raise ValueError(f"integrate: y0 has {len(y)} components, the problem's state {len(problem.y0)}")
    cls = METHODS[method] if isinstance(method, str) else method
    _check_options(cls, options)
    if problem.positions and issubclass(cls, SymplecticEuler) and "nq" not in options and "positions" not in options:
        options = {**options, "positions": tuple(problem.positions)}     # the problem's kick–drift split
    batched = events is None                    # the RHS's event kernel, if any, matches problem.events
    events = list(problem.events if events is None else events)
    breaks = breaks_in(problem, t0, tf) + [tf]
    if t_eval is not None:
        try:
            t_eval = np.asarray(t_eval, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"integrate: t_eval must be a sequence of times (s), got {t_eval!r:.80}") from None
        if t_eval.ndim != 1:
            raise ValueError(f"integrate: t_eval must be a 1-D sequence of times (s), got an array of shape "
                             f"{t_eval.shape}")
        if t_eval.size and (not np.all(np.isfinite(t_eval)) or np.any(np.diff(t_eval) < 0) or t_eval[0] < t0
                            or t_eval[-1] > tf):
            raise ValueError(f"integrate: t_eval must be finite and increasing inside t_span = ({t0}, {tf})")
        out_y = np.empty((len(y), t_eval.size))
        i_eval = int(np.searchsorted(t_eval, t0, side="right"))
        out_y[:, :i_eval] = np.asarray(y)[:, None]
        t_list = t_eval.tolist()
        pending: list = []                      # (dense, i, j): samples filled in one pass at the end
    else:
        ts, ys = [t0], [y]
    t = t0
    reset = problem.reset or (lambda t_, y_: False)
    reset(t, y)
    g_old = _finite(events, [e.fun(t, y) for e in events], t, y)
    stalled, t_last_cut, stiff_at = 0, math.nan, None
    monitor = None
    records: list[EventRecord] = []
    nfev = nsteps = restarts = 0
    status, h_next = "finished", options.pop("first_step", None)
    first_step = h_next                         # also the first step after an action that changed the state
    at_zero: set[int] = set()                   # events an action left exactly on their surface (g = 0)
    bi = 0
    while True:
        exact = problem.flow(t, y, breaks[bi]) if problem.flow else None
        if exact is None:
            solver = _make_solver(cls, fun, t, y, breaks[bi], dict(options, first_step=h_next))
            if isinstance(solver, FixedStepper):
                solver.check_at_end = False     # tested once at the end of the run, below
            if monitor is not None and hasattr(solver, "monitor"):
                monitor.watch = solver.monitor.watch    # the stiffness/growth watch spans restarts (else a
                solver.monitor = monitor                # diverging run bouncing between contacts is never reported)
            monitor = getattr(solver, "monitor", monitor)
            if monitor is not None:
                monitor.horizon = tf            # the span the accuracy advice extrapolates its summed faults to
        else:
            solver = ClosedFormSolver(exact, t, y, breaks[bi])
        cut = None
        fixed = isinstance(solver, FixedStepper)     # events on re-stepped states (see the docstring)
        plain_restarts = problem.reset is None and hasattr(solver, "state_at")   # no mode to re-select
        runs = batched and bool(events) and getattr(solver, "can_advance", False)
        bi0 = bi
        if runs and problem.reset is None and problem.flow is None and bi + 1 < len(breaks):
            solver.pass_breaks(breaks[bi + 1:])     # no mode to re-select, no closed form to ask: the runs pass them
        values = (lambda t_, y_, s=solver, n=len(events): s.event_values(t_, y_, n)) if runs else \
            (lambda t_, y_: [e.fun(t_, y_) for e in events])
        while solver.status == "running":
            if runs:                            # compiled run of steps up to a sign change of some event
                g_run = np.array(g_old)
                if t_eval is not None:          # the run samples the output times its quiet steps pass
                    quiet = solver.advance(g_run, times=t_eval, out=out_y, first=i_eval)
                    i_eval = solver.sampled
                else:
                    quiet = solver.advance(g_run)
                bi = bi0 + solver.breaks_passed
                for row in solver.acted:        # restarts the compiled run acted on itself
                    records.append(EventRecord(float(row[0]), events[int(row[1])].name, tuple(row[3:].tolist()),
                                               float(row[2])))
                    restarts += 1
                if quiet is not None:           # steps before the current one, no event there
                    g_old = g_run.tolist()
                    if t_eval is None:
                        ts += quiet.T[1:].tolist()
                        ys += map(tuple, quiet.Y[1:].tolist())
            else:
                solver.step()
            t_old, t_new, y_new = solver.t_old, solver.t, solver.y
            dense = None
            hits = []
            simultaneous: set[int] = set()
            if events:
                g_new = _finite(events, values(t_new, y_new), t_new, y_new)
                for i, e in enumerate(events):
                    a, b = g_old[i], g_new[i]
                    t_from = t_old
                    if a == 0.0 and i in at_zero and b != 0.0:   # a new crossing only if g left zero first
                        t_from, a = _left_zero(e.fun, dense := dense or solver.dense_output(), t_old, t_new, b)
                    if e.direction:              # reaching zero at the span's end: no later step sees it leave
                        on_end = b == 0.0 and t_new >= tf and (a < 0.0 if e.direction > 0 else a > 0.0)
                        if not (on_end or (b < 0.0 <= a if e.direction < 0 else a <= 0.0 < b)):
                            continue
                        rising = e.direction > 0
                    elif a * b < 0 or (b == 0.0 and a != 0.0):
                        rising = b > a
                    else:
                        continue
                    if b == 0.0:
                        t_root = t_new
                    else:
                        dense = dense or solver.dense_output()
                        on = solver.state_at if fixed else dense
                        g_at = (lambda tt, f=e.fun, d=on: f(tt, d(tt)))
                        if t_from > t_old:
                            t_root = _root(g_at, t_from, t_new)
                        elif (g_at(t_old) < 0.0) == (b < 0.0):
                            t_root = t_old      # g jumped at a restart (RHS/mode discontinuity): past at once
                        elif runs and not fixed:  # compiled events: compiled search on the same dense output
                            t_root = solver.locate(i)
                        else:
                            t_root = _root(g_at, t_old, t_new)
                        if e.mode_dependent:
                            t_root = _past_root(e.fun, on, t_root, t_new, rising)
                    hits.append((t_root, i, 1.0 if rising else -1.0))
                hits.sort()
                for n_hit, (t_root, i, sign) in enumerate(hits):
                    e = events[i]
                    dense = dense or solver.dense_output()
                    if t_root >= t_new:
                        y_root = y_new
                    elif fixed and e.action is None and not e.mode_dependent:  # step to the root from the side where
                        # the old RHS holds
                        y_root = solver.state_at(_before_root(e.fun, solver.state_at, t_root, t_old, sign > 0.0))
                    elif fixed:                 # a mode switch acts where the old mode is invalid (before its root
                        # the next step would find the same root again: chattering without time advancing)
                        y_root = solver.state_at(t_root)
                    elif plain_restarts and e.restart and e.action is None and not e.mode_dependent:
                        y_root = solver.state_at(t_root)          # a plain restart: land on it with a step
                    else:
                        y_root = dense(t_root)
                    rec = EventRecord(t_root, e.name, y_root, sign)
                    records.append(rec)
                    changed = e.action(rec) if e.action is not None else False
                    if e.terminal or e.restart or changed is not False:
                        cut = (t_root, changed if isinstance(changed, tuple) else rec.y, e.terminal,
                               isinstance(changed, tuple))
                        near = 4 * np.finfo(float).eps * max(1.0, abs(t_root))
                        for t2, i2, sign2 in hits[n_hit + 1:]:    # crossings at the same instant (e.g. contact
                            if t2 - t_root <= near and not events[i2].mode_dependent:   # moving flank to flank)
                                records.append(EventRecord(t_root, events[i2].name, rec.y, sign2))
                                simultaneous.add(i2)
                        break
            t_stop = cut[0] if cut else t_new
            if t_eval is not None:
                j = bisect.bisect_right(t_list, t_stop)
                if j > i_eval:
                    inner = t_eval[i_eval:j]
                    k = j - 1 if inner[-1] == t_new else j
                    if k > i_eval:
                        pending.append((dense or solver.dense_output(), i_eval, k))
                    if k < j:
                        out_y[:, k] = y_new
                    i_eval = j
            elif not cut:
                ts.append(t_new)
                ys.append(y_new)
            if cut:
                t, y = cut[0], cut[1]
                if t_eval is None:
                    ts.append(t)
                    ys.append(y)
                reset(t, y)
                fired = {i for tr, i, _ in hits if tr <= t and not events[i].mode_dependent} | simultaneous
                now = _finite(events, values(t, y), t, y)
                if cut[3]:                      # the action set a new state: every g from that state; one left on
                    g_old = now                 # its surface must leave zero before it can cross
                    at_zero = {i for i, g in enumerate(g_old) if g == 0.0}
                else:
                    g_old = [g_new[i] if i in fired else now[i] if e.mode_dependent else (now[i] or g_old[i])
                             for i, e in enumerate(events)]
                stalled = stalled + 1 if t - t_last_cut <= STALL_SPAN * max(1.0, abs(t)) else 0
                t_last_cut = t
                if stalled > MAX_STALLED:
                    raise SolverDivergence(f"event chattering: {stalled} restarts without time advancing "
                                           f"(last event {records[-1].name!r}; Zeno point)", t, y)
                break
            if events:
                g_old = g_new
                at_zero = set()
        nfev += solver.nfev
        nsteps += solver.nsteps
        restarts += bi - bi0                    # the breaks a compiled run passed
        if stiff_at is None:
            stiff_at = getattr(solver, "stiff_at", None)
        if exact is None:                       # the old step size means nothing for a state an action set
            h_next = first_step if cut is not None and cut[3] else solver.h_last
        if cut is None:
            bi += 1
            t, y = solver.t, solver.y
            if bi == len(breaks):               # the span's end: t_final is it, not one ulp past
                break
            t = math.nextafter(t, math.inf)
            if reset(t, y):
                g_old = _finite(events, [e.fun(t, y) for e in events], t, y)
        elif cut[2]:
            status = "terminated"
            break
        elif t >= breaks[bi]:                   # the event fell on the break itself: move on past it
            bi += 1
            if bi == len(breaks):
                break
            t = math.nextafter(t, math.inf)
        restarts += 1
    if monitor is not None and isinstance(solver, FixedStepper):     # the steps since the growth test's last check
        calls = monitor.calls
        monitor.finish(t, y)
        nfev += monitor.calls - calls
        stiff_at = monitor.detected_at if stiff_at is None else stiff_at
    if t_eval is not None:
        fill_dense(out_y, t_eval, pending)
        t_out, y_out = t_eval[:i_eval], out_y[:, :i_eval]
    else:
        t_out, y_out = np.array(ts), np.array(ys).T
    t_events: dict[str, list[float]] = {}
    for r in records:
        t_events.setdefault(r.name, []).append(r.t)
    return Solution(t_out, y_out, records, status, t, y, nfev, nsteps, h_next, restarts, stiff_at, t_events)
