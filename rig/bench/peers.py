"""Peer solvers on our problems: scipy ``solve_ivp`` (RK45, DOP853, Radau, BDF, LSODA), scipy ``odeint`` and
SUNDIALS CVODE (scikit-sundae, BDF), each driven through the same hybrid :class:`rig.solvers.Problem` as ours.

A peer gets the problem's compiled kernel (``JitRhs.kernel`` with the live parameter vector, taken when a
segment starts, as our compiled solvers do) as a plain ``f(t, y)`` and the events that change the problem
(``restart``, ``action`` or ``terminal``) as terminal events. At each root the integration restarts just past
it (where the event function has its new sign: :func:`rig.solvers.integrate._past_root`, on the first-order
continuation from the root over a few ulps) after the event's action and the problem's ``reset``, as our
driver does; ``time_breaks`` are hit exactly and passed one ulp later. ``odeint`` has no root finding: its
events are detected as sign changes between output times (in calls of :data:`ODEINT_CHUNK` output times) and
located by Brent's method on ``odeint`` runs restarted from the last output before the change (their RHS calls
are counted). CVODE is SUNDIALS' BDF (variable order, dense direct solver, its own difference-quotient
Jacobian) with its own root finding; our kernel writes straight into its derivative array. Recorded-only events
(level 2's flank contacts) are not given to the peers.

Restarts at events that change nothing but the smoothness of the right-hand side (level 2's contact onsets and
releases: the contact force's derivatives jump) help a one-step method and cost a multistep method a new
start at order 1. The multistep peers therefore also run as ``"<peer> (no restarts)"``: those events are not
given to them (events with an action, a terminal or a mode-dependent one still are), and they step across.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.integrate import odeint, solve_ivp
from scipy.optimize import brentq

from rig.solvers import EventRecord, Problem, SolverDivergence
from rig.solvers.integrate import MAX_STALLED, STALL_SPAN, _past_root, breaks_in

SOLVE_IVP = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
NO_RESTARTS = " (no restarts)"
PEERS = tuple(f"scipy {m}" for m in SOLVE_IVP) + ("scipy odeint", "cvode") + tuple(
    f"{m}{NO_RESTARTS}" for m in ("scipy LSODA", "scipy odeint", "cvode"))
MAX_STEPS = 10 ** 7         # odeint / CVODE step limits per segment (the defaults, 500, end long segments)


class Segment(NamedTuple):
    """One peer run from a restart to the next: end time and state, index of the event that stopped it in the
    list passed (None: reached the bound), the samples on the grid times given up to the end, RHS calls."""

    t: float
    y: np.ndarray
    event: int | None
    samples: np.ndarray
    nfev: int


Backend = Callable[..., Segment]


def _rhs(kernel, p) -> Callable[[float, np.ndarray], np.ndarray]:
    """``f(t, y) -> dy/dt`` of a compiled kernel with parameter vector ``p``."""
    def f(t, y):
        dy = np.empty(y.size)
        kernel(t, y, p, dy)
        return dy
    return f


def _span(t0: float, times: np.ndarray, t1: float) -> np.ndarray:
    """Output times of a segment: its start, the grid times in it and its bound."""
    return np.concatenate(([t0], times, [] if times.size and times[-1] == t1 else [t1]))


def _ivp_backend(method: str) -> Backend:
    def run(kernel, p, t0, y0, t1, events, times, rtol, atol, sampled=None) -> Segment:
        gs = []
        for e in events:
            g = (lambda t, y, fun=e.fun: fun(t, y))
            g.terminal, g.direction = True, e.direction
            gs.append(g)
        ts = _span(t0, times, t1)[1:]
        s = solve_ivp(_rhs(kernel, p), (t0, t1), y0, method=method, rtol=rtol, atol=atol, events=gs or None,
                      t_eval=ts)
        if s.status < 0:
            raise RuntimeError(f"scipy {method}: {s.message} at t = {s.t[-1] if len(s.t) else t0:.9g} s")
        samples = np.reshape(s.y, (len(y0), -1))[:, :min(len(s.t), times.size)]   # t, y are lists when empty
        if s.status == 1:
            k = next(i for i, te in enumerate(s.t_events) if te.size)
            return Segment(float(s.t_events[k][-1]), s.y_events[k][-1], k, samples, s.nfev)
        return Segment(t1, s.y[:, -1], None, samples, s.nfev)
    return run


def _crossings(g: np.ndarray, direction: float) -> np.ndarray:
    """Indices i where g crosses zero between values i and i + 1 in ``direction`` (0: either), as our driver
    counts them (:class:`rig.solvers.integrate.Event`): leaving g = 0 in the event's direction counts."""
    a, b = g[:-1], g[1:]
    if direction:
        return np.flatnonzero((b < 0.0) & (a >= 0.0) if direction < 0 else (b > 0.0) & (a <= 0.0))
    return np.flatnonzero((a * b < 0.0) | ((b == 0.0) & (a != 0.0)))


def _leaving(events: list, f: Callable, t0: float, y0: np.ndarray) -> int | None:
    """Index of the first directional event whose g is 0 at the segment's start and leaves it in its direction
    along the first-order continuation (a mode switch due at once: CVODE's root finding, like odeint's output
    sampling, does not report a root at the initial point); None if there is none."""
    dy = f(t0, y0)
    for k, e in enumerate(events):
        if e.direction and e.fun(t0, tuple(y0)) == 0.0:
            t1 = t0 + 1e-9 * max(1.0, abs(t0))
            t = _past_root(e.fun, lambda tt: tuple(y0 + (tt - t0) * dy), t0, t1, e.direction > 0)
            if t < t1:
                return k
    return None


# output times per odeint call: it has no root finding, so the part of a call past an event is wasted, and each
# call restarts LSODA; 1000 was the fastest on level 2 (15 ms at 1e-7 against 24 ms with 100 or doubling chunks)
ODEINT_CHUNK = 1000


@njit
def _event_values(event, ts, Y, p, k):
    """Event ``k`` of a compiled event kernel at the rows of ``Y`` (states at times ``ts``)."""
    out = np.empty(ts.size)
    for i in range(ts.size):
        out[i] = event(ts[i], Y[i], p, k)
    return out


def _odeint_backend(kernel, p, t0, y0, t1, events, times, rtol, atol, sampled=None) -> Segment:
    """``sampled(k, ts, Y)``: event k of ``events`` at the output rows (compiled, as our solvers evaluate events);
    without it each event's Python function at each output time."""
    f = _rhs(kernel, p)
    nfev, done = 0, []

    def solve(y, ts):
        nonlocal nfev
        Y, info = odeint(f, y, ts, tfirst=True, rtol=rtol, atol=atol, full_output=True, mxstep=MAX_STEPS)
        nfev += int(info["nfe"][-1])
        if info["message"] != "Integration successful.":
            raise RuntimeError(f"scipy odeint: {info['message']} (t = {ts[0]:.9g} .. {ts[-1]:.9g} s)")
        return Y
    span = _span(t0, times, t1)
    y, a = np.asarray(y0, dtype=float), 0
    while True:
        ts = span[a:a + ODEINT_CHUNK + 1]
        Y = solve(y, ts)
        first = None
        for k, e in enumerate(events):
            g = sampled(k, ts, Y) if sampled is not None else np.array([e.fun(t, v) for t, v in zip(ts, Y)])
            hit = _crossings(g, e.direction)
            if hit.size and (first is None or hit[0] < first[0]):
                first = (int(hit[0]), k)
        if first is None:
            done.append(Y[1:])
            a += ts.size - 1
            y = Y[-1]
            if a == span.size - 1:
                samples = np.concatenate(done)[:times.size].T
                return Segment(t1, y, None, samples, nfev)
            continue
        i, k = first
        done.append(Y[1:i + 1])
        g = events[k].fun
        state = (lambda t: Y[i] if t == ts[i] else solve(Y[i], [ts[i], t])[-1])
        t_root = brentq(lambda t: g(t, state(t)), ts[i], ts[i + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps)
        samples = np.concatenate(done)[:int(np.searchsorted(times, t_root, side="right"))].T
        return Segment(t_root, state(t_root), k, samples, nfev)


def _cvode_backend(kernel, p, t0, y0, t1, events, times, rtol, atol, sampled=None) -> Segment:
    import sksundae

    def rhs(t, y, yp):
        kernel(t, y, p, yp)
    options = dict(rtol=rtol, atol=atol, method="BDF", max_num_steps=MAX_STEPS)
    if events:
        def g(t, y, out):
            for k, e in enumerate(events):
                out[k] = e.fun(t, y)
        g.terminal, g.direction = [True] * len(events), [int(np.sign(e.direction)) for e in events]
        options.update(eventsfn=g, num_events=len(events))
    r = sksundae.cvode.CVODE(rhs, **options).solve(_span(t0, times, t1), np.asarray(y0, dtype=float))
    if not r.success:
        raise RuntimeError(f"CVODE: {r.message} at t = {r.t[-1]:.9g} s")
    if r.status == 2:                               # stopped at an event: the last row is the event point
        k = int(np.flatnonzero(r.i_events[-1])[0])
        n = int(np.searchsorted(times, r.t[-1], side="right"))
        return Segment(float(r.t[-1]), r.y[-1], k, r.y[1:1 + n].T, int(r.nfev))
    return Segment(t1, r.y[-1], None, r.y[1:1 + times.size].T, int(r.nfev))


def backend(name: str) -> Backend:
    """The segment runner of peer ``name`` (one of :data:`PEERS`)."""
    name = name.removesuffix(NO_RESTARTS)
    if name == "scipy odeint":
        return _odeint_backend
    if name == "cvode":
        return _cvode_backend
    if name.startswith("scipy ") and name[6:] in SOLVE_IVP:
        return _ivp_backend(name[6:])
    raise ValueError(f"unknown peer {name!r} (known: {', '.join(PEERS)})")


class TimeLimit(RuntimeError):
    """A peer run stopped at its wall-clock limit; ``t``: the simulation time it had reached (s)."""

    def __init__(self, name: str, limit: float, t: float) -> None:
        super().__init__(f"{name}: stopped after its time limit of {limit:g} s at t = {t:.6g} s")
        self.limit, self.t = limit, t


def _limited(kernel, name: str, limit: float):
    """``kernel`` raising :class:`TimeLimit` once ``limit`` s of wall time have passed since this call (a clock
    read per right-hand-side call, ≈ 0.05 µs against the peer's ≈ 1 µs per call through Python)."""
    deadline = time.perf_counter() + limit

    def limited(t, y, p, dy):
        if time.perf_counter() > deadline:
            raise TimeLimit(name, limit, t)
        kernel(t, y, p, dy)
    return limited


def run_peer(name: str, problem: Problem, t_span: tuple[float, float], grid: np.ndarray, rtol: float,
             atol: float, limit: float | None = None) -> tuple[np.ndarray, int]:
    """Integrate ``problem`` over ``t_span`` (s) with peer ``name``; states on ``grid`` (n, m) and RHS calls.

    Raises :class:`SolverDivergence` on a non-finite state or a terminal event, :class:`TimeLimit` after
    ``limit`` s of wall time (None: none), RuntimeError when the peer fails (its message) or events chatter."""
    run = backend(name)
    kernel, params = problem.fun.kernel, problem.fun.params
    if limit is not None:
        kernel = _limited(kernel, name, limit)
    smooth_only = not name.endswith(NO_RESTARTS)       # restarts that only mark a jump in a derivative
    if not smooth_only and problem.reset is not None and any(e.restart for e in problem.events):
        raise RuntimeError(f"{name} does not apply: this problem's restarts re-select its mode (its reset: e.g. the "
                           f"cam segment a tappet holds), so no method may step across them; "
                           f"'{name.removesuffix(NO_RESTARTS)}' keeps them")
    acting = [e for e in problem.events if (e.restart and smooth_only) or e.action or e.terminal or e.mode_dependent]
    position = {id(e): k for k, e in enumerate(problem.events)}   # a compiled event kernel's index of each event
    t_end = float(t_span[1])
    edges = breaks_in(problem, float(t_span[0]), t_end) + [t_end]
    y = np.array(problem.y0, dtype=float)
    out = np.empty((y.size, grid.size))
    i = int(np.searchsorted(grid, t_span[0], side="right"))
    out[:, :i] = y[:, None]
    tc, nfev, stalls, last_cut = float(t_span[0]), 0, 0, -math.inf
    reset = problem.reset or (lambda t_, y_: False)
    reset(tc, tuple(y))
    for b in edges:
        while True:
            p = params()
            live = [e for e in acting if e.mode_dependent or e.fun(tc, tuple(y)) != 0.0]  # not the one just acted on
            j = int(np.searchsorted(grid, b, side="right"))
            now = _leaving(live, _rhs(kernel, p), tc, y)
            sampled = None if problem.fun.event is None else (
                lambda k, ts, Y, p=p, live=live: _event_values(problem.fun.event, np.asarray(ts, dtype=float),
                                                               np.ascontiguousarray(Y), p, position[id(live[k])]))
            seg = (run(kernel, p, tc, y, b, live, grid[i:j], rtol, atol, sampled=sampled) if now is None
                   else Segment(tc, y, now, np.empty((y.size, 0)), 1))
            nfev += seg.nfev
            n = seg.samples.shape[1]
            out[:, i:i + n] = seg.samples
            i += n
            if not np.all(np.isfinite(seg.y)) or not np.all(np.isfinite(seg.samples)):
                raise SolverDivergence(f"{name}: non-finite state", seg.t, tuple(seg.y))
            if seg.event is None:
                tc, y = math.nextafter(b, math.inf), seg.y
                reset(tc, tuple(y))
                break
            e = live[seg.event]
            g0 = e.fun(tc, tuple(y))
            rising = e.direction > 0 if e.direction else g0 < 0.0
            f_root = _rhs(kernel, p)(seg.t, seg.y)
            y_at = (lambda tt, y0=seg.y, t0=seg.t, d=f_root: tuple(y0 + (tt - t0) * d))
            t_cut = _past_root(e.fun, y_at, seg.t, b, rising)
            y_cut = y_at(t_cut)
            if e.terminal:
                raise SolverDivergence(f"{name}: terminal event {e.name!r}", t_cut, y_cut)
            changed = e.action(EventRecord(t_cut, e.name, y_cut, 1.0 if rising else -1.0)) if e.action else False
            y = np.array(changed if isinstance(changed, tuple) else y_cut)
            stalls = stalls + 1 if t_cut - last_cut <= STALL_SPAN * max(1.0, abs(t_cut)) else 0
            if stalls > MAX_STALLED:
                raise RuntimeError(f"{name}: event chattering at t = {t_cut:.9g} s (event {e.name!r})")
            tc = last_cut = t_cut
            while i < grid.size and grid[i] <= tc:   # grid times within the few ulps past the root
                out[:, i] = y
                i += 1
            if tc >= b:
                tc = math.nextafter(b, math.inf)
            reset(tc, tuple(y))
            if tc > b:
                break
    out[:, i:] = y[:, None]                         # grid times at the end not reached by a sample (a cut there)
    return out, nfev
