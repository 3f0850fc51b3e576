"""ODE solvers and the event-locating driver against closed forms and scipy."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rig.solvers import RK4, DormandPrince45, Event, Problem, SolverDivergence, integrate

W = 3.0


def oscillator(t, y):
    return (y[1], -W * W * y[0])


def test_dp45_harmonic_oscillator_closed_form():
    t = np.linspace(0, 10, 201)
    sol = integrate(Problem(oscillator, (1.0, 0.0)), (0, 10), t_eval=t, rtol=1e-11, atol=1e-13)
    np.testing.assert_allclose(sol.y[0], np.cos(W * t), atol=1e-9)
    np.testing.assert_allclose(sol.y[1], -W * np.sin(W * t), atol=3e-9)


def test_dp45_error_scales_with_tolerance():
    errs = []
    for rtol in (1e-5, 1e-8):
        s = integrate(Problem(lambda t, y: (-2.0 * y[0],), (1.0,)), (0, 3), rtol=rtol, atol=1e-14)
        errs.append(np.max(np.abs(s.y[0] - np.exp(-2 * s.t)) / np.exp(-2 * s.t)))
    assert errs[0] < 1e-4 and errs[1] < 1e-7 and errs[1] < errs[0] / 100


def test_dense_output_accuracy_between_steps():
    t = np.linspace(0, 10, 5001)   # many samples per step: dense output only
    s = integrate(Problem(oscillator, (1.0, 0.0)), (0, 10), t_eval=t, rtol=1e-9, atol=1e-12)
    assert s.nsteps < 1000
    np.testing.assert_allclose(s.y[0], np.cos(W * t), atol=5e-8)


def test_rk4_fourth_order_convergence():
    errs = []
    for h in (0.02, 0.01):
        s = integrate(Problem(oscillator, (1.0, 0.0)), (0, 2), method="RK4", h=h, t_eval=[2.0])
        errs.append(abs(s.y[0, -1] - math.cos(2 * W)))
    assert 14 < errs[0] / errs[1] < 18


def test_matches_scipy_at_tight_tolerance():
    def vdp(t, y):
        return (y[1], 2.0 * (1 - y[0] ** 2) * y[1] - y[0])
    t = np.linspace(0, 8, 81)
    ours = integrate(Problem(vdp, (2.0, 0.0)), (0, 8), t_eval=t, rtol=1e-11, atol=1e-12)
    ref = solve_ivp(lambda t, y: vdp(t, y), (0, 8), [2.0, 0.0], method="DOP853", t_eval=t, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(ours.y, ref.y, atol=2e-8)


def test_event_location_accuracy_and_direction():
    ev_all = Event(lambda t, y: y[0], "zero")
    ev_up = Event(lambda t, y: y[0], "up", direction=1.0)
    s = integrate(Problem(oscillator, (1.0, 0.0), [ev_all, ev_up]), (0, 5), rtol=1e-10, atol=1e-12)
    zeros = np.array(s.t_events["zero"])
    exact = (math.pi / 2 + math.pi * np.arange(zeros.size)) / W
    np.testing.assert_allclose(zeros, exact, atol=1e-9)
    np.testing.assert_allclose(s.t_events["up"], exact[1::2], atol=1e-9)
    for r in s.events:
        assert abs(r.y[0]) < 1e-8


def test_terminal_event_stops():
    s = integrate(Problem(oscillator, (1.0, 0.0), [Event(lambda t, y: y[0], "zero", terminal=True)]), (0, 5),
                  rtol=1e-10, atol=1e-12)
    assert s.status == "terminated"
    assert s.t_final == pytest.approx(math.pi / (2 * W), abs=1e-9)
    assert s.t[-1] == pytest.approx(s.t_final)


def test_time_breaks_and_restart_events_handle_discontinuities():
    # y' = u(t), u = 1 up to t = 0.3, 3 afterwards (left-continuous); a kink at y = 0.5 as a restart event
    def fun(t, y):
        return (1.0 if t <= 0.3 else 3.0,)
    s = integrate(Problem(fun, (0.0,), time_breaks=[0.3]), (0, 1), t_eval=[1.0], rtol=1e-6, atol=1e-9)
    assert s.y[0, -1] == pytest.approx(0.3 + 3 * 0.7, rel=1e-12)
    def kink(t, y):
        return (1.0 if y[0] < 0.5 else -0.5 * y[0] + 1.25,)
    ev = Event(lambda t, y: y[0] - 0.5, "kink", restart=True)
    s = integrate(Problem(kink, (0.0,), [ev]), (0, 2), t_eval=[2.0], rtol=1e-10, atol=1e-12)
    exact = 2.5 - 2.0 * math.exp(-0.5 * 1.5)
    assert s.t_events["kink"][0] == pytest.approx(0.5, abs=1e-8)   # step straddles the jump: local-tolerance accuracy
    assert s.y[0, -1] == pytest.approx(exact, rel=1e-9)
    assert s.restarts >= 1


def test_divergence_names_time_and_state():
    with pytest.raises(SolverDivergence, match=r"t = (0\.99|1\.0)"):
        integrate(Problem(lambda t, y: (y[0] ** 2,), (1.0,)), (0, 2), rtol=1e-6, atol=1e-9)
    with pytest.raises(SolverDivergence, match="state"):
        integrate(Problem(lambda t, y: (y[0] ** 2,), (1.0,)), (0, 2), method="RK4", h=0.01)


def test_solver_objects_step_interface():
    s = DormandPrince45(oscillator, 0.0, (1.0, 0.0), 1.0, rtol=1e-8, atol=1e-10)
    while s.status == "running":
        s.step()
        d = s.dense_output()
        mid = 0.5 * (s.t_old + s.t)
        assert d(mid)[0] == pytest.approx(math.cos(W * mid), abs=1e-7)
    assert s.t == 1.0 and s.status == "finished"
    r = RK4(oscillator, 0.0, (1.0, 0.0), 0.05, h=0.02)
    r.step(); r.step(); r.step()
    assert r.t == pytest.approx(0.05) and r.status == "finished"
    with pytest.raises(RuntimeError):
        r.step()
    with pytest.raises(ValueError, match="unknown method"):
        integrate(Problem(oscillator, (1.0, 0.0)), (0, 1), method="Euler")
