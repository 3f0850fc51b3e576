"""Rod pin-joint clearances as the slider's degree of freedom (rig.plants.cam_bar.joints) and the per-cycle clearance
draw at level 2."""

import numpy as np
import pytest

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.scene_io import mechanism_from_scene
from rig.plants.cam_bar.plant import DEMO_SPEED, CamBarPlant, Setting
from rig.plants.cam_bar.joints import JointClearance
from rig.plants.cam_bar.level2 import ContactLaw, Level2
from rig.motion.speed import RPM, SinusoidalSpeed
from rig.plants.cam_bar.variation import CycleVariation
from rig.scene import SceneError, load_scene

from tests.cam_bar.test_cam_bar_scene import write


def _cycle(joints, rtol=1e-7):
    """Signals of one revolution of the nominal machine at 150 rpm with ``joints`` (Rodas4, 8001 samples)."""
    mech = PinInsertionMechanism(joints=joints)
    model = Level2(mech, DEMO_SPEED)
    t = np.linspace(0.0, 0.4, 8001)
    run = model.simulate((0.0, 0.4), t_eval=t, method="Rodas4", rtol=rtol, atol=1e-12)
    return mech, model, run, model.signals(t, run.solution.y)


def test_free_play_and_static_stretch():
    j = JointClearance(20e-6, 30e-6, stiffness=1e7)
    assert j.play == pytest.approx(25e-6)
    assert j.stretch(0.0) == 0.0 and j.stretch(10.0) == pytest.approx(26e-6) and j.stretch(-10.0) == -j.stretch(10.0)
    for bad in ((-1e-6,), (0.0, 0.0, 0.0), (0.0, 0.0, 1e7, -1.0)):
        with pytest.raises(ValueError, match="joint clearances"):
            JointClearance(*bad)


def test_stiff_joints_without_clearance_are_the_rigid_rod():
    """The slider as its own body on a stiff rod (10 GN/m, no play) moves and loads the cam as the rigid chain does:
    the coupling terms (rod force on follower and slider, z = s − s_r(ψ)) are right and lumping the rod into its pins
    costs only its rotary inertia."""
    _, _, _, rigid = _cycle(None)
    _, _, _, stiff = _cycle(JointClearance(0.0, 0.0, stiffness=1e10))
    assert np.max(np.abs(stiff["s"] - rigid["s"])) < 0.01e-6
    assert np.max(np.abs(stiff["rod_tension"] - rigid["rod_tension"])) < 1e-3 * np.max(np.abs(rigid["rod_tension"]))
    assert np.max(np.abs(stiff["R23"] - rigid["R23"])) < 1e-4 * np.max(np.abs(rigid["R23"]))


def test_pins_cross_their_clearance_where_the_rod_force_reverses():
    """Nominal machine, 20 µm + 20 µm: where level 1's rod force changes sign the slider flies across the pins'
    free play and strikes (rod force and contact force well beyond the rigid rod's); in the dwells it rests on
    friction with the rod unloaded, on different sides of the play (the clearances are not taken up in the same
    direction): the gripper's dwell positions against the rigid rod's differ by a sizeable part of the play."""
    mech, _, run, sig = _cycle(JointClearance(20e-6, 20e-6))
    _, _, _, rigid = _cycle(None)
    phi = np.degrees(sig["cam_angle"])
    ds = sig["s"] - rigid["s"]
    upper, lower = (phi > 185.0) & (phi < 215.0), (phi > 330.0) & (sig["t"] > 0.3)
    assert np.max(np.abs(sig["rod_tension"][upper | lower])) < 0.5                   # rod unloaded at rest
    assert np.ptp(ds[upper]) < 0.05e-6 and np.ptp(ds[lower]) < 0.05e-6                # held by the guide
    assert 10e-6 < abs(np.mean(ds[upper]) - np.mean(ds[lower])) < 45e-6               # sides of the play
    assert sig["rod_tension"].min() < 2.0 * rigid["rod_tension"].min()                # impacts in the pins
    assert sig["R23"].max() > 1.5 * rigid["R23"].max()
    assert np.max(np.abs(ds)) < 2.0 * 40e-6 / 0.9                                     # bounded by the play
    pins = [e for e in run.solution.events if e.name == "pins"]                     # the solver restarted there
    signs = [e.sign for e in pins]
    assert len(pins) >= 4 and all(a != b for a, b in zip(signs, signs[1:]))          # onsets and releases alternate
    i = np.searchsorted(sig["t"], [e.t for e in pins if e.sign < 0])                 # released: the rod unloaded
    assert np.all(sig["rod_tension"][np.minimum(i + 1, sig["t"].size - 1)] == 0.0)


def test_energy_balance_closes_with_the_pins():
    """W_drive + W(F_c, friction) − E_dissipated (contacts and pins) = Δ(kinetic + gravity + spring + contact and
    pin energy), to the solver's accuracy, with a varying cam speed; soft roller contact (K/100)."""
    mech = PinInsertionMechanism(joints=JointClearance(20e-6, 20e-6))
    base = ContactLaw.steel_line(mech.roller_width)
    soft = ContactLaw(base.stiffness * 0.01, base.exponent, base.damping)
    model = Level2(mech, SinusoidalSpeed(150 * RPM, 1.5), soft, energy=True, max_penetration=1e-3)
    sol = model.simulate((0.0, 0.4), method="DP45", rtol=1e-8, atol=1e-12).solution
    energy = model.energies(sol.t[[0, -1]], sol.y[:, [0, -1]])
    change = sum(v[1] - v[0] for v in energy.values())
    w_drive, w_load, dissipated = sol.y[4:, -1]
    assert dissipated > 1e-3 and abs(w_load) > 0.1
    assert w_drive + w_load - dissipated - change == pytest.approx(0.0, abs=1e-5 * dissipated)


def test_level2_cycles_draw_their_groove_clearance(tmp_path):
    variation = CycleVariation(clearance_lambda=1 / 20e-6)
    mech = CamBarPlant(PinInsertionMechanism(), Setting(fidelity=2, variation=variation, rng=np.random.default_rng(4)))
    for c in range(3):                                                # cycles advance: draw, then use
        take_up = mech.cycles.deviation(c).take_up
        assert mech.cycles.mechanism(c).clearance == take_up and 0.0 <= take_up <= 0.05e-3
        assert np.all(mech.cycles.stroke_deviation(c, np.linspace(0, 6, 7)) == 0.0)  # simulated, not offset
    level1 = CamBarPlant(mech.mech, Setting(fidelity=1, variation=variation, rng=np.random.default_rng(4)))
    assert level1.cycles.mechanism(0).clearance == mech.mech.clearance                # level 1: a take-up
    assert np.any(level1.cycles.stroke_deviation(0, np.linspace(0, 6, 7)) != 0.0)


def test_scene_table(tmp_path):
    scene = write(tmp_path, '\n[plant.joints]\nfollower = "0.02 mm"\nslider = "0.03 mm"\nstiffness = "20 N/um"\n',
                  "[[plant.cam_program]]", "[[plant.cam_program]]")
    assert mechanism_from_scene(scene).joints == JointClearance(20e-6, 30e-6, 2e7)
    path = tmp_path / "scene.toml"
    text = path.read_text()
    for old, new, message in [             # each names its key as written (it gave the four values in SI, no key)
            ('slider = "0.03 mm"', 'slider = "-0.03 mm"', r"key 'slider' must not be negative .*got \"-0.03 mm\""),
            ('stiffness = "20 N/um"', 'stiffness = "0 N/um"', r"key 'stiffness' must be positive and at most 1e12"),
            ('stiffness = "20 N/um"', 'stiffness = "1e9 N/um"', r"key 'stiffness' must be positive and at most 1e12"),
            ('follower = "0.02 mm"', 'follower = "500 mm"',            # (an audit: 500 mm ran, no curve came)
             r"pin clearances \(\[plant.joints\] follower \+ slider = 500.03 mm\) are not smaller than the stroke")]:
        path.write_text(text.replace(old, new))
        with pytest.raises(SceneError, match=message):
            mechanism_from_scene(load_scene(path))


def test_pins_driven_beyond_the_overload_limit_are_named():
    """A state with the slider 0.5 mm past the pins' play (what a diverging solution reaches) stops the run with an
    error that names the pins and the cam angle, not the roller."""
    from rig.solvers import SolverDivergence
    mech = PinInsertionMechanism(joints=JointClearance(20e-6, 20e-6))
    model = Level2(mech, DEMO_SPEED)
    y0 = list(model.initial_state(0.0))
    y0[2] = 0.5e-3
    with pytest.raises(SolverDivergence, match=r"rod's pins penetrate their bores by 0\.4\d* mm .* at cam angle"):
        model.simulate((0.0, 0.01), y0=y0)
    y0[2] = 0.0                                                      # inside the limit: runs
    assert model.simulate((0.0, 0.01), y0=y0).solution.status != "terminated"


def test_two_methods_agree_at_tight_tolerance():
    """The slider's flight and impacts are resolved: the explicit DP45 and the implicit Rodas4 at rtol 1e-10 give the
    same gripper motion (measured: 1.2e-12 m) and rod force (6e-5 N of 130 N peaks)."""
    mech = PinInsertionMechanism(joints=JointClearance(20e-6, 20e-6))
    t = np.linspace(0.0, 0.4, 4001)
    sig = {}
    for method in ("DP45", "Rodas4"):
        model = Level2(mech, DEMO_SPEED)
        sig[method] = model.signals(t, model.simulate((0.0, 0.4), t_eval=t, method=method, rtol=1e-10,
                                                      atol=1e-14).solution.y)
    assert np.max(np.abs(sig["DP45"]["s"] - sig["Rodas4"]["s"])) < 1e-10
    assert np.max(np.abs(sig["DP45"]["rod_tension"] - sig["Rodas4"]["rod_tension"])) < 1e-2


def test_fixed_step_methods_pass_the_insertion_switch_with_the_pins_free():
    """Found by `rig bench work-precision` on the worn-pins scene: a fixed-step method put the state of the
    insertion switch (a mode-dependent event) a rounding error before its root, found the same root again on the
    next step and stopped with "event chattering" at every step size. It now lands past the root as for any
    switch of the RHS: RK4 and the semi-implicit Euler cross it, once, and converge on the DP45 reference."""
    from rig.bench.problems import load_problem
    from rig.solvers import integrate
    problem = load_problem(load_scene("data/scenes/pin_insertion_worn_pins.toml").path, 0.2)
    ref = integrate(problem.make(), (0.0, 0.2), method="DP45", rtol=1e-11, atol=1e-16, t_eval=problem.grid,
                    stiffness="ignore")
    assert [e.sign for e in ref.events if e.name == "insertion"] == [1.0]
    for method, steps in (("RK4", (5e-5, 2.5e-5)), ("SymplecticEuler", (5e-6, 2.5e-6))):
        errors = []
        for h in steps:
            sol = integrate(problem.make(), (0.0, 0.2), method=method, t_eval=problem.grid, h=h)
            assert sol.status == "finished"
            assert [e.sign for e in sol.events if e.name == "insertion"] == [1.0]
            errors.append(problem.error(sol.y, ref.y))
        assert errors[1] < errors[0], (method, errors)
