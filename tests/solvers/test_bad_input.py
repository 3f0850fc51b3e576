"""Input no method can work with, and failures of the model rather than the method, named as such — never a hang, a
silent wrong answer or another method's words (cases from an independent audit against scipy's solve_ivp)."""
import math

import numpy as np
import pytest
from numba import njit

from rig.solvers import METHODS, Event, Problem, SolverDivergence, integrate
from rig.solvers.compiled import JitRhs
from rig.solvers.implicit import Rosenbrock23

ADAPTIVE = ("DP45", "Tsit5", "DOP853", "Rodas4")
FIXED = ("Euler", "SymplecticEuler", "RK4")
DECAY = Problem(lambda t, y: (-y[0],), (1.0,))
OSCILLATOR = Problem(lambda t, y: (y[1], -y[0]), (1.0, 0.0))       # two states: symplectic Euler too


def _options(method: str) -> dict:
    return {"h": 1e-3} if method in FIXED else {"rtol": 1e-8, "atol": 1e-10}


@pytest.mark.timeout(60)
@pytest.mark.parametrize("method", ADAPTIVE)
@pytest.mark.parametrize("rtol, atol, said", [
    (math.inf, 1e-9, "rtol = inf must be finite"),          # hung: a NaN first step passed the underflow test
    (1e-20, 1e-9, "rtol = 1e-20 must be finite and at least 2.22e-14"),
    (1e-6, 0.0, "atol = 0.0 must be positive and finite"),
    (1e-6, math.inf, "atol = inf must be positive and finite"),
    (1e-6, [1e-9, 1e-9], "atol = [1e-09, 1e-09] must be a real number"),
])
def test_tolerances_no_step_can_meet_are_named(method, rtol, atol, said):
    with pytest.raises(ValueError, match=re_escape(said)):
        integrate(DECAY, (0.0, 1.0), method, rtol=rtol, atol=atol)


def re_escape(text: str) -> str:
    import re
    return re.escape(text)


@pytest.mark.timeout(60)
def test_rosenbrock23_checks_as_the_others_and_never_hangs():
    nan = Problem(lambda t, y: (math.nan,), (1.0,))
    with pytest.raises(SolverDivergence, match="non-finite derivatives at the start"):
        integrate(nan, (0.0, 1.0), Rosenbrock23)
    for options, said in (({"first_step": -1.0}, "first_step = -1.0 s must be positive"),
                          ({"max_step": 0.0}, "max_step = 0.0 s must be positive"),
                          ({"first_step": math.inf}, "first_step = inf s must be positive and finite"),
                          ({"rtol": math.inf}, "rtol = inf must be finite")):
        with pytest.raises(ValueError, match=re_escape(said)):
            integrate(DECAY, (0.0, 1.0), Rosenbrock23, **options)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_a_right_hand_side_of_the_wrong_length_is_named(method):
    """Euler, RK4 and symplectic Euler shrank the state to one component (zip), DP45 and Tsit5 said 'not enough values
    to unpack'."""
    short = Problem(lambda t, y: (-y[0],), (1.0, 5.0))
    with pytest.raises(ValueError, match="returned 1 components at the start for a state of 2"):
        integrate(short, (0.0, 1.0), method, **_options(method))


def test_an_initial_state_that_does_not_fit_the_problem_is_named():
    """A compiled kernel read and wrote past a shorter or longer state (the process aborted at exit)."""
    for y0 in ((1.0,), (1.0, 0.0, 0.0)):
        with pytest.raises(ValueError, match=f"y0 has {len(y0)} components, the problem's state 2"):
            integrate(Problem(lambda t, y: (y[1], -y[0]), (1.0, 0.0)), (0.0, 1.0), y0=y0)
    for y0 in ((), [[1.0, 2.0]], "1.0"):
        with pytest.raises(ValueError, match="must be a non-empty sequence of numbers"):
            integrate(DECAY, (0.0, 1.0), y0=y0)


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_a_directional_event_reaching_zero_at_the_spans_end_is_recorded(method, direction):
    """g = ±(t − 1) on (0, 1): scipy records t = 1 and stops; it was lost (no later step to see g leave zero)."""
    event = Event(lambda t, y: direction * (t - 1.0), "end", direction=direction, terminal=True)
    sol = integrate(OSCILLATOR, (0.0, 1.0), method, events=[event], **_options(method))
    assert sol.t_events.get("end") == [1.0] and sol.status == "terminated"


@njit(cache=True)
def _oscillator(t, y, p, out):
    out[0] = y[1]
    out[1] = -y[0]


@njit(cache=True)
def _broken(t, y, p, k):
    return math.nan if t > 0.3 else 1.0


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("method", ("DP45", "RK4"))
def test_an_event_function_returning_nan_is_named(method, compiled):
    """A compiled run saw no sign change in a NaN and stepped on (an audit of this session's change)."""
    event = Event(lambda t, y: _broken(t, y, None, 0), "broken")
    fun = JitRhs(_oscillator, lambda: np.zeros(1), event=_broken) if compiled else OSCILLATOR.fun
    with pytest.raises(SolverDivergence, match=r"event 'broken' returned nan at t = 0\.3([012]\d*)? s"):  # 1st step past
        integrate(Problem(fun, (1.0, 0.0), [event]), (0.0, 1.0), method, **_options(method))


@pytest.mark.parametrize("method", sorted(METHODS))
def test_a_right_hand_side_turning_nan_is_blamed_not_the_method(method):
    """NaN from t = 0.5: the fixed-step methods said 'h*|lambda| = 0.01 … reduce h', Rodas4 'too stiff for Rodas4 …
    try the implicit method Rodas4'."""
    nan_late = Problem(lambda t, y: (y[1], math.nan if t >= 0.5 else -y[0]), (1.0, 0.0))
    with pytest.raises(SolverDivergence) as info:
        integrate(nan_late, (0.0, 1.0), method, **_options(method))
    said = str(info.value)
    assert "the right-hand side is not finite at t = 0.5" in said and "Rodas4 - check" not in said
    assert "try the implicit method Rodas4" not in said or method != "Rodas4"


@pytest.mark.parametrize("t_eval, said", [
    ([[0.1, 0.2]], "t_eval must be a 1-D sequence of times (s), got an array of shape (1, 2)"),   # numpy's "truth
    (0.5, "t_eval must be a 1-D sequence of times (s), got an array of shape ()"),     # value of an array ...", and
    ("abc", "t_eval must be a sequence of times (s), got 'abc'"),        # "diff requires input that is at least 1-D"
])
def test_output_times_that_are_not_a_sequence_are_named(t_eval, said):
    with pytest.raises(ValueError, match=re_escape(said)):
        integrate(DECAY, (0.0, 1.0), "DP45", t_eval=t_eval)
    assert np.allclose(integrate(DECAY, (0.0, 1.0), "DP45", t_eval=[0.1, 0.5]).y[0], np.exp([-0.1, -0.5]), rtol=1e-5)


@pytest.mark.parametrize("method", METHODS)
def test_dense_output_before_the_first_step_is_named(method):
    """The interpolant spans the last step: asked before one, every method says so (it failed on ``None - float``)."""
    solver = METHODS[method](OSCILLATOR.fun, 0.0, OSCILLATOR.y0, 1.0, **({"h": 1e-3} if method in FIXED else {}))
    with pytest.raises(RuntimeError, match="dense_output\\(\\) interpolates over the last step: call step\\(\\) first"):
        solver.dense_output()
    solver.step()
    assert solver.dense_output()(solver.t_old)[0] == pytest.approx(1.0)


@pytest.mark.parametrize("method", ["Euler", "RK4", "SymplecticEuler"])
def test_a_blow_up_of_the_model_is_named_as_such_not_as_an_unstable_step(method):
    """y' = y² (q'' = q² for symplectic Euler) goes to infinity in finite time whatever the step: the overflow is the
    model's, and the error says so (it read "explicit Euler unstable: h*|lambda| = 5.76e+69 > 2 … reduce h below
    3.47e-73 s")."""
    import warnings
    from rig.solvers import StiffnessError
    problem = (Problem(lambda t, y: (y[1], y[0] * y[0]), (1.0, 1.0)) if method == "SymplecticEuler"
               else Problem(lambda t, y: (y[0] * y[0],), (1.0,)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                   # the ResolutionWarning before it ("a blow-up ahead?")
        with pytest.raises(SolverDivergence) as info:
            integrate(problem, (0.0, 5.0), method=method, h=1e-3)
    assert not isinstance(info.value, StiffnessError)
    assert "the solution itself grows without bound" in str(info.value) and "not the method" in str(info.value)
    assert "reduce h" not in str(info.value)


@njit(cache=True)
def _drift(t, y, p, out):
    out[0] = 1.0
    out[1] = 0.0


@njit(cache=True)
def _level(t, y, p, k):
    return y[0] - p[0]


@pytest.mark.parametrize("compiled", [False, True])
@pytest.mark.parametrize("method", ("DOP853", "Tsit5", "DP45"))
@pytest.mark.parametrize("kind", ["terminal", "restart"])
@pytest.mark.parametrize("level, breaks", [(1.0, ()), (0.5, (0.5,))])
def test_a_root_on_a_step_end_within_the_interpolants_rounding_is_found_there(method, compiled, kind, level, breaks):
    """y = t, the event y − level with its root on the span's end or on a time break, where every step ends: DOP853's
    interpolant misses the end state by ≈ 1e-13·h, the sign change was in the states but not on it — the compiled root
    search returned t = 0 (a terminal run 'stopped' at 0, a restart sent time back and ended at y = 1.11) and the
    Python one raised brentq's bare ValueError (an audit)."""
    p = np.array([level])
    fun = JitRhs(_drift, lambda: p, event=_level) if compiled else (lambda t, y: (1.0, 0.0))
    event = Event(lambda t, y: y[0] - level, "level", direction=1.0, terminal=kind == "terminal",
                  restart=kind == "restart")
    sol = integrate(Problem(fun, (0.0, 0.0), [event], time_breaks=list(breaks)), (0.0, 1.0), method,
                    rtol=1e-8, atol=1e-10)
    found = sol.t_events.get("level", [])      # on the span's end y may stop an ulp short of 1: then none
    assert found == pytest.approx([level], abs=1e-12) or (level == 1.0 and found == [])
    assert np.all(np.diff(sol.t) >= 0.0)
    end = level if kind == "terminal" else 1.0
    assert sol.t_final == pytest.approx(end, abs=1e-12) and sol.y_final[0] == pytest.approx(end, abs=1e-12)
