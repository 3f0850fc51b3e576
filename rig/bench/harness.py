"""Work–precision harness (issue 13): our solvers against scipy and SUNDIALS on the same compiled problem.

For a :class:`~rig.bench.problems.WorkProblem` every method runs a sweep — step sizes for the fixed-step
methods (ours: euler, semi-implicit euler, rk4), tolerances for the adaptive ones (ours: dp45, rodas4; peers:
scipy RK45, DOP853, Radau, BDF, LSODA, odeint and CVODE, :mod:`rig.bench.peers`) — and each run gives a row
``method, setting, error, wall_s, nfev, t_sim, status``: error against a reference, wall time (best of a few
repeats, caches warm), RHS calls, simulated span (s) and ``ok``, ``diverged: why``, ``failed: why``,
``inaccurate: …`` (a relative error above 1 that the method did not report as a divergence), or with a time limit
per run ``timeout: …`` and ``skipped: …`` (the method's finer settings after a timeout).

The reference is our DP45 at rtol 1e-13, confirmed by scipy DOP853 and our Rodas4 at rtol 1e-12 (their
distances to it are the ``reference`` row's setting and error). Errors below :data:`RESOLVE` times the larger
distance cannot be told from the reference's own error: such rows get status ``unresolved: …`` and are not
charted; a distance above :data:`REF_CONFIRM` is reported loudly and marks the reference ``unconfirmed``.
"""
from __future__ import annotations

from collections import Counter

import csv
import math
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.bench.peers import PEERS, TimeLimit, run_peer
from rig.bench.problems import WorkProblem
from rig.solvers import ResolutionWarning, SolverDivergence, StiffnessWarning, integrate

COLUMNS = ("method", "setting", "error", "wall_s", "nfev", "t_sim", "status")
OURS = {"euler": "Euler", "semi-implicit euler": "SymplecticEuler", "rk4": "RK4", "dp45": "DP45", "tsit5": "Tsit5",
        "dop853": "DOP853",
        "rodas4": "Rodas4"}
FIXED = ("euler", "semi-implicit euler", "rk4")
METHODS = tuple(OURS) + PEERS
TARGET = 1e-6            # error of the summary: cheapest run at or below it
REF_RTOL, CHECK_RTOL = 1e-13, 1e-12
REF_CONFIRM = 1e-8       # confirmations farther than this from the reference: reference unconfirmed
RESOLVE = 10.0           # errors below RESOLVE x the reference's distance to its confirmations are unresolved


@dataclass
class Row:
    """One run of one method at one setting (SI: s)."""

    method: str
    setting: str
    error: float
    wall_s: float
    nfev: int | None
    t_sim: float
    status: str


@dataclass
class Reference:
    """The reference states on the grid, how they were computed and their distances to the confirmations."""

    y: np.ndarray
    label: str
    distances: dict[str, float]
    wall_s: float
    failures: dict[str, str]

    @property
    def uncertainty(self) -> float:
        """The larger distance to a confirmation (inf without any)."""
        return max(self.distances.values(), default=math.inf)

    @property
    def confirmed(self) -> bool:
        """At least one other method agrees within :data:`REF_CONFIRM` and none disagrees."""
        return self.uncertainty <= REF_CONFIRM

    def describe(self) -> str:
        """The confirmations in words: distances, failures."""
        return "; ".join([f"{k} differs by {d:.1e}" for k, d in self.distances.items()]
                         + [f"{k} failed ({why[:100]})" for k, why in self.failures.items()])


@dataclass
class Result:
    """The rows of one problem and the reference they were measured against."""

    problem: WorkProblem
    reference: Reference
    rows: list[Row]


def _ours(problem: WorkProblem, method: str, t_end: float | None = None, **options) -> tuple[np.ndarray, int]:
    """Our ``method`` on the problem: states on the grid, RHS calls (SolverDivergence on a terminal event)."""
    t_end = problem.t_sim if t_end is None else t_end
    grid = problem.grid[problem.grid <= t_end]
    if method not in FIXED:
        options = {"stiffness": "ignore", **options}     # DP45 is stability-limited on the contact, still accurate
    with warnings.catch_warnings():                      # the error is measured against the reference: a method's
        warnings.simplefilter("ignore", StiffnessWarning)    # own warnings (a fixed step's ResolutionWarning) add
        warnings.simplefilter("ignore", ResolutionWarning)   # nothing to the row
        sol = integrate(problem.make(), (0.0, t_end), method=OURS[method], t_eval=grid, **options)
    if sol.status == "terminated":
        raise SolverDivergence(f"{method}: terminal event {sol.events[-1].name!r}", sol.t_final, sol.y_final)
    return sol.y, sol.nfev


def _peer(problem: WorkProblem, method: str, rtol: float, t_end: float | None = None,
          limit: float | None = None) -> tuple[np.ndarray, int]:
    t_end = problem.t_sim if t_end is None else t_end
    grid = problem.grid[problem.grid <= t_end]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)      # overflow in a diverging peer's trial step
        return run_peer(method, problem.make(), (0.0, t_end), grid, rtol, rtol * problem.atol_scale, limit)


def runner(problem: WorkProblem, method: str, value: float, t_end: float | None = None,
           limit: float | None = None) -> Callable[[], tuple]:
    """A call running ``method`` at step size / rtol ``value`` over (0, t_end or t_sim); a peer stops with
    :class:`~rig.bench.peers.TimeLimit` after ``limit`` s of wall time (our compiled runs cannot be stopped: the
    sweep skips a method's finer settings after a run of it took longer, :func:`work_precision`)."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r} (known: {', '.join(METHODS)})")
    if method in FIXED:
        return lambda: _ours(problem, method, t_end, h=value)
    if method in OURS:
        return lambda: _ours(problem, method, t_end, rtol=value, atol=value * problem.atol_scale)
    return lambda: _peer(problem, method, value, t_end, limit)


def setting_of(method: str, value: float) -> str:
    return f"h={value:g}" if method in FIXED else f"rtol={value:g}"


def reference(problem: WorkProblem) -> Reference:
    """Our DP45 at rtol 1e-13, with its distances to scipy DOP853 and our Rodas4 at rtol 1e-12."""
    t0 = time.perf_counter()
    try:
        ref, _ = runner(problem, "dp45", REF_RTOL)()
    except SolverDivergence as exc:
        raise ValueError(f"{problem.name}: the reference run (dp45 rtol={REF_RTOL:g}) failed, nothing to chart "
                         f"against: {_one_line(exc)}") from None
    wall = time.perf_counter() - t0
    distances, failures = {}, {}
    for method in ("scipy DOP853", "rodas4"):
        key = f"{method} rtol={CHECK_RTOL:g}"
        try:
            y, _ = runner(problem, method, CHECK_RTOL)()
        except (SolverDivergence, RuntimeError) as exc:
            failures[key] = _one_line(exc)
            continue
        distances[key] = problem.error(y, ref)
    return Reference(ref, f"dp45 rtol={REF_RTOL:g}", distances, wall, failures)


MIN_TIMED = 0.1      # s: a fast run is repeated until this much was timed (its best of many, not of three)
MAX_RUNS = 50


def measure(problem: WorkProblem, method: str, value: float, ref: Reference, repeats: int = 3,
            budget: float = 1.0, limit: float | None = None) -> Row:
    """One row: best wall time of ``repeats`` runs (fewer once they took ``budget`` s together; more, up to
    :data:`MAX_RUNS`, until :data:`MIN_TIMED` s were timed: a run of a few ms is noisy on a shared machine).
    ``limit``: wall seconds a run may take (a peer is stopped there: status ``timeout``; ours, compiled, end
    their run, which is then ``timeout`` too when it took longer)."""
    run, setting = runner(problem, method, value, limit=limit), setting_of(method, value)
    best, spent, n = math.inf, 0.0, 0
    while n == 0 or (spent < budget and (n < repeats or (spent < MIN_TIMED and n < MAX_RUNS))):
        t0 = time.perf_counter()
        try:
            y, nfev = run()
        except TimeLimit as exc:
            return Row(method, setting, math.nan, time.perf_counter() - t0, None, problem.t_sim,
                       f"timeout: {_one_line(exc)}")
        except SolverDivergence as exc:
            return Row(method, setting, math.nan, time.perf_counter() - t0, None, problem.t_sim,
                       "diverged: " + _one_line(exc))
        except (RuntimeError, ValueError, ArithmeticError) as exc:
            return Row(method, setting, math.nan, time.perf_counter() - t0, None, problem.t_sim,
                       "failed: " + _one_line(exc))
        dt = time.perf_counter() - t0
        best, spent, n = min(best, dt), spent + dt, n + 1
    if limit is not None and best > limit:
        return Row(method, setting, math.nan, best, nfev, problem.t_sim,
                   f"timeout: {method} took {best:.3g} s, over the time limit of {limit:g} s")
    err = problem.error(y, ref.y)
    if not math.isfinite(err):
        status = "diverged: non-finite output"
    elif err > 1.0:
        status = f"inaccurate: relative error {err:.2g} > 1 and no divergence reported by the method"
    elif err < RESOLVE * ref.uncertainty:
        status = f"unresolved: error below {RESOLVE:g}x the reference uncertainty {ref.uncertainty:.1e}"
    else:
        status = "ok"
    return Row(method, setting, err, best, nfev, problem.t_sim, status)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


WARM_LIMIT = 30.0     # s a peer's warm-up run may take


def warm_up(problem: WorkProblem, methods: tuple[str, ...]) -> None:
    """Compile / load every method's code (numba caches, imports) on the whole span at its coarsest setting of the
    quick sweep: every path the measured runs take (events, restarts) — a short span missed some, and with a cold
    cache a measured run over a second then timed its compilation (1.97 s for 0.04 s) and was not repeated."""
    for method in methods:
        value = problem.quick.steps[method][0] if method in FIXED else max(problem.quick.tols)
        try:
            runner(problem, method, value, limit=WARM_LIMIT)()
        except (SolverDivergence, TimeLimit, RuntimeError, ValueError, ArithmeticError):
            pass                            # reported by the measured runs


def run_count(problem: WorkProblem, quick: bool = False, methods: tuple[str, ...] = METHODS) -> int:
    """How many runs :func:`work_precision` makes (its progress total)."""
    sweeps = problem.quick if quick else problem.full
    return sum(len(sweeps.steps[m]) if m in FIXED else len(sweeps.tols) for m in methods)


def work_precision(problem: WorkProblem, quick: bool = False, methods: tuple[str, ...] = METHODS,
                   repeats: int | None = None, log: Callable[[str], None] = print, limit: float | None = None,
                   done: Callable[[Row, str], None] | None = None) -> Result:
    """All rows of the problem's sweeps (``quick``: the short ones) for ``methods``; ``log`` gets the reference and
    warnings, and each run's line unless ``done`` is given: then ``done(row, line)`` gets them (a progress bar).
    ``limit``: wall seconds per run (None: none); after a run over it, a method's finer settings (smaller steps,
    tighter tolerances: slower still) are not run and get the status ``skipped: …``."""
    sweeps = problem.quick if quick else problem.full
    repeats = repeats or (3 if quick else 5)
    warm_up(problem, methods)
    ref = reference(problem)
    log(f"{problem.name}: reference {ref.label} ({ref.wall_s:.2f} s); {ref.describe()}")
    if not ref.confirmed:
        log(f"WARNING: {problem.name}: the reference is NOT confirmed (distance {ref.uncertainty:.1e} > "
            f"{REF_CONFIRM:g}); errors below {RESOLVE * ref.uncertainty:.1e} are marked unresolved")
    rows = []
    for method in methods:
        over = None                                  # the setting that ran over the limit
        for value in (sweeps.steps[method] if method in FIXED else sweeps.tols):
            row = (measure(problem, method, value, ref, repeats, limit=limit) if over is None else
                   Row(method, setting_of(method, value), math.nan, math.nan, None, problem.t_sim,
                       f"skipped: {over} ran over the time limit of {limit:g} s"))
            if over is None and row.status.startswith("timeout"):
                over = row.setting
            rows.append(row)
            line = f"  {row.method:26s} {row.setting:16s} " + (
                f"error {row.error:9.2e}  wall {row.wall_s * 1e3:9.2f} ms  nfev {row.nfev:8d}  "
                f"{row.t_sim / row.wall_s:8.1f}x real time" if row.status == "ok" else row.status[:110])
            (log(line) if done is None else done(row, line))
    return Result(problem, ref, rows)


def reference_row(result: Result) -> Row:
    """The reference as a CSV row: setting names the confirmations and distances, error the larger distance."""
    ref = result.reference
    setting = f"{ref.label} vs " + "; ".join([f"{k}: {d:.2e}" for k, d in ref.distances.items()]
                                             + [f"{k}: failed" for k in ref.failures])
    status = "reference" if ref.confirmed else f"reference unconfirmed: distance {ref.uncertainty:.1e} > {REF_CONFIRM:g}"
    return Row("reference", setting, ref.uncertainty, ref.wall_s, None, result.problem.t_sim, status)


def write_csv(result: Result, path: Path) -> None:
    """``path``: the columns :data:`COLUMNS`, the reference row first."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for r in [reference_row(result)] + result.rows:
            w.writerow([r.method, r.setting, f"{r.error:.6e}", f"{r.wall_s:.6e}", "" if r.nfev is None else r.nfev,
                        f"{r.t_sim:g}", r.status])


def read_csv(path: Path, problem: WorkProblem) -> Result:
    """The result a :func:`write_csv` file holds, measured on ``problem`` (its reference row gives the reference's
    label, distances (the largest exactly, the others to the 3 digits the file keeps) and failures; the reference
    states are not in the file). ValueError naming the file and line when it is not such a file."""
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None or tuple(header) != COLUMNS:
            raise ValueError(f"{path}: not a work-precision CSV (its first line must be {','.join(COLUMNS)})")
        try:
            rows = [Row(m, s, float(e), float(w), int(n) if n else None, float(t), st) for m, s, e, w, n, t, st in reader]
        except ValueError as exc:
            raise ValueError(f"{path} line {reader.line_num}: {exc}") from None
    if not rows or rows[0].method != "reference":
        raise ValueError(f"{path}: the first row must be the reference")
    ref, rows = rows[0], rows[1:]
    spans = {r.t_sim for r in rows} | {ref.t_sim}
    if spans != {problem.t_sim}:
        raise ValueError(f"{path}: measured over {', '.join(f'{t:g}' for t in sorted(spans))} s, the problem "
                         f"{problem.name} spans {problem.t_sim:g} s")
    label, _, checks = ref.setting.partition(" vs ")
    distances, failures = {}, {}
    for check in filter(None, checks.split("; ")):
        name, _, value = check.rpartition(": ")
        if value == "failed":
            failures[name] = "failed"
        else:
            distances[name] = float(value)
    if distances:                                            # the error column holds the largest one exactly
        distances[max(distances, key=distances.get)] = ref.error
    return Result(problem, Reference(np.empty(0), label, distances, ref.wall_s, failures), rows)


def best_runs(rows: list[Row], target: float = TARGET) -> dict[str, Row]:
    """Per method the cheapest (wall time) ok run with error ≤ ``target``."""
    best: dict[str, Row] = {}
    for r in rows:
        if r.status == "ok" and r.error <= target and (r.method not in best or r.wall_s < best[r.method].wall_s):
            best[r.method] = r
    return best


def wall_at(rows: list[Row], method: str, target: float = TARGET) -> float | None:
    """Wall time (s) of ``method`` at error = ``target``, interpolated log–log on its Pareto front (the ok runs no
    other run beats in both error and time) between the front's runs just below and just above ``target``; the
    cheapest run below it where none lies above; None where none reaches it. Unlike :func:`best_runs`, not tied to
    the tolerance grid: a run landing just above ``target`` (odeint at rtol 1e-7: error 1.03e-6) does not send the
    comparison half a decade on (to rtol 1e-8, 17 % dearer)."""
    runs = sorted(((r.error, r.wall_s) for r in rows if r.method == method and r.status == "ok"
                   and r.error > 0.0 and math.isfinite(r.error)), key=lambda x: (x[0], x[1]))
    front: list[tuple[float, float]] = []
    for error, wall in runs:                                   # increasing error: keep those cheaper than all before
        if not front or wall < front[-1][1]:
            front.append((error, wall))
    below = [x for x in front if x[0] <= target]
    above = [x for x in front if x[0] > target]
    if not below:
        return None
    (e0, w0) = below[-1]
    if not above or e0 == target:
        return w0
    (e1, w1) = above[0]
    f = math.log(target / e0) / math.log(e1 / e0)
    return w0 * (w1 / w0) ** f


def summary(result: Result, target: float = TARGET) -> list[str]:
    """One line per method (cheapest run with error ≤ target, its real-time factor), then ours against the best
    peer (any: scipy's solve_ivp and odeint, CVODE) and against the best of scipy's solve_ivp methods."""
    best = best_runs(result.rows, target)
    lines = [f"{result.problem.name}: cheapest run with error <= {target:g} per method (error: the relative max error in "
             f"{result.problem.quantity} against the reference; t_sim {result.problem.t_sim:g} s):"]
    for method in dict.fromkeys(r.method for r in result.rows):
        r = best.get(method)
        stopped = Counter(x.status.split(":")[0] for x in result.rows if x.method == method and x.status != "ok")
        why = f" ({', '.join(f'{n} {status}' for status, n in stopped.items())})" if stopped else ""
        lines.append(f"  {method:26s} " + (f"{r.setting:16s} wall {r.wall_s * 1e3:9.2f} ms  error {r.error:.1e}  "
                                           f"{r.t_sim / r.wall_s:8.1f}x real time" if r else
                                           f"no run reached {target:g}{why}"))
    ours = min((r for m, r in best.items() if m in OURS), key=lambda r: r.wall_s, default=None)
    solve_ivp = tuple(p for p in PEERS if p.startswith("scipy") and "odeint" not in p)
    for label, group in (("best peer", PEERS), ("best solve_ivp", solve_ivp)):
        peer = min((r for m, r in best.items() if m in group), key=lambda r: r.wall_s, default=None)
        if ours and peer:
            lines.append(f"  ours best ({ours.method} {ours.setting}, {ours.t_sim / ours.wall_s:.1f}x real time) vs "
                         f"{label} ({peer.method} {peer.setting}): {peer.wall_s / ours.wall_s:.1f}x faster")
        else:
            lines.append(f"  ours vs {label}: no comparison (" + ("ours" if not ours else label) +
                         f" never reached {target:g})")
    at = {m: w for m in dict.fromkeys(r.method for r in result.rows)
          if (w := wall_at(result.rows, m, target)) is not None}
    mine = min((m for m in at if m in OURS), key=at.get, default=None)
    peer = min((m for m in at if m in PEERS), key=at.get, default=None)
    if mine and peer:
        lines.append(f"  at equal error {target:g} (each method's time interpolated on its Pareto front, not tied to the "
                     f"tolerance grid): ours {mine} {at[mine] * 1e3:.2f} ms vs {peer} {at[peer] * 1e3:.2f} ms: "
                     f"{at[peer] / at[mine]:.1f}x faster")
    return lines
