"""The course lab's cam through ``rig cam-design`` (rig.mechanisms.cam.translating): its pressure angle and pitch
curve against the pitch curve drawn point by point, and the checks a scene's radii make possible."""
from __future__ import annotations

import re
from math import radians
from pathlib import Path

import numpy as np
import pytest

from rig.mechanisms.cam.translating import pitch_radius, translating_design
from rig.motion import CamProgram, Segment

ROOT = Path(__file__).resolve().parents[2]
LAB = ROOT / "data" / "scenes" / "lab_cam.toml"
PROGRAM = CamProgram([Segment("rise", radians(120), "cycloidal", 0.02), Segment("dwell", radians(60)),
                      Segment("return", radians(120), "3-4-5", 0.02), Segment("dwell", radians(60))])


def _pitch_points(r_b: float, phi: np.ndarray) -> np.ndarray:
    """The roller centre (0, r_b + s) on the follower's axis, seen from the cam turned by φ."""
    r = r_b + PROGRAM.evaluate(phi).s
    return np.stack([-r * np.sin(phi), r * np.cos(phi)])


def test_pitch_radius_and_pressure_angle_are_those_of_the_curve_drawn_point_by_point():
    r_b, h = 0.025, 1e-4
    phi = np.linspace(0.0, 2 * np.pi, 3601)[:-1] + 3e-4            # stencils off the segment joints (s'' jumps)
    p, pp, pm = _pitch_points(r_b, phi), _pitch_points(r_b, phi + h), _pitch_points(r_b, phi - h)
    d1, d2 = (pp - pm) / (2 * h), (pp - 2 * p + pm) / h ** 2
    curvature = (d1[0] * d2[1] - d2[0] * d1[1]) / (d1 ** 2).sum(0) ** 1.5      # 1/ρ: finite through inflections
    assert np.allclose(1.0 / pitch_radius(PROGRAM, r_b, phi), curvature, rtol=1e-5, atol=1e-4)
    assert pitch_radius(PROGRAM, r_b, np.array([150.0]) * np.pi / 180)[0] == pytest.approx(r_b + 0.02)   # dwell
    # the tangent, turned back into the follower's frame, leans from the cam's direction by the pressure angle
    design = translating_design(PROGRAM, 1.0, lambda f: np.ones_like(f), base_radius=r_b, n=3600)
    phi = design.phi
    d1 = (_pitch_points(r_b, phi + h) - _pitch_points(r_b, phi - h)) / (2 * h)
    c, s = np.cos(-phi), np.sin(-phi)
    tx, ty = c * d1[0] - s * d1[1], s * d1[0] + c * d1[1]
    assert np.allclose(design.pressure_angle, np.abs(np.arctan2(ty, -tx)), atol=1e-6)


def test_the_lab_cam_scene_is_checked_and_its_missing_radii_are_said(tmp_path, capsys):
    from rig.cli import main
    assert main(["-q", "cam-design", str(LAB), "-o", str(tmp_path / "lab.png")]) == 0
    out = capsys.readouterr().out
    assert "the scene gives no base_radius" in out and "min contact force (force closure)" in out
    assert (tmp_path / "lab.png").read_bytes()[:4] == b"\x89PNG"
    # the cam's own radii: 20 mm is below the 24.29 mm the rise needs, an 18 mm roller beyond 0.7 of the base circle
    text = LAB.read_text().replace('cam_inertia = "0.002 kg*m^2"',
                                   'cam_inertia = "0.002 kg*m^2"\nbase_radius = "20 mm"\nroller_radius = "18 mm"')
    scene = tmp_path / "lab_cam_radii.toml"
    scene.write_text(text)
    assert main(["-q", "cam-design", str(scene), "-o", str(tmp_path / "radii.png")]) == 1
    rows = {line.split("  ")[0]: line for line in capsys.readouterr().out.splitlines()}
    assert "FAIL" in rows["max pressure angle"] and "r_b = 20 mm" in rows["max pressure angle"]
    assert "FAIL" in rows["min convex pitch radius"] and "r_R = 18 mm" in rows["min convex pitch radius"]


@pytest.mark.parametrize("kwargs, named", [
    (dict(base_radius=float("nan")), "base radius (m) must be a finite number"),
    (dict(base_radius=-0.01), "base radius (m) must be positive"),
    (dict(roller_radius=0.0), "roller radius (m) must be positive"),
    (dict(mu=-0.1), "guide friction mu must be >= 0"),
    (dict(n=2), "angles n must be a whole number >= 8"),
    (dict(omega=float("inf")), "cam speed omega (rad/s) must be a finite number"),
    (dict(contact_force=lambda f: np.full_like(f, np.nan)), "contact force (N) must be finite (3600 of 3600"),
])
def test_library_call_with_an_impossible_input_names_it(kwargs, named):
    """Called from a script (no scene checks in between), a NaN base radius drew every curve as NaN without a word."""
    args = dict(omega=1.0, contact_force=lambda f: np.ones_like(f)) | kwargs
    with pytest.raises(ValueError, match=re.escape(named)):
        translating_design(PROGRAM, **args)
