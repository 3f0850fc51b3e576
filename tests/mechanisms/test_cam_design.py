"""Cam design (rig.mechanisms.cam): closed forms, hand values and independent computations."""
from __future__ import annotations

from math import asin, pi, radians, sin, sqrt, tau
from pathlib import Path

import numpy as np
import pytest

from rig.mechanisms.cam import (DoubleSlider, FlatFollower, FourBar, SizeModel, SliderCrank, SlottedLink,
                                centric_base_ratio, curvature_radius, effective_modulus, exact_base_radius,
                                flocke_base_radius, hertz_line_stress, pressure_angle_limit, pressure_angles,
                                round_trip_error, synthesize, undercut_radius)
from rig.mechanisms.cam.pitch import pitch_curve
from rig.motion import CamProgram, Segment, get_law
from rig.plants.cam_bar.chain import SingularPositionError
from rig.plants.cam_bar.mechanism import PinInsertionMechanism


@pytest.fixture(scope="module")
def mech() -> PinInsertionMechanism:
    return PinInsertionMechanism()


def test_limits():
    assert pressure_angle_limit("translating") == pytest.approx(radians(30))
    assert pressure_angle_limit("oscillating", high_speed=True) == pytest.approx(radians(30))
    assert pressure_angle_limit("oscillating", high_speed=False) == pytest.approx(radians(45))
    assert undercut_radius(0.007) == pytest.approx(0.01)
    with pytest.raises(ValueError, match="follower"):
        pressure_angle_limit("rotating")


def test_curvature_of_a_parametric_circle_and_ellipse():
    t = np.linspace(0.0, 2 * pi, 50)
    r = 0.03
    rho = curvature_radius(-r * np.sin(t), r * np.cos(t), -r * np.cos(t), -r * np.sin(t))
    assert np.allclose(rho, r, rtol=1e-14)
    a, b = 0.05, 0.02                      # ellipse (a cos t, b sin t): ρ = b²/a at the ends of the major axis
    assert curvature_radius(0.0, b, -a, 0.0) == pytest.approx(b * b / a)


def test_dwell_pitch_curve_is_a_circle_of_radius_r(mech):
    phi = np.radians(np.linspace(1.0, 59.0, 30))     # first dwell of the default program
    pc, st = pitch_curve(mech, phi), mech.state(phi)
    assert np.ptp(st.r) < 1e-15
    assert np.allclose(pc.rho, st.r, rtol=1e-12)
    assert np.allclose(np.hypot(pc.x, pc.y), st.r, rtol=1e-14)


@pytest.mark.parametrize("direction", [1, -1])
def test_pitch_curvature_against_finite_differences(direction):
    mech = PinInsertionMechanism(cam_direction=direction)
    phi = np.radians(np.array([75.0, 100.0, 130.0, 160.0, 240.0, 270.0, 300.0]))
    h = 1e-4
    a, b, c = (pitch_curve(mech, phi + k * h) for k in (-1, 0, 1))
    dx, dy = (c.x - a.x) / (2 * h), (c.y - a.y) / (2 * h)
    ddx, ddy = (c.x - 2 * b.x + a.x) / h ** 2, (c.y - 2 * b.y + a.y) / h ** 2
    fd = -direction * curvature_radius(dx, dy, ddx, ddy)   # the cam frame runs clockwise for a ccw cam
    assert np.allclose(fd, b.rho, rtol=1e-5)


def test_hertz_hand_value():
    e_star = effective_modulus()                      # 2/(2·(1 − 0.3²)/210 GPa) = 230.77 GPa
    assert e_star == pytest.approx(210e9 / 0.91)
    # F = 1000 N, b = 10 mm, r_R = 8 mm, ρ_C = 40 mm: σ² = 1000/0.02 · 230.77e9/π · (125 + 25)
    sigma = hertz_line_stress(1000.0, 0.010, 0.008, 0.040)
    assert sigma == pytest.approx(sqrt(5e4 * (210e9 / 0.91) / pi * 150.0), rel=1e-12)
    assert sigma == pytest.approx(742.2e6, rel=1e-3)
    # independent textbook form: half-width a = sqrt(4FR/(πLE')), p_max = 2F/(πaL), E' = E/(2(1 − ν²))
    big_r = 1 / (1 / 0.008 + 1 / 0.040)
    half = sqrt(4 * 1000.0 * big_r / (pi * 0.010 * 210e9 / (2 * 0.91)))
    assert sigma == pytest.approx(2 * 1000.0 / (pi * half * 0.010), rel=1e-12)
    assert hertz_line_stress(-1000.0, 0.010, 0.008, -0.040) < sigma   # concave: lower stress, sign of F ignored
    with pytest.raises(ValueError, match="tighter than the roller"):
        hertz_line_stress(1000.0, 0.010, 0.008, -0.006)


def test_flocke_forward_check():
    law, h, big_phi, alpha = get_law("3-4-5"), 0.042, radians(120), radians(30)
    exact = exact_base_radius(law, h, big_phi, alpha)
    fine = np.linspace(0.0, 1.0, 200001)
    assert pressure_angles(law, h, big_phi, exact, x=fine).max() == pytest.approx(alpha, abs=1e-9)
    flocke = flocke_base_radius(law, h, big_phi, alpha)
    assert flocke == pytest.approx(h * centric_base_ratio(law, big_phi, alpha), rel=1e-12)
    # Flocke evaluates at the velocity peak, not where (s' + e)/tan α − s peaks: a little small, α a little big
    assert flocke < exact
    assert alpha < pressure_angles(law, h, big_phi, flocke).max() < alpha + radians(2)
    # offset follower: the exact radius is again the one whose largest pressure angle is α
    e = 0.01
    exact_e = exact_base_radius(law, h, big_phi, alpha, e)
    assert pressure_angles(law, h, big_phi, exact_e, e, x=fine).max() == pytest.approx(alpha, abs=1e-9)


def _smallest_radius_by_bisection(law, h, big_phi, alpha, e, x):
    """Brute force: the smallest r_b whose forward-checked |pressure angle| stays ≤ α on the grid ``x``."""
    lo, hi = abs(e) * (1 + 1e-12), 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if np.abs(pressure_angles(law, h, big_phi, mid, e, x=x)).max() <= alpha else (mid, hi)
    return hi


def test_exact_base_radius_bounds_the_pressure_angle_on_both_sides():
    """A negative offset makes s' + e negative near the ends of the rise: the radius must bound α there too
    (it bounded only the positive side: e = −20 mm gave r_b = 23.5 mm and α down to −58.2°). Offsets where either
    side binds, against a bisection on the forward check."""
    h, big_phi, alpha = 0.042, radians(120), radians(30)
    x = np.linspace(0.0, 1.0, 20001)
    for law in (get_law("3-4-5"), get_law("cycloidal")):
        for e in (-0.025, -0.02, -0.015, -0.008, -0.004, 0.0, 0.01):
            exact = exact_base_radius(law, h, big_phi, alpha, e)
            assert exact == pytest.approx(_smallest_radius_by_bisection(law, h, big_phi, alpha, e, x), rel=1e-7)
            angles = pressure_angles(law, h, big_phi, exact, e, x=x)
            assert np.abs(angles).max() == pytest.approx(alpha, abs=1e-7)
            if e <= -0.015:  # the start of the rise (s = s' = 0) binds: α = −atan(|e|/d) = −α, r_b = |e|/sin α
                assert exact == pytest.approx(abs(e) / sin(alpha), rel=1e-12)
                assert angles.min() == pytest.approx(-alpha)


def test_exact_base_radius_names_a_non_finite_offset():
    with pytest.raises(ValueError, match=r"offset e \(m\) must be a finite number, got nan"):
        exact_base_radius(get_law("3-4-5"), 0.042, radians(120), radians(30), float("nan"))


def test_flocke_closed_form_for_the_parabolic_law():
    # parabolic: y'_max = 2 at x = ½, y = ½ there → r_b/h = 2/(Φ tan α) − ½
    law, big_phi, alpha = get_law("parabolic"), radians(90), radians(30)
    assert centric_base_ratio(law, big_phi, alpha) == pytest.approx(2 / (big_phi * np.tan(alpha)) - 0.5, rel=1e-9)


def test_optimum_pressure_angle_against_a_scan():
    model = SizeModel(get_law("cycloidal"), radians(100), mu=0.15, load=0.4)
    opt = model.optimum()
    alphas = np.linspace(radians(5), model.alpha_lock - 1e-4, 20001)
    sizes = np.array([model.size(a).total for a in alphas])
    i = int(np.argmin(sizes))
    assert abs(opt.alpha - alphas[i]) < 2 * (alphas[1] - alphas[0])
    assert opt.total <= sizes[i] + 1e-12
    assert abs(model.scan().alpha - opt.alpha) < 1e-4
    assert abs(model.derivative(opt.alpha)) < 1e-9
    h = 1e-6                              # the analytic dH/dα against a central difference
    a = radians(35)
    assert model.derivative(a) == pytest.approx((model.size(a + h).total - model.size(a - h).total) / (2 * h),
                                                rel=1e-6)
    with pytest.raises(ValueError, match="self-locks"):
        model.size(model.alpha_lock + 0.01)


def _uniform(k: float):
    return lambda phi: (k * phi, np.full_like(phi, k), np.zeros_like(phi))


def test_flat_follower_cusp_limit_for_a_uniform_law():
    # ψ = kφ: ρ = A sin γ (1 + 2k)/(1 + k)² − e, smallest at the lowest γ = ψ0 − |k|·φ_end
    A, e, k = 0.1, 0.01, -0.3
    phi = np.linspace(0.0, 1.0, 501)
    follower = FlatFollower(A, e, _uniform(k))
    factor = (1 + 2 * k) / (1 + k) ** 2
    psi0 = 0.3 + asin(e / (factor * A))
    assert follower.min_base_radius(phi) == pytest.approx(A * sin(psi0) - e, rel=1e-9)
    with pytest.raises(ValueError, match="cusp for every base radius"):
        FlatFollower(A, 0.0, _uniform(-0.6)).min_base_radius(phi)   # k < −½: cusps whatever the radius


def test_flat_follower_envelope_curvature_and_cusp_by_finite_differences():
    prog = CamProgram([Segment("rise", radians(90), "harmonic", radians(20)), Segment("dwell", radians(90)),
                       Segment("return", radians(90), "harmonic", radians(20)), Segment("dwell", radians(90))])
    follower = FlatFollower(0.1, 0.0, lambda f: prog.evaluate(f)[:3])
    rb = follower.min_base_radius()
    phi = np.linspace(radians(185), radians(265), 4001)   # the return, where ρ is smallest
    psi = prog.evaluate(phi)[0]
    theta = np.pi / 2 - (np.arcsin(np.array([rb * 1.02, rb * 0.9]) / 0.1)[:, None] + psi) - phi
    inner = slice(5, -5)
    moves = []
    for k, radius in enumerate((rb * 1.02, rb * 0.9)):
        pr = follower.profile(radius, phi)
        dx, dy = np.gradient(pr.x, phi), np.gradient(pr.y, phi)
        fd = curvature_radius(dx, dy, np.gradient(dx, phi), np.gradient(dy, phi))[inner]
        rho = pr.rho[inner]
        far = np.abs(rho) > 1e-3                           # the geometric radius is |ρ| (FD is poor at ρ = 0)
        assert np.allclose(np.abs(fd[far]), np.abs(rho[far]), rtol=3e-3)
        # the contact point slides along the face one way; at a cusp it turns back (ρ changes sign)
        moves.append(np.sign(dx * -np.sin(theta[k]) + dy * np.cos(theta[k]))[inner])
    assert np.ptp(moves[0]) == 0.0
    assert np.ptp(moves[1]) == 2.0
    assert follower.profile(rb * 0.98).has_cusp and not follower.profile(rb * 1.02).has_cusp
    assert follower.profile(0.04, np.array([radians(315)])).rho[0] == pytest.approx(0.04)   # dwell: the base circle


def _rise(span: float):
    prog = CamProgram([Segment("rise", radians(150), "cycloidal", 1.0), Segment("dwell", radians(60)),
                       Segment("return", radians(150), "3-4-5", 1.0)])
    phi = np.linspace(0.0, 2 * pi, 2000, endpoint=False)
    m = prog.evaluate(phi)
    return phi, m.s * span, m.s_p * span, m.s_pp * span


@pytest.mark.parametrize("linkage, offset, span", [
    (SliderCrank(0.03, 0.1, 0.01), 0.08, 0.04),
    (SliderCrank(0.03, 0.1, 0.01, side=-1.0), -0.12, 0.04),
    (FourBar(0.1, 0.03, 0.12, 0.07), 1.2, 0.4),
    (FourBar(0.1, 0.03, 0.12, 0.07, branch=-1.0), -1.6, 0.4),
    (SlottedLink(0.03, 0.08), -0.15, 0.5),
    (DoubleSlider(0.05), -0.045, 0.09),
])
def test_synthesis_round_trip(linkage, offset, span):
    phi, o, o_p, o_pp = _rise(span)
    o = o + offset
    law = synthesize(linkage, o, o_p, o_pp)
    assert round_trip_error(linkage, law, o) < 1e-10
    assert np.ptp(law.q) > 0.05
    assert np.max(np.abs(np.diff(law.q))) < 0.05               # continuous branch, no jump between roots
    inner = slice(5, -5)
    assert np.allclose(np.gradient(law.q, phi)[inner], law.q_p[inner], atol=2e-4 * np.abs(law.q_p).max())
    assert np.allclose(np.gradient(law.q_p, phi)[inner], law.q_pp[inner], atol=3e-3 * np.abs(law.q_pp).max() + 1e-9)


def test_synthesis_of_the_pin_insertion_follower_matches_the_chain(mech):
    phi = np.linspace(0.0, 2 * pi, 720, endpoint=False)
    st = mech.state(phi)
    crank = SliderCrank(mech.L3, mech.l4, mech.e_sk, mech.chain.rod_side)
    law = synthesize(crank, mech.s0 - st.s, -st.s_p, -st.s_pp)
    assert np.max(np.abs(np.angle(np.exp(1j * (law.q - st.psi))))) < 1e-12
    assert np.allclose(law.q_p, st.psi_p, atol=1e-12) and np.allclose(law.q_pp, st.psi_pp, atol=1e-11)


def test_synthesis_refuses_an_unreachable_output():
    with pytest.raises(SingularPositionError, match="cannot reach"):
        synthesize(SlottedLink(0.03, 0.08), np.array([0.0, 0.5]), np.zeros(2), np.zeros(2))  # > asin(r/d)
    with pytest.raises(ValueError, match="length r"):
        DoubleSlider(0.0)


@pytest.mark.parametrize("linkage", [DoubleSlider(0.05), FourBar(0.1, 0.04, 0.09, 0.07, 1.0)])
def test_synthesis_refuses_a_law_through_a_dead_centre_between_samples(linkage):
    """A smooth input q(φ) whose output passes the linkage's extreme (its dead centre, F_q = 0) between two grid
    points: continuity picked the mirrored assembly (the Scotch yoke's q bounced off 0 with a velocity step) or gave a
    q' of 0/0 (the four-bar's off by 0.23 against an amplitude of 0.5), silently. Now it is refused, naming where."""
    phi = np.linspace(0.0, 2 * pi, 3601)
    q = (0.3 if isinstance(linkage, DoubleSlider) else 1.0) + 0.5 * np.sin(phi)
    o = np.unwrap(linkage.forward(q)) if linkage.angular_output else linkage.forward(q)
    o_p = np.gradient(o, phi)
    with pytest.raises(SingularPositionError, match="passes a dead centre near point"):
        synthesize(linkage, o, o_p, np.gradient(o_p, phi), q_start=q[0])
    far = slice(0, 1200)                         # the same law short of the dead centre: inverted as before
    law = synthesize(linkage, o[far], o_p[far], np.gradient(o_p, phi)[far], q_start=q[0])
    assert np.max(np.abs(np.angle(np.exp(1j * (law.q - q[far]))))) < 1e-9


def test_design_checks_of_the_scene(tmp_path):
    from rig.cam_design_chart import plot_design
    from rig.mechanisms.cam.design import design_checks, format_checks
    from rig.plants.cam_bar.scene_io import cam_bar_from_scene
    mech, omega = cam_bar_from_scene("data/scenes/pin_insertion.toml")
    assert omega == pytest.approx(150 * tau / 60)
    design = design_checks(mech, omega, n=720)
    names = {c.name: c for c in design.checks}
    assert names["max pressure angle"].value == pytest.approx(np.degrees(design.pressure_angle.max()))
    assert names["min convex pitch radius"].limit == pytest.approx(8.0 / 0.7)
    assert names["series synthesis round trip"].ok
    text = format_checks(design)
    assert "max Hertz stress" in text and "MPa" in text
    png = plot_design(design, tmp_path / "cam.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from rig.mechanisms.cam.design import Check, utilisation        # the bars: the share of each limit used
    assert utilisation(names["max pressure angle"]) == pytest.approx(names["max pressure angle"].value / 30.0)
    assert utilisation(Check("r", 20.0, 25.0, "mm", "≥")) == pytest.approx(1.25)      # too small: above 1
    assert np.isnan(utilisation(Check("r_b/h", -0.1, 0.0, "", "≥")))


def test_rig_cam_design_command(tmp_path, capsys):
    from rig.cli import main
    png = tmp_path / "chart.png"
    assert main(["cam-design", "--low-speed", "-o", str(png)]) == 0
    out = capsys.readouterr().out
    assert "max pressure angle" in out and "45" in out and "FAIL" not in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["cam-design", "--load-coefficient", "0", "-o", str(png)]) == 1   # r_b/h < 0 at the optimum
    assert "FAIL" in capsys.readouterr().out



def test_the_default_chart_is_named_after_the_scene(tmp_path, capsys, monkeypatch):
    """Without -o each scene's chart has a name of its own (one fixed name let a second scene replace the first)."""
    from rig.cli import main
    root = Path(__file__).resolve().parents[2] / "data" / "scenes"
    monkeypatch.chdir(tmp_path)
    assert main(["-q", "cam-design"]) == 0
    assert main(["-q", "cam-design", str(root / "lab_cam.toml")]) in (0, 1)
    assert "chart: out/lab_cam.cam_design.png" in capsys.readouterr().out
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["lab_cam.cam_design.png",
                                                                   "pin_insertion.cam_design.png"]


def test_cam_design_refuses_a_scene_without_a_cam():
    from rig.plants.cam_bar.scene_io import cam_bar_from_scene
    from rig.scene import SceneError
    with pytest.raises(SceneError, match="rig cam-design needs plant \"cam_bar\".*clutch_stop.toml is a 'clutch"):
        cam_bar_from_scene("data/scenes/clutch_stop.toml", "rig cam-design")


@pytest.mark.parametrize("value", ["-5", "0", "nan"])
def test_cam_design_refuses_an_allowed_stress_that_is_not_positive(value, tmp_path, capsys):
    from rig.cli import main
    assert main(["-q", "cam-design", "--sigma-allow", value, "-o", str(tmp_path / "c.png")]) == 2
    assert "--sigma-allow must be a positive permissible Hertz stress in MPa" in capsys.readouterr().err
    assert not (tmp_path / "c.png").exists()


def test_the_synthesis_linkages_close_their_loops():
    """Each linkage's output by the geometry of its own drawing, not by its inversion: the four-bar's coupler keeps
    its length l3 between crank pin and rocker pin, the slotted link's pin lies on the lever through its pivot."""
    q = np.linspace(0.0, 2 * pi, 73)
    for branch in (1.0, -1.0):
        bar = FourBar(0.1, 0.03, 0.12, 0.07, branch=branch)
        o = bar.forward(q)
        b = np.c_[0.03 * np.cos(q), 0.03 * np.sin(q)]
        c = np.c_[0.1 + 0.07 * np.cos(o), 0.07 * np.sin(o)]
        assert np.allclose(np.hypot(*(c - b).T), 0.12, rtol=0, atol=1e-12)
    slot = SlottedLink(0.03, 0.08)
    o = slot.forward(q)
    pin = np.c_[0.03 * np.cos(q) + 0.08, 0.03 * np.sin(q)]                  # from the lever's pivot (−d, 0)
    assert np.allclose(pin[:, 0] * np.sin(o) - pin[:, 1] * np.cos(o), 0.0, atol=1e-15)   # on the lever's line
    assert np.all(pin[:, 0] * np.cos(o) + pin[:, 1] * np.sin(o) > 0)                      # on its near side


def _menger_radius(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Radius of the circle through each point and its two neighbours (closed curve) and that circle's centre."""
    ax, ay, bx, by, cx, cy = np.roll(x, 1), np.roll(y, 1), x, y, np.roll(x, -1), np.roll(y, -1)
    d = 2 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    ux = ((ax ** 2 + ay ** 2) * (by - cy) + (bx ** 2 + by ** 2) * (cy - ay) + (cx ** 2 + cy ** 2) * (ay - by)) / d
    uy = ((ax ** 2 + ay ** 2) * (cx - bx) + (bx ** 2 + by ** 2) * (ax - cx) + (cx ** 2 + cy ** 2) * (bx - ax)) / d
    return np.hypot(bx - ux, by - uy), ux, uy


def test_hertz_stress_on_the_groove_wall_the_force_presses():
    """R23 > 0 turns the follower towards larger ψ; in the §3.1 coordinates that moves the roller towards the cam
    centre, so the outer wall (at r + r_R, concave to the roller) carries it — the check took the inner, convex wall
    (523 MPa at 295.6° instead of 428 MPa at 155.7°). Reference: the walls built as offset curves of the pitch curve,
    their radii from circles through neighbouring points, the loaded one picked by moving the roller."""
    from rig.mechanisms.cam.design import STEEL_E, STEEL_NU, design_checks, effective_modulus
    from rig.mechanisms.cam.pitch import pitch_curve
    mech = PinInsertionMechanism()
    omega = 150 * pi / 30
    phi = np.linspace(0.0, 2 * pi, 7200, endpoint=False)
    design = design_checks(mech, omega, n=7200)
    ks = mech.kinetostatics(phi, omega)
    pc = pitch_curve(mech, phi)
    # which way a growing ψ moves the roller centre, from two positions (not the project's derivative)
    psi = mech.state(phi).psi
    gap = [np.hypot(mech.l3 * np.cos(p) - mech.x_A0, mech.l3 * np.sin(p) - mech.y_A0) for p in (psi, psi + 1e-7)]
    assert np.all(gap[1] < gap[0])                     # towards the cam centre all round
    tx, ty = np.roll(pc.x, -1) - np.roll(pc.x, 1), np.roll(pc.y, -1) - np.roll(pc.y, 1)     # closed curve
    nx, ny = ty, -tx                                    # a normal, turned to point away from the cam centre
    flip = np.sign(nx * pc.x + ny * pc.y)
    norm = np.hypot(nx, ny) * flip
    wall = np.where(ks.R23n >= 0.0, 1.0, -1.0) * mech.r_R          # outer wall where R23 > 0, else inner
    wx, wy = pc.x + wall * nx / norm, pc.y + wall * ny / norm
    radius, ux, uy = _menger_radius(wx, wy)
    roller_side = (ux - wx) * (pc.x - wx) + (uy - wy) * (pc.y - wy) > 0.0     # centre on the roller's side: concave
    rho_c = np.where(roller_side, -radius, radius)
    ref = hertz_line_stress(ks.R23n, mech.roller_width, mech.r_R, rho_c,
                            effective_modulus(STEEL_E, STEEL_NU, STEEL_E, STEEL_NU))
    jumps = (np.abs(np.diff(ks.R23n, append=ks.R23n[0])) > 1.0) | \
        (np.abs(np.diff(pc.rho, append=pc.rho[0])) > 1e-3)           # the program's boundaries (ψ'' jumps)
    smooth = ~(jumps | np.roll(jumps, 1) | np.roll(jumps, -1) | np.roll(jumps, 2) | np.roll(jumps, -2))
    assert smooth.mean() > 0.95
    assert np.allclose(design.sigma_h[smooth], ref[smooth], rtol=2e-3)
    i = int(np.argmax(ref))
    assert int(np.argmax(design.sigma_h)) == pytest.approx(i, abs=2)
    assert design.sigma_h.max() == pytest.approx(ref.max(), rel=2e-3)


def test_flat_follower_limit_is_the_base_radius_of_its_own_cusp_free_profile():
    """The flat-faced follower's lift must be 0 on the base circle and ≥ 0 all round: taken from the least stroke while
    the swing runs the other way, the 'base radius' was the face distance at the farthest position (20.47 mm) while
    the profile built with it reaches 8.86 mm from the cam centre. Now the limit is the nearest distance of its own
    cusp-free profile, and a profile slightly inside it has a cusp."""
    from rig.mechanisms.cam.design import design_checks
    mech = PinInsertionMechanism()
    check = next(c for c in design_checks(mech, 150 * pi / 30).checks if c.name.startswith("flat-faced follower"))
    st = mech.state(np.linspace(0.0, 2 * pi, 3600, endpoint=False))
    sign = 1.0 if st.r[np.argmax(st.s)] >= st.r[np.argmin(st.s)] else -1.0
    psi0 = float(np.min(sign * st.psi))

    def law(f):
        s = mech.state(f)
        return sign * s.psi - psi0, sign * s.psi_p, sign * s.psi_pp

    follower = FlatFollower(float(np.hypot(mech.x_A0, mech.y_A0)), 0.0, law)
    rb = check.limit / 1e3
    profile = follower.profile(rb * 1.001)
    assert np.min(np.hypot(profile.x, profile.y)) == pytest.approx(rb * 1.001, rel=1e-4) and not profile.has_cusp
    assert follower.profile(rb * 0.99).has_cusp


def test_a_radius_sized_to_the_limit_passes_its_check():
    """The exact base radius puts the pressure angle on its limit; checked back it lands a few ulp above it
    (20.000000000000004° for a parabolic rise): on the limit, within rounding, is within it — and a value a
    millionth beyond is not."""
    from rig.mechanisms.cam.design import Check
    from rig.mechanisms.cam.sizing import exact_base_radius, pressure_angles
    r_b = exact_base_radius(get_law("parabolic"), 0.042, radians(200), radians(20))
    worst = float(np.degrees(np.max(np.abs(pressure_angles(get_law("parabolic"), 0.042, radians(200), r_b)))))
    assert worst == pytest.approx(20.0, rel=1e-12)
    assert Check("max pressure angle", worst, 20.0, "°", "≤").ok
    assert not Check("max pressure angle", 20.00002, 20.0, "°", "≤").ok
    assert Check("r", 25.0 * (1 - 1e-15), 25.0, "mm", "≥").ok and not Check("r", 24.99, 25.0, "mm", "≥").ok
    assert not Check("max Hertz stress", float("inf"), 1200.0, "MPa", "≤").ok            # a zero flank radius
    assert not Check("r", float("-inf"), 5.0, "mm", "≥").ok and not Check("r", float("nan"), 5.0, "mm", "≥").ok


def test_a_clockwise_cam_needs_the_base_radius_of_the_reversed_law_counter_clockwise():
    """The flat-faced check ignored the cam's sense of rotation (8.861 mm either way on the demo). Turned clockwise by
    φ the cam meets the face lines a counter-clockwise cam meets with the law run backwards, ψ(−φ): the same envelope,
    the same minimum base radius — an identity independent of the envelope code's sign conventions."""
    prog = CamProgram([Segment("rise", radians(120), "cycloidal", radians(10)), Segment("dwell", radians(60)),
                       Segment("return", radians(90), "3-4-5", radians(10)), Segment("dwell", radians(90))])
    law = lambda f: prog.evaluate(f)[:3]                                           # noqa: E731

    def backwards(f):
        psi, psi_p, psi_pp = prog.evaluate(-np.asarray(f))[:3]
        return psi, -psi_p, psi_pp
    clockwise = FlatFollower(0.1, 0.0, law, -1.0).min_base_radius()
    assert clockwise == pytest.approx(FlatFollower(0.1, 0.0, backwards, 1.0).min_base_radius(), rel=1e-9)
    assert abs(clockwise - FlatFollower(0.1, 0.0, law, 1.0).min_base_radius()) > 1e-4     # not the same cam
    with pytest.raises(ValueError, match="direction must be"):
        FlatFollower(0.1, 0.0, law, 0.5)


def test_a_rise_angle_beyond_a_turn_is_refused_as_degrees_given_for_rad():
    """flocke_base_radius(law, 0.02, 120, …) took Φ = 120 rad (degrees passed by mistake) and returned 9.4 mm."""
    from rig.mechanisms.cam.sizing import flocke_base_radius
    from rig.motion.registry import get_law
    with pytest.raises(ValueError, match=r"rise angle Φ must lie in \(0, 2π\] rad, got 120 rad \(degrees given as rad\?\)"):
        flocke_base_radius(get_law("3-4-5"), 0.02, 120, radians(30))
    assert flocke_base_radius(get_law("3-4-5"), 0.02, radians(120), radians(30)) > 0.0


@pytest.mark.parametrize("scene, switches", [("pin_insertion.toml", False), ("pin_insertion_as_drawn.toml", True)])
def test_force_closure_check_finds_where_the_roller_leaves_the_working_flank(scene, switches):
    """MODELS §2: R23 must stay > 0 on the working flank; where it does not, the roller crosses the clearance (the
    jump). The check's minimum and its spans against level 1's contact force on a finer grid of its own."""
    from rig.mechanisms.cam.design import design_checks
    from rig.plants.cam_bar.scene_io import cam_bar_from_scene
    mech, omega = cam_bar_from_scene(f"data/scenes/{scene}")
    row = {c.name: c for c in design_checks(mech, omega, n=720).checks}["min contact force on the working flank"]
    phi = np.linspace(0.0, tau, 7200, endpoint=False)
    r23 = mech.kinetostatics(phi, omega).R23n
    assert row.value == pytest.approx(r23.min(), rel=0.02, abs=1.0)
    assert row.ok is not switches
    if switches:
        spans = [[float(v) for v in span.split("–")] for span in
                 row.note.split("over φ = ")[1].split(":")[0].replace("°", "").split(", ")]
        other = np.degrees(phi[r23 < 0.0])
        for lo, hi in spans:                    # each span named holds R23 < 0 at its ends (within the coarse grid)
            assert np.any(np.abs(other - lo) < 0.6) and np.any(np.abs(other - hi) < 0.6)
        assert sum(hi - lo + 0.5 for lo, hi in spans) == pytest.approx(other.size * 0.05, abs=2.0)


def test_an_undercut_wall_fails_the_hertz_check_instead_of_stopping_the_checks():
    """A 13 mm roller on a steep 40° rise: where the loaded wall's radius ρ ∓ r_R changes sign the offset curve loops
    (no contact geometry). The checks go on and the Hertz row fails naming it (it used to stop with 'concave profile
    radius … tighter than the roller')."""
    from rig.mechanisms.cam.design import design_checks
    program = CamProgram([Segment("dwell", radians(140)), Segment("rise", radians(40), "3-4-5", 0.042),
                          Segment("dwell", radians(40)), Segment("return", radians(100), "3-4-5", 0.042),
                          Segment("dwell", radians(40))])
    mech = PinInsertionMechanism(r_R=0.013, program=program)
    design = design_checks(mech, 100 * tau / 60, n=3600)
    rows = {c.name: c for c in design.checks}
    hertz = rows["max Hertz stress"]
    assert not hertz.ok and hertz.value == np.inf and "undercut" in hertz.note
    gone = np.isnan(design.sigma_h)
    assert 0 < gone.sum() < design.phi.size
    assert not rows["min convex pitch radius"].ok and "series synthesis round trip" in rows


def test_the_flocke_row_says_when_its_radius_is_exact():
    """For the parabolic law the steepest pressure angle lies at s'_max: Flocke's radius is the exact one."""
    from rig.mechanisms.cam.design import sizing_checks
    program = CamProgram([Segment("dwell", radians(60)), Segment("rise", radians(120), "parabolic", 0.042),
                          Segment("dwell", radians(40)), Segment("return", radians(100), "parabolic", 0.042),
                          Segment("dwell", radians(40))])
    flocke = sizing_checks(program, 0.1, 0.5)[0]
    assert flocke.value == pytest.approx(30.0, rel=1e-9) and "exact for this law" in flocke.note
    default = sizing_checks(PinInsertionMechanism().program, 0.1, 0.5)[0]
    assert default.value > 30.0 and "too small" in default.note


@pytest.mark.parametrize("name", ["3-4-5", "cycloidal", "modified_trapezoid", "parabolic"])
def test_a_reversed_law_is_the_return_read_backwards(name):
    """y_r(x) = 1 − y(1 − x): a rise from 0 to 1, its derivatives those of the return s = 1 − y run backwards
    (finite differences of y_r itself)."""
    from rig.motion.laws import ReversedLaw
    law = ReversedLaw(get_law(name))
    x = np.linspace(0.01, 0.99, 97)
    x = x[np.all(np.abs(x[:, None] - np.array([*law.breakpoints(), -1.0])) > 1e-3, axis=1)]   # y'' jumps there
    assert law.breakpoints() == tuple(sorted(1.0 - b for b in get_law(name).breakpoints()))
    y, y1, y2, _ = law.derivatives(x)
    assert law.y(np.array([0.0, 1.0])) == pytest.approx([0.0, 1.0], abs=1e-12)
    h = 1e-6
    assert np.allclose(y1, (law.y(x + h) - law.y(x - h)) / (2 * h), atol=1e-6)
    assert np.allclose(y2, (law.derivatives(x + h)[1] - law.derivatives(x - h)[1]) / (2 * h), atol=1e-4)
    back = get_law(name).derivatives(1.0 - x)
    assert np.allclose(y, 1.0 - back[0]) and np.allclose(y1, back[1])


def test_the_sizing_rows_size_the_segment_that_needs_the_largest_radius():
    """The demo's return (100°, 3-4-5) is steeper than its rise (120°): the exact radius must keep |α| ≤ 30° on both
    (it was sized on the first rise only, 47.05 mm, where the return reaches ≈ 34.7°). Independent: the program's own
    s, s' over each moving segment, s measured from the segment's bottom, r_b = max(|s'|/tan 30° − s)."""
    from rig.mechanisms.cam.design import sizing_checks
    mech = PinInsertionMechanism()
    prog = mech.program
    need = []
    for seg, start in zip(prog.segments, prog.starts):
        if seg.kind in ("rise", "return"):
            phi = start + np.linspace(0.0, seg.angle, 200001)
            m = prog.evaluate(phi)
            need.append(float(np.max(np.abs(m.s_p) / np.tan(radians(30)) - (m.s - m.s.min()))))
    flocke, exact = sizing_checks(mech.program, mech.mu, 0.5)[:2]
    assert float(exact.note.split("r_b = ")[1].split(" mm")[0]) == pytest.approx(max(need) * 1e3, abs=0.006)
    assert max(need) > min(need) * 1.2 and "on the return" in flocke.note and "the others: rise 47.05 mm" in exact.note
    assert exact.ok and exact.value == pytest.approx(30.0, rel=1e-9)


def test_the_exact_base_radius_counts_the_lift_a_stacked_rise_starts_from():
    """A 5 mm rise then a 15 mm rise (60° each, cycloidal): the second was sized from its own bottom, 42.58 mm, where
    tan α = s'/(r_b + s) with the whole lift s needs 37.58 mm (an audit). Brute force over the program."""
    from rig.mechanisms.cam.design import required_base_radius
    program = CamProgram([Segment("rise", radians(60), "cycloidal", 0.005), Segment("rise", radians(60), "cycloidal",
                                                                                      0.015),
                          Segment("dwell", radians(60)), Segment("return", radians(120), "cycloidal", 0.02),
                          Segment("dwell", radians(60))])
    m = program.evaluate(np.linspace(0.0, tau, 720_001))
    brute = float(np.max(np.abs(m.s_p) / np.tan(radians(30)) - m.s))
    assert required_base_radius(program, radians(30)) == pytest.approx(brute, rel=1e-6)
    assert brute == pytest.approx(0.03758, abs=1e-5)


def test_a_steep_program_fails_the_flat_follower_row_and_keeps_the_table(tmp_path):
    """A 20° rise: no cusp-free flat-faced follower exists below the pivot distance, and rig cam-design ended with that
    sentence and no table (an audit). The row fails; the others are computed."""
    from rig.mechanisms.cam.design import design_checks
    from rig.plants.cam_bar.scene_io import cam_bar_from_scene
    text = (Path(__file__).resolve().parents[2] / "data" / "scenes" / "pin_insertion.toml").read_text()
    program = text[text.index("[[plant.cam_program]]"):]
    first, rise = program.index('angle = "'), program.index('kind = "rise"')
    steep = text.replace(program, program[:first] + 'angle = "160 deg"' + program[program.index("\n", first):rise]
                         + program[rise:].replace(program[rise:][program[rise:].index('angle = "'):].split("\n")[0],
                                                  'angle = "20 deg"', 1))
    path = tmp_path / "steep.toml"
    path.write_text(steep)
    mech, omega = cam_bar_from_scene(path)
    checks = {c.name: c for c in design_checks(mech, omega, n=720).checks}
    flat = checks["flat-faced follower: base radius"]
    assert not flat.ok and "no cusp-free flat-faced follower for this swing" in flat.note
    assert checks["series synthesis round trip"].ok and not checks["max pressure angle"].ok
