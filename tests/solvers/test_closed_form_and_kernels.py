"""Closed-form segments (AffineRotor, ClosedFormSolver through integrate) and the unrolled RK kernels."""
import math

import numpy as np
import pytest
from scipy.integrate._ivp.rk import RK45, rk_step

from rig.solvers import AffineRotor, Event, Problem, integrate
from rig.solvers.dopri import DormandPrince45
from rig.solvers.unrolled import rk_kernels


@pytest.mark.parametrize("a, b, J", [(30.0, 2.0, 0.4), (30.0, 0.0, 0.4), (-5.0, -0.5, 0.1)])
def test_affine_rotor_matches_tight_numerical_solution(a, b, J):
    rot = AffineRotor(0.2, 0.0, 10.0, a, b, J)
    t = np.linspace(0.2, 1.2, 101)
    sol = integrate(Problem(lambda tt, y: (y[1], (a - b * y[1]) / J), (0.0, 10.0)), (0.2, 1.2), t_eval=t,
                    rtol=1e-13, atol=1e-13)
    d, w = rot.states(t)
    np.testing.assert_allclose(w, sol.y[1], rtol=1e-11)
    np.testing.assert_allclose(d, sol.y[0], rtol=1e-11, atol=1e-12)
    for ti, di, wi in zip(t, d, w):                 # scalar and vector paths agree
        assert rot.state(float(ti)) == pytest.approx((di, wi), rel=1e-14, abs=1e-15)


def test_affine_rotor_closed_forms_series_branch_and_inverse():
    a, b, J, w0 = 12.0, 3.0, 0.5, 2.0
    rot = AffineRotor(0.0, 0.0, w0, a, b, J)
    lam, w_inf = b / J, a / b
    for tau in (1e-9, 1e-4, 1.6e-4, 1.7e-4, 0.3, 2.0):    # around the series switch |λτ| = 1e-3
        d, w = rot.state(tau)
        assert w == pytest.approx(w_inf + (w0 - w_inf) * math.exp(-lam * tau), rel=1e-14)
        exact_d = w_inf * tau + (w0 - w_inf) * (-math.expm1(-lam * tau)) / lam
        assert d == pytest.approx(exact_d, rel=1e-12)
    # uniformly accelerated rotor (b = 0)
    acc = AffineRotor(1.0, 0.0, 2.0, 4.0, 0.0, 2.0)
    assert acc.state(3.0) == pytest.approx((2.0 * 2 + 0.5 * 2.0 * 4, 2.0 + 2.0 * 2), rel=1e-15)
    assert acc.time_of_speed(10.0) == pytest.approx(5.0)
    t_hit = rot.time_of_speed(3.0)
    assert rot.state(t_hit)[1] == pytest.approx(3.0, rel=1e-13)
    assert rot.time_of_speed(1.0) == math.inf and rot.time_of_speed(w_inf + 1.0) == math.inf
    with pytest.raises(ValueError, match="inertia"):
        AffineRotor(0.0, 0.0, 0.0, 1.0, 1.0, 0.0)


class DecayFlow:
    """Exact flow of y' = −y from (t0, y0) (closed form for the test problem)."""

    def __init__(self, t0, y0):
        self.t0, self.y0, self.stops = t0, y0, []

    def __call__(self, t):
        if isinstance(t, float):
            return (self.y0 * math.exp(-(t - self.t0)),)
        return (self.y0 * np.exp(-(np.asarray(t) - self.t0)))[None, :]


def test_integrate_steps_along_closed_form_and_locates_events():
    calls = []

    def fun(t, y):
        calls.append(t)
        return (-y[0],)

    ev = Event(lambda t, y: y[0] - 0.5, "half", direction=-1.0)
    t = np.linspace(0.0, 2.0, 41)
    prob = Problem(fun, (1.0,), [ev], time_breaks=[1.0], flow=lambda t0, y, tb: DecayFlow(t0, y[0]))
    s = integrate(prob, (0.0, 2.0), t_eval=t)
    assert calls == [] and s.nfev == 0                             # no right-hand side evaluation at all
    np.testing.assert_allclose(s.y[0], np.exp(-t), rtol=1e-14)
    assert s.t_events["half"] == [pytest.approx(math.log(2.0), abs=1e-14)]
    # a flow that declines (None) falls back to the method
    s2 = integrate(Problem(fun, (1.0,), [ev], flow=lambda *a: None), (0.0, 2.0), t_eval=t, rtol=1e-10, atol=1e-12)
    assert s2.nfev > 0 and abs(s2.y[0, -1] - math.exp(-2.0)) < 1e-9


def test_unrolled_dp45_step_equals_scipy_rk45_step():
    def f(t, y):
        return (y[1], -4.0 * y[0] + math.sin(t), 0.1 * y[0] * y[1])
    y0, h, t0 = (1.0, 0.5, -0.2), 0.05, 0.3
    stages, error_norm = rk_kernels(*DormandPrince45.tableau, 3)
    k1 = f(t0, y0)
    y_new, _, *ks = stages(f, t0, y0, k1, h)
    K = np.empty((RK45.n_stages + 1, 3))
    ref, _ = rk_step(lambda t, y: np.array(f(t, y)), t0, np.array(y0), np.array(k1), h,
                         RK45.A, RK45.B, RK45.C, K)
    np.testing.assert_allclose(y_new, ref, rtol=1e-15, atol=1e-16)
    k7 = f(t0 + h, y_new)
    rtol, atol = 1e-6, 1e-9
    scale = atol + rtol * np.maximum(np.abs(y0), np.abs(ref))
    ref_norm = np.linalg.norm(h * (K.T @ RK45.E) / scale) / np.sqrt(3)
    assert error_norm(y0, y_new, k1, *ks, k7, h, rtol, atol) == pytest.approx(ref_norm, rel=1e-10)
    with pytest.raises(ValueError, match="inconsistent"):
        rk_kernels(((0.5,),), (0.0, 1.0), (0.0, 0.5), (0.1, 0.2), 2)
