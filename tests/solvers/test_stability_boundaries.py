"""Stability boundaries of the fixed-step methods on a linear oscillator x'' + 2ζω x' + ω² x = 0, as theory
predicts: explicit Euler h·ω < 2ζ (|1 + hλ| ≤ 1), symplectic Euler h·ω < 2 (undamped), RK4 h·ω < 2√2 on the
imaginary axis (|R(ix)| = 1 with R(z) = 1 + z + z²/2 + z³/6 + z⁴/24); no step limit for Rodas4. Inside the
boundary the run ends bounded and is not reported; outside it the divergence is detected and named — explicit
Euler's slow growth just beyond 2ζ/ω_n included (×1.002 per step: the state stays finite for thousands of steps,
so only a test of the step's amplification against the exact flow, rig.solvers.amplification, can see it)."""
from __future__ import annotations

import itertools
import math
import warnings

import numpy as np
import pytest
from scipy.optimize import brentq

from rig.solvers import Problem, SolverDivergence, integrate

W = 2 * math.pi * 100.0       # ω_n, rad/s


def rk4_boundary() -> float:
    """h·ω where |R(i·x)| = 1 for RK4's stability polynomial (independent of the solver code)."""
    r = lambda x: abs(1 + 1j * x + (1j * x) ** 2 / 2 + (1j * x) ** 3 / 6 + (1j * x) ** 4 / 24) - 1.0
    return brentq(r, 2.0, 3.0, xtol=1e-14)


LIMITS = {"Euler": (lambda: 2 * 0.1, 0.1), "SymplecticEuler": (lambda: 2.0, 0.0), "RK4": (rk4_boundary, 0.0)}


def run(method: str, hw: float, zeta: float, periods: int = 300) -> float:
    """|x| after ``periods`` periods from x = 1 at fixed step h = hw/ω."""
    def f(t, y):
        return (y[1], -W * W * y[0] - 2 * zeta * W * y[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = integrate(Problem(f, (1.0, 0.0)), (0.0, periods * 2 * math.pi / W), method=method, h=hw / W,
                        t_eval=[periods * 2 * math.pi / W])
    return float(abs(sol.y[0, -1]))


def test_rk4_boundary_is_the_textbook_value():
    assert rk4_boundary() == pytest.approx(2 * math.sqrt(2), rel=1e-10)


@pytest.mark.parametrize("method", list(LIMITS))
def test_inside_the_boundary_bounded_outside_detected(method):
    limit, zeta = LIMITS[method][0](), LIMITS[method][1]
    hw = 0.9 * limit
    # stable: Euler and RK4 decay; symplectic Euler stays on its invariant ellipse, |x| <= 1/(1 - (hω/2)²)
    bound = 1.0 / (1.0 - (hw / 2) ** 2) if method == "SymplecticEuler" else 1.0
    assert run(method, hw, zeta) <= bound + 1e-9
    with pytest.raises(SolverDivergence, match=r"unstable at t = .* s: .*h = .* s.*implicit method Rodas4"):
        run(method, 1.1 * limit, zeta)


@pytest.mark.parametrize("side", [0.98, 1.02])
def test_explicit_euler_slow_growth_is_reported_just_beyond_two_zeta(side):
    """h·ω_n = 2ζ·(1 ± 2 %): per step |1 + hλ| = 0.9996 / 1.0004 — below, the run decays unreported; above, it
    is stopped with the step that keeps the mode stable (2ζ/ω_n) in the message."""
    hw = side * 2 * 0.1
    if side < 1.0:
        assert run("Euler", hw, 0.1, periods=2000) < 1.0
        return
    with pytest.raises(SolverDivergence, match=r"grows without physical cause - reduce h below (\S+) s") as err:
        run("Euler", hw, 0.1, periods=2000)
    h_ok = float(str(err.value).split("reduce h below ")[1].split(" s")[0])
    assert h_ok == pytest.approx(2 * 0.1 / W, rel=2e-3)


def test_symplectic_euler_keeps_the_amplitude_inside_its_boundary():
    """Undamped: symplectic Euler neither decays nor grows (its error is a phase and a bounded ellipse)."""
    amplitudes = [run("SymplecticEuler", 1.8, 0.0, periods) for periods in (100, 200, 300)]
    assert all(0.1 < a <= 1.0 / (1.0 - 0.9 ** 2) for a in amplitudes)


def test_rodas4_has_no_step_limit_on_the_contact_mode():
    """ω = 2π·1e5 rad/s, ζ = 0.1, over 0.1 s (1e4 periods): Rodas4 resolves the ringing while it matters, then
    steps far beyond every explicit boundary (h·ω ≫ 2.83) and ends at rest; RK4 would need 0.1·ω/2.83 ≈ 22 000
    steps at its boundary."""
    w = 2 * math.pi * 1e5
    sol = integrate(Problem(lambda t, y: (y[1], -w * w * y[0] - 2 * 0.1 * w * y[1]), (1.0, 0.0)), (0.0, 0.1),
                    method="Rodas4", rtol=1e-6, atol=1e-9)
    assert abs(sol.y_final[0]) < 1e-6
    assert sol.nsteps < 0.1 * w / rk4_boundary() / 5 and sol.h_last * w > 100.0


def test_explicit_euler_growth_too_slow_per_step_is_reported_once_it_adds_up():
    """Undamped, h·ω = 0.01: explicit Euler grows by (1 + h²ω²)^½ = 1.00005 per step — far below what one check
    calls growth — yet doubles the amplitude after ln 2 / 5e-5 ≈ 13 900 steps (t ≈ 139 s for ω = 1): reported then,
    saying it grew slowly and that no step cures it; a run ending before is not."""
    osc = Problem(lambda t, y: (y[1], -y[0]), (1.0, 0.0))
    done = integrate(osc, (0.0, 50.0), method="Euler", h=0.01)
    assert done.status == "finished" and math.hypot(*done.y_final) == pytest.approx(math.exp(5000 * 5e-5), rel=1e-3)
    with pytest.raises(SolverDivergence, match=r"explicit Euler unstable at t = (\S+) s: .*slowly, but 2(\.\d+)?-fold "
                                               r"since the run began: .*no practical step") as err:
        integrate(osc, (0.0, 1000.0), method="Euler", h=0.01)
    t = float(str(err.value).split("unstable at t = ")[1].split(" s")[0])
    assert math.log(2) / 5e-5 * 0.01 <= t <= math.log(2) / 5e-5 * 0.01 + 1.0         # within a check's spacing


@pytest.mark.parametrize("method", ["Euler", "RK4", "SymplecticEuler"])
def test_a_fixed_step_solvers_nfev_counts_every_call_its_tests_make(method):
    """A solver object's nfev counts the amplification test's calls too (they were only in integrate's total)."""
    import rig.solvers as solvers
    calls = [0]

    def f(t, y):
        calls[0] += 1
        return (y[1], -y[0])
    solver = getattr(solvers, method)(f, 0.0, (1.0, 0.0), 2.0, h=1e-3)
    while solver.status == "running":
        solver.step()
    assert solver.nfev == calls[0] > 2000
    calls[0] = 0
    assert integrate(Problem(f, (1.0, 0.0)), (0.0, 2.0), method=method, h=1e-3).nfev == calls[0]


@pytest.mark.parametrize("method, hl, steps", [("RK4", 5.0, 10), ("RK4", 2.9, 7), ("RK4", 2.9, 1), ("Euler", 20.0, 10),
                                               ("Euler", 2.9, 7)])
def test_a_run_too_short_for_the_periodic_checks_is_still_tested_at_its_end(method, hl, steps):
    """x' = −1000·x beyond the method's real-axis limit (RK4 2.785, explicit Euler 2) for fewer steps than the first
    periodic check: the run's end is checked (it once returned 2e11 for RK4 at h·|λ| = 5 where the exact value is
    2e-22, silently); inside the limit a short run passes."""
    problem = Problem(lambda t, y: (-1000.0 * y[0],), (1.0,))
    with pytest.raises(SolverDivergence, match=r"unstable at t = .* by .* per step"):
        integrate(problem, (0.0, steps * hl / 1000.0), method=method, h=hl / 1000.0)
    inside = 2.5 if method == "RK4" else 1.5
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        sol = integrate(problem, (0.0, steps * inside / 1000.0), method=method, h=inside / 1000.0)
    assert abs(sol.y[0, -1]) < 1.0
    # warned as inaccurate where 5 % of the mode is left at the end against the exact e^{-2.5·steps}: RK4's one step
    left = abs(sol.y[0, -1])
    warned = any("may be inaccurate" in str(w.message) for w in said)
    assert warned == (left >= 0.05) and warned == ((method, steps) == ("RK4", 1))


def test_the_end_of_run_check_judges_the_steps_taken_not_the_nominal_h():
    """A run shorter than h, or one whose steps the time breaks cut to 1 ms, takes no step of the nominal h = 5 ms
    (h·|λ| = 5): the end-of-run check once judged them at h and raised; at the steps taken they are stable."""
    decay = Problem(lambda t, y: (-1000.0 * y[0],), (1.0,))
    assert integrate(decay, (0.0, 1e-4), method="RK4", h=5e-3).y[0, -1] == pytest.approx(math.exp(-0.1), rel=1e-6)
    cut = Problem(decay.fun, (1.0,), time_breaks=[k * 1e-3 for k in range(1, 50)])
    sol = integrate(cut, (0.0, 0.05), method="RK4", h=5e-3)
    assert sol.nsteps == 50 and abs(sol.y[0, -1]) < 1e-20
    with pytest.raises(SolverDivergence):
        integrate(decay, (0.0, 0.05), method="RK4", h=5e-3)          # the same h uncut: 10 steps at h·|λ| = 5


@pytest.mark.parametrize("span, h", [(0.0401, 0.004), (4.1, 0.4), (3.0, 0.29)])
def test_a_periodic_check_landing_on_the_cut_last_step_judges_the_full_ones(span, h):
    """Ten full steps beyond the limit and a cut last step on which the periodic check lands: the check judged the cut
    step (stable) and the run ended silently (RK4 x' = −1000·x at h·|λ| = 4 gave 8.8e6 for 3.8e-18; an undamped
    oscillator at h·ω = 4 grew 6.5e8-fold). It judges the largest step since the check before."""
    problem = Problem(lambda t, y: (-1000.0 * y[0],), (1.0,)) if h == 0.004 else \
        Problem(lambda t, y: (y[1], -100.0 * y[0]), (1.0, 0.0))
    with pytest.raises(SolverDivergence, match="RK4 unstable"):
        integrate(problem, (0.0, span), method="RK4", h=h)


def test_a_fixed_step_solver_stepped_to_its_end_is_tested_there():
    """Driven by step() (not integrate): five RK4 steps at h·ω = 4 on an undamped oscillator ended 'finished' grown
    25 000-fold; the solver tests its steps on reaching t_bound. At a stable step it finishes."""
    from rig.solvers.rk4 import RK4
    solver = RK4(lambda t, y: (y[1], -100.0 * y[0]), 0.0, (1.0, 0.0), 2.0, h=0.4)
    with pytest.raises(SolverDivergence, match="RK4 unstable"):
        while solver.status == "running":
            solver.step()
    solver = RK4(lambda t, y: (y[1], -100.0 * y[0]), 0.0, (1.0, 0.0), 2.0, h=0.02)
    while solver.status == "running":
        solver.step()
    assert math.hypot(solver.y[0], solver.y[1] / 10.0) == pytest.approx(1.0, abs=1e-3)


def test_breaks_and_events_a_few_ulp_apart_leave_no_span_too_short_for_a_step():
    """Level 2 at 300 rpm: a program break at 1.4999999999999998 s and an event a few ulp after it gave a fixed-step
    method a 1.1e-15 s step ("step size underflow"); breaks that close are merged and the state at such an event is
    the step's interpolant. Two breaks 5 ulp apart are one."""
    from rig.solvers.integrate import breaks_in
    close = Problem(lambda t, y: (-y[0],), (1.0,), time_breaks=[1.4999999999999998, 1.500000000000001, 1.7])
    assert breaks_in(close, 0.0, 2.0) == [1.4999999999999998, 1.7]
    assert integrate(close, (0.0, 2.0), method="RK4", h=1e-3).y[0, -1] == pytest.approx(math.exp(-2.0), rel=1e-9)
    from rig.bench.stability import _model
    from rig.scene import load_scene
    model, y0, _ = _model(load_scene("data/scenes/pin_insertion_l2.toml"), 1.0, 2.0)
    sol = integrate(model.problem(y0), (0.0, 1.55), method="RK4", h=1e-4)
    assert sol.status == "finished" and sol.t_final == pytest.approx(1.55)


def test_the_periodic_and_end_checks_count_the_steps_since_the_one_checked_last():
    """The first check (at the 11th step) judges the steps since the run began, the first included (its step was left
    out); the end-of-run check counts the steps after the one checked last (it counted one more: a neutral check
    then a growth of e^0.4 per step over one step was summed over two, 2.2-fold, and reported)."""
    from rig.solvers.base import StiffnessMonitor

    class Watch:
        def __init__(self, grows):
            self.grows, self.h = grows, []

        def check(self, t, y, h, steps=0.0):
            self.h.append(h)
            modes = (np.empty(0),) * 7                  # no persistent mode for the accuracy test
            return (math.exp(0.4), 1.0, 1j, modes) if self.grows and t > 12.5 else (1.0, 1.0, 1j, modes)

    h = [2.0] + [1.0] * 11
    t = list(itertools.accumulate(h))
    batch = StiffnessMonitor("RK4", 2.785, "raise", fixed=True)
    batch.watch = Watch(False)
    batch.update_many(np.array(t), np.zeros((12, 1)), np.array(h), np.full(12, 0.1))
    assert batch.watch.h == [2.0]                       # the check at step 11 judged the run's steps, the first one's h
    end = StiffnessMonitor("RK4", 2.785, "raise", fixed=True)
    end.watch = Watch(True)
    for k in range(12):
        end.update(t[k], (0.0,), h[k], 0.1)
    end.finish(t[-1], (0.0,))                           # one step after the check: 1.49-fold, below 2-fold: silent
    assert end.detected_at is None and end.watch.h[-1] == 1.0


@pytest.mark.parametrize("method, hw, steps_per_period", [("RK4", 2.7, 2.33), ("SymplecticEuler", 1.9, 3.31)])
def test_a_stable_but_coarse_fixed_step_is_warned(method, hw, steps_per_period):
    """Inside the stability boundary and still wrong: RK4 at h·ω = 2.7 (< 2√2) damps an undamped oscillation by 28 %
    per step (|R(2.7i)| = 0.72: x(1 s) ≈ 1e-52 instead of cos 1000), symplectic Euler at h·ω = 1.9 (< 2) keeps the
    amplitude but turns 2.51 rad per step instead of 1.9 (error 3.1). Both ran to the end unreported (an audit); now a
    ResolutionWarning names the mode, its steps per period and a step, once."""
    from rig.solvers import ResolutionWarning
    osc = Problem(lambda t, y: (y[1], -1e6 * y[0]), (1.0, 0.0), positions=(0,))
    with pytest.warns(ResolutionWarning) as said:
        sol = integrate(osc, (0.0, 1.0), method=method, h=hw / 1000.0)
    assert abs(sol.y_final[0] - math.cos(1000.0 * sol.t_final)) > 0.5           # the answer it warns about
    ours = [str(w.message) for w in said if issubclass(w.category, ResolutionWarning)]
    assert len(ours) == 1 and "may be inaccurate" in ours[0] and "lambda = 0+1000j 1/s" in ours[0]
    assert f"{steps_per_period:.3g} steps per period" in ours[0] and "reduce h to about" in ours[0]
    suggested = float(ours[0].split("reduce h to about ")[1].split(" s")[0])
    assert suggested < 0.5 * hw / 1000.0                # a step that helps (an audit saw "at h = 0.0002 s … about 0.0002 s")
    with warnings.catch_warnings():                     # and following the advice ends the warnings (an audit: it took
        warnings.simplefilter("error", ResolutionWarning)   # two or three reruns when only the fault that fired counted)
        again = integrate(osc, (0.0, 1.0), method=method, h=suggested)
    assert abs(again.y_final[0] - math.cos(1000.0 * again.t_final)) < 0.05


@pytest.mark.parametrize("method, hw", [("RK4", 1.0), ("SymplecticEuler", 0.3)])
def test_the_accuracy_advice_counts_the_phase_error_still_to_come(method, hw):
    """A phase error summed over a persistent mode's life fires part-way through the run and keeps growing: the advice
    extrapolates it to the run's end, so a rerun at the suggested step is not warned again."""
    from rig.solvers import ResolutionWarning
    osc = Problem(lambda t, y: (y[1], -1e6 * y[0]), (1.0, 0.0), positions=(0,))
    with pytest.warns(ResolutionWarning, match="phase error") as said:
        integrate(osc, (0.0, 1.0), method=method, h=hw / 1000.0)
    message = next(str(w.message) for w in said if issubclass(w.category, ResolutionWarning))
    suggested = float(message.split("reduce h to about ")[1].split(" s")[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResolutionWarning)
        integrate(osc, (0.0, 1.0), method=method, h=suggested)


@pytest.mark.parametrize("method, hw, within", [("RK4", 0.05, 5e-5), ("RK4", 0.2, 0.01), ("SymplecticEuler", 0.02, 0.03)])
def test_a_fine_fixed_step_draws_no_accuracy_warning(method, hw, within):
    """Over 1 s of an undamped ω = 1000 oscillation: RK4 at h·ω = 0.05 ends within 5e-5 of cos 1000 and at 0.2
    within 1 %, symplectic Euler at 0.02 within 3 %: none is warned."""
    from rig.solvers import ResolutionWarning
    osc = Problem(lambda t, y: (y[1], -1e6 * y[0]), (1.0, 0.0), positions=(0,))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResolutionWarning)
        sol = integrate(osc, (0.0, 1.0), method=method, h=hw / 1000.0)
    assert abs(sol.y_final[0] - math.cos(1000.0 * sol.t_final)) < within


@pytest.mark.parametrize("hw", [1.0, 1.3])
def test_rk4_damping_a_mode_away_is_warned(hw):
    """RK4 at h·ω = 1 and 1.3 (6.3 and 4.8 steps per period, error per step only 0.6–3 % of the mode) damps an
    undamped oscillation away over 1 s (x(1) ≈ 0 for cos 1000 = 0.56): the per-step test alone missed it (a review);
    the error summed over the mode's life is warned."""
    from rig.solvers import ResolutionWarning
    osc = Problem(lambda t, y: (y[1], -1e6 * y[0]), (1.0, 0.0), positions=(0,))
    with pytest.warns(ResolutionWarning, match="RK4 may be inaccurate"):
        sol = integrate(osc, (0.0, 1.0), method="RK4", h=hw / 1000.0)
    assert abs(sol.y_final[0] - math.cos(1000.0 * sol.t_final)) > 0.4


def test_a_stiff_decay_stepped_stably_draws_no_accuracy_warning():
    """RK4 at h·λ = −2.5 on a decay: stable, and the mode is gone in a few steps (e^−2.5 = 0.08 per step: not
    persistent), whatever RK4 leaves of it (0.65 per step)."""
    from rig.solvers import ResolutionWarning
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResolutionWarning)
        sol = integrate(Problem(lambda t, y: (-1000.0 * y[0],), (1.0,)), (0.0, 0.2), method="RK4", h=2.5e-3)
    assert abs(sol.y_final[0]) < 1e-15


GROWTH = Problem(lambda t, y: (10.0 * y[0],), (1.0,))                         # y = e^{10t}


def _falling_pendulum(t, y):
    """An inverted pendulum (g/l = 98.1 1/s², damping 0.5 1/s) falling from 1e-8 rad: a mode growing at ≈ 9.7 1/s for
    ≈ 2 s, then a swing."""
    return (y[1], 98.1 * math.sin(y[0]) - 0.5 * y[1])


@pytest.mark.parametrize("problem, h, t_end", [(GROWTH, 0.005, 5.0), (Problem(_falling_pendulum, (1e-8, 0.0),
                                                                                positions=(0,)), 0.002, 4.0)])
def test_a_model_that_grows_by_itself_is_not_called_unstable(problem, h, t_end):
    """The increments' growth test stopped both as "RK4 unstable … a lightly damped mode outside the method's stability
    region" (×12.2 per 50 steps: e^2.5, the model's own growth), though 2.5e-6 from e^50 and 5e-8 from the reference
    (an audit): it now asks the amplification test whether a mode grows by itself at that rate."""
    from scipy.integrate import solve_ivp
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sol = integrate(problem, (0.0, t_end), "RK4", h=h)
    ref = solve_ivp(lambda t, y: problem.fun(t, y), (0.0, t_end), problem.y0, method="DOP853", rtol=1e-12,
                    atol=1e-14).y[:, -1]
    assert np.allclose(sol.y_final, ref, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("method, h", [("Euler", 0.01), ("Euler", 0.03), ("RK4", 0.19), ("RK4", 0.15)])
def test_a_growing_mode_stepped_coarsely_is_warned(method, h):
    """y' = 10y over 1 s: explicit Euler at h·λ = 0.1 ends 37 % low, RK4 at h·λ = 1.9 20 % and at 1.5 11 % low — all
    silent before (the accuracy test judged only modes that do not grow; an audit). The error on a growing mode
    compounds while it grows: summed, it is warned once at 5 %."""
    from rig.solvers import ResolutionWarning
    with pytest.warns(ResolutionWarning, match=r"lambda = 10\+0j 1/s, which grows by .* summed while it grew") as said:
        sol = integrate(GROWTH, (0.0, 1.0), method, h=h)
    assert abs(sol.y_final[0] / math.exp(10.0) - 1.0) > 0.1                        # the answer it warns about
    assert len([w for w in said if issubclass(w.category, ResolutionWarning)]) == 1
    fix = float(str(said[0].message).split("reduce h to about ")[1].split(" s")[0])
    with warnings.catch_warnings():                                                 # the step it suggests is fine
        warnings.simplefilter("error")
        better = integrate(GROWTH, (0.0, 1.0), method, h=1.0 / math.ceil(1.0 / fix))
    assert abs(better.y_final[0] / math.exp(10.0) - 1.0) < 0.05


@pytest.mark.parametrize("method, h", [("Euler", 1e-4), ("RK4", 0.01)])
def test_a_growing_mode_stepped_finely_draws_no_warning(method, h):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sol = integrate(GROWTH, (0.0, 1.0), method, h=h)
    assert abs(sol.y_final[0] / math.exp(10.0) - 1.0) < 0.01


def test_episodes_of_growth_in_a_model_that_damps_between_them_are_not_summed():
    """A forced two-well oscillator y' = 10(y − y³) + 10 cos t grows (λ up to 10 1/s) each time it crosses between
    its wells and damps in them: explicit Euler at 2 ms ends 6e-5 from the reference after 100 s, and the growing-mode
    test, summing every episode over the run, warned (a review); each episode is summed alone now."""
    from scipy.integrate import solve_ivp

    def two_wells(t, y):
        return (10.0 * (y[0] - y[0] ** 3) + 10.0 * math.cos(t),)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sol = integrate(Problem(two_wells, (0.5,)), (0.0, 100.0), "Euler", h=2e-3)
    ref = solve_ivp(two_wells, (0.0, 100.0), [0.5], method="DOP853", rtol=1e-12, atol=1e-14).y[0, -1]
    assert abs(sol.y_final[0] - ref) < 1e-3
