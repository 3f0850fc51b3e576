"""Clutch variants (MODELS.md §4.5): hand values, independent references, properties, errors."""
import math

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid, quad

from rig.analysis.clutch_metrics import loop_energy
from rig.plants.clutch import FlatTappetClutch, GeometryError
from rig.plants.clutch.variants import (MEASURED_TABLES, FlatTappetCharacteristic, LeafSpringClutch,
                                        RollerTappetClutch, RubberRollerClutch, RubberShoeClutch, ShearPin,
                                        StaticCharacteristic, TabulatedClutch, measured_table)

ROLLER = dict(r0=0.030, r1=0.050, a1=0.020, k_a=28e3, delta=0.005, n=3)
LEAF = dict(width=0.020, thickness=0.002, span=0.120, r0=0.030, r1=0.050, a1=0.020, E=206e9, mu=0.1, n=4)
DEG = math.pi / 180


def flat_tappet(mu=0.1):
    return FlatTappetCharacteristic(FlatTappetClutch(r0=0.032, r1=0.100, r2=0.028, k_a=28e3, delta=0.005,
                                                     mu_B=mu))


# --- roller tappets -------------------------------------------------------------------------------

def test_roller_geometry_against_vector_construction():
    c = RollerTappetClutch(**ROLLER)
    for phi in (0.1, 0.5, 1.0):
        rho = float(c.radius(phi))
        centre = ROLLER["a1"] * np.array([math.cos(math.pi - phi), math.sin(math.pi - phi)])
        roller = np.array([rho, 0.0])
        assert np.linalg.norm(roller - centre) == pytest.approx(ROLLER["r1"], rel=1e-12)
        normal = (roller - centre) / ROLLER["r1"]
        assert math.atan2(abs(normal[1]), normal[0]) == pytest.approx(float(c.pressure_angle(phi)), rel=1e-12)


def test_roller_hand_value_at_30deg():
    # ρ = sqrt(50² − 20²·0.25) − 20·cos30 = sqrt(2400) − 17.3205 = 31.6684 mm; s = 1.6684 mm
    # sinβ = 0.4·0.5 = 0.2; T_source = ½·3·28e3·(6.6684e-3)(31.6684e-3)·sin(2β)
    rho = math.sqrt(2400) - 20 * math.cos(math.pi / 6)
    s = (rho - 30) * 1e-3
    beta = math.asin(0.2)
    expected = 0.5 * 3 * 28e3 * (s + 0.005) * (s + 0.030) * math.sin(2 * beta)
    c = RollerTappetClutch(**ROLLER)
    assert float(c.torque(30 * DEG)) == pytest.approx(expected, rel=1e-12)
    assert expected == pytest.approx(3.4767, rel=1e-4)   # hand calculator: 1.5·186.7 N·31.669 mm·0.39192
    t = RollerTappetClutch(**ROLLER, form="textbook")
    assert float(t.torque(30 * DEG)) == pytest.approx(3 * 28e3 * (s + 0.005) * rho * 1e-3 * math.tan(beta), rel=1e-12)


def test_roller_textbook_form_is_virtual_work_and_source_differs_by_cos2beta():
    """Frictionless: T dφ = d(spring energy) ⇒ T = n F dρ/dφ; the source's form is that times cos²β."""
    src = RollerTappetClutch(**ROLLER)
    txt = RollerTappetClutch(**ROLLER, form="textbook")
    phi = np.linspace(0.05, 1.0, 12)
    h = 1e-6

    def energy(p):
        s = src.radius(p) - ROLLER["r0"]
        return ROLLER["n"] * 0.5 * ROLLER["k_a"] * (s + ROLLER["delta"]) ** 2

    virtual_work = (energy(phi + h) - energy(phi - h)) / (2 * h)
    np.testing.assert_allclose(txt.torque(phi), virtual_work, rtol=1e-7)
    ratio = src.torque(phi) / txt.torque(phi)
    np.testing.assert_allclose(ratio, np.cos(src.pressure_angle(phi)) ** 2, rtol=1e-12)
    # agree to 1 % while β < 5.7° (φ small), differ by more than 5 % at the larger angles
    beta = src.pressure_angle(phi)
    assert np.all(np.abs(1 - ratio[beta < 0.099]) < 0.01) and np.any(beta < 0.099)
    assert np.all(np.abs(1 - ratio[beta > 0.23]) > 0.05) and np.any(beta > 0.23)


def test_roller_zero_at_origin_and_bad_geometry():
    assert float(RollerTappetClutch(**ROLLER).torque(0.0)) == 0.0
    with pytest.raises(GeometryError, match="a1"):
        RollerTappetClutch(**{**ROLLER, "a1": 0.06})
    with pytest.raises(ValueError, match="form"):
        RollerTappetClutch(**ROLLER, form="other")


# --- leaf springs and rubber shoes ----------------------------------------------------------------

def test_leaf_hand_value():
    c = LeafSpringClutch(**LEAF)
    phi = 30 * DEG
    x, y = 0.020 * 0.5, 0.050 - 0.030 - 0.020 * math.cos(phi)
    inertia = 0.020 * 0.002 ** 3 / 12
    fv = 3 * 206e9 * inertia * 0.120 * y / ((0.060 - x) ** 2 * (0.060 + x) ** 2)
    assert float(c.leaf_force(phi)) == pytest.approx(fv, rel=1e-12)
    assert fv == pytest.approx(216.28, rel=1e-4)   # hand calculator: 0.98880 N/m·2.6795 mm / 1.225e-5 m⁴
    arm = x + 0.1 * (0.050 - 0.020 * math.cos(phi))
    assert float(c.torque(phi, 1)) == pytest.approx(4 * fv * arm, rel=1e-12)
    assert float(c.torque(phi, 0)) == pytest.approx(4 * fv * x, rel=1e-12)


def test_leaf_force_and_strain_from_an_independent_beam_solution():
    """Solve EI w'''' = 0 with a point load numerically: deflection under the load is y, strain matches."""
    c = LeafSpringClutch(**LEAF)
    phi = 35 * DEG
    x, y = c.contact(phi)
    force = float(c.leaf_force(phi))
    l, ei = LEAF["span"], LEAF["E"] * c.second_moment
    a = l / 2 + float(x)

    def moment(u):
        return np.where(u <= a, force * (l - a) * u / l, force * a * (l - u) / l)

    # w'' = M/EI (deflection w positive toward the load), w(0) = w(l) = 0: integrate twice on a fine grid
    u = np.linspace(0, l, 200001)
    slope = cumulative_trapezoid(moment(u) / ei, u, initial=0.0)
    w = cumulative_trapezoid(slope, u, initial=0.0)
    w -= w[-1] * u / l
    assert -np.interp(a, u, w) == pytest.approx(float(y), rel=1e-6)
    for offset in (0.0, 0.02, -0.03):
        strain = float(moment(l / 2 + offset)) * LEAF["thickness"] / 2 / ei
        assert float(c.leaf_strain(phi, offset)) == pytest.approx(strain, rel=1e-12)


def test_leaf_properties_and_shoes_twice_the_leaf():
    leaf = LeafSpringClutch(**LEAF)
    shoes = RubberShoeClutch(**{**LEAF, "apex": 45 * DEG})
    phi = np.linspace(0, 45 * DEG, 200)
    assert float(leaf.torque(0.0)) == 0.0
    assert np.all(np.diff(leaf.torque(phi)) > 0)
    for d in (-1, 0, 1):
        np.testing.assert_allclose(shoes.torque(phi, d), 2 * leaf.torque(phi, d), rtol=1e-14)
    assert leaf.disengagement_angle == pytest.approx(45 * DEG)
    default_shoes = RubberShoeClutch(**{k: v for k, v in LEAF.items() if k != "n"})
    assert default_shoes.disengagement_angle == pytest.approx(60 * DEG) and default_shoes.n == 3
    with pytest.raises(ValueError, match="outside the engaged range"):
        leaf.torque(50 * DEG)
    float(default_shoes.torque(50 * DEG))


@pytest.mark.parametrize("cls, apex, n", [(RubberShoeClutch, 55.0, 3), (LeafSpringClutch, 45.0, 3),
                                          (RollerTappetClutch, 50.0, 3)])
def test_a_lobe_period_that_does_not_fill_the_turn_in_phase_is_refused(cls, apex, n):
    """2·55° = 110°: 3.27 lobes per turn; 3 leaves on the 4 lobes of a 45° cam sit at 0°, 30°, 60° of their lobes,
    not in phase, so T = n·(one leaf) would not hold."""
    args = ROLLER if cls is RollerTappetClutch else LEAF
    with pytest.raises(GeometryError, match=r"lobes per turn: a cam has a whole number of lobes.*apex = 180 deg"):
        cls(**{**args, "apex": apex * DEG, "n": n})


def test_leaf_geometry_errors():
    with pytest.raises(GeometryError, match="support"):
        LeafSpringClutch(**{**LEAF, "span": 0.025})
    with pytest.raises(GeometryError, match="lose contact"):
        LeafSpringClutch(**{**LEAF, "a1": 0.025})
    with pytest.raises(GeometryError, match="thickness"):
        LeafSpringClutch(**{**LEAF, "thickness": -1.0})
    with pytest.raises(GeometryError, match="gauge"):
        LeafSpringClutch(**LEAF).leaf_strain(0.1, 0.07)


# --- rubber rollers -------------------------------------------------------------------------------

RUBBER = dict(D0=0.100, h=0.010, z=6, A0=1e-4, E1=5e6, apex=0.15)


def test_rubber_roller_closed_form_and_round_trip():
    c = RubberRollerClutch(**RUBBER)
    # φ = 2 M h / (D0 (M + ½ D0 z A0 E1)); ½·0.1·6·1e-4·5e6 = 150 N·m; M = 50 → φ = 2·50·0.01/(0.1·200) = 0.05
    assert c.torque_scale == pytest.approx(150.0)
    assert float(c.angle(50.0)) == pytest.approx(0.05, rel=1e-14)
    assert float(c.torque(0.05)) == pytest.approx(50.0, rel=1e-12)
    m = np.linspace(0, c.peak_torque, 50)
    np.testing.assert_allclose(c.torque(c.angle(m)), m, rtol=1e-12, atol=1e-12)
    # the closed-form inverse agrees with the generic bisection inverse of T(φ)
    np.testing.assert_allclose(StaticCharacteristic.angle(c, m), c.angle(m), rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="outside"):
        c.angle(c.peak_torque * 1.01)
    with pytest.raises(GeometryError, match="apex"):
        RubberRollerClutch(**{**RUBBER, "apex": 0.25})


# --- measured tables ------------------------------------------------------------------------------

def test_tables_reproduce_points_and_are_monotone():
    expected_last = {"rubber_d25_rubber_d20": (150.0, 22.5), "rubber_d25_pu_d20": (190.0, 26.2)}
    for name in MEASURED_TABLES:
        t = measured_table(name)
        np.testing.assert_allclose(t.torque(t.angles), t.torques, rtol=1e-12)
        np.testing.assert_allclose(t.angle(t.torques), t.angles, rtol=1e-12, atol=1e-14)
        assert t.torques[0] == pytest.approx(10.0) and t.angles[0] == pytest.approx(math.radians(
            {"rubber_d25_rubber_d20": 1.3, "rubber_d25_pu_d20": 1.8}[name]))
        assert (t.torques[-1], math.degrees(t.angles[-1])) == pytest.approx(expected_last[name])
        dense = np.linspace(t.angles[0], t.angles[-1], 2000)
        assert np.all(np.diff(t.torque(dense)) > 0)
        assert t.peak_torque == pytest.approx(t.torques[-1])


def test_tables_out_of_range_errors():
    t = measured_table("rubber_d25_rubber_d20")
    with pytest.raises(ValueError, match="outside the engaged range"):
        t.torque(math.radians(23.0))
    with pytest.raises(ValueError, match="outside the engaged range"):
        t.torque(math.radians(1.0))
    with pytest.raises(ValueError, match="exceeds the peak"):
        t.angle(151.0)
    with pytest.raises(ValueError, match="below the start"):
        t.angle(5.0)
    with pytest.raises(ValueError, match="unknown measured clutch table"):
        measured_table("steel")
    anchored = measured_table("rubber_d25_rubber_d20", through_origin=True)
    assert float(anchored.angle(0.0)) == 0.0 and float(anchored.torque(0.0)) == 0.0


@pytest.mark.parametrize("text, message", [
    ("torque_N_mm,speed_rpm\n1,2\n2,3\n", "header"),
    ("torque_N_mm,angle_deg\n1,2\n2,x\n", "row 3"),
    ("torque_N_mm,angle_deg\n1,2\n2,1\n", "not strictly increasing"),
    ("torque_N_mm,angle_mm\n1,2\n2,3\n", "wrong dimension"),
    ("torque_N_mm,angle_deg\n1,2,3\n", "3 fields"),
])
def test_table_file_errors(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        TabulatedClutch.from_file(path)


# --- shear pin ------------------------------------------------------------------------------------

def test_shear_pin_breaks_irreversibly():
    pin = ShearPin(idle_torque=10.0, limit_factor=1.15)
    assert pin.limit_torque == pytest.approx(11.5)
    t = np.linspace(0, 1, 11)
    demand = np.array([0, 5, 10, 11, 11.4, 11.6, 9, 5, 12, 3, 0.0])
    out = pin.transmit(t, demand)
    np.testing.assert_array_equal(out[:5], demand[:5])
    np.testing.assert_array_equal(out[5:], 0.0)
    assert pin.broken and pin.break_time == pytest.approx(0.5) and pin.break_torque == pytest.approx(11.6)
    np.testing.assert_array_equal(pin.transmit(t + 1, np.full(11, 1.0)), 0.0)   # still broken
    pin.replace()
    assert not pin.broken
    np.testing.assert_array_equal(pin.transmit(t + 2, np.full(11, 1.0)), 1.0)
    assert pin.breaks == 1
    reverse = ShearPin(10.0).transmit(t, -demand)              # default M_lim = 12 N·m, either sign breaks it
    np.testing.assert_array_equal(reverse[:8], -demand[:8])
    np.testing.assert_array_equal(reverse[8:], 0.0)
    with pytest.raises(ValueError, match="limit_factor"):
        ShearPin(10.0, limit_factor=0.9)


# --- common interface, inverses and hysteresis ----------------------------------------------------

@pytest.mark.parametrize("make", [
    lambda: flat_tappet(), lambda: RollerTappetClutch(**ROLLER), lambda: LeafSpringClutch(**LEAF),
    lambda: RubberShoeClutch(**{**LEAF, "n": 3}), lambda: RubberRollerClutch(**RUBBER),
    lambda: measured_table("rubber_d25_pu_d20")])
def test_inverse_round_trip_on_the_rising_branch(make):
    c = make()
    for d in ((-1, 0, 1) if c.has_friction else (0,)):
        phi_peak, t_peak = c.branch_peak(d)
        phi = np.linspace(c.phi_min, phi_peak, 40)
        torque = c.torque(phi, d)
        phi = phi[torque >= torque[0]]
        torque = torque[torque >= torque[0]]
        np.testing.assert_allclose(c.angle(torque, d), phi, atol=1e-9)
        with pytest.raises(ValueError, match="exceeds the peak|outside"):
            c.angle(t_peak * 1.001 + 1e-9, d)


def test_flat_tappet_branches_and_peak_against_closed_form():
    c = flat_tappet()
    phi = np.linspace(0, math.pi / 3, 301)
    g = c.clutch.geometry(phi)
    fa = 28e3 * (g["s"] + 0.005)
    np.testing.assert_allclose(c.torque(phi, 1), 3 * fa * (g["k1"] + 0.1 * g["k2"]), rtol=1e-12)
    np.testing.assert_allclose(c.torque(phi, -1), 3 * fa * (g["k1"] - 0.1 * g["k2"]), rtol=1e-12)
    # frictionless peak in phase II: 2 a2 cos²u + (r2 − r0 + δ) cos u − a2 = 0, u = 60° − φ
    a2, cc = c.clutch.limits.a2, 0.028 - 0.032 + 0.005
    u = math.acos((-cc + math.sqrt(cc ** 2 + 8 * a2 ** 2)) / (4 * a2))
    assert c.branch_peak(0)[0] == pytest.approx(math.pi / 3 - u, abs=1e-8)


def _flat_k2(phi, r0=0.032, r1=0.100, r2=0.028):
    """k2 written out independently from MODELS.md §4.1."""
    pm = math.pi / 3 - math.asin((r1 - r0) / (r1 - r2) * math.sin(math.pi / 3))
    a2 = (r1 - r0) * math.sin(pm) / math.sin(math.pi / 3 - pm)
    return r1 - (r1 - r0) * math.cos(phi) if phi <= pm else r2 + a2 * math.cos(math.pi / 3 - phi)


def test_flat_tappet_loop_area_equals_friction_work():
    c = flat_tappet()
    top = 0.15
    up = np.linspace(0.0, top, 3001)
    history = np.concatenate([up, up[::-1]])     # the repeated top angle carries the vertical torque jump
    torque = c.loop_torque(history)
    energy = float(loop_energy(history, torque))

    def friction_gap(p):                 # T_load − T_unload = 2 μ n F_a k2
        k2 = _flat_k2(p)
        return 2 * 0.1 * 3 * 28e3 * (k2 - 0.032 + 0.005) * k2

    reference, _ = quad(friction_gap, 0.0, top, points=[0.0893], limit=200)
    assert energy > 0
    assert energy == pytest.approx(reference, rel=1e-6)


def test_leaf_loop_area_equals_friction_work_and_direction_rules():
    c = LeafSpringClutch(**LEAF)
    top = 40 * DEG
    up = np.linspace(0.0, top, 4001)
    history = np.concatenate([up, np.full(5, top), up[::-1]])   # a pause keeps the direction
    torque = c.loop_torque(history)
    assert torque[4001] == pytest.approx(float(c.torque(top, 1)))
    energy = float(loop_energy(history, torque))
    reference, _ = quad(lambda p: 2 * 0.1 * 4 * float(c.leaf_force(p)) * (0.050 - 0.020 * math.cos(p)), 0.0, top)
    assert energy == pytest.approx(reference, rel=1e-6)
    with pytest.raises(ValueError, match="never moves"):
        c.loop_torque(np.zeros(5))
    with pytest.raises(ValueError, match="direction"):
        c.torque(0.1, 2)


def test_an_apex_typed_to_six_digits_is_taken_at_its_whole_lobe_count():
    """25.7143° (7 lobes) was refused with a message suggesting 25.7143°: within 1e-5 it is 180°/7, and taken so."""
    c = RollerTappetClutch(**{**ROLLER, "n": 7, "apex": 25.7143 * DEG})
    assert c.apex == pytest.approx(math.pi / 7, rel=1e-15) and c.period == pytest.approx(2 * math.pi / 7, rel=1e-15)
    assert LeafSpringClutch(**{**LEAF, "apex": 0.7854}).apex == pytest.approx(math.pi / 4, rel=1e-15)
    with pytest.raises(GeometryError, match=r"e\.g\. 25\.714286 deg"):
        RollerTappetClutch(**{**ROLLER, "n": 7, "apex": 26.0 * DEG})
