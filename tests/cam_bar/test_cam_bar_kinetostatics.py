"""Level-1 kinetostatics: virtual-power balance, free-body consistency, flank switches, spring design."""
from math import pi, tau

import numpy as np
import pytest

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.summary import STUDY_RATES, flank_switch_table

RPM = pi / 30
OMEGA = 150 * RPM   # the demo machine's cam speed (rad/s)
PHI = np.linspace(0.0, tau, 1441)[:-1] + 1e-4


def applied_and_inertia_power(mech, st, ks):
    """Σ rate of work of gravity, spring, F_c, guide friction and inertia on follower, rod and slider (W),
    from positions/velocities built here from ψ, ϑ, s and their time derivatives."""
    g = np.array([0.0, -mech.g])[:, None]
    e_psi = np.array([np.cos(st.psi), np.sin(st.psi)])
    n_psi = np.array([-np.sin(st.psi), np.cos(st.psi)])
    e_th = np.array([np.cos(st.theta), np.sin(st.theta)])
    n_th = np.array([-np.sin(st.theta), np.cos(st.theta)])
    pd, pdd, td, tdd = st.psi_d, st.psi_dd, st.theta_d, st.theta_dd
    v_g3 = mech.a3 * pd * n_psi
    v_g4 = mech.L3 * pd * n_psi + 0.5 * mech.l4 * td * n_th
    a_g4 = mech.L3 * (pdd * n_psi - pd**2 * e_psi) + 0.5 * mech.l4 * (tdd * n_th - td**2 * e_th)
    xd_dot, xd_ddot = -st.s_d, -st.s_dd
    p = (mech.m3 * (g * v_g3).sum(0) - mech.J3 * pdd * pd          # follower: gravity, inertia about B0
         + mech.m4 * ((g - a_g4) * v_g4).sum(0) - mech.J4 * tdd * td  # rod
         - mech.m5 * xd_ddot * xd_dot                                 # slider inertia (gravity ⟂ motion)
         + (ks.F_c + ks.friction) * xd_dot                            # insertion force and guide friction
         - ks.M_e * pd)                                               # spring moment acts towards smaller ψ
    return p


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("omega, alpha", [(150 * RPM, 0.0), (290 * RPM, -40.0), (100 * RPM, 25.0)])
def test_virtual_power_balance(direction, omega, alpha):
    mech = PinInsertionMechanism(cam_direction=direction)
    st = mech.state(PHI, omega, alpha)
    ks = mech.kinetostatics(PHI, omega, alpha)
    p_drive = ks.drive_torque * omega
    p_rest = applied_and_inertia_power(mech, st, ks)
    scale = np.max(np.abs(p_drive))
    assert scale > 1.0
    assert np.max(np.abs(p_drive + p_rest)) < 1e-9 * scale
    assert np.any(ks.friction != 0.0) and np.any(ks.F_c > 0.0)


def test_free_body_consistency():
    mech = PinInsertionMechanism(sensor_position=1.0)
    ks = mech.kinetostatics(PHI, OMEGA)
    st = mech.state(PHI, OMEGA)
    e = np.array([np.cos(st.theta), np.sin(st.theta)])
    # sensor at the slider end reads R54 along the rod; at the follower end −R34 along the rod
    assert ks.rod_tension == pytest.approx(ks.R54.x * e[0] + ks.R54.y * e[1], abs=1e-10)
    at_c = PinInsertionMechanism(sensor_position=0.0).kinetostatics(PHI, OMEGA)
    assert at_c.rod_tension == pytest.approx(-(ks.R34.x * e[0] + ks.R34.y * e[1]), abs=1e-10)
    assert ks.F_rod == pytest.approx(ks.rod_tension + mech.sensor_preload)
    # contact force: magnitude |R23n|, moment about B0 equals M_Σ, sign follows M_Σ
    assert ks.R23.mag == pytest.approx(np.abs(ks.R23n))
    bx, by = mech.l3 * np.cos(st.psi), mech.l3 * np.sin(st.psi)
    assert bx * ks.R23.y - by * ks.R23.x == pytest.approx(ks.M_sigma, abs=1e-10)
    assert np.all(np.sign(ks.R23n) == np.sign(ks.M_sigma))
    # Coulomb friction in the guide: |friction| = μ|N| while moving
    moving = st.s_d != 0.0
    assert np.abs(ks.friction[moving]) == pytest.approx(mech.mu * np.abs(ks.R15.y[moving]))
    assert np.all(ks.pressure_angle < np.radians(30.0))


def test_static_drive_torque_is_potential_gradient():
    """Quasi-static, frictionless, no F_c: drive torque = d(gravity + spring energy)/dφ (finite differences)."""
    mech = PinInsertionMechanism(mu=0.0, F_c=0.0)
    omega = 1e-4
    phi = np.linspace(0.5, 6.0, 200)
    h = 1e-5

    def energy(p):
        st = mech.state(p, omega)
        f_e0 = mech.Me_0 / mech.l_F
        stretch = mech.l_F * (st.psi - mech.psi0)
        spring = f_e0 * stretch + 0.5 * mech.k * stretch**2
        y4 = mech.L3 * np.sin(st.psi) + 0.5 * mech.l4 * np.sin(st.theta)
        return mech.g * (mech.m3 * mech.a3 * np.sin(st.psi) + mech.m4 * y4) + spring

    dV = (energy(phi + h) - energy(phi - h)) / (2 * h)
    torque = mech.kinetostatics(phi, omega).drive_torque
    assert torque == pytest.approx(dV, abs=1e-6 * np.max(np.abs(dV)))


def test_flank_switches_are_zeros_of_contact_moment():
    mech = PinInsertionMechanism()
    for spring in (False, True):
        omega = 150 * RPM if not spring else 300 * RPM
        angles = mech.flank_switch_angles(omega, spring=spring)
        assert len(angles) >= 2
        ks_lo = mech.kinetostatics(angles - 1e-6, omega)
        ks_hi = mech.kinetostatics(angles + 1e-6, omega)
        m_lo = ks_lo.M_sigma if spring else ks_lo.M23
        m_hi = ks_hi.M_sigma if spring else ks_hi.M23
        assert np.all(m_lo * m_hi <= 0.0)


def test_flank_switches_depend_on_speed_and_spring_rate():
    mech = PinInsertionMechanism()
    table = flank_switch_table(mech, OMEGA)
    assert len(table["no spring"]) > 0  # without the spring the contact force reverses at 150 rpm
    assert all(len(v) == 0 for k, v in table.items() if k != "no spring")  # springs keep it on the flank
    counts = [len(mech.flank_switch_angles(285 * RPM, k=k)) for k in STUDY_RATES]
    assert counts == sorted(counts, reverse=True) and counts[0] > 0 and counts[-1] == 0  # stiffer → fewer
    slow = mech.flank_switch_angles(290 * RPM, k=1090.0)
    fast = mech.flank_switch_angles(400 * RPM, k=1090.0)
    assert len(fast) > len(slow) > 0
    assert fast[fast > np.radians(200)][0] < slow[0]  # the return-phase switch comes earlier


def test_spring_design():
    d = PinInsertionMechanism().spring_rate_design()
    assert d.F_e0 == pytest.approx(200.0) and d.F_eS == pytest.approx(250.0)
    assert d.k == pytest.approx(1190.476, rel=1e-6)
    m = PinInsertionMechanism()
    psi = m.kinematics(np.array([0.0, 0.042])).psi
    assert d.travel_geometry == pytest.approx(0.1 * (psi[1] - psi[0]))
    assert d.travel_geometry < d.travel_thesis
    assert m.spring_moment(np.array([m.psi0]))[0] == pytest.approx(20.0)


def test_b_min_closed_form_at_rise_start():
    """Just after the rise starts (a ≈ 0, F_c off) the rod only overcomes μ·N: b_min → 2μ·m5·g·x_s5/(μ·N)."""
    mech = PinInsertionMechanism()
    ks = mech.kinetostatics(np.array([np.radians(60.0) + 1e-7]), OMEGA)
    n = ks.R15.y[0]
    assert ks.b_min[0] == pytest.approx(2 * mech.m5 * mech.g * mech.x_s5 / abs(n), rel=1e-3)
    assert np.isnan(mech.kinetostatics(np.array([0.5]), OMEGA).b_min[0])  # at rest in the lower dwell


def test_a_self_locking_guide_is_named_at_its_first_angle():
    """μ so high that no Coulomb state balances the rod somewhere: the vector call names the first such angle,
    the one a scalar call per angle finds first (the compiled solve goes point by point)."""
    from rig.plants.cam_bar import JammingError
    mech = PinInsertionMechanism(mu=300.0)        # the rod lies nearly along the guide: only a huge μ locks it
    phi = PHI[::8]
    first = None
    for p in phi:
        try:
            mech.kinetostatics(float(p), OMEGA)
        except JammingError:
            first = p
            break
    assert first is not None                                   # the premise: this guide does self-lock
    with pytest.raises(JammingError, match=f"φ = {np.degrees(first):.4g}° \\(μ = 300\\)"):
        mech.kinetostatics(phi, OMEGA)


def test_a_contact_normal_through_the_follower_pivot_is_an_error_naming_the_angle():
    """Cam pivot A0 at the follower pivot B0 and the follower at rest in φ (a dwell): the relative path's normal
    passes through B0, so the cam has no lever to drive the follower — an error, not an infinite force."""
    from rig.plants.cam_bar.kinetostatics import solve

    class AtPivot:                       # the mechanism with its cam pivot moved onto the follower pivot
        def __init__(self, mech):
            self._mech, self.x_A0, self.y_A0 = mech, 0.0, 0.0

        def __getattr__(self, name):
            return getattr(self._mech, name)

    mech = PinInsertionMechanism()
    dwell = PHI[np.abs(mech.state(PHI, OMEGA).psi_p) == 0.0]
    assert dwell.size                                          # the program has dwells
    with pytest.raises(ValueError, match=f"cam cannot drive the follower at φ = {np.degrees(dwell[0]):.4g}°"):
        solve(AtPivot(mech), mech.state(dwell, OMEGA), mech.k)


def test_the_summary_never_prints_two_flank_switch_angles_alike():
    """At 300 rpm without spring the force changes sign just before the 320° program boundary and jumps back across
    it: two angles 0.04° apart, printed with the decimals that tell them apart (not "320.0°, 320.0°")."""
    from math import radians
    from rig.plants.cam_bar.summary import _angles
    assert _angles(np.radians([120.3, 319.96, 320.0])) == "120.30°, 319.96°, 320.00°"
    assert _angles(np.array([radians(120.3), radians(180.0)])) == "120.3°, 180.0°"
    assert _angles(np.array([])) == "none"
