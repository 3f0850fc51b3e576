"""The compiled DP45 step (numba) against the pure-Python step, on a generic kernel and on the clutch."""
import math

import numpy as np
import pytest
from numba import njit

from rig.plants.clutch import FlatTappetClutch
from rig.plants.clutch.dynamics import ClutchDynamics
from rig.plants.clutch.loads import LinearMotor, LoadSum, ShoeBrake, constant, shock
from rig.solvers import Event, Problem, SolverDivergence, integrate
from rig.solvers.compiled import JitRhs


@njit(cache=True)
def _van_der_pol(t, y, p, out):
    out[0] = y[1]
    out[1] = p[0] * (1.0 - y[0] * y[0]) * y[1] - y[0]


@njit(cache=True)
def _blow_up(t, y, p, out):
    out[0] = y[0] * y[0] if t < 0.5 else math.nan


def _vdp(mu: float = 2.0) -> JitRhs:
    p = np.array([mu])
    return JitRhs(_van_der_pol, lambda: p)


def test_jit_rhs_is_a_plain_callable():
    f = _vdp()
    assert f(0.0, (2.0, 1.0)) == pytest.approx((1.0, 2.0 * (1 - 4.0) * 1.0 - 2.0))


@pytest.mark.parametrize("rtol", [1e-4, 1e-8])
def test_compiled_step_takes_the_pure_python_steps(rtol):
    """Same method, same steps: the same number of steps and RHS calls, and step times, solution and
    events agreeing to rounding (amplified by the cancellation in the error estimate at tight rtol)."""
    ev = [Event(lambda t, y: y[0], "zero")]
    runs = [integrate(Problem(_vdp(), (2.0, 0.0), ev), (0.0, 8.0), rtol=rtol, atol=rtol * 1e-3, compiled=c)
            for c in (True, False)]
    a, b = runs
    assert a.nsteps == b.nsteps and a.nfev == b.nfev and a.nsteps > 20
    np.testing.assert_allclose(a.t, b.t, rtol=1e-7)
    np.testing.assert_allclose(a.y, b.y, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(a.t_events["zero"], b.t_events["zero"], rtol=1e-7)
    assert len(a.t_events["zero"]) >= 2


@njit(cache=True)
def _bounded(t, y, p, out):
    out[0] = 3.0 * (1.5 - y[0]) if abs(y[0]) < 2.0 else math.nan    # defined only on |y| < 2 (as a chain's range)


def test_jit_rhs_gives_nan_outside_its_range_so_a_foreign_solver_can_reject_the_step():
    """As a plain callable the RHS answers NaN where the kernel does (no exception): scipy's solver rejects such a
    trial step and shrinks it, and our solvers do the same; a start outside the range is an error naming it."""
    from scipy.integrate import solve_ivp
    f = JitRhs(_bounded, lambda: np.zeros(1), lambda: "outside |y| < 2")
    assert math.isnan(f(0.0, (3.0,))[0])
    exact = 1.5 * (1.0 - math.exp(-3.0))
    sol = solve_ivp(f, (0.0, 1.0), (0.0,), method="DOP853", rtol=1e-10, atol=1e-12, first_step=0.9)
    assert sol.success and sol.y[0, -1] == pytest.approx(exact, rel=1e-8)
    for compiled in (True, False):
        ours = integrate(Problem(f, (0.0,)), (0.0, 1.0), rtol=1e-10, atol=1e-12, first_step=0.9, compiled=compiled)
        assert ours.y[0, -1] == pytest.approx(exact, rel=1e-8)
    with pytest.raises(SolverDivergence, match="non-finite derivatives at the start.*outside"):
        integrate(Problem(f, (3.0,)), (0.0, 1.0))


def test_compiled_step_reports_underflow_with_the_kernel_diagnosis():
    f = JitRhs(_blow_up, lambda: np.zeros(1), lambda: "the test kernel returned NaN past t = 0.5 s")
    with pytest.raises(SolverDivergence, match="step size underflow.*NaN past t = 0.5 s"):
        integrate(Problem(f, (1.0,)), (0.0, 0.9), rtol=1e-6, atol=1e-9)


def test_clutch_run_compiled_and_pure_python_agree():
    """The clutch through a shock (stick–slip switches, restarts, disengagements): compiled runs of DP45
    steps with compiled root finding, and the Python step with scipy's brentq, take the same steps on the
    same kernel (up to an accept/reject decision flipped by rounding)."""
    c = FlatTappetClutch(r0=0.055, r1=0.130, r2=0.030, k_a=3000.0, F_a1=1284.0, J1=0.35, J3=0.02)
    runs = []
    for compiled in (True, False):
        d = ClutchDynamics(c, LinearMotor(437.708, 3.870), LoadSum([constant(5.0), shock(0.05, 0.05, 150.0)]))
        runs.append(integrate(d.problem((0.0, 0.0, 0.0, 111.8)), (0.0, 0.2), t_eval=np.linspace(0, 0.2, 201),
                              rtol=1e-8, atol=1e-11, compiled=compiled))
    a, b = runs
    assert len(a.t_events["apex"]) >= 1 and a.restarts > 5
    assert abs(a.nsteps - b.nsteps) <= 2
    np.testing.assert_allclose(a.t_events["apex"], b.t_events["apex"], rtol=1e-6)
    # segment boundaries restarted inside the compiled runs: the same events, times and states
    assert [r.name for r in a.events] == [r.name for r in b.events] and a.restarts == b.restarts
    np.testing.assert_allclose([r.t for r in a.events], [r.t for r in b.events], rtol=1e-6)
    early = [i for i, r in enumerate(b.events) if r.t < 0.1]              # before rounding is amplified
    assert len(early) >= 5
    np.testing.assert_allclose([a.events[i].y[:4] for i in early], [b.events[i].y[:4] for i in early],
                               rtol=1e-7, atol=1e-6)
    # up to 0.1 s (before the ratcheting amplifies rounding differences)
    np.testing.assert_allclose(a.y[:, :101], b.y[:, :101], rtol=1e-7, atol=1e-6)


def test_clutch_self_locking_is_named():
    """μ_C large enough for the tappet to lock in its guide: a clear error, not a silent NaN."""
    c = FlatTappetClutch(r0=0.055, r1=0.130, r2=0.030, k_a=3000.0, F_a1=1284.0, J1=0.35, J3=0.02, mu_C=2.0,
                         L1=0.14, L2=0.145)
    d = ClutchDynamics(c, LinearMotor(437.708, 3.870), ShoeBrake(0.01, 0.005, 5000.0))
    with pytest.raises(SolverDivergence, match="self-locks in its guide"):
        integrate(d.problem((0.3, 5.0, 0.0, 50.0, 5000.0)), (0.0, 0.1), rtol=1e-6, atol=1e-9)


@njit(cache=True)
def _unit_rate(t, y, p, out):
    out[0] = 1.0


@njit(cache=True)
def _level(t, y, p, k):
    return y[0]


@pytest.mark.parametrize("method, options", [("RK4", {"h": 0.1}), ("Euler", {"h": 0.1}), ("DP45", {"rtol": 1e-6})])
def test_a_compiled_run_sees_an_event_leaving_zero_and_samples_nothing_past_its_stop(method, options):
    """y' = 1 from y = 0 with a rising terminal event on y: leaving g = 0 upwards counts (a direction is given), so
    the integration stops at t = 0 — the compiled runs stepped on past it (an audit: they tested only sign changes
    and zeros at a step's end), and sampled the output times of a step the driver then cut."""
    stop = Event(lambda t, y: y[0], "up", direction=1.0, terminal=True)
    runs = [integrate(Problem(fun, (0.0,), [stop]), (0.0, 1.0), method=method, t_eval=[0.0, 0.5, 1.0], **options)
            for fun in (JitRhs(_unit_rate, lambda: np.zeros(1), event=_level), lambda t, y: (1.0,))]
    for sol in runs:
        assert sol.status == "terminated" and sol.t_final == 0.0 and [r.t for r in sol.events] == [0.0]
        assert sol.t.tolist() == [0.0] and sol.y.tolist() == [[0.0]]


def test_advance_refuses_an_output_array_that_does_not_fit_its_times():
    """A compiled run writes its samples without bounds checks: the output array must match the times."""
    from rig.solvers.tsit5 import Tsitouras45
    solver = Tsitouras45(JitRhs(_unit_rate, lambda: np.zeros(1), event=_level), 0.0, (1.0,), 1.0)
    times = np.linspace(0.0, 1.0, 11)
    with pytest.raises(ValueError, match=r"out has shape \(1, 5\).*\(1, 11\)"):
        solver.advance(np.array([1.0]), times=times, out=np.empty((1, 5)))
    solver.advance(np.array([1.0]), times=times)           # times without an output array: nothing sampled
    assert solver.sampled == 0 and solver.t > 0.0


@pytest.mark.parametrize("method", ["Euler", "SymplecticEuler", "RK4"])
@pytest.mark.parametrize("compiled", [True, False])
def test_a_long_fixed_step_run_stays_on_its_grid(method, compiled):
    """10 000 steps of 0.1 ms from t = 1000 s: step k ends at t0 + k·h (t + h summed step by step drifted by 2.5e-5·h
    and ended in an extra step of 2.5e-9 s), the last one of size h."""
    h, t0 = 1e-4, 1000.0
    sol = integrate(Problem(_vdp(), (2.0, 0.0)), (t0, t0 + 1.0), method=method, h=h, compiled=compiled)
    assert sol.nsteps == 10_000 and sol.t[-1] == t0 + 1.0
    grid = t0 + np.arange(sol.t.size) * h
    assert np.max(np.abs(sol.t - grid)) <= 2 * np.spacing(t0 + 1.0)
    assert sol.h_last == pytest.approx(h, rel=1e-9)
