"""The mechanism library against closed forms and identities (issue 16): Cardan extremes and mean ratio,
double-Cardan cancellation, Geneva timing and kinematics, gear geometry consistency, mobility, Willis."""
from __future__ import annotations

import re
import warnings
from math import cos, degrees, pi, radians, sin, sqrt, tan

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.integrate import trapezoid

from rig.mechanisms.cam.sizing import flocke_base_radius
from rig.motion import get_law
from rig.mechanisms import (Belt, Cardan, DoubleCardan, FrictionWheels, Geneva, Ratchet, SpurGearPair, involute,
                            inverse_involute, mobility, willis)

TURN = np.linspace(0.0, 2 * pi, 200001)


@pytest.mark.parametrize("alpha_deg", [0.0, 10.0, 30.0, 45.0, 60.0])
def test_cardan_ratio_lies_between_cos_and_its_inverse_and_averages_one(alpha_deg):
    c = Cardan(radians(alpha_deg))
    r = c.speed_ratio(TURN)
    assert r.min() == pytest.approx(cos(radians(alpha_deg)), rel=1e-12)
    assert r.max() == pytest.approx(1 / cos(radians(alpha_deg)), rel=1e-9)
    assert trapezoid(r, TURN) / (2 * pi) == pytest.approx(1.0, rel=1e-9)       # one output turn per input turn
    phi2 = c.output_angle(TURN)
    assert phi2[-1] - phi2[0] == pytest.approx(2 * pi, rel=1e-12)
    assert np.allclose(np.tan(phi2[1:-1:997]) * cos(radians(alpha_deg)), np.tan(TURN[1:-1:997]), atol=1e-6,
                       rtol=1e-9) or alpha_deg == 0
    # speed ratio = dφ2/dφ1 and acceleration = ω1² d(ratio)/dφ1 (finite differences)
    h = 1e-6
    phi = np.linspace(0.1, 6.0, 37)
    assert np.allclose((c.output_angle(phi + h) - c.output_angle(phi - h)) / (2 * h), c.speed_ratio(phi), atol=1e-8)
    w1 = 15.0
    assert np.allclose(w1 ** 2 * (c.speed_ratio(phi + h) - c.speed_ratio(phi - h)) / (2 * h),
                       c.acceleration(phi, w1), rtol=1e-6, atol=1e-6)
    assert np.allclose(c.input_angle(c.output_angle(TURN[::1001])), TURN[::1001], atol=1e-12)


def test_cardan_ratio_holds_to_rounding_next_to_90_degrees():
    """1 − sin²α cos²φ cancelled near 90°: 1/cos α read 37 % high at 89.999999° and divided by zero at 90° − 1e-12 rad
    (an audit). At φ1 = 0 the ratio is 1/cos α, at 90° it is cos α, to rounding; no warning."""
    import warnings
    for alpha in (np.radians(89.999999), pi / 2 - 1e-12):
        joint = Cardan(alpha)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert joint.speed_ratio(0.0) == pytest.approx(1 / np.cos(alpha), rel=1e-12)
            assert joint.speed_ratio(pi / 2) == pytest.approx(np.cos(alpha), rel=1e-12)
            assert np.isfinite(joint.acceleration(np.linspace(0, 2 * pi, 13), 1.0)).all()


@pytest.mark.parametrize("arrangement", ["Z", "W"])
def test_double_cardan_cancels_with_equal_angles_and_yokes_in_one_plane(arrangement):
    equal = DoubleCardan(radians(25), radians(25), arrangement)
    assert np.max(np.abs(equal.output_angle(TURN) - TURN)) < 1e-12
    assert np.max(np.abs(equal.speed_ratio(TURN) - 1.0)) < 1e-12
    unequal = DoubleCardan(radians(25), radians(15), arrangement)
    misassembled = DoubleCardan(radians(25), radians(25), arrangement, yoke_offset=radians(90))
    for d in (unequal, misassembled):
        assert np.ptp(d.speed_ratio(TURN)) > 0.05
        assert trapezoid(d.speed_ratio(TURN), TURN) / (2 * pi) == pytest.approx(1.0, rel=1e-9)
    # a 90° yoke error doubles the single joint's fluctuation instead of cancelling it: cos²α .. 1/cos²α
    r = misassembled.speed_ratio(TURN)
    assert r.min() == pytest.approx(cos(radians(25)) ** 2, rel=1e-9)
    assert r.max() == pytest.approx(1 / cos(radians(25)) ** 2, rel=1e-9)
    with pytest.raises(ValueError, match="arrangement must be 'Z' or 'W'"):
        DoubleCardan(0.1, 0.1, "X")


@pytest.mark.parametrize("z", [3, 4, 5, 6, 8, 12])
def test_geneva_timing_and_kinematics(z):
    g = Geneva(z, 0.05)
    t = g.timing(10.0)
    assert t.motion_time + t.dwell_time == pytest.approx(t.period, rel=1e-15)
    assert t.motion_ratio == pytest.approx((z - 2) / (2 * z), rel=1e-12)
    assert t.dwell_ratio == pytest.approx(1 - (z - 2) / (2 * z), rel=1e-12)
    phi = np.linspace(-pi, pi, 400001)
    m = g.kinematics(phi, 1.0)
    engaged = m.engaged
    # the wheel turns one slot pitch per crank turn: ∫ω2 dφ1 = 2π/z, and the angle goes from −π/z to π/z
    assert trapezoid(m.velocity, phi) == pytest.approx(2 * pi / z, rel=1e-6)
    assert m.angle[engaged].min() == pytest.approx(-pi / z, abs=1e-4) and m.angle[-1] == pytest.approx(pi / z)
    # the pin enters and leaves tangentially: no speed jump at the ends of engagement
    assert np.max(np.abs(m.velocity[engaged][[0, -1]])) < 1e-4
    # velocity and acceleration are the derivatives (finite differences inside the engagement)
    inner = np.flatnonzero(engaged)[5:-5:1000]
    assert np.allclose(np.gradient(m.angle, phi)[inner], m.velocity[inner], rtol=1e-5, atol=1e-8)
    assert np.allclose(np.gradient(m.velocity, phi)[inner], m.acceleration[inner], rtol=1e-4, atol=1e-6)
    assert np.all(m.velocity[~engaged] == 0.0) and np.all(m.acceleration[~engaged] == 0.0)
    assert g.crank_radius == pytest.approx(0.05 * np.sin(pi / z))


def test_geneva_of_the_student_project():
    """z = 5, L = 50 mm, driven from 1140 rpm through 34/80: the crank turns at 484.5 rpm."""
    crank = 1140 * 34 / 80 * 2 * pi / 60
    t = Geneva(5, 0.050).timing(crank)
    assert t.period == pytest.approx(60 / 484.5, rel=1e-12)
    assert t.motion_time == pytest.approx(0.3 * 60 / 484.5, rel=1e-12)


@pytest.mark.parametrize("bad, message", [((2, 0.05), r"slots \(a wheel with fewer cannot index\) must be a whole number >= 3"),
                                          ((5, 0.0), "centre_distance must be positive")])
def test_geneva_refuses_impossible_input(bad, message):
    with pytest.raises(ValueError, match=message):
        Geneva(*bad)


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(st.floats(radians(1), radians(60)))
def test_inverse_involute_inverts(alpha):
    """Pressure angles of real gears (inv α ≈ α³/3 cancels in floating point below ~1°)."""
    assert inverse_involute(involute(alpha)) == pytest.approx(alpha, abs=1e-10)


def test_gear_pair_of_the_student_project_is_consistent():
    pair = SpurGearPair(34, 80, 4.5e-3, 0.98, 1.81)
    g = pair.geometry()
    a0, aw = radians(20), g.working_pressure_angle
    # the working pressure angle solves the involute equation and fixes the centre distance: a cos αw = a0 cos α0
    assert involute(aw) == pytest.approx(involute(a0) + 2 * (0.98 + 1.81) / 114 * tan(a0), rel=1e-12)
    assert g.centre_distance * cos(aw) == pytest.approx(g.reference_centre_distance * cos(a0), rel=1e-12)
    assert g.reference_centre_distance == pytest.approx(0.2565)
    assert sum(g.working_diameters) / 2 == pytest.approx(g.centre_distance, rel=1e-12)
    assert g.working_diameters[0] * cos(aw) == pytest.approx(g.base_diameters[0], rel=1e-12)
    # tip clearance kept at 0.25 m: a = (da1 + df2)/2 + 0.25 m
    assert (g.tip_diameters[0] + g.root_diameters[1]) / 2 + 0.25 * 4.5e-3 == pytest.approx(g.centre_distance, rel=1e-12)
    assert 1.0 < g.contact_ratio < 2.0
    assert degrees(aw) == pytest.approx(25.70, abs=0.01)
    # y·m = a − a0 and k·m = (x1 + x2 − y)·m; tooth thickness on the reference circle s = m(π/2 + 2x tan α0)
    y = (g.centre_distance - g.reference_centre_distance) / 4.5e-3
    assert g.centre_distance_modification == pytest.approx(y * 4.5e-3, rel=1e-12)
    assert g.tip_reduction == pytest.approx((0.98 + 1.81 - y) * 4.5e-3, rel=1e-12) and 0 < g.tip_reduction
    assert g.tooth_thickness == pytest.approx(tuple(4.5e-3 * (pi / 2 + 2 * x * tan(a0)) for x in (0.98, 1.81)),
                                              rel=1e-12)


def test_unshifted_gears_have_the_standard_geometry_and_contact_ratio():
    g = SpurGearPair(20, 40, 2e-3).geometry()
    assert g.working_pressure_angle == pytest.approx(radians(20), abs=1e-12)
    assert g.centre_distance == pytest.approx(0.060, rel=1e-12) and g.tip_reduction == pytest.approx(0, abs=1e-15)
    assert g.tip_diameters == pytest.approx((0.044, 0.084)) and g.root_diameters == pytest.approx((0.035, 0.075))
    # textbook value for 20/40 teeth, 20°: ε ≈ 1.64
    assert g.contact_ratio == pytest.approx(1.64, abs=0.01)


def test_library_inputs_beyond_their_formulas_are_named():
    """Each returned NaN, inf or a misleading error, or raised a TypeError/ZeroDivisionError (an audit)."""
    from rig.mechanisms.cam import DoubleSlider, FourBar, SliderCrank, hertz_line_stress, synthesize
    from rig.mechanisms.cam.sizing import flocke_base_radius, guide_ratio, pressure_angles
    from rig.mechanisms.gears import involute
    from rig.motion import get_law
    for call, message in [
            (lambda: hertz_line_stress(float("nan"), 0.01, 0.01, 0.05), "contact force \\(N\\) must be finite"),
            (lambda: hertz_line_stress(100.0, 0.01, 0.01, 0.0), "profile radius \\(m\\) must be a number other than 0"),
            (lambda: hertz_line_stress(100.0, float("inf"), 0.01, 0.05), "contact width \\(m\\) must be a finite"),
            (lambda: pressure_angles(get_law("cycloidal"), float("nan"), 1.0, 0.05),
             "stroke h \\(m\\) must be a finite"),
            (lambda: guide_ratio(-0.3, 0.1, 1.0, 0.5), "pressure angle α must lie in \\(0, 90°\\)"),
            (lambda: guide_ratio(0.3, -0.1, 1.0, 0.5), "guide friction μ and Φ_L must not be negative"),
            (lambda: involute(float("nan")), "involute angle α \\(rad\\) must be a finite"),
            (lambda: involute(pi / 2), "involute angle α must lie in \\[0, 90°\\)"),
            (lambda: SpurGearPair(20, 40, 1e-200), "module is in metres, from 1e-05"),
            (lambda: SpurGearPair(10**9, 10**9, 1e-3), "z1 \\(teeth\\) must be a whole number >= 5 and <= 10000"),
            (lambda: SliderCrank(0.05, 0.1, 0.0, 0.0), "linkage side is an assembly choice, \\+1 or -1, got 0.0"),
            (lambda: FourBar(0.1, 0.04, 0.09, 0.07, 0), "linkage branch is an assembly choice"),
            (lambda: SliderCrank(0.05, float("inf")), "linkage length l must be positive and finite"),
            (lambda: synthesize(DoubleSlider(0.05), np.array([0.01, np.nan]), np.zeros(2), np.zeros(2)),
             "synthesize needs finite output values"),
            (lambda: synthesize(DoubleSlider(0.05), np.array(0.01), np.zeros(1), np.zeros(1)), "as 1-D arrays"),
            (lambda: Geneva(4, 0.05).timing(1e-320), "too slow to time"),
            (lambda: FrictionWheels(0.1, 0.3, 1e-320).pressing_force(100.0), "pressing force overflows"),
            (lambda: FrictionWheels(1e-320, 0.3, 0.3).ratio, "ratio d2/d1 overflows"),
            (lambda: willis(1, None, 3, 1e-320), "willis: the speeds overflow"),
            (lambda: flocke_base_radius(get_law("cycloidal"), 0.02, 1.0, 1e-320), "must lie in \\[0.1°, 90°\\)")]:
        with pytest.raises(ValueError, match=message):
            call()
    assert hertz_line_stress(100.0, 0.01, 0.01, np.inf) == pytest.approx(hertz_line_stress(100.0, 0.01, 0.01, 1e300))
    assert Belt(1e3, pi).tensions(100.0) == (100.0, 0.0)     # a grip beyond any number (an OverflowError before)


def test_gears_refuse_undercut_and_bad_input():
    with pytest.raises(ValueError, match=r"x1 = 0 undercuts the 12-tooth gear \(needs x1 >= 0.298, or at x1 = 0 at least 17.10 teeth"):
        SpurGearPair(12, 40, 2e-3)
    with pytest.raises(ValueError, match="module is in metres, from 1e-05 to 0.1 m"):
        SpurGearPair(20, 40, 0.0)
    with pytest.raises(ValueError, match="pointed tooth"):
        SpurGearPair(12, 40, 2e-3, 1.5, 0.0).geometry()
    with pytest.raises(ValueError, match=r"got 4.5 m: did you mean 4.5 mm = 0.0045 m"):
        SpurGearPair(34, 80, 4.5)                        # a module in mm given as metres
    with pytest.raises(ValueError, match=r"contact ratio 0.958 < 1 .* profile shifts x1 = 0.75, x2 = 0.5"):
        SpurGearPair(8, 12, 1e-3, 0.75, 0.5).geometry()
    assert SpurGearPair(np.int64(34), np.int64(80), 2e-3).z1 == 34     # numpy integers are whole numbers too


def test_mobility_of_the_course_examples():
    assert mobility(4, 4, 0) == 1                        # four-bar linkage
    assert mobility(4, 4, 0) == mobility(4, 4, 0, 0, 0)  # slider-crank has the same count
    assert mobility(3, 2, 1) == 1                        # cam with a flat-faced follower
    assert mobility(4, 3, 1, redundant=1) == 1           # roller follower: the roller's spin is an idle motion
    assert mobility(5, 5, 0) == 2                        # five-bar linkage
    assert mobility(5, 6, 0, passive=-1) == 1            # parallelogram with a redundant (passive) link
    with pytest.raises(ValueError, match=r"n \(links counting the frame\) must be a whole number >= 1"):
        mobility(0, 0, 0)
    with pytest.raises(ValueError, match=r"redundant \(independent motions\) must be a whole number >= 0, got -3"):
        mobility(4, 4, 0, redundant=-3)
    with pytest.raises(ValueError, match=r"passive .* must be a whole number, got 0.5"):
        mobility(4, 4, 0, passive=0.5)


def test_willis_planetary_and_differential():
    # planetary, ring held (n3 = 0), sun 30 teeth, ring 90: i0 = −90/30 = −3 → carrier = n1/4
    out = willis(n1=1000.0, n3=0.0, carrier=None, ratio=-3.0)
    assert out["carrier"] == pytest.approx(250.0)
    assert willis(n1=None, n3=0.0, carrier=250.0, ratio=-3.0)["n1"] == pytest.approx(1000.0)
    # car differential (i0 = −1): the carrier turns at the mean of the wheels
    assert willis(n1=110.0, n3=90.0, carrier=None, ratio=-1.0)["carrier"] == pytest.approx(100.0)
    with pytest.raises(ValueError, match="exactly two"):
        willis(1.0, None, None, -1.0)


def test_belt_ratchet_and_friction_wheels():
    belt = Belt(0.3, pi)
    f1, f2 = belt.tensions(500.0)
    assert f1 - f2 == pytest.approx(500.0) and f1 / f2 == pytest.approx(np.exp(0.3 * pi))
    assert belt.output_speed(100.0, 0.1, 0.2) == pytest.approx(49.0)
    assert Ratchet(radians(20), 0.15).self_locking and not Ratchet(radians(5), 0.15).self_locking
    w = FrictionWheels(0.1, 0.3, 0.4, slip=0.02, safety=1.5)
    assert w.ratio == pytest.approx(3 / 0.98) and w.pressing_force(100.0) == pytest.approx(375.0)
    assert belt.output_speed(-100.0, 0.1, 0.2) == pytest.approx(-49.0)      # a reversed drive: signed speeds
    # a small μβ: e^{μβ} − 1 without cancellation (F2 = F/(e^{μβ} − 1) ≈ F/μβ·(1 − μβ/2)), no division by zero
    assert Belt(1e-9, 1.0).tensions(100.0)[1] == pytest.approx(1e11 - 50.0, rel=1e-13)
    assert Belt(1e-300, 3.0).tensions(100.0) == pytest.approx((100 / 3e-300, 100 / 3e-300), rel=1e-12)
    with pytest.raises(ValueError, match="slip is a fraction"):
        Belt(0.3, pi, slip=1.5)
    with pytest.raises(ValueError, match="peripheral force F1 − F2 must not be negative"):
        belt.tensions(-100.0)
    with pytest.raises(ValueError, match=r"Ratchet tooth_angle must lie in \(0, 90°\)"):
        Ratchet(-1.0, 0.1)
    with pytest.raises(ValueError, match="Ratchet mu must not be negative"):
        Ratchet(0.3, -1.0)


@pytest.mark.parametrize("make, message", [
    (lambda: SpurGearPair(80, 80, 0.002, -3.2, 0).geometry(), "gear 1 (80 teeth, x = -3.2) has its tip circle"),
    (lambda: SpurGearPair(34, 80, 1e-3, 5, 5).geometry(),      # the tip is cut below the rack's flank: no teeth
     "gear 1 (34 teeth, x = 5) has its tip circle (40.766 mm) inside its form circle (47.404 mm"),
    (lambda: SpurGearPair(100, 100, 0.002, -3, -3).geometry(), "leave no working pressure angle"),
    (lambda: SpurGearPair(20, 40, 0.002, float("nan"), 0), "SpurGearPair x1 must be a finite number"),
    (lambda: willis(1, None, 0, 0), "i0 = 0 is no gear train"),
    (lambda: willis(1, float("inf"), None, -4), "willis n3 must be a finite number"),
    (lambda: Geneva(5, 0.05).timing(float("inf")), "Geneva crank_speed must be a finite number"),
    (lambda: Geneva(5, 50), "did you mean 50 mm = 0.05 m"),
    (lambda: Belt(0.3, 180), "did you mean 180° = 3.142 rad"),
    (lambda: FrictionWheels(0.1, 0.2, 0.3).pressing_force(-10), "tangential force F_t must not be negative"),
    (lambda: Cardan(0.5).output_angle(float("inf")), "Cardan phi1 (rad) must be finite"),
    (lambda: Geneva(5, 0.05).kinematics(0.1, float("nan")), "Geneva omega1 (rad/s) must be a finite number"),
    (lambda: SpurGearPair(34, 80, "0.0045"), "SpurGearPair module must be a finite number, got '0.0045'"),
    (lambda: Cardan("0.5"), "Cardan shaft_angle (rad) must be a finite number, got '0.5'"),
    (lambda: Cardan(30), "did you mean 30° = 0.5236 rad"),
    (lambda: SpurGearPair(20, 40, 0.002, pressure_angle=20), "got 20 rad: the angle is in radians: did you mean 20° ="),
    (lambda: DoubleCardan(0.1, 0.1, "Z", float("nan")), "DoubleCardan yoke_offset (rad) must be a finite number"),
    (lambda: Ratchet(0.3, float("nan")), "Ratchet mu must be a finite number, got nan"),
    (lambda: Ratchet(30, 0.2), "did you mean 30° = 0.5236 rad"),
    (lambda: Cardan(0.2).acceleration(0.2, float("nan")), "Cardan omega1 (rad/s) must be finite, got nan"),
    (lambda: Cardan(0.2).acceleration(0.2, "10"), "Cardan omega1 (rad/s) must be finite numbers, got '10'"),
    (lambda: Cardan(0.2).output_angle("abc"), "Cardan phi1 (rad) must be finite numbers, got 'abc'"),
    (lambda: Belt(0.3, pi).output_speed(100.0, 0.1, -0.2), "Belt d2 (m) must be positive, got -0.2"),
    (lambda: Belt(0.3, pi).output_speed(100.0, 0.1, 0), "Belt d2 (m) must be positive, got 0"),
    (lambda: Belt(0.3, pi).output_speed(100.0, float("nan"), 0.2), "Belt d1 (m) must be a finite number, got nan"),
    (lambda: Belt(0.3, pi).output_speed(float("nan"), 0.1, 0.2), "Belt input_speed (rad/s) must be a finite number"),
    (lambda: Belt(1e-300, 3).tensions(1e10), "Belt mu·wrap = 3e-300 (mu = 1e-300, wrap = 3 rad) is too small to carry "
                                             "F1 − F2 = 10000000000.0 N"),
    (lambda: inverse_involute(float("nan")), "inverse_involute value inv α (rad) must be a finite number, got nan"),
    (lambda: inverse_involute(1e12), "inverse_involute value inv α must lie in [0, 1e+09) rad"),
    (lambda: Belt(0.3, pi, slip="0.02"), "Belt slip must be a finite number, got '0.02'"),
    (lambda: flocke_base_radius(get_law("3-4-5"), 0.042, radians(120), radians(30), e=float("nan")),
     "offset e (m) must be a finite number, got nan"),
])
def test_impossible_or_mistyped_input_is_named(make, message):
    """Geometry that cannot exist, a value in the wrong unit or not a finite number: a ValueError saying which
    (never scipy's or math's own words, a division by zero or a silent NaN)."""
    with pytest.raises(ValueError, match=re.escape(message)):
        make()


def test_a_gear_shifted_below_its_reference_circle_is_still_a_gear():
    """x = −2.5 on 100 teeth: the reference-circle thickness is negative (a formal value), the tooth is real (with
    x2 = 1: against an unshifted mate the shift sum −2.5 pulls the mate's tip into its fillet)."""
    g = SpurGearPair(100, 100, 0.002, -2.5, 1.0).geometry()
    assert g.tooth_thickness[0] < 0 < g.tip_diameters[0] - g.base_diameters[0] and g.contact_ratio > 1


def _interferes(pair: SpurGearPair) -> tuple[bool, bool]:
    """(meshing interference, inside a base circle) from Cartesian geometry, independently of geometry(): the
    mate's tip circle cut with the line of action through the working pitch point, against each gear's form
    circle, where the generating rack's flank (1·m deep) meets its generating line of action."""
    m, a0 = pair.module, pair.pressure_angle
    aw = inverse_involute(involute(a0) + 2 * (pair.x1 + pair.x2) / (pair.z1 + pair.z2) * tan(a0))
    a = m * (pair.z1 + pair.z2) / 2 * cos(a0) / cos(aw)
    k = (pair.x1 + pair.x2) * m - (a - m * (pair.z1 + pair.z2) / 2)           # tip reduction
    centres = (np.array([0.0, 0.0]), np.array([a, 0.0]))
    pitch = np.array([a * pair.z1 / (pair.z1 + pair.z2), 0.0])
    u = np.array([sin(aw), cos(aw)])                                          # along the line of action
    foot = [pitch + np.dot(c - pitch, u) * u for c in centres]                # T1, T2
    clash, inside = False, False
    for i, j in ((0, 1), (1, 0)):
        z, x = (pair.z1, pair.x1) if i == 0 else (pair.z2, pair.x2)
        zj, xj = (pair.z1, pair.x1) if j == 0 else (pair.z2, pair.x2)
        r, ra_j = m * z / 2, m * zj / 2 + m * (1 + xj) - k
        rack = (1 - x) * m                                                    # rack flank end below the pitch line
        r_form = np.hypot(rack / tan(a0), r - rack)
        # |pitch + t u − O_j| = r_aj, the root on gear i's side of the pitch point
        w = pitch - centres[j]
        b, c = np.dot(w, u), np.dot(w, w) - ra_j ** 2
        roots = (-b - np.sqrt(b * b - c), -b + np.sqrt(b * b - c))
        t_i = np.dot(foot[i] - pitch, u)
        t = roots[0] if t_i < 0 else roots[1]
        beyond = abs(t) > abs(t_i)                                            # past T_i: inside its base circle
        below = np.linalg.norm(pitch + t * u - centres[i]) < r_form * (1 - 1e-12)
        clash, inside = clash or beyond or below, inside or beyond
    return clash, inside


@pytest.mark.parametrize("pair, numbers", [
    (SpurGearPair(12, 80, 1e-3, 0.3, -1.2), "T1T2 = a·sin α_w = 12.558 mm (a = 45.013 mm, α_w = 16.20°); gear 2's "
                                              "tip (d_a = 79.426 mm) runs sqrt(r_a2² − r_b2²) = 12.818 mm"),
    (SpurGearPair(10, 200, 1e-3, 0.42, -1.0), "T1T2 = a·sin α_w = 34.140 mm (a = 104.407 mm, α_w = 19.09°); gear 2's "
                                              "tip (d_a = 199.974 mm) runs sqrt(r_a2² − r_b2²) = 34.164 mm"),
])
def test_gears_refuse_tip_interference_named_with_its_numbers(pair, numbers):
    """The audit's pairs: gear 2's tip runs past T1 into the pinion's base circle (the undercut check at α0 = 20°
    passes, but they mesh at α_w < α0); the contact ratio they reported (1.61, 1.48) counted that part."""
    assert _interferes(pair) == (True, True)
    with pytest.raises(ValueError, match=re.escape(numbers) + ".*inside its base circle .* involute interference"):
        pair.geometry()


@pytest.mark.filterwarnings("ignore::rig.mechanisms.gears.ThinToothWarning")     # thin tips among the grid: valid
def test_gear_interference_against_the_cartesian_construction():
    """Over a grid of tooth counts and shifts (from each undercut limit up), geometry() refuses exactly the pairs
    whose tips reach the mate inside its base circle or below its form circle."""
    seen = {"ok": 0, "fillet": 0, "base": 0}
    for z1 in (8, 10, 12, 17, 25, 40):
        for z2 in (12, 20, 40, 80, 200):
            for x1 in np.linspace(1 - z1 * np.sin(radians(20)) ** 2 / 2, 1.0, 6):
                for x2 in np.linspace(1 - z2 * np.sin(radians(20)) ** 2 / 2, 1.0, 8):
                    pair = SpurGearPair(z1, z2, 1e-3, float(x1), float(x2))
                    try:
                        g = pair.geometry()
                    except ValueError as err:
                        if "interferes" not in str(err):
                            if "contact ratio" in str(err):                   # checked after interference
                                assert not _interferes(pair)[0]
                            continue
                        inside = "inside its base circle" in str(err)
                        assert _interferes(pair) == (True, inside), (z1, z2, x1, x2)
                        seen["base" if inside else "fillet"] += 1
                        continue
                    assert not _interferes(pair)[0], (z1, z2, x1, x2)
                    # the textbook condition for both gears: each tip stays within T1T2 = a sin α_w
                    rim = np.sqrt(np.square(g.tip_diameters) - np.square(g.base_diameters)) / 2
                    assert np.all(rim <= g.centre_distance * np.sin(g.working_pressure_angle))
                    seen["ok"] += 1
    assert min(seen.values()) >= 10, seen            # each outcome is exercised


@pytest.mark.parametrize("z", [4, 5, 6])
def test_geneva_wheel_angle_is_continuous_through_every_dwell_even_on_odd_multiples_of_pi(z):
    """A crank angle landing exactly on (2k+1)π (mid-dwell, where the turn count changes) once made the wheel jump a
    slot pitch for one sample (half-to-even rounding of the turn against a (−π, π] wrap): 60° of false angle error in
    a lab run at 300 rpm. The angle now steps 2π/z per crank turn and never goes back."""
    g = Geneva(z, 0.08)
    omega, t = 300 * 2 * pi / 60, np.arange(0, 2.0, 1 / 20000)
    for phi0 in (pi, 0.0, 0.3):
        phi1 = phi0 + omega * t                                  # as the lab's drive computes it
        assert np.any(np.isclose(np.mod(phi1, 2 * pi), pi, rtol=0, atol=1e-12)) or phi0 == 0.3
        w = g.wheel_angle(phi1)
        assert np.all(np.diff(w) >= -1e-12) and np.max(np.diff(w)) < 0.01
        turns = (phi1[-1] - phi1[0]) / (2 * pi)
        assert w[-1] - w[0] == pytest.approx(2 * pi / z * turns, abs=2 * pi / z)
    exact = np.array([pi, 3 * pi, 5 * pi, 7 * pi]) * (1 + np.array([0, 1e-16, -1e-16, 0]))
    assert np.allclose(g.wheel_angle(exact), 2 * pi / z * np.arange(1, 5), rtol=0, atol=1e-12)


@pytest.mark.parametrize("alpha, message", [
    (pi / 2, r"must lie in \[0, 90°\) \(at 90° the output shaft cannot turn\), got 1.5708 rad = 90°$"),  # no hint
    (30.0, r"got 30 rad = 1718.87°: the angle is in radians: did you mean 30° = 0.5236 rad\?$"),
])
def test_a_cardan_shaft_angle_hints_at_degrees_only_for_an_impossible_angle(alpha, message):
    with pytest.raises(ValueError, match=message):
        Cardan(alpha)


def _tip_thickness_from_the_curve(d: float, db: float, s: float, da: float) -> float:
    """The tip's arc thickness from the involute drawn in Cartesian coordinates: the flank through the reference
    circle at half the tooth's angle s/d, followed out to the tip circle (roll t: r = r_b·sqrt(1 + t²))."""
    rb = db / 2

    def unrolled(r: float) -> float:
        """Polar angle of the point at radius r of the involute unrolled from the base circle at angle 0."""
        t = sqrt((r / rb) ** 2 - 1)
        return float(np.arctan2(rb * (np.sin(t) - t * np.cos(t)), rb * (np.cos(t) + t * np.sin(t))))
    theta0 = s / d + unrolled(d / 2)           # the flank, unrolled towards the tooth's centre line, at s/d there
    return 2 * (theta0 - unrolled(da / 2)) * da / 2


def test_the_tip_thickness_is_the_involute_drawn_out_and_a_nearly_pointed_tip_is_warned():
    from rig.mechanisms.gears import ThinToothWarning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g = SpurGearPair(34, 80, 4.5e-3, 0.98, 1.81).geometry()           # no warning: s_a ≈ 0.8·m
    for i in (0, 1):
        assert g.tip_thickness[i] == pytest.approx(_tip_thickness_from_the_curve(
            g.reference_diameters[i], g.base_diameters[i], g.tooth_thickness[i], g.tip_diameters[i]), rel=1e-9)
    with pytest.warns(ThinToothWarning, match=r"gear 1 \(12 teeth, x = 0.85\) has a nearly pointed tooth: tip "
                                              r"thickness 0.002696 mm = 0.0027·m"):
        thin = SpurGearPair(12, 300, 0.001, 0.85, 0.0).geometry()       # an independent audit's case
    assert thin.tip_thickness[0] == pytest.approx(_tip_thickness_from_the_curve(
        thin.reference_diameters[0], thin.base_diameters[0], thin.tooth_thickness[0], thin.tip_diameters[0]), rel=1e-6)
