"""Level-0 chain: spec formulas, branch, round trip, derivatives vs finite differences, singular positions."""
from math import degrees, pi, radians, tau

import numpy as np
import pytest

from rig.motion import SinusoidalSpeed
from rig.plants.cam_bar import PinInsertionMechanism, SingularPositionError

M = PinInsertionMechanism()


def test_start_angle_matches_machine():
    assert degrees(M.psi0) == pytest.approx(90.0 - 4.65, abs=0.05)


def test_closed_forms_of_models_3_2():
    s = np.linspace(0.0, 0.042, 50)
    pos = M.kinematics(s)
    u = M.s0 - s
    A, B, C = -2 * M.L3 * u, -2 * M.L3 * M.e_sk, u**2 + M.e_sk**2 + M.L3**2 - M.l4**2
    psi_spec = 2 * np.arctan((B + np.sqrt(A**2 + B**2 - C**2)) / (A - C))
    D, E, F = -2 * M.l4 * u, -2 * M.l4 * M.e_sk, u**2 + M.e_sk**2 - M.L3**2 + M.l4**2
    theta_spec = 2 * np.arctan((E - np.sqrt(D**2 + E**2 - F**2)) / (D - F))
    wrap = lambda a: np.angle(np.exp(1j * a))  # noqa: E731
    assert wrap(pos.psi - psi_spec) == pytest.approx(np.zeros_like(s), abs=1e-12)
    assert wrap(pos.theta - theta_spec) == pytest.approx(np.zeros_like(s), abs=1e-12)
    # loop closure and pitch-radius equation G = 0
    assert M.L3 * np.cos(pos.psi) + M.l4 * np.cos(pos.theta) == pytest.approx(u, abs=1e-14)
    assert M.L3 * np.sin(pos.psi) + M.l4 * np.sin(pos.theta) == pytest.approx(np.full_like(s, M.e_sk), abs=1e-14)
    cp, sp = np.cos(pos.psi), np.sin(pos.psi)
    G = 2 * M.x_A0 * M.l3 * cp + 2 * M.y_A0 * M.l3 * sp + pos.r**2 - M.x_A0**2 - M.y_A0**2 - M.l3**2
    assert G == pytest.approx(np.zeros_like(s), abs=1e-15)


def test_inverse_round_trip_and_spec_quadratic():
    s = np.linspace(-0.002, 0.044, 101)
    psi = M.kinematics(s).psi
    back = M.slider_from_follower(psi)
    assert back == pytest.approx(s, abs=1e-13)
    Ds = 2 * M.L3 * np.cos(psi) - 2 * M.s0
    Es = (M.s0**2 + M.e_sk**2 + M.L3**2 - M.l4**2 - 2 * M.L3 * M.e_sk * np.sin(psi)
          - 2 * M.L3 * M.s0 * np.cos(psi))
    assert back**2 + Ds * back + Es == pytest.approx(np.zeros_like(s), abs=1e-14)
    assert float(M.slider_from_follower(M.psi0)) == pytest.approx(0.0, abs=1e-13)


def test_phi_derivatives_match_finite_differences():
    phi = np.linspace(0.0, tau, 721)[:-1] + 1e-3
    h = 1e-5
    st, up, dn = M.state(phi), M.state(phi + h), M.state(phi - h)
    for q in ("s", "psi", "theta", "r"):
        for d0, d1 in (("", "_p"), ("_p", "_pp")):
            fd = (getattr(up, q + d0) - getattr(dn, q + d0)) / (2 * h)
            exact = getattr(st, q + d1)
            assert fd == pytest.approx(exact, abs=1e-6 * np.max(np.abs(exact)) + 1e-12), q + d1


def test_time_derivatives_with_speed_fluctuation():
    mech, speed = PinInsertionMechanism(), SinusoidalSpeed(omega_mean=15.7, amplitude=4.0)
    t = np.linspace(0.01, 0.39, 300)
    h = 1e-6

    def at(tt):
        d = speed.drive(tt)
        return mech.state(d.phi, d.omega, d.alpha)

    st, up, dn = at(t), at(t + h), at(t - h)
    for q in ("s", "psi", "theta", "r"):
        v_fd = (getattr(up, q) - getattr(dn, q)) / (2 * h)
        a_fd = (getattr(up, q + "_d") - getattr(dn, q + "_d")) / (2 * h)
        assert v_fd == pytest.approx(getattr(st, q + "_d"), abs=1e-6 * np.max(np.abs(v_fd)))
        assert a_fd == pytest.approx(getattr(st, q + "_dd"), abs=1e-5 * np.max(np.abs(a_fd)))


def test_impossible_geometry_at_construction():
    with pytest.raises(SingularPositionError, match=r"impossible cam-bar geometry.*\|B0D\|.*l4 = 20 mm"):
        PinInsertionMechanism(l4=0.020)


def test_singular_positions_name_angle_and_parameters():
    reach = np.sqrt((M.L3 + M.l4) ** 2 - M.e_sk**2)
    with pytest.raises(SingularPositionError, match=r"φ = 123°.*L3 = 260 mm, l4 = 122 mm"):
        M.chain.angles(np.array([0.0, M.s0 + reach + 0.01]), np.radians([0.0, 123.0]))
    with pytest.raises(SingularPositionError, match=r"dead centre.*φ = 45°"):
        M.chain.angles(np.array([M.s0 + reach]), np.array([radians(45)]))
    with pytest.raises(SingularPositionError, match="cannot be reached"):
        M.slider_from_follower(-pi / 2)
