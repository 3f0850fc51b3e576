"""Cam programs: validation, evaluation (wrapping, derivatives, time derivatives), events; speed profiles."""
from math import radians, tau

import numpy as np
import pytest

from rig.motion import CamProgram, ConstantSpeed, ProgramError, RampSpeed, Segment, SinusoidalSpeed

H = 0.042


def program(rise_law="3-4-5", return_law="harmonic", angles=(60, 120, 40, 100, 40), up=H, down=H):
    a = [radians(x) for x in angles]
    return CamProgram([Segment("dwell", a[0]), Segment("rise", a[1], rise_law, up), Segment("dwell", a[2]),
                       Segment("return", a[3], return_law, down), Segment("dwell", a[4])])


@pytest.mark.parametrize("kwargs, message", [
    (dict(angles=(60, 120, 40, 100, 50)), "sum to 370°, not 360°"),
    (dict(rise_law="bogus"), "segment 2 .rise.: unknown motion law 'bogus'"),
    (dict(down=0.040), "rises total 42 mm but returns total 40 mm"),
    (dict(angles=(-20, 200, 40, 100, 40)), "segment 1 .dwell.: angle must be positive, got -20°"),
])
def test_validation_errors(kwargs, message):
    with pytest.raises(ProgramError, match=message):
        program(**kwargs)


def test_other_validation_errors():
    with pytest.raises(ProgramError, match="kind must be one of"):
        CamProgram([Segment("hold", tau)])
    with pytest.raises(ProgramError, match="needs a motion law"):
        CamProgram([Segment("rise", tau / 2, None, H), Segment("return", tau / 2, "cycloidal", H)])
    with pytest.raises(ProgramError, match="stroke must be positive"):
        CamProgram([Segment("rise", tau / 2, "cycloidal", -H), Segment("return", tau / 2, "cycloidal", -H)])


def test_levels_wrapping_and_closed_form():
    p = program()
    phi = np.radians([0.0, 30.0, 120.0, 180.0, 200.0, 270.0, 330.0])
    m = p.evaluate(phi)
    x = 0.5
    assert m.s == pytest.approx([0, 0, H * (10 * x**3 - 15 * x**4 + 6 * x**5), H, H, H * 0.5, 0], abs=1e-15)
    assert p.evaluate(phi + 3 * tau).s == pytest.approx(m.s, abs=1e-15)
    assert p.evaluate(phi - 2 * tau).s == pytest.approx(m.s, abs=1e-15)
    assert p.levels == (0.0, H)
    # s' of the 3-4-5 rise at its middle: (h/Φ)·1.875
    assert p.evaluate(np.radians([120.0])).s_p[0] == pytest.approx(H / radians(120) * 1.875)


def test_derivatives_match_finite_differences():
    p = program(rise_law="modified_sine", return_law="cycloidal")
    phi = np.linspace(0.01, tau - 0.01, 500)
    h = 1e-6
    m = p.evaluate(phi)
    up, dn = p.evaluate(phi + h), p.evaluate(phi - h)
    for lo, hi, name in ((up.s, dn.s, "s_p"), (up.s_p, dn.s_p, "s_pp"), (up.s_pp, dn.s_pp, "s_ppp")):
        exact = getattr(m, name)
        fd = (lo - hi) / (2 * h)
        ok = np.abs(fd - exact) <= 1e-6 * np.max(np.abs(exact)) + 1e-12
        assert ok.mean() > 0.99, name  # only the few points straddling a breakpoint may differ


def test_time_derivatives_with_varying_speed():
    p = program(rise_law="cycloidal")
    prof = SinusoidalSpeed(omega_mean=15.0, amplitude=3.0)
    t = np.linspace(0.1, 0.5, 200)
    h = 1e-6

    def s_of(tt):
        d = prof.drive(tt)
        return p.evaluate(d.phi).s

    d = prof.drive(t)
    tm = p.at_speed(d.phi, d.omega, d.alpha)
    fd_v = (s_of(t + h) - s_of(t - h)) / (2 * h)
    fd_a = (s_of(t + h) - 2 * s_of(t) + s_of(t - h)) / h ** 2
    assert tm.v == pytest.approx(fd_v, abs=1e-7)
    assert tm.a == pytest.approx(fd_a, abs=2e-3)
    # dropping ω̇ s' would be wrong by far more than the tolerance
    assert np.max(np.abs(d.alpha * p.evaluate(d.phi).s_p)) > 0.1


def test_events_from_law_properties():
    ev = program(rise_law="parabolic", return_law="harmonic").events()
    got = [round(np.degrees(e.angle), 9) for e in ev]
    assert got == [60.0, 120.0, 180.0, 220.0, 320.0]
    jumps = {round(np.degrees(e.angle)): e.jump for e in ev}
    assert jumps[120] == pytest.approx(-8 * H / radians(120) ** 2)
    assert jumps[220] == pytest.approx(-(np.pi ** 2 / 2) * H / radians(100) ** 2)
    assert program(rise_law="3-4-5", return_law="cycloidal").events() == []
    # a parabolic rise straight into a parabolic return: the boundary jumps cancel, only the midpoints remain
    back = CamProgram([Segment("rise", tau / 2, "parabolic", H), Segment("return", tau / 2, "parabolic", H)])
    assert [round(np.degrees(e.angle), 6) for e in back.events()] == [90.0, 270.0]


def test_speed_profiles_consistent():
    h = 1e-6
    for prof in (ConstantSpeed(10.0), RampSpeed(5.0, 20.0, 0.3, 0.1), SinusoidalSpeed(15.0, 5.0, 3.0)):
        t = np.array([0.05, 0.2, 0.25, 0.6])
        d, up, dn = prof.drive(t), prof.drive(t + h), prof.drive(t - h)
        assert (up.phi - dn.phi) / (2 * h) == pytest.approx(d.omega, rel=1e-7)
        assert (up.omega - dn.omega) / (2 * h) == pytest.approx(d.alpha, abs=1e-5)
    assert RampSpeed(5.0, 20.0, 0.3, 0.1).drive(np.array([1.0])).omega[0] == 20.0
    with pytest.raises(ValueError, match="amplitude"):
        SinusoidalSpeed(10.0, 12.0)


def test_angles_typed_in_rad_or_rounded_are_taken_as_the_whole_turn():
    """3 × 2.0944 rad sums to 6.2832 rad, 7e-6 rad past 2π: refused with "sum to 360°, not 360°" (the message rounded
    to six digits). Within 1e-4 rad the program is scaled to exactly 360°; beyond, the message says by how much."""
    prog = CamProgram([Segment("rise", 2.0944, "cycloidal", H), Segment("dwell", 2.0944),
                       Segment("return", 2.0944, "cycloidal", H)])
    assert sum(s.angle for s in prog.segments) == pytest.approx(tau, abs=1e-15)
    assert prog.segments[0].angle == pytest.approx(tau / 3, rel=1e-15)
    with pytest.raises(ProgramError, match=r"sum to 360\.035219°, not 360° \(off by \+0\.0352°; only a sum within 0\.0057° of 360°"):
        CamProgram([Segment("rise", 2.095, "cycloidal", H), Segment("dwell", 2.0944), Segment("return", 2.0944,
                                                                                              "cycloidal", H)])
