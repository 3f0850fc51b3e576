"""Motion laws: derivatives vs finite differences, boundary conditions, textbook coefficients, registry."""
from math import pi

import numpy as np
import pytest

from rig.motion import UnknownLawError, available_laws, get_law, register_law
from rig.motion.laws import PolynomialLaw

LAWS = ["parabolic", "3-4-5", "4-5-6-7", "cycloidal", "harmonic", "modified_trapezoid", "modified_sine"]

# textbook values (Norton, Rothbart): C_v, C_a, C_j (finite part)
TEXTBOOK = {
    "cycloidal": (2.0, 2 * pi, 4 * pi ** 2),
    "3-4-5": (1.875, 5.7735, 60.0),
    "4-5-6-7": (2.1875, 7.5132, 52.5),
    "modified_sine": (1.76, 5.528, 69.47),
    "modified_trapezoid": (2.0, 4.888, 61.43),
    "parabolic": (2.0, 4.0, 0.0),
    "harmonic": (pi / 2, pi ** 2 / 2, pi ** 3 / 2),
}


def test_all_laws_registered():
    assert set(LAWS) <= set(available_laws())


@pytest.mark.parametrize("name", LAWS)
def test_boundaries_and_monotone(name):
    law = get_law(name)
    y, y1, _, _ = law.derivatives(np.array([0.0, 1.0]))
    assert y == pytest.approx([0.0, 1.0], abs=1e-12)
    assert y1 == pytest.approx([0.0, 0.0], abs=1e-12)
    x = np.linspace(0, 1, 2001)
    assert np.all(np.diff(law.y(x)) >= -1e-15)


@pytest.mark.parametrize("name", LAWS)
def test_derivatives_match_finite_differences(name):
    law = get_law(name)
    bps = np.array([0.0, *law.breakpoints(), 1.0])
    x = np.linspace(0.003, 0.997, 397)
    x = x[np.min(np.abs(x[:, None] - bps[None, :]), axis=1) > 2e-3]  # stay off the piece boundaries
    h = 1e-5
    for k in range(3):
        up, dn = law.derivatives(x + h)[k], law.derivatives(x - h)[k]
        fd = (up - dn) / (2 * h)
        exact = law.derivatives(x)[k + 1]
        scale = max(1.0, np.max(np.abs(exact)))
        assert np.max(np.abs(fd - exact)) < 1e-6 * scale, (name, k)


@pytest.mark.parametrize("name", LAWS)
def test_textbook_coefficients(name):
    c = get_law(name).coefficients
    cv, ca, cj = TEXTBOOK[name]
    assert c.C_v == pytest.approx(cv, rel=2e-3)
    assert c.C_a == pytest.approx(ca, rel=2e-3)
    assert c.C_j == pytest.approx(cj, rel=2e-3, abs=1e-9)


def test_corrected_4567_is_symmetric_and_smooth():
    law = get_law("4-5-6-7")
    x = np.linspace(0, 1, 101)
    assert law.y(x) + law.y(1 - x) == pytest.approx(np.ones_like(x), abs=1e-12)
    _, _, y2, y3 = law.derivatives(np.array([0.0, 1.0]))
    assert np.abs(y2).max() < 1e-12 and np.abs(y3).max() < 1e-12


def test_acceleration_jumps_from_law_properties():
    assert [x for x, _ in get_law("parabolic").accel_jumps()] == [0.0, 0.5, 1.0]
    assert [j for _, j in get_law("parabolic").accel_jumps()] == pytest.approx([4.0, -8.0, 4.0])
    assert [x for x, _ in get_law("harmonic").accel_jumps()] == [0.0, 1.0]
    for name in ("3-4-5", "4-5-6-7", "cycloidal", "modified_sine", "modified_trapezoid"):
        assert get_law(name).accel_jumps() == []


def test_source_names_and_unknown_law():
    assert get_law("sinusoidal") is get_law("cycloidal")
    assert get_law("Cosinusoidal") is get_law("harmonic")
    with pytest.raises(UnknownLawError, match="unknown motion law 'bogus'.*cycloidal"):
        get_law("bogus")


def test_register_custom_law():
    law = PolynomialLaw("test-ramp-cubic", [0, 0, 3, -2])
    register_law(law)
    assert get_law("test-ramp-cubic").coefficients.C_v == pytest.approx(1.5)
    with pytest.raises(ValueError, match="already registered"):
        register_law(law)
