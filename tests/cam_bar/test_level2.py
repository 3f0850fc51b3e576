"""Level 2 of the pin-insertion mechanism (MODELS §3.4): groove dynamics against independent references."""
import warnings
from math import degrees, radians

import numpy as np
import pytest

from rig.motion import ConstantSpeed
from rig.motion.speed import SinusoidalSpeed
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.insertion import InsertionLaw
from rig.plants.cam_bar.level2 import ContactLaw, Level2, groove
from rig.plants.cam_bar.level2_model import Level2Model
from rig.plants.cam_bar.plant import DEMO_SPEED
from rig.motion.speed import RPM
from rig.solvers import SolverDivergence
from rig.solvers.rodas import fd_jacobian

NO_SPRING = dict(k=0.0, Me_0=0.0)


def _scaled(mech: PinInsertionMechanism, scale: float) -> ContactLaw:
    """The steel contact with stiffness × scale and damping × √scale (same damping ratio of the contact mode)."""
    base = ContactLaw.steel_line(mech.roller_width, Level2Model().contact_damping)
    return ContactLaw(base.stiffness * scale, base.exponent, base.damping * scale ** 0.5)


W = DEMO_SPEED.omega


def _window(model: Level2, a_deg: float, b_deg: float, **options):
    w = model.speed.nominal_omega
    run = model.simulate((radians(a_deg) / w, radians(b_deg) / w), **{"rtol": 1e-3, "atol": 1e-9, **options})
    return run, model.signals(run.solution.t, run.solution.y)


def test_contact_law_is_palmgren_line_contact_with_consistent_energy():
    law = ContactLaw.steel_line(0.010)
    for q in (50.0, 500.0, 5000.0):  # Palmgren: δ = 3.84e-5·Q^0.9/l^0.8 (mm, N)
        delta = 3.84e-5 * q ** 0.9 / 10.0 ** 0.8 * 1e-3
        assert law.elastic(np.array(delta)) == pytest.approx(q, rel=1e-12)
        assert law.penetration(np.array(q)) == pytest.approx(delta, rel=1e-12)
        h = delta * 1e-6
        assert (law.energy(np.array(delta + h)) - law.energy(np.array(delta - h))) / (2 * h) == pytest.approx(q, rel=1e-7)
    assert law.force(np.array(-1e-6), np.array(1.0)) == 0.0                    # no contact, no force
    assert law.force(np.array(1e-6), np.array(-1.0)) == 0.0                    # never pulls
    assert law.force(np.array(1e-6), np.array(0.01)) > law.elastic(np.array(1e-6))  # damping while penetrating
    with pytest.raises(ValueError, match="stiffness"):
        ContactLaw(-1.0)
    with pytest.raises(ValueError, match="width"):
        ContactLaw.steel_line(0.0)


def test_groove_geometry_matches_level1_lever_and_finite_differences():
    mech = PinInsertionMechanism()
    phi = np.linspace(0.05, 6.2, 40)
    g = groove(mech, phi)
    ks = mech.kinetostatics(phi, W)
    assert g.lever == pytest.approx(ks.M_sigma / ks.R23n, rel=1e-12)  # ℓ = B_R × n of level 1
    h = 1e-6
    gp, gm = groove(mech, phi + h), groove(mech, phi - h)
    assert g.lever_p == pytest.approx((gp.lever - gm.lever) / (2 * h), abs=1e-9)
    assert g.psi_p == pytest.approx((gp.psi - gm.psi) / (2 * h), abs=1e-8)
    assert g.psi == pytest.approx(mech.state(phi).psi, abs=1e-14)
    assert np.all(g.rising == (mech.state(phi).s_p > 0))


def test_zero_clearance_and_stiff_contact_converge_to_levels_0_and_1():
    mech = PinInsertionMechanism(clearance=0.0, F_c=0.0, **NO_SPRING)  # R23 changes sign at 121.1°
    l1_switch = degrees(mech.flank_switch_angles(W)[0])
    dev, err = [], []
    for scale in (1.0, 100.0):
        run, sig = _window(Level2(mech, DEMO_SPEED, _scaled(mech, scale)), 90.0, 175.0, rtol=1e-4, atol=1e-10, method="Rodas4")
        ks = mech.kinetostatics(sig["phi"], W)
        dev.append(np.max(np.abs(sig["psi"] - mech.state(sig["phi"]).psi)))     # ψ against the cam law
        err.append(np.max(np.abs(sig["R23"] - ks.R23n)) / np.max(np.abs(ks.R23n)))
        assert [e.data["to"] for e in run.switches] == ["other"]
        late = degrees(run.switches[0].data["phi"]) - l1_switch          # the compliant contact delays it
        assert 0.0 < late < (0.06 if scale == 1.0 else 0.006)
    assert dev[0] < 1e-5 and dev[1] < dev[0] / 30.0           # δ ∝ K^(-0.9): 100× stiffer → 63× closer
    assert err[0] < 0.01 and err[1] < 0.002


def test_energy_balance_over_a_cycle_with_speed_variation():
    """W_drive + W(F_c, friction) − E_dissipated = Δ(kinetic + gravity + spring + contact), to the solver's
    accuracy; soft contact (K/100) so that a tight DP45 reference stays affordable."""
    mech = PinInsertionMechanism()
    model = Level2(mech, SinusoidalSpeed(150 * RPM, 1.5), _scaled(mech, 0.01), energy=True, max_penetration=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = model.simulate((0.0, 0.4), method="DP45", rtol=1e-8, atol=1e-12)
    sol = run.solution
    energy = model.energies(sol.t[[0, -1]], sol.y[:, [0, -1]])
    change = sum(v[1] - v[0] for v in energy.values())
    w_drive, w_load, dissipated = sol.y[2:, -1]
    assert dissipated > 1e-3 and abs(w_load) > 0.1 and abs(w_drive) > 0.1  # contact damping, F_c and friction do work
    assert w_drive + w_load - dissipated - change == pytest.approx(0.0, abs=1e-5 * dissipated)


def test_flank_switches_where_level1_predicts_and_fewer_with_a_stiffer_spring():
    omega = 300 * RPM                                          # level 1: switches during the return
    runs = {}
    for k in (1090.0, 1890.0):
        mech = PinInsertionMechanism(k=k)
        model = Level2(mech, ConstantSpeed(omega))
        run, sig = _window(model, 200.0, 300.0)
        l1 = np.degrees(mech.flank_switch_angles(omega))
        leave = [degrees(t * omega) for t, flank in run.releases if flank == "working"]
        assert leave[0] == pytest.approx(l1[0], abs=0.5)       # the roller leaves where R23n changes sign
        gap = sig["psi"] - sig["psi_kin"]
        runs[k] = (run, np.max(gap * groove(mech, sig["phi"]).lever) / mech.clearance)
    soft, stiff = runs[1090.0], runs[1890.0]
    assert [e.data["to"] for e in soft[0].switches] == ["other", "working"]
    assert degrees(soft[0].switches[0].data["phi"]) > 234.0    # arrives after crossing the clearance
    assert len(stiff[0].switches) < len(soft[0].switches)      # 1.89 N/mm: the roller never reaches the other flank
    assert soft[1] > 1.0 > stiff[1] > 0.2                       # gap opened: full clearance vs. part of it


def test_jump_at_end_of_active_stroke_and_fourfold_clearance_amplification():
    spread = {}
    for c in (0.05e-3, 0.10e-3):
        mech = PinInsertionMechanism(clearance=c, **NO_SPRING)
        run, sig = _window(Level2(mech, DEMO_SPEED), 100.0, 178.0)
        ds = sig["s"] - mech.state(sig["phi"]).s                 # gripper ahead of the level-0 stroke (m)
        phi = np.degrees(sig["phi"])
        assert degrees(run.switches[0].data["phi"]) == pytest.approx(121.1 + 12.0, abs=8.0)
        assert np.max(ds[phi > 125.0]) > 3.0 * c                 # the jump: decelerating rise, roller crosses
        assert np.max(ds[phi < 120.0]) < 0.2 * c
        on_other, on_working = sig["delta_o"] > 0.0, sig["delta_w"] > 0.0
        spread[c] = np.median(ds[on_other]) - np.median(ds[on_working])
    ratio = mech.L3 / mech.l3
    for c, value in spread.items():
        assert value / c == pytest.approx(ratio, rel=0.15)      # ≈ L3/l3 = 4 × the cam clearance
    assert spread[0.10e-3] / spread[0.05e-3] == pytest.approx(2.0, rel=0.1)


def test_gripper_rings_in_the_upper_dwell_at_the_contact_frequency():
    mech = PinInsertionMechanism(insertion=InsertionLaw("step"))   # the constant-F_c window: a load step
    model = Level2(mech, DEMO_SPEED)
    run, sig = _window(model, 178.0, 220.0, rtol=1e-4)
    phi = np.degrees(sig["phi"])
    t = sig["t"]
    dwell = phi > 181.0                                          # F_c released at 180°: load step → ringing
    ds = sig["s"][dwell] - mech.state(sig["phi"][dwell]).s
    x = ds - np.median(ds)
    early, late = t[dwell] < t[dwell][0] + 0.004, t[dwell] > t[dwell][-1] - 0.004
    assert np.ptp(x[early]) > 1e-6 and np.ptp(x[late]) < 0.1 * np.ptp(x[early])  # visible, then decays
    grid = np.linspace(t[dwell][0], t[dwell][0] + 0.006, 3001)
    xs = np.interp(grid, t[dwell], x)
    crossings = grid[1:][np.diff(np.sign(xs - np.mean(xs))) != 0]
    f_ring = 0.5 / np.mean(np.diff(crossings))
    y = run.solution.y[:, -1]
    t_end = float(run.solution.t[-1])
    jac, _ = fd_jacobian(model.rhs, t_end, y, np.array(model.rhs(t_end, tuple(y))), 1e-6, 1e-12, 1e-4)
    f_mode = np.max(np.abs(np.linalg.eigvals(jac).imag)) / (2 * np.pi)   # linearised contact mode
    assert 300.0 < f_mode < 1500.0
    assert f_ring == pytest.approx(f_mode, rel=0.1)


def test_diverging_run_is_reported_with_time_and_state():
    mech = PinInsertionMechanism()
    law = ContactLaw(ContactLaw.steel_line(0.01).stiffness * 1e-3)          # a far too soft contact
    start = float(law.penetration(mech.kinetostatics(np.array([0.0]), W).R23n[0]))
    soft = Level2(mech, DEMO_SPEED, law, max_penetration=1.3 * start)
    with pytest.raises(SolverDivergence, match=r"penetrates a flank by more than .* mm at cam angle .* state at t = "
                       ) as caught:
        soft.simulate((0.0, 0.2))
    assert 0.0 < caught.value.t < 0.2                                      # found during the run, not at the start
    with pytest.raises(SolverDivergence, match=r"penetrates"):
        Level2(mech, DEMO_SPEED, law, max_penetration=0.5 * start).simulate((0.0, 0.2))  # already at the start
    with pytest.raises(SolverDivergence, match=r"state at t = .* s: \("):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            Level2(mech, DEMO_SPEED).simulate((0.0, 0.05), method="RK4", h=2e-3)      # beyond RK4's stability limit
