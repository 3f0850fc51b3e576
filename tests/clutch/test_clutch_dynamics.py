"""2-DOF clutch dynamics, loads, events and scenes (MODELS.md §4.3–4.4)."""
import math
from pathlib import Path

import numpy as np
import pytest

from rig.plants.clutch import FlatTappetClutch
from rig.plants.clutch.dynamics import ClutchDynamics
from rig.plants.clutch.loads import LinearInSpeed, LinearMotor, LoadSum, ShoeBrake, Zone, constant, shock
from rig.plants.clutch.stand import ClutchStand
from rig.scene import SceneError, load_scene
from rig.solvers import integrate
from rig.solvers.base import StiffnessWarning

SCENES = Path(__file__).resolve().parents[2] / "data" / "scenes"
THESIS = dict(r0=0.055, r1=0.130, r2=0.030, k_a=3000.0, F_a1=1284.0, J1=0.35, J3=0.02)


def test_energy_conserved_without_friction_motor_and_load():
    c = FlatTappetClutch(**dict(THESIS, mu_B=0.0, mu_C=0.0, J1=0.08, J3=0.05))
    d = ClutchDynamics(c, LinearMotor(0.0, 0.0), constant(0.0))
    y0 = (0.0, 80.0, 0.0, 20.0)      # ωr = 80 rad/s: ½J_eff·ωr² ≈ 98 J > 52 J apex barrier: passes phase boundaries and apexes
    s = integrate(d.problem(y0), (0, 0.5), rtol=1e-11, atol=1e-12)
    E = np.array([d.energy(y) for y in s.y.T])
    assert np.ptp(E) / E[0] < 1e-8
    assert len(s.t_events["phase_boundary"]) > 4 and len(s.t_events["apex"]) > 2
    # the check can fail: with a motor torque the energy changes
    d2 = ClutchDynamics(c, LinearMotor(1.0, 0.0), constant(0.0))
    s2 = integrate(d2.problem(y0), (0, 0.5), rtol=1e-11, atol=1e-12)
    assert abs(d2.energy(s2.y_final) - E[0]) > 1e-3


def test_startup_reaches_motor_load_equilibrium():
    c = FlatTappetClutch(**THESIS)
    load = LinearInSpeed(3.0, 0.02)
    d = ClutchDynamics(c, LinearMotor(437.708, 3.870), load)
    s = integrate(d.problem(d.initial_state()), (0, 1.5), rtol=1e-7, atol=1e-9)
    w_exact = (437.708 - 3.0) / (3.870 + 0.02)
    assert s.y_final[1] + s.y_final[3] == pytest.approx(w_exact, rel=1e-4)
    assert s.y_final[3] == pytest.approx(w_exact, rel=1e-4)


def test_belt_ratio_scales_motor_line():
    m = LinearMotor(100.0, 2.0, ratio=2.0, t_off=1.0)
    assert m.torque(0.0, 10.0) == pytest.approx(2 * (100 - 2 * 2 * 10))
    assert m.torque(1.5, 10.0) == 0.0


def test_blocked_quasistatic_torque_matches_static_characteristic():
    c = FlatTappetClutch(**dict(THESIS, mu_C=0.0))
    d = ClutchDynamics(c, LinearMotor(437.708, 437.708 / 0.2), constant(0.0), v_s=1e-3, blocked=True)
    t = np.linspace(0.5, 4.0, 200)
    with pytest.warns(StiffnessWarning, match="DP45: problem is stiff"):   # motor slope / J1 ≈ 2.2e4 1/s
        integrate(d.problem(d.initial_state()), (0, 0.5), rtol=1e-8, atol=1e-10)
    s = integrate(d.problem(d.initial_state()), (0, 4.0), "Rodas4", t_eval=t, rtol=1e-8, atol=1e-10)
    out = d.outputs(s.t, s.y)
    phi = out["phi_r"]
    ok = np.radians(5) < np.mod(phi, 2 * math.pi / 3)   # skip the start transient near 0
    ok &= np.mod(phi, 2 * math.pi / 3) < np.radians(55)
    assert ok.sum() > 50
    np.testing.assert_allclose(out["M_t"][ok], c.static_torque(phi[ok], friction=True), rtol=2e-3, atol=0.1)


def test_sustained_overload_counts_disengagements_and_flags_shutdown():
    c = FlatTappetClutch(**THESIS)
    d = ClutchDynamics(c, LinearMotor(437.708, 3.870), LoadSum([constant(5.0), shock(0.05, 0.3, 150.0)]))
    st = ClutchStand(d, omega0=(437.708 - 5) / 3.870, trip_on_shutdown=True)
    out = st.advance(np.linspace(0, 0.6, 601))
    kinds = [e.kind for e in st.events]
    assert kinds.count("disengagement") >= 2 and "shutdown" in kinds
    t_sd = next(e.time for e in st.events if e.kind == "shutdown")
    assert 0.05 < t_sd < 0.35
    apex = np.array([e.data["phi_r"] for e in st.events if e.kind == "disengagement"])
    off = np.mod(apex - math.pi / 3, 2 * math.pi / 3)
    np.testing.assert_allclose(np.minimum(off, 2 * math.pi / 3 - off), 0.0, atol=1e-7)
    assert np.all(out["M1"][np.linspace(0, 0.6, 601) > t_sd + 1e-3] == 0.0)   # motor tripped


def test_advance_continues_across_calls():
    c = FlatTappetClutch(**THESIS)
    def run(chunks):
        d = ClutchDynamics(c, LinearMotor(437.708, 3.870), LoadSum([constant(5.0), shock(0.1, 0.02, 16.5)]))
        st = ClutchStand(d, rtol=1e-9, atol=1e-11)
        return np.concatenate([st.advance(ch)["M_t"] for ch in chunks])
    t = np.linspace(0, 0.3, 301)
    np.testing.assert_allclose(run([t[:150], t[150:]]), run([t]), atol=1e-5)


def test_loads_zone_and_brake():
    z = Zone(7.0, 1.0, 2.0)
    assert z.torque(0, 1.5 + 2 * math.pi, 1.0, ()) == 7.0 and z.torque(0, 0.5, 1.0, ()) == 0.0
    b = ShoeBrake(gain=0.02, tau=0.01, force=100.0, times=(0.1,), levels=(500.0,))
    assert b.torque(0, 0, 50.0, (100.0,)) == pytest.approx(2.0, rel=1e-9)
    assert b.rates(0.2, 0, 0, (100.0,))[0] == pytest.approx(40000.0)
    with pytest.raises(ValueError, match="start"):
        Zone(1.0, 2.0, 1.0)


DYNAMIC_SCENES = [p for p in sorted(SCENES.glob("clutch_*.toml")) if 'plant = "clutch_dynamic"' in p.read_text()]


def test_all_six_dynamic_scenes_present():
    assert len(DYNAMIC_SCENES) >= 6


@pytest.mark.parametrize("path", DYNAMIC_SCENES, ids=lambda p: p.stem)
def test_scenes_load_and_run_briefly(path):
    st = ClutchStand.from_scene(load_scene(path))
    out = st.advance(np.linspace(0, 0.02, 21))
    for key in ("phi1", "omega1", "phi3", "omega3", "phi_r", "M_t", "F_a"):
        assert out[key].shape == (21,) and np.all(np.isfinite(out[key]))


def test_scene_errors_name_key(tmp_path):
    text = (SCENES / "clutch_startup.toml").read_text().replace('k_a = "3 N/mm"', 'k_a = "3 N"')
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(SceneError, match="k_a"):
        ClutchStand.from_scene(load_scene(p))
    p.write_text((SCENES / "clutch_startup.toml").read_text().replace('r1 = "130 mm"', 'r1 = "50 mm"'))
    with pytest.raises(SceneError, match="r1"):
        ClutchStand.from_scene(load_scene(p))
    p.write_text((SCENES / "clutch_shock_short.toml").read_text().replace('pulse_duration = "55 ms"', "#"))
    with pytest.raises(SceneError, match="pulse"):                 # a brake pulse needs all three keys
        ClutchStand.from_scene(load_scene(p))
    # a fixed-step method has no rtol/atol: named as the scene's key (was a TypeError traceback from rig run)
    p.write_text((SCENES / "clutch_startup.toml").read_text().replace("[plant]\n", '[plant]\nmethod = "RK4"\n', 1))
    with pytest.raises(SceneError, match=r"\[plant\]: key 'method': method 'RK4' is not one of the adaptive methods "
                                         r"DP45, Tsit5, DOP853, Rodas4, Rosenbrock23 \(a fixed-step method has no rtol/atol"):
        ClutchStand.from_scene(load_scene(p))


def test_stick_slip_startup_sticks_and_follows_rigid_closed_form():
    """After the start-up slip the halves stick (ωr ≡ 0) and move as one rigid body:
    J_tot ω̇ = a0 − b0 ω − M_tc with J_tot = J1 + J3 + n m_t k2² — an exponential in closed form."""
    st = ClutchStand.from_scene(load_scene(SCENES / "clutch_startup.toml"))
    d = st.dynamics
    t = np.linspace(0.0, 0.6, 601)
    out = st.advance(t)
    switches = list(zip(d._log_t, d._log_mode))
    i_stick = next(i for i, (ts, m) in enumerate(switches) if m == 0)
    t_stick = switches[i_stick][0]
    t_next = switches[i_stick + 1][0] if i_stick + 1 < len(switches) else np.inf
    assert 0.005 < t_stick < 0.1 and t_next > t_stick + 0.2
    # later, as the needed torque decays below the unloading branch, the deflection relaxes by slow
    # creep along the band edge (short slips at |ωr| well below 1 rad/s)
    assert np.max(np.abs(out["omega_r"][t > 0.1])) < 0.5
    after = (t > t_stick) & (t < t_next)
    assert np.all(out["omega_r"][after] == 0.0)
    c = d.clutch
    k2 = float(c.geometry(out["phi_r"][after][0])["k2"])
    J = c.J1 + c.J3 + c.n * c.m_t * k2 ** 2
    i0 = int(np.argmax(after))
    w_ss = (437.708 - 50.0) / 3.870                 # 50 N*m brake load (tanh(ω/0.5 rad/s) = 1 at speed)
    w_exact = w_ss + (out["omega1"][i0] - w_ss) * np.exp(-3.870 * (t[after] - t[i0]) / J)
    np.testing.assert_allclose(out["omega1"][after], w_exact, rtol=1e-6)
    # the transmitted torque stays inside the static friction band while stuck
    assert np.all(np.abs(out["T_c"][after]) < c.static_torque(out["phi_r"][after], direction=1.0) + 1e-9)


def test_tanh_regularisation_is_reported_stiff_but_stick_slip_is_not():
    import warnings
    from rig.solvers import StiffnessWarning
    st = ClutchStand.from_scene(load_scene(SCENES / "clutch_shock_short.toml"))   # running, stuck
    d = st.dynamics
    smooth = ClutchDynamics(d.clutch, d.motor, d.load, v_s=0.01, J_down=d.J_down, friction="tanh")
    with pytest.warns(StiffnessWarning, match="stiff"):
        s = integrate(smooth.problem(st.y), (0, 0.1), rtol=1e-5, atol=1e-8)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StiffnessWarning)
        s2 = integrate(d.problem(st.y), (0, 0.1), rtol=1e-5, atol=1e-8)
    assert s.stiff_at is not None and s2.stiff_at is None
    assert s.nsteps > 10 * s2.nsteps            # the explicit method is forced to tiny steps
    with pytest.raises(ValueError, match="friction"):
        ClutchDynamics(d.clutch, d.motor, d.load, friction="viscous")
