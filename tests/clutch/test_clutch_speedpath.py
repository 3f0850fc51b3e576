"""Closed-form stuck segments of the clutch dynamics against numerical integration and balances."""

import numpy as np
import pytest
from scipy.integrate import quad

from rig.plants.clutch import FlatTappetClutch
from rig.plants.clutch.dynamics import ClutchDynamics
from rig.plants.clutch.loads import (
    LinearInSpeed,
    LinearMotor,
    LoadSum,
    ShoeBrake,
    constant,
    shock,
    step,
)
from rig.solvers import integrate

THESIS = dict(r0=0.055, r1=0.130, r2=0.030, k_a=3000.0, F_a1=1284.0, J1=0.35, J3=0.02)
MOTOR = (437.708, 3.870)


def run_both(load, y0, T, t_eval=None, motor=MOTOR, clutch=THESIS):
    """Integrate the same problem with the closed-form stuck flow and with DP45 only (rtol 1e-12)."""
    out = []
    for closed in (True, False):
        d = ClutchDynamics(FlatTappetClutch(**clutch), LinearMotor(*motor), load)
        prob = d.problem(y0)
        if not closed:
            prob.flow = None
        s = integrate(prob, (0.0, T), t_eval=t_eval, rtol=1e-12, atol=1e-14)
        out.append((d, s))
    return out


@pytest.fixture(scope="module")
def startup_runs():
    """Start-up from rest, then a load step at 0.4 s that starts stick–slip cycles (affine loads)."""
    load = LoadSum([constant(5.0), LinearInSpeed(1.0, 0.05), step(0.4, 20.0)])
    return run_both(load, (0.0, 0.0, 0.0, 0.0), 0.8, np.linspace(0.0, 0.8, 801))


def test_stuck_startup_closed_form_matches_numerical_integration(startup_runs):
    (d, s), (dn, sn) = startup_runs
    # stuck → slip → stuck cycles after the load step (band edges crossed inside closed-form segments)
    assert d._log_mode.count(0) >= 4 and sum(m != 0 for m in d._log_mode[2:]) >= 3
    assert s.nsteps < 0.95 * sn.nsteps                              # stuck time costs no RK steps
    scale = np.max(np.abs(sn.y), axis=1)
    np.testing.assert_allclose(s.y[:4] / scale[:4, None], sn.y[:4] / scale[:4, None], rtol=0, atol=1e-10)
    np.testing.assert_allclose(d._log_t, dn._log_t, atol=1e-10)
    assert d._log_mode == dn._log_mode


def test_stick_to_slip_located_in_the_closed_form(startup_runs):
    """After the load step the stuck halves break loose away from any time break: the band margin is
    crossed inside a closed-form segment and located as in the numerical run, on the band edge."""
    (d, s), _ = startup_runs
    modes = list(zip(d._log_t, d._log_mode))
    breaks = [(t, m) for (t, m), (_, m0) in zip(modes[1:], modes) if m0 == 0 and m != 0 and t > 0.41]
    assert len(breaks) >= 2
    t_break, mode = breaks[0]
    yb = next(r.y for r in s.events if r.name == "stick_slip" and r.t == t_break)
    tc, tp, tm = d.band(t_break, yb)[:3]
    edge = tp if mode == 1 else tm
    assert tc == pytest.approx(edge, rel=1e-9) and tm < tp


def test_stuck_flow_energy_balance():
    """While stuck: ½(J1 + J3')ω² changes by ∫(M1 − M3)ω dt (virtual power), spring energy is frozen."""
    c = FlatTappetClutch(**THESIS)
    load = LoadSum([constant(5.0), LinearInSpeed(0.0, 0.02)])
    d = ClutchDynamics(c, LinearMotor(*MOTOR), load)
    w_ss = (MOTOR[0] - 5.0) / (MOTOR[1] + 0.02)
    phi_r = d.equilibrium_angle(w_ss)
    y0 = (phi_r, 0.0, 0.0, w_ss - 10.0)
    d.reset(0.0, y0)
    assert d.mode == 0
    flow = d.stuck_flow(0.0, y0, 0.3)
    assert flow is not None and flow.stops == []
    k2 = float(c.geometry(phi_r)["k2"])
    J = c.J1 + c.J3 + c.n * c.m_t * k2 ** 2
    y1 = flow(0.3)
    assert y1[0] == phi_r and y1[1] == 0.0                            # relative angle frozen
    work = quad(lambda t: (d.motor.torque(t, flow(t)[3]) - load.torque(t, 0.0, flow(t)[3], ())) * flow(t)[3],
                0.0, 0.3, epsabs=1e-12, epsrel=1e-13)[0]
    assert d.energy(y1) - d.energy(y0) == pytest.approx(work, rel=1e-10)
    assert 0.5 * J * (y1[3] ** 2 - y0[3] ** 2) == pytest.approx(work, rel=1e-10)
    # momentum balance: J Δω = ∫(M1 − M3) dt
    impulse = quad(lambda t: d.motor.torque(t, flow(t)[3]) - load.torque(t, 0.0, flow(t)[3], ()), 0.0, 0.3,
                   epsabs=1e-12, epsrel=1e-13)[0]
    assert J * (y1[3] - y0[3]) == pytest.approx(impulse, rel=1e-10)


def test_shock_disengagements_agree_with_numerical_integration():
    load = LoadSum([constant(5.0), shock(0.05, 0.1, 150.0)])
    w0 = (MOTOR[0] - 5.0) / MOTOR[1]
    (_, s), (_, sn) = run_both(load, (0.0, 0.0, 0.0, w0), 0.4)
    assert len(s.t_events["apex"]) >= 2
    np.testing.assert_allclose(s.t_events["apex"], sn.t_events["apex"], atol=1e-9)
    assert s.y_final[1] == pytest.approx(sn.y_final[1], rel=1e-8)     # 64 disengagements: roundoff amplified


def test_closed_form_only_for_stuck_mode_and_a_resting_saturated_brake():
    c = FlatTappetClutch(**THESIS)
    d = ClutchDynamics(c, LinearMotor(*MOTOR), ShoeBrake(gain=0.01, tau=0.005, force=1000.0))
    w = (MOTOR[0] - 10.0) / MOTOR[1]
    y = (d.equilibrium_angle(w), 0.0, 0.0, w, 1000.0)
    d.reset(0.0, y)
    assert d.mode == 0 and d.stuck_flow(0.0, y, 0.1) is not None      # brake at rest, saturated: constant
    moving = y[:4] + (900.0,)                                          # actuator still moving: numerical
    assert d.stuck_flow(0.0, moving, 0.1) is None
    d2 = ClutchDynamics(c, LinearMotor(*MOTOR), constant(5.0))
    d2.reset(0.0, (0.0, 10.0, 0.0, 50.0))
    assert d2.mode == 1 and d2.stuck_flow(0.0, (0.0, 10.0, 0.0, 50.0), 0.1) is None


def test_load_affine_forms():
    ld = LoadSum([constant(5.0), LinearInSpeed(1.0, 0.5), step(0.2, 3.0)])
    assert ld.affine(0.1) == (6.0, 0.5) and ld.affine(0.3) == (9.0, 0.5)
    for t, w in ((0.1, 7.0), (0.3, -2.0)):
        a, b = ld.affine(t)
        assert ld.torque(t, 0.0, w, ()) == pytest.approx(a + b * w)
    brake = LoadSum([constant(1.0), ShoeBrake(0.01, 0.005, 100.0)])
    assert brake.affine(0.1) is None and brake.affine(0.1, (90.0,), 20.0, 30.0) is None   # actuator moving
    assert brake.affine(0.1, (100.0,), 20.0, 30.0) == (2.0, 0.0)                          # tanh saturated
    assert brake.torque(0.1, 0.0, 20.0, (100.0,)) == 2.0
    assert brake.affine(0.1, (100.0,), 5.0, 30.0) is None                                # tanh not saturated
    m = LinearMotor(100.0, 2.0, ratio=2.0, t_off=1.0)
    A, B = m.affine(0.5)
    assert m.torque(0.5, 3.0) == pytest.approx(A - B * 3.0) and m.affine(1.5) == (0.0, 0.0)


def test_brake_loaded_startup_closed_form_matches_numerical_integration():
    """The stand's start-up under its shoe brake (actuator at rest, tanh saturated once moving): the
    closed-form stuck segments agree with DP45 at 1e-12 and skip its steps."""
    load = ShoeBrake(gain=0.01, tau=0.005, force=5000.0)
    (d, s), (dn, sn) = run_both(load, (0.0, 0.0, 0.0, 0.0, 5000.0), 0.8, np.linspace(0.0, 0.8, 401))
    assert 0 in d._log_mode and s.nsteps < 0.8 * sn.nsteps
    scale = np.max(np.abs(sn.y[:4]), axis=1)
    np.testing.assert_allclose(s.y[:4] / scale[:, None], sn.y[:4] / scale[:, None], rtol=0, atol=1e-9)
