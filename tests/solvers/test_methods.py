"""The one-step methods behind one interface: orders of convergence on closed forms, stability limits and clear
divergence reports, the implicit method on a stiff problem, compiled runs against the Python steps."""
import math
import warnings

import numpy as np
import pytest
from numba import njit

from rig.solvers import (
    DOP853,
    METHODS,
    RK4,
    DormandPrince45,
    Euler,
    Event,
    Problem,
    Rodas4,
    SolverDivergence,
    StiffnessError,
    StiffnessWarning,
    SymplecticEuler,
    Tsitouras45,
    integrate,
)
from rig.solvers.compiled import JitRhs

W = 3.0
FIXED = ("Euler", "SymplecticEuler", "RK4")


@njit(cache=True)
def _oscillator(t, y, p, out):
    """q'' = −ω²q − 2ζωq' with p = (ω, ζ, t_r, t_nan, k, breaks…), state (q, q'); t_r is the restart time of
    :func:`_crossings`. The derivatives are NaN after t_nan (a model that cannot go on), and ω jumps k-fold and back
    at each break (left-continuous: after the time, so the RHS jumps there and the step after it is refused). One
    kernel for the tests of this file: each kernel costs every method a numba compilation (~10 s)."""
    w = p[0]
    for tb in p[5:]:
        if t > tb:
            w = p[0] * p[4] if w == p[0] else p[0]
    out[0] = y[1] if t <= p[3] else math.nan
    out[1] = -w * w * y[0] - 2.0 * p[1] * w * y[1]


@njit(cache=True)
def _crossings(t, y, p, k):
    """Event 0: q = 0; event 1: t = p[2] (restart)."""
    return y[0] if k == 0 else t - p[2]


@njit(cache=True)
def _stiff(t, y, p, out):
    """y0' = −λ(y0 − cos t) − sin t (solution cos t), y1' = −2·y1; λ = p[0]."""
    out[0] = -p[0] * (y[0] - math.cos(t)) - math.sin(t)
    out[1] = -2.0 * y[1]


def oscillator(t, y):
    return (y[1], -W * W * y[0])


def stiff(lam: float):
    return lambda t, y: (-lam * (y[0] - math.cos(t)) - math.sin(t), -2.0 * y[1])


def _error_at(method: str, h: float, t_end: float = 2.0) -> float:
    """|q − cos ωt| at t_end with step h (adaptive methods forced to h: tolerance far above their error)."""
    opts = {"h": h} if method in FIXED else {"rtol": 1.0, "atol": 1.0, "first_step": h, "max_step": h}
    sol = integrate(Problem(oscillator, (1.0, 0.0)), (0.0, t_end), method=method, **opts)
    return abs(sol.y_final[0] - math.cos(W * t_end))


@pytest.mark.parametrize("method, h, order", [("Euler", 1e-3, 1), ("SymplecticEuler", 1e-3, 1), ("RK4", 0.02, 4),
                                              ("DP45", 0.05, 5), ("Tsit5", 0.025, 5), ("DOP853", 0.2, 8),
                                              ("Rodas4", 0.05, 4)])
def test_order_of_convergence_on_the_harmonic_oscillator(method, h, order):
    errors = [_error_at(method, h / 2 ** k) for k in range(3)]
    observed = [math.log2(a / b) for a, b in zip(errors, errors[1:])]
    assert observed == pytest.approx([order, order], abs=0.3 if order < 8 else 0.4), errors   # DOP853: pre-asymptotic


def test_symplectic_euler_keeps_the_energy_error_bounded_where_explicit_euler_drifts():
    h, periods = 0.01, 20
    t = np.linspace(0.0, periods * 2 * math.pi / W, 2001)
    energy = {}
    for method in ("SymplecticEuler", "Euler"):
        with warnings.catch_warnings(record=True) as caught:    # explicit Euler's growth is reported, not stopped
            warnings.simplefilter("always")
            sol = integrate(Problem(oscillator, (1.0, 0.0)), (0.0, t[-1]), method=method, h=h, t_eval=t,
                            stiffness="warn")
        reported = [w for w in caught if issubclass(w.category, StiffnessWarning)]
        assert bool(reported) == (method == "Euler")
        energy[method] = 0.5 * (sol.y[1] ** 2 + W * W * sol.y[0] ** 2) / (0.5 * W * W) - 1.0
    sym, eul = energy["SymplecticEuler"], energy["Euler"]
    first, last = np.abs(sym[:200]).max(), np.abs(sym[-200:]).max()
    assert last < 1.2 * first < 2.4 * h * W                   # O(hω), oscillating, no growth over 20 periods
    assert eul[-1] > 1.0 and eul[-1] > 50 * last                # (1 + h²ω²)^n: the energy more than doubles


@pytest.mark.parametrize("method, limit", [("Euler", 2.0), ("RK4", 2.78)])
def test_explicit_fixed_step_stability_limit_on_the_real_axis(method, limit):
    """y' = −λy: stable just inside h·λ = limit, reported as divergence (naming h·|λ| and the fix) outside. Inside,
    explicit Euler keeps the mode alive (R = −0.94 per step where the exact flow keeps 0.14): warned as inaccurate;
    RK4's R = 0.87 lets it go within the run's first steps: not warned."""
    from rig.solvers import ResolutionWarning
    lam = 1000.0
    decay = Problem(lambda t, y: (-lam * y[0],), (1.0,))
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        inside = integrate(decay, (0.0, 0.5), method=method, h=0.97 * limit / lam)
    warned = [str(w.message) for w in said if issubclass(w.category, ResolutionWarning)]
    assert abs(inside.y_final[0]) < 1e-3
    assert (len(warned), method) in ((1, "Euler"), (0, "RK4"))
    assert not warned or "lambda = -1000+0j 1/s with an error of 1.2 of the mode per step" in warned[0]
    exact = {"Euler": 2.0, "RK4": 2.785293563}[method]      # where |R(-x)| = 1 on the negative real axis
    with pytest.raises(StiffnessError, match=rf"unstable at t = .*lambda = -1000\+0j 1/s .*h\*\|lambda\| = "
                                             rf"{1.05 * limit:.3g}.* reduce h below {exact / lam:.3g} s or use the "
                                             rf"implicit method Rodas4"):
        integrate(decay, (0.0, 0.2), method=method, h=1.05 * limit / lam)


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("method", ["Euler", "RK4"])
def test_divergence_is_never_silent(method, compiled):
    """λ = 1e4, h = 1 ms (h·λ = 10): the stiffness test stops the run; with it switched off the state overflows
    and the error still names method, time, step and cause."""
    fun = JitRhs(_stiff, lambda: np.array([1e4])) if compiled else stiff(1e4)
    label, limit = {"Euler": ("explicit Euler", 2.0), "RK4": ("RK4", 2.78)}[method]
    with pytest.raises(StiffnessError, match=rf"{label} unstable at t = .*lambda = -1e\+04\+0j 1/s .*h\*\|lambda\| = "
                                             rf"10\b.*reduce h below"):
        integrate(Problem(fun, (1.0, 1.0)), (0.0, 2.0), method=method, h=1e-3, compiled=compiled)
    exact = {"Euler": 2.0, "RK4": 2.785293563}[method] / 1e4       # the stable step, from the amplification test
    with pytest.raises(SolverDivergence, match=rf"{label} diverged: non-finite state after a step of h = 0.001 s; "
                                               rf"{label} unstable(?: from the run's start,)?(?: at t = [^:]*)?: "
                                               rf"(the step amplified the mode lambda = -1e\+04\+0j "
                                               rf"1/s by .* per step \(h\*\|lambda\| = 10\) - reduce h below "
                                               rf"{exact:.3g}|h\*\|lambda\| = 10 > .* reduce h below {limit * 1e-4:.3g})"
                                               rf" s or use the implicit method Rodas4; state at t = "):
        integrate(Problem(fun, (1.0, 1.0)), (0.0, 2.0), method=method, h=1e-3, stiffness="ignore", compiled=compiled)


@pytest.mark.parametrize("compiled", [False, True])
def test_rodas4_is_accurate_and_stable_where_explicit_methods_diverge(compiled):
    fun = JitRhs(_stiff, lambda: np.array([1e4])) if compiled else stiff(1e4)
    t = np.linspace(0.0, 2.0, 21)
    sol = integrate(Problem(fun, (1.0, 1.0)), (0.0, 2.0), method="Rodas4", rtol=1e-6, atol=1e-9, t_eval=t,
                    compiled=compiled)
    assert np.max(np.abs(sol.y - [np.cos(t), np.exp(-2 * t)])) < 1e-5
    assert sol.nsteps < 100 and sol.stiff_at is None          # h·λ up to ~1e3
    forced = integrate(Problem(fun, (1.0, 1.0)), (0.0, 2.0), method="Rodas4", rtol=1.0, atol=1.0, first_step=0.1,
                       max_step=0.1, compiled=compiled)        # h·λ = 1000 on every step: L-stable, no blow-up
    assert forced.nsteps == 20 and abs(forced.y_final[0] - math.cos(2.0)) < 1e-3


@pytest.mark.parametrize("method", ["Euler", "SymplecticEuler", "RK4", "DP45", "Tsit5", "DOP853", "Rodas4"])
def test_compiled_runs_take_the_python_steps(method):
    """Same kernel, events (a recorded crossing and a restart), dense output: the compiled runs and the Python
    steps agree on steps, RHS calls, samples and event times."""
    p = np.array([W, 0.05, 0.77, math.inf, 1.0])
    opts = {"h": 2e-3} if method in FIXED else {"rtol": 1e-8, "atol": 1e-10}
    t = np.linspace(0.0, 2.0, 41)
    runs = []
    for compiled in (True, False):
        events = [Event(lambda tt, y: y[0], "zero"), Event(lambda tt, y: tt - p[2], "restart", restart=True)]
        fun = JitRhs(_oscillator, lambda: p, event=_crossings)
        runs.append(integrate(Problem(fun, (1.0, 0.0), events), (0.0, 2.0), method=method, t_eval=t,
                              compiled=compiled, **opts))
    a, b = runs
    # Rodas4: its hand-written LU (compiled) and LAPACK (Python) round differently, which may flip an
    # accept/reject decision: the same steps up to that, then agreement to the tolerance
    implicit = method == "Rodas4"
    assert abs(a.nsteps - b.nsteps) <= (1 if implicit else 0) and a.restarts == b.restarts == 1
    assert abs(a.nfev - b.nfev) <= (25 if implicit else 0)         # a flipped decision: a step or two
    np.testing.assert_allclose(a.y, b.y, rtol=1e-7 if implicit else 1e-9, atol=1e-11)
    assert [r.name for r in a.events] == [r.name for r in b.events] and len(a.t_events["zero"]) == 2
    np.testing.assert_allclose([r.t for r in a.events], [r.t for r in b.events], rtol=1e-8 if implicit else 1e-10)
    zeta, wd = 0.05, W * math.sqrt(1 - 0.05 ** 2)                                # the damped closed form
    exact = np.exp(-zeta * W * t) * (np.cos(wd * t) + zeta * W / wd * np.sin(wd * t))
    assert np.max(np.abs(a.y[0] - exact)) < {"Euler": 0.02, "SymplecticEuler": 0.01}.get(method, 1e-4)


@pytest.mark.parametrize("method", ["RK4", "DP45", "Tsit5", "Rodas4"])
def test_compiled_runs_pass_time_breaks_as_the_driver_does(method, monkeypatch):
    """Time breaks (the frequency jumping 20-fold and back at 12 times, some 20 µs apart, the steps after them refused): the compiled runs restart past each themselves
    (one ulp on, f there, the step size kept within the next segment) where the driver started a new solver for each — as it still does for a problem with
    a mode to re-select (``reset``). Same steps, RHS calls, restarts and states either way; and as the Python steps
    (Rodas4: to its LU's rounding, a decision or two apart)."""
    breaks = np.array([0.6, 0.63, 0.9, 0.95, 1.3, 1.32, 1.6, 1.64, 1.8, 1.81, 1.9, 1.90002])   # fast phases, short
    p = np.r_[W, 0.05, 20.0, math.inf, 20.0, breaks]     # ω jumping 20-fold at the breaks; the restart at t = 20
    opts = {"h": 2e-3} if method in FIXED else {"rtol": 1e-6, "atol": 1e-8}
    t = np.linspace(0.0, 2.0, 41)

    import sys
    driver = sys.modules["rig.solvers.integrate"]
    made = []

    def run(compiled, reset=None):
        fun = JitRhs(_oscillator, lambda: p, event=_crossings)
        problem = Problem(fun, (1.0, 0.0), [Event(lambda tt, y: y[0], "zero")], time_breaks=list(breaks), reset=reset)
        made.append(0)
        return integrate(problem, (0.0, 2.0), method=method, t_eval=t, compiled=compiled, **opts)

    def counting(*args):
        made[-1] += 1
        return make(*args)

    make = driver._make_solver
    monkeypatch.setattr(driver, "_make_solver", counting)
    passed, segments, python = run(True), run(True, reset=lambda tt, y: False), run(False)
    assert made == [1, 13, 13]                    # one solver across the breaks, else one per segment
    for other in (segments, python):
        implicit = other is python and method == "Rodas4"
        assert passed.restarts == other.restarts == 12
        if not implicit:                        # Rodas4's LU rounds otherwise in Python: decisions a few steps apart
            assert (passed.nsteps, passed.nfev) == (other.nsteps, other.nfev)
        exact = other is segments              # the same compiled steps; the Python steps round otherwise
        np.testing.assert_allclose(passed.y, other.y, rtol=1e-13 if exact else 1e-5 if implicit else 1e-9,
                                   atol=1e-12 if exact else 1e-9)          # Rodas4 vs Python: to its tolerance
        np.testing.assert_allclose(passed.t_events["zero"], other.t_events["zero"],
                                   rtol=1e-14 if exact else 1e-5 if implicit else 1e-8)


@pytest.mark.parametrize("cls, opts", [(Euler, {"h": 0.01}), (SymplecticEuler, {"h": 0.01}), (RK4, {"h": 0.01}),
                                       (DormandPrince45, {"rtol": 1e-8, "atol": 1e-10}),
                                       (Tsitouras45, {"rtol": 1e-8, "atol": 1e-10}),
                                       (DOP853, {"rtol": 1e-8, "atol": 1e-10}),
                                       (Rodas4, {"rtol": 1e-8, "atol": 1e-10})])
def test_solver_objects_share_one_interface(cls, opts):
    """step(), dense_output() over the last step, status, nfev and nsteps — each method as a class."""
    s = cls(oscillator, 0.0, (1.0, 0.0), 0.5, **opts)
    worst = 0.0
    while s.status == "running":
        s.step()
        for th in (0.25, 0.5, 0.75):
            tt = s.t_old + th * (s.t - s.t_old)
            worst = max(worst, abs(s.dense_output()(tt)[0] - math.cos(W * tt)))
    assert s.status == "finished" and s.t == 0.5 and s.nsteps > 0 and s.nfev >= s.nsteps
    assert worst < (0.02 if cls in (Euler, SymplecticEuler) else 1e-6)
    assert cls in METHODS.values()
    with pytest.raises(RuntimeError):
        s.step()



@njit(cache=True)
def _quintic(t, y, p, out):
    """y' = 5t⁴: DP45's step integrates it exactly (order 5), its quartic dense output does not."""
    out[0] = 5.0 * t ** 4


@njit(cache=True)
def _level(t, y, p, k):
    """Event 0: y = p[0] (a restart the compiled runs take themselves, :func:`_plain_restart`)."""
    return y[0] - p[0]


@njit(cache=True)
def _plain_restart(t, y, p, k, apply):
    return k == 0


def test_at_a_plain_restart_the_state_is_a_step_of_the_method_not_the_interpolant():
    """y = t⁵ crosses 0.5: the root is found on the dense output (quartic, not exact for t⁵), but the state the run
    restarts from is one DP45 step landing on it (exact for t⁵), in the Python driver and in the compiled runs
    (restart taken by Python or inside the run) alike; the interpolant's value is off by far more."""
    p = np.array([0.5])
    interpolant = []
    for compiled, act in ((False, None), (True, None), (True, _plain_restart)):
        fun = JitRhs(_quintic, lambda: p, event=_level, act=act)
        sol = integrate(Problem(fun, (0.0,), [Event(lambda tt, y: y[0] - p[0], "level", restart=True)]),
                        (0.0, 1.2), method="DP45", compiled=compiled, rtol=1e-3, atol=1e-3, first_step=0.5)
        (rec,) = sol.events
        assert abs(rec.t - 0.5 ** 0.2) < 1e-3 and sol.y_final[0] == pytest.approx(1.2 ** 5, rel=1e-12)
        assert abs(rec.y[0] - rec.t ** 5) < 1e-14, (compiled, act)        # the step's exact state at the root
        interpolant.append(abs(p[0] - rec.t ** 5))                        # the dense output's value there is 0.5
    assert min(interpolant) > 1e-6                                       # what the interpolant would have given


@pytest.mark.parametrize("method", ["DP45", "RK4"])
def test_a_time_break_within_an_ulp_of_the_end_is_not_a_restart(method):
    """A break one ulp before t_bound (a cam-program boundary computed as 1.4 s at the end of a level-2 chunk
    ending at 1.4000000000000001 s) used to leave the restarted solver an empty span and stop the run."""
    tf = math.nextafter(1.4, 2.0)
    opts = {"h": 1e-3} if method in FIXED else {"rtol": 1e-8, "atol": 1e-10}
    for breaks in ([1.4], [math.nextafter(1.0, 0.0), 1.4]):
        sol = integrate(Problem(oscillator, (1.0, 0.0), time_breaks=breaks), (1.0, tf), method=method,
                        t_eval=np.array([1.0, 1.2, tf]), y0=(1.0, 0.0), **opts)
        assert sol.status == "finished" and sol.t[-1] == tf
        exact = math.cos(W * (tf - 1.0))
        assert sol.y[0, -1] == pytest.approx(exact, abs=1e-4 if method in FIXED else 1e-7)


@pytest.mark.parametrize("compiled", [False, True])
def test_dop853_takes_scipys_steps(compiled):
    """The same tableau, error norm and controller as scipy's DOP853: the same step times and the same solution to
    rounding, and its 7th-order dense output (our polynomial form of scipy's nested one) gives scipy's samples."""
    from scipy.integrate import solve_ivp
    p = np.array([W, 0.05, 1e9, math.inf, 1.0])
    fun = JitRhs(_oscillator, lambda: p)
    t = np.linspace(0.0, 2.0, 41)
    for rtol in (1e-4, 1e-9):
        steps = integrate(Problem(fun, (1.0, 0.0)), (0.0, 2.0), method="DOP853", rtol=rtol, atol=rtol,
                          compiled=compiled, first_step=1e-3)
        samples = integrate(Problem(fun, (1.0, 0.0)), (0.0, 2.0), method="DOP853", t_eval=t, rtol=rtol, atol=rtol,
                            compiled=compiled, first_step=1e-3)
        ref = solve_ivp(lambda tt, y: fun(tt, y), (0.0, 2.0), (1.0, 0.0), method="DOP853", t_eval=t, rtol=rtol,
                        atol=rtol, first_step=1e-3, dense_output=True)
        np.testing.assert_allclose(steps.t, ref.sol.ts, rtol=1e-8, atol=1e-15)          # norms round differently
        np.testing.assert_allclose(samples.y, ref.y, rtol=1e-10, atol=1e-12)


def test_dop853_tableau_is_scipys():
    """Our copy of the DOP853 coefficients equals scipy's (a private module: skipped when scipy moves it)."""
    theirs = pytest.importorskip("scipy.integrate._ivp.dop853_coefficients")
    from rig.solvers import dop853_tableau as ours
    for name in ("C", "A", "B", "E3", "E5", "D"):
        np.testing.assert_array_equal(getattr(ours, name), getattr(theirs, name), err_msg=name)


@njit(cache=True)
def _two_oscillators(t, y, p, out):
    """Two coupled oscillators, state interleaved (q1, v1, q2, v2) as the plants lay theirs out."""
    out[0] = y[1]
    out[1] = -p[0] * y[0] + 0.3 * (y[2] - y[0]) - 0.1 * y[1]
    out[2] = y[3]
    out[3] = -2.0 * p[0] * y[2] + 0.3 * (y[0] - y[2])


@njit(cache=True)
def _two_oscillators_split(t, y, p, out):
    """The same with the positions first: (q1, q2, v1, v2)."""
    out[0] = y[2]
    out[1] = y[3]
    out[2] = -p[0] * y[0] + 0.3 * (y[1] - y[0]) - 0.1 * y[2]
    out[3] = -2.0 * p[0] * y[1] + 0.3 * (y[0] - y[1])


@pytest.mark.parametrize("compiled", [True, False])
def test_symplectic_euler_takes_the_positions_the_problem_names(compiled):
    """Symplectic Euler split the state into its first and second half whatever the plant's layout: on the level-2
    state (e, τė, φ, ω, …) and the clutch's (φr, ωr, φ3, ω3) it drifted velocities with kicked velocities (an audit:
    error 0.89 where the method converges). The problem's ``positions`` now give the split: the interleaved system
    steps exactly as the same system written positions-first, compiled or in Python."""
    p = np.array([4.0])
    inter = Problem(JitRhs(_two_oscillators, lambda: p), (1.0, 0.0, -0.5, 0.2), positions=(0, 2))
    split = Problem(JitRhs(_two_oscillators_split, lambda: p), (1.0, -0.5, 0.0, 0.2))
    a = integrate(inter, (0.0, 3.0), method="SymplecticEuler", h=0.01, compiled=compiled)
    b = integrate(split, (0.0, 3.0), method="SymplecticEuler", h=0.01, nq=2, compiled=compiled)
    np.testing.assert_array_equal(a.y[[0, 2, 1, 3]], b.y)
    halves = integrate(Problem(inter.fun, inter.y0), (0.0, 3.0), method="SymplecticEuler", h=0.01, compiled=compiled)
    assert not np.allclose(halves.y, a.y)          # the old default split is another (non-symplectic) scheme
    with pytest.raises(ValueError, match="leaving at least one velocity"):
        SymplecticEuler(inter.fun, 0.0, inter.y0, 1.0, h=0.01, positions=(0, 1, 2, 3))
    with pytest.raises(ValueError, match="not both"):
        SymplecticEuler(inter.fun, 0.0, inter.y0, 1.0, h=0.01, positions=(0, 2), nq=2)


def test_an_amplification_beyond_float_range_is_reported_not_an_overflow():
    """The report's "N-fold since the run began" took exp() of the summed log-growth: past ~709 that raised
    OverflowError inside the report (rig bench stability stopped on three issue-14 scenes, an audit)."""
    from rig.solvers.base import StiffnessMonitor

    class Watch:
        def largest_stable_step(self, t, y, h):
            return 1e-5
    monitor = StiffnessMonitor("RK4", 2.78, "raise", fixed=True)
    monitor.watch = Watch()
    with pytest.raises(StiffnessError, match=r"10\^434-fold since the run began"):
        monitor._report_amplification(0.1, (1.0, 0.0), 4e-4, (3.0, 0.9, complex(-100.0, 4000.0)), 1000.0)


@pytest.mark.parametrize("method", ["RK4", "DP45", "Rodas4"])
def test_non_finite_derivatives_past_a_passed_break_are_reported_there(method):
    """The compiled run passing a break evaluates f one ulp past it; NaN there was stepped on (DP45 and Rodas4 shrank
    to a step-size underflow, RK4 blamed its step size). It hands the break back to the driver, whose new solver
    reports the derivatives at the break, as before."""
    p = np.array([W, 0.0, 0.7, 0.7, 1.0])                  # the derivatives NaN after t = 0.7
    opts = {"h": 2e-3} if method in FIXED else {"rtol": 1e-8, "atol": 1e-10}
    problem = Problem(JitRhs(_oscillator, lambda: p, event=_crossings), (1.0, 0.0),
                      [Event(lambda tt, y: y[0], "zero")], time_breaks=[0.3, 0.7])
    with pytest.raises(SolverDivergence, match=r"non-finite derivatives at the start; state at t = 0\.7\b"):
        integrate(problem, (0.0, 2.0), method=method, **opts)


def test_a_problem_with_a_closed_form_is_asked_at_every_break():
    """``flow`` is asked where each segment starts (the compiled runs do not pass breaks past it): from t = 1 on the
    decay has its closed form, and the run follows it there."""
    asked = []

    def flow(t, y, t_bound):
        asked.append(t)
        if t < 1.0:
            return None

        class Exact:
            stops: list = []

            def __call__(self, tt):
                return (y[0] * np.exp(-(np.asarray(tt) - t)),) if np.ndim(tt) else (y[0] * math.exp(-(tt - t)),)
        return Exact()

    p = np.array([0.0])
    problem = Problem(JitRhs(_decay, lambda: p, event=_decay_events), (1.0,), [Event(lambda tt, y: y[0] - 2.0, "never")],
                      time_breaks=[0.5, 1.0, 1.5], flow=flow)
    sol = integrate(problem, (0.0, 2.0), rtol=1e-10, atol=1e-12)
    assert [round(a, 12) for a in asked] == [0.0, 0.5, 1.0, 1.5] and abs(sol.y_final[0] - math.exp(-2.0)) < 1e-9


@njit(cache=True)
def _decay(t, y, p, out):
    out[0] = -y[0]


@njit(cache=True)
def _decay_events(t, y, p, k):
    return y[0] - 2.0


@pytest.mark.parametrize("method", ["Euler", "RK4"])
def test_a_fixed_step_run_restarted_by_an_acted_event_keeps_its_step_and_grid(method):
    """y = t⁵ crosses 0.5 (RK4: at t ≈ 0.87, inside the step 0.8 → 0.88 that a time break at 0.88 cut to 0.08):
    the run restarts at the root (and the break), and from the last restart steps 0.1 again on its grid, whether the
    Python driver or the compiled run (``act``) restarts (the compiled restart kept the cut 0.08 as its step: 0.96,
    1.04, …, one step more)."""
    p = np.array([0.5])
    runs = []
    for compiled, act in ((False, None), (True, None), (True, _plain_restart)):
        fun = JitRhs(_quintic, lambda: p, event=_level, act=act)
        runs.append(integrate(Problem(fun, (0.0,), [Event(lambda tt, y: y[0] - p[0], "level", restart=True)],
                                      time_breaks=[0.88]), (0.0, 2.0), method=method, h=0.1, compiled=compiled))
    for sol in runs:
        (rec,) = sol.events
        assert 0.8 < rec.t < 0.88 if method == "RK4" else 0.88 < rec.t < 0.98     # Euler lags: after the break
        start = max(rec.t, 0.88)                           # the last restart (one ulp past the break: aside)
        after = sol.t[sol.t > start + 1e-9]
        assert np.allclose(after[:-1], start + 0.1 * np.arange(1, after.size), rtol=0, atol=1e-12), sol.t
    assert [s.nsteps for s in runs[1:]] == [runs[0].nsteps] * 2
    np.testing.assert_allclose(runs[2].t, runs[0].t, rtol=0, atol=1e-6)     # the root: found to Brent's tolerance
