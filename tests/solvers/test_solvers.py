"""ODE solvers and the event-locating driver against closed forms and scipy."""
import math
import re
import warnings

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


def _bounce_times(g: float, e: float, h0: float, t_end: float) -> list[float]:
    """Impact times of a ball dropped from ``h0`` (m) under ``g`` (m/s²) with restitution ``e``, closed form."""
    t, v, times = math.sqrt(2 * h0 / g), math.sqrt(2 * g * h0), []
    while t <= t_end:
        times.append(t)
        v *= e
        t += 2 * v / g
    return times


@pytest.mark.parametrize("method", ["DP45", "Tsit5", "DOP853", "Rodas4"])
@pytest.mark.parametrize("first_step", [None, 2.0])
def test_an_action_that_resets_the_state_finds_every_later_crossing(method, first_step):
    """A bouncing ball: the action leaves the state on the event surface (y = 0) moving away. Every bounce is
    found, also when a whole flight fits in one step (a first step of 2 s on this polynomial problem); before the
    fix the step size kept from before the bounce let the ball fall through the ground after the first one."""
    g, e = 9.81, 0.8
    ground = Event(lambda t, y: y[0], "ground", direction=-1, action=lambda r: (0.0, -e * r.y[1]))
    s = integrate(Problem(lambda t, y: (y[1], -g), (1.0, 0.0), events=[ground]), (0, 3), method, rtol=1e-9,
                  atol=1e-12, first_step=first_step)
    expected = _bounce_times(g, e, 1.0, 3.0)
    assert s.status == "finished" and len(expected) == 6
    np.testing.assert_allclose(s.t_events["ground"], expected, rtol=0, atol=1e-9)
    assert 0.0 <= s.y_final[0] < 0.2


def test_divergence_names_time_and_state():
    with pytest.raises(SolverDivergence, match=r"t = (0\.99|1\.0)"):
        integrate(Problem(lambda t, y: (y[0] ** 2,), (1.0,)), (0, 2), rtol=1e-6, atol=1e-9)
    from rig.solvers import ResolutionWarning
    with pytest.raises(SolverDivergence, match="state"), \
            pytest.warns(ResolutionWarning, match="faster than the step resolves \\(a blow-up ahead\\?\\)"):
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
        integrate(Problem(oscillator, (1.0, 0.0)), (0, 1), method="Heun")


def _stiff(t, y):
    """Stiff linear pair: fast mode λ = −1e4 1/s, slow mode −1 1/s."""
    return (-1e4 * (y[0] - math.cos(t)), -y[1])


def test_dp45_reports_stiffness_and_can_raise():
    import warnings as _w
    from rig.solvers import StiffnessError, StiffnessWarning
    with pytest.warns(StiffnessWarning, match=r"DP45: problem is stiff at t = .*\|lambda\| = 1e\+04"):
        s = integrate(Problem(_stiff, (1.0, 1.0)), (0, 0.5), rtol=1e-3, atol=1e-6)
    assert s.stiff_at is not None and s.nsteps > 1000    # forced to h ≈ 3.3/|λ| although rtol is loose
    with pytest.raises(StiffnessError, match="stiff"):
        integrate(Problem(_stiff, (1.0, 1.0)), (0, 0.5), rtol=1e-3, atol=1e-6, stiffness="raise")
    with _w.catch_warnings():
        _w.simplefilter("error", StiffnessWarning)       # the non-stiff oscillator must not trigger it
        assert integrate(Problem(oscillator, (1.0, 0.0)), (0, 10), rtol=1e-4, atol=1e-7).stiff_at is None


def test_rk4_too_large_step_on_stiff_problem_is_reported():
    """A fixed step beyond the stability limit diverges: reported as such (StiffnessError), or as a warning
    with stiffness="warn"; a step inside the limit is not reported."""
    from rig.solvers import StiffnessError, StiffnessWarning
    with pytest.raises(StiffnessError, match="RK4 unstable"):
        integrate(Problem(_stiff, (1.0, 1.0)), (0, 0.1), method="RK4", h=1e-3)
    with pytest.warns(StiffnessWarning, match="RK4 unstable"):
        try:
            integrate(Problem(_stiff, (1.0, 1.0)), (0, 0.1), method="RK4", h=1e-3, stiffness="warn")
        except SolverDivergence:
            pass                                            # blowing up is a report too
    s = integrate(Problem(_stiff, (1.0, 1.0)), (0, 0.01), method="RK4", h=1e-4, t_eval=[0.01])
    assert s.stiff_at is None and s.y[0, -1] == pytest.approx(math.cos(0.01), abs=1e-3)


def test_hybrid_mode_switch_with_projection_and_reset():
    # block with Coulomb friction: v' = −μg·sgn(v) while sliding, stuck (v ≡ 0) after v reaches 0
    mode = {"m": 1}
    def fun(t, y):
        return (y[1], -2.0 * mode["m"])
    def g(t, y):
        return mode["m"] * y[1] if mode["m"] else 1.0
    def stop(rec):
        mode["m"] = 0
        return (rec.y[0], 0.0)
    ev = Event(g, "stick", direction=-1.0, action=stop, mode_dependent=True)
    s = integrate(Problem(fun, (0.0, 3.0), [ev]), (0, 4), t_eval=np.linspace(0, 4, 41), rtol=1e-9, atol=1e-12)
    assert s.t_events["stick"] == [pytest.approx(1.5, abs=1e-9)]
    assert s.y_final[1] == 0.0 and s.y_final[0] == pytest.approx(3.0 * 1.5 - 1.5 ** 2, rel=1e-9)


def test_event_chattering_is_reported():
    # a reset that puts the state back on its switching surface after every switch: each restart only
    # advances past the root by a few ulps (Zeno point) -> reported instead of looping for ever
    ev = Event(lambda t, y: 1.0 - y[0], "zeno", direction=-1.0, action=lambda rec: (1.0,), mode_dependent=True)
    with pytest.raises(SolverDivergence, match="chattering"):
        integrate(Problem(lambda t, y: (1.0,), (0.0,), [ev]), (0, 2), rtol=1e-6, atol=1e-9)
    # the check can fail: a reset that moves off the surface lets time advance
    ev_ok = Event(lambda t, y: 1.0 - y[0], "bounce", direction=-1.0, action=lambda rec: (0.0,), mode_dependent=True)
    s = integrate(Problem(lambda t, y: (1.0,), (0.0,), [ev_ok]), (0, 3.5), rtol=1e-6, atol=1e-9)
    assert s.t_events["bounce"] == pytest.approx([1.0, 2.0, 3.0], abs=1e-9)


def test_restart_event_exactly_at_the_end_of_the_span():
    """A restarting event whose root is t_bound itself ends the run instead of restarting with t0 == t_bound."""
    ev = Event(lambda t, y: t - 1.0, "at_end", restart=True)      # g reaches 0 exactly at the last step
    sol = integrate(Problem(lambda t, y: (1.0,), (0.0,), [ev]), (0.0, 1.0), rtol=1e-8, atol=1e-10)
    assert [r.t for r in sol.events] == [1.0] and sol.y_final[0] == pytest.approx(1.0, rel=1e-12)
    ev2 = Event(lambda t, y: t - 0.5, "at_break", restart=True)
    sol2 = integrate(Problem(lambda t, y: (1.0,), (0.0,), [ev2], time_breaks=[0.5]), (0.0, 1.0), rtol=1e-8, atol=1e-10)
    assert sol2.y_final[0] == pytest.approx(1.0, rel=1e-12)


def test_stiffness_monitor_in_batches_is_the_monitor_step_by_step():
    """The compiled runs hand the stiffness test whole batches of h·|λ| estimates (vectorised); it must end in the
    state — count, calm run, recent estimates, the step and words of a report — of feeding them one by one, for any
    cut into batches, with non-finite estimates skipped."""
    import warnings
    from rig.solvers.base import StiffnessMonitor
    rng = np.random.default_rng(7)
    reports = 0
    for trial in range(300):
        n = int(rng.integers(1, 120))
        hl = np.where(rng.random(n) < 0.55 + 0.4 * rng.random(), 3.25 + rng.random(n), 3.25 * rng.random(n))
        hl[rng.random(n) < 0.05] = np.nan
        t = np.cumsum(rng.random(n)) * 1e-3
        y = rng.random((n, 2))
        h = np.full(n, 1e-4)
        one, many = StiffnessMonitor("DP45", 3.25), StiffnessMonitor("DP45", 3.25)
        with warnings.catch_warnings(record=True) as said_one:
            warnings.simplefilter("always")
            for k in range(n):
                one.update(float(t[k]), tuple(y[k]), float(h[k]), float(hl[k]))
        cuts = np.sort(rng.choice(np.arange(1, n), size=min(n - 1, int(rng.integers(0, 6))), replace=False)) \
            if n > 1 else []
        with warnings.catch_warnings(record=True) as said_many:
            warnings.simplefilter("always")
            for a, b in zip([0, *cuts], [*cuts, n]):
                many.update_many(t[a:b], y[a:b], h[a:b], hl[a:b])
        state = lambda m: (m.count, m.calm, m._recent, m.detected_at, m.last)  # noqa: E731
        assert state(many) == state(one), trial
        assert [str(w.message) for w in said_many] == [str(w.message) for w in said_one], trial
        reports += len(said_one)
    assert 20 < reports < 290            # both outcomes are exercised


def test_options_a_method_does_not_take_and_nonsense_steps_are_named():
    """An audit: Euler given rtol crashed with a TypeError from deep inside; max_step 0 or −1 ran into a "step size
    underflow (h = −1 s)"; a negative or NaN first_step was silently replaced by the heuristic; a NaN in t_eval gave
    a NaN sample time. Each is now a ValueError naming the option (a first_step of 0 or NaN still means "choose
    it": a run feeds a solver's h_last back, NaN before its first step)."""
    decay = Problem(lambda t, y: (-y[0],), (1.0,))
    for options, said in ((dict(method="Euler", rtol=1e-3), "explicit Euler is a fixed-step method (give h) and takes "
                                                             "no option 'rtol'"),
                          (dict(method="DP45", h=1e-3), "DP45 is an adaptive method (give rtol, atol) and takes no "
                                                        "option 'h'"),
                          (dict(method="DP45", max_step=0.0), "max_step = 0.0 s must be positive"),
                          (dict(method="Tsit5", max_step=-1.0), "max_step = -1.0 s must be positive"),
                          (dict(method="Tsit5", first_step=-1.0), "first_step = -1.0 s must be positive and finite"),
                          (dict(method="DP45", first_step=math.inf), "first_step = inf s must be positive and finite"),
                          (dict(method="DP45", t_eval=[0.2, math.nan, 0.5]), "t_eval must be finite and increasing")):
        with pytest.raises(ValueError, match=re.escape(said)):
            integrate(decay, (0.0, 1.0), **options)
    for span in ((0.0, math.inf), (1.0, 0.0), (0.0, math.nan)):        # (0, inf) ran for ever
        with pytest.raises(ValueError, match="t_span = .* must be two finite times, the end after the start"):
            integrate(decay, span)
    assert integrate(decay, (0.0, 1.0), method="DP45", first_step=1e-3).y_final[0] == pytest.approx(math.exp(-1), rel=1e-5)


def test_a_python_rhs_overflowing_on_a_trial_stage_rejects_the_trial():
    """Robertson's kinetics written with y2**2: DOP853's first trial step from (1, 0, 0) is far too large and the
    square raises OverflowError (y2*y2 would give inf). That trial is rejected as a non-finite one is — it stopped
    the run as a divergence "at t = 0" (an audit), where scipy's DOP853 goes on."""
    from scipy.integrate import solve_ivp

    def rob(t, y):
        return (-0.04 * y[0] + 1e4 * y[1] * y[2], 0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2, 3e7 * y[1] ** 2)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                   # stiff for an explicit method: that is not the point here
        sol = integrate(Problem(rob, (1.0, 0.0, 0.0)), (0.0, 0.5), method="DOP853", rtol=1e-8, atol=1e-11)
        ref = solve_ivp(rob, (0.0, 0.5), (1.0, 0.0, 0.0), method="Radau", rtol=1e-11, atol=1e-14).y[:, -1]
    assert sol.status == "finished" and sol.y_final[0] == pytest.approx(ref[0], rel=1e-7)


def test_a_step_size_underflow_names_the_method_and_what_it_can_tell_of_the_cause():
    """An audit: "solver diverged: step size underflow (h = 2.77e-16 s)" named neither the method (compiled path) nor
    a cause. Now: a right-hand side that is NaN past the point says so; a finite one there points at a blow-up
    (y' = y², y(0) = 1: singular at t = 1), a right-hand side that fails just beyond, or stiffness."""
    nan_past = Problem(lambda t, y: (math.nan if t > 0.5 else -y[0],), (1.0,))
    with pytest.raises(SolverDivergence, match=r"DP45 step size underflow \(h = .*\): the right-hand side is not "
                                               r"finite at t = 0\.5.* s, just past t = 0\.5"):
        integrate(nan_past, (0.0, 1.0), method="DP45")
    blow_up = Problem(lambda t, y: (y[0] * y[0],), (1.0,))
    with pytest.raises(SolverDivergence, match=r"Tsit5 step size underflow .*: the right-hand side is finite at the last "
                                               r"state \(\|y\| = .*\), yet no step .*\(a finite-time singularity"):
        integrate(blow_up, (0.0, 2.0), method="Tsit5")


def test_a_run_ends_on_its_span_end_not_one_ulp_past():
    """Solution.t_final is the span's end (it read 1.0000000000000002 for (0, 1): the restart one ulp past a break
    was taken at the last one too), with or without t_eval and across a time break."""
    decay = Problem(lambda t, y: (-y[0],), (1.0,), time_breaks=(0.5,))
    for options in ({}, {"t_eval": [0.25, 1.0]}, {"method": "RK4", "h": 0.01}):
        sol = integrate(decay, (0.0, 1.0), **options)
        assert sol.t_final == 1.0 and sol.y_final[0] == pytest.approx(math.exp(-1.0), rel=1e-5)
