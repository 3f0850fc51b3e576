"""The compiled level-2 kernel against the previous (numpy, two trial solves) implementation, level 1 and the
Python motion, speed and contact models.

``data/level2_reference.npz`` was written by the previous implementation (rig/plants/cam_bar/level2.py at
commit 63b6649, Level2(energy=True), its Python DP45 at rtol 1e-11, atol 1e-15) for the nominal machine over a
revolution (0.4 s) and for a flank-switching case (300 rpm, k = 1.09 N/mm, 0.2 s): states on a 2 ms grid, event
times and names, and right-hand-side values at 120 states per case (on the trajectory and perturbed: other
flank, free flight, other speeds). For the trajectories it took the insertion window's "cam in a rise" as φ in
a rise segment, as the kernel does, instead of the sign of s' that rounding flips in the last nanoseconds of
the rise (which moved its F_c switch-off by ~1e-9 s, 5e-7 of max|e|).
"""
from math import tau
from pathlib import Path

import numpy as np
import pytest

from rig.motion import ConstantSpeed, RampSpeed, SinusoidalSpeed, SpeedProfile
from rig.motion.program import CamProgram, Segment
from rig.motion.registry import available_laws
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar import level2_kernel as kernel
from rig.plants.cam_bar.guide_friction import GuideFriction
from rig.plants.cam_bar.insertion import InsertionLaw
from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.level2_model import Level2Model
from rig.plants.cam_bar.plant import DEMO_SPEED
from rig.motion.speed import RPM
from rig.solvers import SolverDivergence

DATA = np.load(Path(__file__).with_name("data") / "level2_reference.npz")
STEP = InsertionLaw("step")        # the reference predates the pin's force-travel law: constant F_c window
CASES = {"nominal": (lambda: (PinInsertionMechanism(insertion=STEP), DEMO_SPEED), 0.4),
         "switching": (lambda: (PinInsertionMechanism(k=1090.0, insertion=STEP), ConstantSpeed(300 * RPM)), 0.2)}


@pytest.mark.parametrize("case", CASES)
def test_rhs_equals_the_previous_implementation(case):
    model = Level2(*CASES[case][0](), energy=True)
    f_old = DATA[f"{case}_rhs_f"]
    f_new = np.array([model.rhs(t, tuple(y)) for t, y in zip(DATA[f"{case}_rhs_t"], DATA[f"{case}_rhs_y"])])
    scale = np.max(np.abs(f_old), axis=0)                   # per component: cancellations leave ~1e-16 of it
    np.testing.assert_allclose(f_new, f_old, rtol=1e-9, atol=0.0 + 1e-12 * scale.max())
    assert np.all(np.abs(f_new - f_old) <= 1e-9 * np.abs(f_old) + 1e-12 * scale)


@pytest.mark.parametrize("case", CASES)
def test_trajectories_and_events_equal_the_previous_implementation(case):
    """Same DP45 tolerance, compiled runs: e to 1e-8 of its maximum (the reference's own error is ~1e-9), the
    velocity and work quadratures to 1e-7, the same events at the same times."""
    (mech, speed), T = CASES[case][0](), CASES[case][1]
    t, y_ref = DATA[f"{case}_t"], DATA[f"{case}_y"]
    sol = Level2(mech, speed, energy=True).simulate((0.0, T), method="DP45", t_eval=t, rtol=1e-11, atol=1e-15,
                                             stiffness="ignore").solution
    for i, tol in enumerate((1e-8, 1e-7, 1e-7, 1e-7, 1e-7)):
        assert np.max(np.abs(sol.y[i] - y_ref[i])) < tol * np.max(np.abs(y_ref[i])), i
    assert [r.name for r in sol.events] == DATA[f"{case}_event_name"].tolist()
    np.testing.assert_allclose([r.t for r in sol.events], DATA[f"{case}_event_t"], rtol=0.0, atol=1e-9)


@pytest.mark.parametrize("guide", ["regularised", "stick"])
def test_closed_form_free_body_solves_the_level1_moment_balance(guide):
    """At the kernel's ψ̈ the level-1 free-body solution of the actual motion needs exactly the cam moment
    ℓ·(F_w − F_o) the contacts deliver — on both flanks, in free flight, with friction either way; with the
    stick-slip guide also where it holds (dwells: ṡ ≈ 3e-7 m/s is inside the stick band)."""
    mech = PinInsertionMechanism(k=1090.0)
    model = Level2(mech, ConstantSpeed(300 * RPM), model=Level2Model(guide=GuideFriction(guide)))
    rng = np.random.default_rng(3)
    t = rng.uniform(0.0, 0.2, 400)
    lever = np.array([kernel.geometry_at(ti, np.zeros(2), model.params)[0] for ti in t])
    e = rng.uniform(-0.5, 1.5, t.size) * mech.clearance / lever          # working flank, gap, other flank
    y = np.array([e, rng.normal(0.0, 1e-6, t.size)])
    dy = model.evaluate(t, y)
    assert np.any(dy.F_w > 0) and np.any(dy.F_o > 0) and np.any((dy.F_w == 0) & (dy.F_o == 0))
    np.testing.assert_allclose(dy.loads.M_sigma, lever * (dy.F_w - dy.F_o), rtol=1e-9,
                               atol=1e-9 * np.max(np.abs(dy.loads.M_sigma)))
    np.testing.assert_allclose(dy.state.psi, dy.psi, atol=1e-12)         # the chain round trip


def test_contact_law_drive_and_program_match_the_python_models():
    mech = PinInsertionMechanism()
    law = Level2(mech, DEMO_SPEED).contact
    p = kernel.pack(mech, DEMO_SPEED, law.stiffness, law.exponent, law.damping)
    delta, rate = np.linspace(-2e-6, 5e-6, 15), np.linspace(-0.05, 0.05, 15)
    expected = law.force(delta, rate)
    assert [kernel.contact_force(kernel.elastic(d, p), r, p) for d, r in zip(delta, rate)] == pytest.approx(expected,
                                                                                               rel=1e-14)
    t = np.linspace(0.0, 3.0, 301)
    for speed in (ConstantSpeed(10.0, phi0=0.3), RampSpeed(5.0, 15.0, 1.0, 0.5), SinusoidalSpeed(15.0, 1.5),
                  SinusoidalSpeed(15.0, 1.5, frequency=4.0)):
        dr = speed.drive(t)
        got = np.array([kernel.drive(ti, kernel.pack(PinInsertionMechanism(), speed)) for ti in t]).T
        np.testing.assert_allclose(got, [dr.phi, dr.omega, dr.alpha], rtol=1e-13, atol=1e-12)
    phi = np.linspace(-1.0, 2 * tau, 997)
    for name in available_laws():                            # every registered law in a rise and a return
        prog = CamProgram([Segment("dwell", 1.0), Segment("rise", 2.0, name, 0.04), Segment("dwell", 0.5),
                           Segment("return", tau - 3.5, name, 0.04)])
        m = prog.evaluate(phi)
        pk = kernel.pack(PinInsertionMechanism(program=prog))
        got = np.array([kernel.program(x, pk)[:3] for x in phi]).T
        np.testing.assert_allclose(got, [m.s, m.s_p, m.s_pp], rtol=1e-9, atol=1e-12, err_msg=name)


def test_unknown_speed_profile_is_refused_and_a_jam_is_named():
    class Wobble(SpeedProfile):
        nominal_omega = 10.0

        def drive(self, t):
            return ConstantSpeed(10.0).drive(t)
    with pytest.raises(ValueError, match="speed profile Wobble is not supported"):
        Level2(PinInsertionMechanism(), Wobble())
    model = Level2(PinInsertionMechanism(), DEMO_SPEED)
    model.params[kernel.MU] = 1e3                          # a guide that self-locks under the rod's push
    with pytest.raises(SolverDivergence, match=r"no consistent friction state in the slider guide at t = .* cam angle"):
        model.simulate((0.115, 0.12), rtol=1e-6)


def test_the_jam_record_describes_the_latest_evaluation():
    """A jam a rejected trial step met must not name the cause of a later, different failure: the record is the latest
    evaluation's at a finite state (a stage computed from a NaN stage keeps it)."""
    model = Level2(PinInsertionMechanism(), DEMO_SPEED)
    y = np.array(model.initial_state(0.115))
    out = np.empty(len(y))
    model.params[kernel.MU] = 1e3                          # self-locking guide: this state jams
    kernel.rhs(0.115, y, model.params, out)
    assert np.isnan(out).all() and model.params[kernel.JAM_T] == 0.115
    kernel.rhs(0.116, np.full_like(y, np.nan), model.params, out)     # a later stage of the same trial step
    assert model.params[kernel.JAM_T] == 0.115 and "self-locks" in model._diagnose()
    model.params[kernel.MU] = PinInsertionMechanism().mu
    kernel.rhs(0.115, y, model.params, out)                # the same state evaluates: the jam is history
    assert np.isfinite(out).all() and np.isnan(model.params[kernel.JAM_T]) and model._diagnose() is None
