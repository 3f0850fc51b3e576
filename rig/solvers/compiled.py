"""Right-hand sides compiled with numba, and the solvers compiled around them.

A problem whose RHS is a :class:`JitRhs` (a numba kernel ``kernel(t, y, p, out)`` on float64 arrays plus
its live parameter vector) lets every method of :mod:`rig.solvers` (explicit and symplectic Euler, RK4, DP45, Tsit5,
DOP853, Rodas4) run each step — all stages, the error norm, rejections and the step-size controller — in machine
code; with the problem's event kernels it runs whole stretches of steps, locates event roots and restarts at
simple events in machine code too, and the Python driver (:func:`rig.solvers.integrate`) only acts where the
problem needs it. Same method as each solver's Python step (tableau, norm, controller constants); the tests
check the two against each other. The compiled functions are written once as templates
(:mod:`rig.solvers.templates`) and instantiated per method and kernel by :func:`compiled_solver`.
"""
from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import re
import sys
import threading
from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path

import numpy as np
from numba import njit

from rig.solvers.base import SolverDivergence


class JitRhs:
    """A compiled RHS: ``kernel(t, y: float64[:], p: float64[:], out: float64[:])`` writing dy/dt into
    ``out``, with ``params()``
    returning its parameter vector p synchronised with the problem's discrete state (called when a
    solver segment starts and on every Python-side call), and ``diagnose()`` explaining non-finite
    derivatives (a message, or None). ``event(t, y, p, k)``, if given, is a compiled kernel for the value
    of event function k, in the order of ``Problem.events``: then the solvers take runs of steps in one
    compiled call until one of them changes sign, and locates roots in compiled code (:func:`compiled_solver`).
    ``act(t, y, p, k, apply)``, if given, tells whether event k (a restart without Python action) can be
    acted on in compiled code and, with ``apply``, does it by updating p: the run then restarts there
    itself. Callable as a plain ``fun(t, y) -> tuple`` (e.g. for scipy), NaN where the kernel finds no finite
    derivatives (a trial stage outside the model's range: a solver rejects the step and shrinks it; where a
    solver of ours cannot go on, :meth:`fail` names the cause)."""

    def __init__(self, kernel, params: Callable[[], np.ndarray], diagnose: Callable[[], str | None] = lambda: None,
                 event=None, act=None):
        self.kernel, self.params, self.diagnose, self.event, self.act = kernel, params, diagnose, event, act

    def __call__(self, t: float, y: Sequence[float]) -> tuple:
        out = np.empty(len(y))
        self.kernel(t, np.asarray(y, dtype=float), self.params(), out)
        return tuple(out.tolist())

    def fail(self, t: float, y: Sequence[float], what: str = "non-finite derivatives") -> None:
        """Raise :class:`SolverDivergence` with the kernel's diagnosis when it has one."""
        why = self.diagnose()
        raise SolverDivergence(f"{what}: {why}" if why else what, t, y)


@njit(cache=True)
def scratch_rows(n: int) -> int:
    """Rows of n floats a method's compiled step may use as scratch (its ``ws``) for a state of n components: 2n + 4,
    what Rodas4 needs (its Jacobian, iteration matrix, ∂f/∂t, a stage state, a derivative and the pivots); the
    explicit methods use up to three."""
    return 2 * n + 4


def run_scratch(n: int, events: int, stages: int, order: int, params: int) -> tuple[np.ndarray, ...]:
    """The scratch arrays a compiled run takes after its buffers (the run allocates nothing:
    :mod:`rig.solvers.templates.runs`), for a state of n components, that many events, a method with ``stages``
    stage rows and a continuous extension of that order, and a parameter vector of ``params`` floats."""
    return (np.empty((3 + scratch_rows(n), n)), np.empty(events), np.empty((n, order)), np.empty((stages, n)),
            np.empty(params))


#: slots of the compiled step's work vector: T, H_ABS (in, updated to t_new, h_next), T_BOUND, RTOL,
#: ATOL, MAX_STEP, QMASK (in: settings; QMASK = the position components of a (q, v) state as a bit mask, bit i for
#: component i), H, NFEV, HL, NEV, FAIL
#: (out: last step taken — or the failed one —, RHS calls, Hairer's stiffness estimate h·|λ|, events acted
#: on in a run, failure status of a run: 1 step-size underflow, 2 non-finite state of a fixed-step method), NBREAK
#: (in/out: how many of a run's further bounds ``BR`` it has passed, restarting past each as the driver would), IE
#: (in/out: index of the first output time a run has not sampled yet), T0 (in/out: where a fixed-step method's grid
#: t0 + k·h starts: the start, or the last restart of a run past a time break or an event it acted on)
T, H_ABS, T_BOUND, RTOL, ATOL, MAX_STEP, QMASK, H, NFEV, HL, NEV, FAIL, NBREAK, IE, T0 = range(15)
TEMPLATES = Path(__file__).with_name("templates")
_KERNELS = re.compile(r"# <kernels>\n.*?# </kernels>\n", re.DOTALL)
_INCLUDE = re.compile(r"^# <include (\w+)>\n", re.MULTILINE)     # a method template's shared part (templates/erk.py)
_IMPORTING = threading.Lock()   # threads (e.g. Dask worker threads) must not see a half-executed module


@cache
def compiled_solver(method: str, kernel, event=None, act=None):
    """Compiled steps of ``method`` ("dp45", "tsit5", "dop853", "rk4", "euler", "symplectic_euler", "rodas4": a template in
    :mod:`rig.solvers.templates`) for ``kernel`` (event kernels ``event``, ``act``: :class:`JitRhs`), cached:

    * ``step(w, y, y_new, K, f, p)`` advances from (w[T], y) with first derivative f by one accepted
      step, writing the new state into ``y_new``, the method's stage vectors into K (the last row is
      f(t_new, y_new)) and H, NFEV, HL and (on success) T, H_ABS into ``w``; returns 0, 1 on a step-size
      underflow (state untouched) or 2 when a fixed-step method's state became non-finite;
    * ``run(w, Y, TT, HH, KK, HL, EV, g, p, BR, *scratch, TE, OUT)`` (with ``event``; ``scratch`` from
      :func:`run_scratch`; output times TE and their states OUT, sampled from w[IE] on by every step but one where an
      event's sign changed) takes steps from (w[T], Y[0]) with KK[0, 0] the first derivative, storing step ends TT[s +
      1], states Y[s + 1], step sizes HH[s], stage vectors KK[s] and h·|λ| HL[s], until an event value in ``g`` (given
      at the start, updated in place) changes sign or reaches 0, t_bound is reached or the buffers are full; returns the
      number of steps, or −1 − steps on a failure (status in w[FAIL]). A t_bound that is a time break of the problem,
      with further bounds in ``BR`` (from w[NBREAK] on), is passed as :func:`rig.solvers.integrate` passes it: the run
      restarts one ulp past it (f evaluated there, an adaptive method's step size kept, the step's stored end TT[s + 1]
      that restart time), takes the next bound and counts it in w[NBREAK]. Sign changes that ``act`` accepts (all of
      them in the step, none exactly zero) are handled in the run as the Python driver would: cut at the earliest root
      (the step then ends there, TT[s + 1] < TT[s] + HH[s]), act, record (t, k, ±1, y) in EV[w[NEV]], restart with the
      last step size; the fired event keeps its value past the root, the others are re-evaluated (a zero keeps the old
      value);
    * ``locate(t_old, t_new, y_old, K, p, k)``: root of event k on the step's dense output by Brent's
      method (as scipy's ``brentq``, xtol 1e-15, rtol 4·eps), given a sign change over the step;
    * ``values(t, y, p, out)``: every event's value at (t, y) into ``out``.

    Arrays in, status out: numba's call overhead grows with the number of arguments and returned
    objects. The sign test is conservative (any change stops, whatever an event's direction): the
    Python driver then examines that last step as usual.

    Module-level njit functions only (``kernel.py_func`` importable by module and name). The shared part
    (``templates/runs.py``) and the method's step (with the templates it includes) are copied into one module
    in ``~/.cache/mechrig`` (``MECHRIG_CACHE``) with the kernels bound, and imported from there: numba then
    caches them like any module.
    """
    names = [_import_path(f) for f in (kernel, event, act)]
    binding = "\n".join(f"from {mod} import {name} as {alias}" if mod
                        else f"{alias} = {'never' if alias == 'act' else 'None'}"
                        for (mod, name), alias in zip(names, ("kernel", "event", "act")))
    step_source = (TEMPLATES / f"{method}.py").read_text()
    while _INCLUDE.search(step_source):         # included parts may include others (tsit5 → pair45 → erk)
        step_source = _INCLUDE.sub(lambda m: (TEMPLATES / f"{m[1]}.py").read_text(), step_source)
    step_source = _KERNELS.sub("", step_source)
    source = _KERNELS.sub(binding + "\n", (TEMPLATES / "runs.py").read_text())
    source = re.sub(r"# <method>\n.*?# </method>\n", lambda _: step_source, source, flags=re.DOTALL)
    # numba checks a cached function against its own file only: key the copy on everything it compiles in
    # (the kernels' packages, the solvers' tableaus and slot constants), so an edit there gives a new copy
    deps = set(Path(__file__).parent.glob("*.py"))
    deps |= {q for f in (kernel, event, act) if f is not None
             for q in Path(inspect.getsourcefile(f.py_func)).parent.glob("*.py")}
    digest = hashlib.sha1(source.encode() + b"".join(q.read_bytes() for q in sorted(deps))).hexdigest()[:16]
    folder = Path(os.environ.get("MECHRIG_CACHE") or Path.home() / ".cache" / "mechrig")
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{method}_{digest}.py"
    name = f"mechrig_{method}_{digest}"
    with _IMPORTING:
        if not path.exists() or path.read_text() != source:
            tmp = path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(source)
            os.replace(tmp, path)                   # atomic: parallel processes see whole files only
        module = sys.modules.get(name)
        if module is None:
            spec = importlib.util.spec_from_file_location(name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            spec.loader.exec_module(module)
    if event is None:
        return module.step, None, None, None
    return module.step, module.run, module.locate, module.values


def _import_path(f) -> tuple[str, str] | tuple[None, None]:
    """(module, name) under which the njit function ``f`` can be imported; (None, None) for None."""
    if f is None:
        return None, None
    mod, name = f.py_func.__module__, f.py_func.__name__
    if getattr(sys.modules.get(mod), name, None) is not f:
        raise ValueError(f"compiled solver: {name!r} must be a module-level numba function of an imported module")
    return mod, name
