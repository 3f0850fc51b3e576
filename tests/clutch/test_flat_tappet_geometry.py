"""Geometry and static characteristic of the flat-tappet clutch (MODELS.md §4.1–4.2)."""
import math

import numpy as np
import pytest

from rig.plants.clutch import APEX, LOBE, FlatTappetClutch, GeometryError
from rig.plants.clutch.kernel import locate_segment, segment_geometry

REF = dict(r0=0.032, r1=0.100, r2=0.028, k_a=28000.0, delta=0.005)
THESIS = dict(r0=0.055, r1=0.130, r2=0.030, k_a=3000.0, F_a1=1284.0)


@pytest.fixture(params=[REF, THESIS], ids=["reference", "thesis"])
def clutch(request):
    return FlatTappetClutch(**request.param)


def _away_from_boundaries(c, phi, margin=1e-4):
    psi = np.mod(phi, LOBE)
    bounds = np.array([0.0, *c.limits.boundaries, LOBE])
    return np.min(np.abs(psi[:, None] - bounds[None, :]), axis=1) > margin


def test_phase_limits_closed_form():
    c = FlatTappetClutch(**THESIS)
    lim = c.phase_limits()
    expected = math.radians(60) - math.asin(0.075 / 0.100 * math.sin(math.radians(60)))
    assert lim.phi_maxI == pytest.approx(expected, rel=1e-14)
    # law of sines in the triangle (centre, arc-r1 centre, fillet centre): |C1C2| = r1 - r2
    c1, a2 = 0.075, lim.a2
    assert math.hypot(c1 + a2 * math.cos(APEX), a2 * math.sin(APEX)) == pytest.approx(0.100, rel=1e-12)
    assert lim.apex == pytest.approx(math.pi / 3)


def test_k1_is_derivative_of_k2_and_k3_of_k1_squared(clutch):
    phi = np.linspace(-2.5, 8.0, 3001)
    phi = phi[_away_from_boundaries(clutch, phi)]
    h = 1e-6
    gp, gm, g = clutch.geometry(phi + h), clutch.geometry(phi - h), clutch.geometry(phi)
    np.testing.assert_allclose(g["k1"], (gp["k2"] - gm["k2"]) / (2 * h), atol=1e-9)
    np.testing.assert_allclose(g["k3"], (gp["k1"] ** 2 - gm["k1"] ** 2) / (2 * h), atol=1e-9)


def test_continuity_and_curvature_jump_at_phi_maxI(clutch):
    pm, e = clutch.limits.phi_maxI, 1e-10
    for phi in (pm, LOBE - pm, pm + LOBE, -pm):
        g = clutch.geometry(np.array([phi - e, phi + e]))
        assert abs(g["k1"][1] - g["k1"][0]) < 1e-9
        assert abs(g["k2"][1] - g["k2"][0]) < 1e-9
    g = clutch.geometry(np.array([pm - e, pm + e]))
    assert g["dk1"][1] - g["dk1"][0] == pytest.approx(-(clutch.r1 - clutch.r2), rel=1e-6)


def test_zero_arm_at_apex_and_symmetry(clutch):
    g = clutch.geometry(np.array([APEX, APEX + LOBE, APEX - 2 * LOBE]))
    np.testing.assert_allclose(g["k1"], 0.0, atol=1e-15)
    np.testing.assert_allclose(clutch.static_torque(APEX, friction=False), 0.0, atol=1e-12)
    phi = np.linspace(0.01, 1.0, 50)
    a, b = clutch.geometry(phi), clutch.geometry(LOBE - phi)
    np.testing.assert_allclose(b["k2"], a["k2"], rtol=1e-12)
    np.testing.assert_allclose(b["k1"], -a["k1"], rtol=1e-12)
    assert float(clutch.geometry(0.0)["s"]) == pytest.approx(0.0, abs=1e-15)


def test_scalar_geometry_matches_vectorised(clutch):
    geom = clutch.scalar_geometry()
    phi = np.linspace(-7, 7, 997)
    g = clutch.geometry(phi)
    got = np.array([geom(p) for p in phi])
    np.testing.assert_allclose(got[:, 0], g["k1"], atol=1e-15)
    np.testing.assert_allclose(got[:, 1], g["k2"], atol=1e-15)
    np.testing.assert_allclose(got[:, 2], g["dk1"], atol=1e-15)
    np.testing.assert_array_equal(got[:, 3], np.where(g["k1"] < 0, -1.0, 1.0))     # flank


def test_held_segment_continues_its_formula_past_the_boundary(clutch):
    """The held geometry equals the plain one inside its segment and continues analytically beyond."""
    pm, c1 = clutch.limits.phi_maxI, clutch.r1 - clutch.r0
    held = lambda phi, base, seg: segment_geometry(phi, base, seg, c1, clutch.limits.a2, clutch.r1, clutch.r2, pm)  # noqa: E731
    locate = lambda phi, direction: locate_segment(phi, direction, pm)  # noqa: E731
    plain = clutch.scalar_geometry()
    base, seg = locate(pm, -1.0)                     # on the boundary moving back: phase I
    assert seg == 0 and locate(pm, 1.0)[1] == 1 and locate(-1e-3, 0.0) == (-2 * np.pi / 3, 3)
    for phi in np.linspace(0.0, pm, 7)[:-1]:          # (at pm itself dk1 is two-valued)
        assert held(phi, base, seg) == pytest.approx(plain(phi), abs=1e-15)
    beyond = held(pm + 0.05, base, seg)              # phase-I arc continued: k1 keeps rising, smooth dk1
    assert beyond[0] == pytest.approx(c1 * np.sin(pm + 0.05)) and beyond[2] == pytest.approx(c1 * np.cos(pm + 0.05))
    assert plain(pm + 0.05)[2] < 0 < beyond[2]       # the plain geometry has jumped to the fillet


def test_torque_proportional_to_k_a_and_peak_angle_independent():
    phi = np.radians(np.linspace(0, 60, 6001))
    curves = [FlatTappetClutch(**dict(REF, k_a=ka)).static_torque(phi) for ka in (14e3, 28e3, 56e3)]
    np.testing.assert_allclose(curves[1], 2 * curves[0], rtol=1e-12)
    np.testing.assert_allclose(curves[2], 2 * curves[1], rtol=1e-12)
    peaks = {int(np.argmax(c)) for c in curves}
    assert len(peaks) == 1
    T = curves[1]
    i = peaks.pop()
    assert 0 < i < len(phi) - 1 and T[0] < T[i] and T[-1] < T[i]   # progressive then regressive


def test_stiffness_is_derivative_of_torque(clutch):
    phi = np.linspace(-1.0, 4.0, 2001)
    phi = phi[_away_from_boundaries(clutch, phi)]
    h = 1e-6
    for fr, d in ((False, 1.0), (True, 1.0), (True, -1.0)):
        fd = (clutch.static_torque(phi + h, fr, d) - clutch.static_torque(phi - h, fr, d)) / (2 * h)
        np.testing.assert_allclose(clutch.stiffness(phi, fr, d), fd, rtol=1e-6, atol=1e-6)


def test_friction_gives_hysteresis_band():
    c = FlatTappetClutch(**THESIS)
    phi = np.linspace(0, 1, 11)
    up, down, el = c.static_torque(phi, True, 1.0), c.static_torque(phi, True, -1.0), c.static_torque(phi, False)
    np.testing.assert_allclose(up - el, el - down, rtol=1e-12)
    np.testing.assert_allclose(up - down, 2 * c.n * c.spring_force(phi) * c.mu_B * c.geometry(phi)["k2"], rtol=1e-12)


@pytest.mark.parametrize("kw, words", [
    (dict(r1=0.030), "r1"),
    (dict(r2=0.040), "r2"),
    (dict(r2=0.2), "r2"),
    (dict(r0=-0.01), "r0"),
    (dict(delta=None), "delta"),
    (dict(k_a=-1.0), "k_a"),
])
def test_impossible_geometry_is_named(kw, words):
    with pytest.raises(GeometryError, match=words):
        FlatTappetClutch(**dict(REF, **kw))


def test_preload_given_either_way():
    a = FlatTappetClutch(**REF)
    b = FlatTappetClutch(**dict(REF, delta=None, F_a1=140.0))
    assert a.F_a1 == pytest.approx(140.0) and b.delta == pytest.approx(0.005)
    with pytest.raises(GeometryError, match="exactly one"):
        FlatTappetClutch(**dict(REF, F_a1=140.0))
