"""Implicit solvers on stiff problems, and on level 2: DP45 is stability-limited on the groove contact, Rodas4
is not; fixed-step explicit methods beyond their limit are reported, not silently wrong."""
import math
import warnings

import numpy as np
import pytest

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.plant import DEMO_SPEED
from rig.solvers import Event, Problem, Rosenbrock23, StiffnessError, StiffnessWarning, integrate
from rig.solvers.rodas import fd_jacobian

LAM = 1e4


def _stiff(t, y):
    """y0' = −λ(y0 − cos t) − sin t (solution cos t after a fast transient), y1' = −2 y1."""
    return (-LAM * (y[0] - math.cos(t)) - math.sin(t), -2.0 * y[1])


def _exact(t):
    return np.array([np.cos(t), np.exp(-2.0 * t)])


def test_rosenbrock23_is_second_order_and_stable_on_a_stiff_problem():
    errors, steps = [], []
    for h in (0.02, 0.01, 0.005):      # max_step forces the step (local error 2e-7 ≪ rtol)
        sol = integrate(Problem(_stiff, (1.0, 1.0)), (0.0, 2.0), method=Rosenbrock23, rtol=1e-2, atol=1e-2,
                        first_step=h, max_step=h)
        errors.append(np.max(np.abs(np.array(sol.y_final) - _exact(2.0))))
        steps.append(sol.nsteps)
    order = np.log2(errors[0] / errors[1]), np.log2(errors[1] / errors[2])
    assert order == pytest.approx((2.0, 2.0), abs=0.25)
    assert steps[0] <= 101                     # h·λ = 200: far beyond any explicit stability limit


def test_rosenbrock23_error_control_dense_output_and_events():
    t_eval = np.linspace(0.0, 2.0, 201)
    ev = Event(lambda t, y: y[1] - 0.5, "half", direction=-1.0)
    sol = integrate(Problem(_stiff, (1.0, 1.0), [ev]), (0.0, 2.0), method=Rosenbrock23, rtol=1e-7, atol=1e-10,
                    t_eval=t_eval)
    assert np.max(np.abs(sol.y - _exact(t_eval))) < 2e-6
    assert sol.t_events["half"][0] == pytest.approx(math.log(2.0) / 2.0, abs=1e-6)
    loose = integrate(Problem(_stiff, (1.0, 1.0)), (0.0, 2.0), method=Rosenbrock23, rtol=1e-3, atol=1e-6)
    assert loose.nsteps < sol.nsteps / 5 and np.max(np.abs(np.array(loose.y_final) - _exact(2.0))) < 1e-3
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dp = integrate(Problem(_stiff, (1.0, 1.0)), (0.0, 2.0), method="DP45", rtol=1e-3, atol=1e-6)
    assert dp.nsteps > 20 * loose.nsteps and any(issubclass(w.category, StiffnessWarning) for w in caught)


def test_level2_contact_mode_is_stiff():
    model = Level2(PinInsertionMechanism(), DEMO_SPEED)
    t, y = 0.17, model.initial_state(0.17)
    jac, _ = fd_jacobian(model.rhs, t, np.array(y), np.array(model.rhs(t, y)), 1e-6, 1e-12, 1e-4)
    assert np.max(np.abs(np.linalg.eigvals(jac))) > 2000.0     # the stiff contact mode (1/s)


def test_level2_is_stiff_for_dp45_but_not_for_rodas4():
    model = Level2(PinInsertionMechanism(), DEMO_SPEED)
    span = (0.0, 0.16)                                          # lower dwell and rise, before F_c acts
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        explicit = model.simulate(span, method="DP45", rtol=1e-3, atol=1e-8, stiffness="warn").solution
    stiff = [w for w in caught if issubclass(w.category, StiffnessWarning)]
    assert len(stiff) == 1 and "stiff at t = " in str(stiff[0].message) and explicit.stiff_at is not None  # once a run
    with warnings.catch_warnings():
        warnings.simplefilter("error")                          # the implicit method reports nothing
        implicit = model.simulate(span, method="Rodas4", rtol=1e-3, atol=1e-8).solution
    assert implicit.stiff_at is None
    h_explicit, h_implicit = np.diff(explicit.t), np.diff(implicit.t)
    assert np.max(h_explicit) < 2e-3 and np.max(h_implicit) > 20 * np.max(h_explicit)
    assert implicit.nsteps * 5 < explicit.nsteps and implicit.nfev * 5 < explicit.nfev
    ref = model.simulate(span, method="DP45", rtol=1e-10, atol=1e-15, stiffness="ignore").solution
    assert implicit.y_final[0] == pytest.approx(ref.y_final[0], rel=1e-4)
    with pytest.raises(StiffnessError, match=r"DP45: problem is stiff at t = .* state"):
        model.simulate(span, method="DP45", rtol=1e-3, atol=1e-8, stiffness="raise")


@pytest.mark.parametrize("method, h", [("Euler", 1e-4), ("RK4", 8e-4)])
def test_level2_fixed_step_beyond_the_contact_stability_limit_is_reported(method, h):
    """The contact mode (−509 ± 4121i 1/s in the dwell, |λ| ≤ 4.2e3 1/s over the revolution — eigenvalues of the
    finite-difference Jacobian): explicit Euler at h = 0.1 ms (h·ω_n = 0.41 > 2ζ = 0.24: a growing oscillation)
    and RK4 at 0.8 ms (h·ω_n = 3.3 > 2√2) are outside their stability regions — the run stops naming method,
    time, the amplified mode and the fix; RK4 at 0.2 ms is inside (h·ω_n = 0.84; Hairer's ‖Δf‖/‖Δy‖ on the
    scaled state used to read τ·ω_n² ≈ 1.7e4 1/s here and stop it) and at 0.1 ms accurate."""
    model = Level2(PinInsertionMechanism(), DEMO_SPEED)
    label = {"Euler": "explicit Euler", "RK4": "RK4"}[method]
    with pytest.raises(StiffnessError, match=rf"{label} unstable at t = .* the step amplifies the mode .* Rodas4"):
        model.simulate((0.0, 0.1), method=method, h=h)
    ref = model.simulate((0.0, 0.1), method="Rodas4", rtol=1e-9, atol=1e-14).solution
    inside = model.simulate((0.0, 0.1), method="RK4", h=2e-4).solution
    assert inside.stiff_at is None and inside.y_final[0] == pytest.approx(ref.y_final[0], rel=1e-3)
    fine = model.simulate((0.0, 0.1), method="RK4", h=1e-4).solution
    assert fine.y_final[0] == pytest.approx(ref.y_final[0], rel=1e-6)


@pytest.mark.parametrize("method, h, span, width", [("RK4", 8e-4, 0.15, None), ("Euler", 1e-4, 0.2, 0.020)])
def test_an_unstable_contact_between_flights_is_reported_wherever_the_run_ends(method, h, span, width):
    """The machine as drawn at 300 rpm: the roller flies across the clearance part of the time, and the amplification
    test's every-100-steps schedule fell in the flights (|λ| ≈ 11 1/s there). RK4 at 0.8 ms over 0.15 s then
    finished with error 0.95 and 8 flank switches instead of 2, explicit Euler at 0.1 ms (20 mm roller) with 61 —
    silently (an audit). A step whose h·|λ| estimate passes the method's limit now brings the next check forward."""
    from rig.motion import ConstantSpeed
    from rig.motion.speed import RPM
    from rig.plants.cam_bar.scene_io import mechanism_from_scene, read_level2_model
    from rig.scene import load_scene
    scene = load_scene("data/scenes/pin_insertion_as_drawn.toml")
    mech = mechanism_from_scene(scene, **({} if width is None else {"roller_width": width}))
    model = Level2(mech, ConstantSpeed(300 * RPM), model=read_level2_model(scene))
    label = {"Euler": "explicit Euler", "RK4": "RK4"}[method]
    with pytest.raises(StiffnessError, match=rf"{label} unstable at t = .* amplifies the mode .*\|lambda\| = [45]\d{{3}}"):
        model.simulate((0.0, span), method=method, h=h)


def test_symplectic_euler_on_the_driven_cam_splits_positions_from_rates():
    """With the cam drive the state is (e, τė, φ, ω, φ_m, ω_m): symplectic Euler took e, τė, φ as positions (its
    first half) and gave error 0.89 with 2 spurious flank switches at h = 10 µs (an audit); with the problem's
    positions it converges as on the undriven machine (error ≈ 4e-3 at 10 µs, halving with h)."""
    from rig.motion import ConstantSpeed
    from rig.motion.speed import RPM
    from rig.plants.cam_bar.scene_io import mechanism_from_scene, read_level2_model
    from rig.scene import load_scene
    scene = load_scene("data/scenes/pin_insertion_as_tested.toml")
    mech = mechanism_from_scene(scene)
    assert mech.cam_drive is not None
    model = Level2(mech, ConstantSpeed(300 * RPM), model=read_level2_model(scene))
    assert model.problem(model.initial_state(0.0)).positions == (0, 2, 4)
    ref = model.simulate((0.0, 0.1), method="DP45", rtol=1e-11, atol=1e-16).solution
    errors = []
    for h in (2e-5, 1e-5):
        run = model.simulate((0.0, 0.1), method="SymplecticEuler", h=h).solution
        errors.append(abs(run.y_final[0] - ref.y_final[0]) / np.max(np.abs(ref.y[0])))
    assert errors[1] < 0.02 and errors[0] / errors[1] == pytest.approx(2.0, rel=0.35)
