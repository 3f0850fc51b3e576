"""Scene reading: the shipped scene, strict [plant]/[speed]/cam-program tables, tolerant elsewhere."""
import re
from pathlib import Path

import numpy as np
import pytest

from rig.motion import RampSpeed, SinusoidalSpeed
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.plant import CamBarPlant, Setting
from rig.plants.cam_bar.scene_io import mechanism_from_scene, read_speed_profile, read_spring_rates
from rig.plants.cam_bar.summary import STUDY_RATES
from rig.scene import SceneError, load_scene

SCENE = Path(__file__).resolve().parents[2] / "data" / "scenes" / "pin_insertion.toml"


def write(tmp_path, text, old=None, new=None):
    base = SCENE.read_text()
    if old is not None:
        assert old in base
        base = base.replace(old, new)
    p = tmp_path / "scene.toml"
    p.write_text(base + text)
    return load_scene(p)


def test_shipped_scene_equals_defaults():
    m = mechanism_from_scene(load_scene(SCENE))
    d = PinInsertionMechanism()
    for name in ("L3", "l3", "x_A0", "e_sk", "s0", "k", "J3", "J4", "mu", "sensor_preload", "alpha_sk"):
        assert getattr(m, name) == pytest.approx(getattr(d, name)), name
    assert read_spring_rates(load_scene(SCENE)) == pytest.approx(STUDY_RATES)
    phi = np.linspace(0, 6.28, 100)
    speed = read_speed_profile(load_scene(SCENE))
    assert speed.nominal_omega == pytest.approx(Setting().speed.nominal_omega)
    assert m.kinetostatics(phi, speed.nominal_omega).R23n == pytest.approx(d.kinetostatics(phi, 5 * np.pi).R23n)
    assert CamBarPlant.from_scene(load_scene(SCENE)).speed == speed


def test_other_sections_are_ignored(tmp_path):
    sc = write(tmp_path, '\n[extra_section]\ntype = "anything"\n[another.nested]\nanything = 1\n')
    mechanism_from_scene(sc)


@pytest.mark.parametrize("old, new, message", [
    ('l_F = "100 mm"', 'l_F = "100 mm"\nlF_typo = 3', r"\[plant\]: unknown key 'lF_typo'"),
    ('L3 = "260 mm"\n', '', r"\[plant\]: missing key 'L3'"),
    ('m3 = "0.910 kg"', 'm3 = "0.910 mm"', r"\[plant\]: key 'm3'.*wrong dimension"),
    ('k = "1.89 N/mm"', 'k_N_per_mm = 1.89\nk = "2 N/mm"', r"'k' is given twice"),
    ('"1.09 N/mm", ', '"1.09 mm", ', r"spring_rates\[0\].*wrong dimension"),
    ('angle = "60 deg"', 'angle = "70 deg"', r"\[plant\]: cam program segments sum to 370°"),
    ('law = "3-4-5"\nstroke = "42 mm"', 'law = "3-4-6"\nstroke = "42 mm"', r"unknown motion law '3-4-6'"),
    ('law = "3-4-5"\nstroke = "42 mm"', 'law = "3-4-5"\nstroke = "42 mm"\nspeed = 1', r"cam_program segment 2: unknown key 'speed'"),
    ('speed = "150 rpm"', 'speed = "150 N"', r"\[speed\]: key 'speed'.*wrong dimension"),
    ('speed = "150 rpm"', 'speed = "150 rpm"\namplitude = "1 rad/s"', r"\[speed\]: unknown key 'amplitude'"),
    ('profile = "constant"', 'profile = "jerky"', r"\[speed\]: unknown speed profile 'jerky'"),
    ('l4 = "122 mm"', 'l4 = "20 mm"', r"\[plant\]: impossible cam-bar geometry"),
])
def test_errors_name_key_and_file(tmp_path, old, new, message):
    sc = write(tmp_path, "", old, new)
    with pytest.raises(SceneError, match=message) as info:
        CamBarPlant.from_scene(sc)
    assert str(sc.path) in str(info.value)


def test_speed_profiles_from_scene(tmp_path):
    sc = write(tmp_path, "", 'profile = "constant"', 'profile = "ramp"\nspeed_end = "300 rpm"\nramp_time = "2 s"')
    speed = CamBarPlant.from_scene(sc).speed
    assert isinstance(speed, RampSpeed) and speed.omega1 == pytest.approx(10 * np.pi)
    sc = write(tmp_path, "", 'profile = "constant"', 'profile = "sinusoidal"\namplitude = "10 rpm"\nfrequency = "5 Hz"')
    speed = read_speed_profile(sc)
    assert isinstance(speed, SinusoidalSpeed) and speed.frequency == pytest.approx(5.0)
    sc = write(tmp_path, "", 'profile = "constant"', 'profile = "sinusoidal"\namplitude = "200 rpm"')
    with pytest.raises(SceneError, match=r"\[speed\].*amplitude"):
        CamBarPlant.from_scene(sc)


def test_level2_assumptions_are_the_runs_setting_not_the_mechanism(tmp_path):
    """contact_damping and [plant.guide] are model assumptions: they reach the level-2 model through the run's
    setting; the mechanism (the machine) does not hold them."""
    from rig.plants.cam_bar.level2 import ContactLaw
    sc = write(tmp_path, '\n[plant.guide]\nmodel = "stick"\n', 'l_F = "100 mm"',
               'l_F = "100 mm"\ncontact_damping = "35 s/m"')
    assert not {"contact_damping", "guide"} & set(vars(mechanism_from_scene(sc)))
    plant = CamBarPlant.from_scene(sc, fidelity=2)
    assert plant.setting.level2.contact_damping == pytest.approx(35.0)
    assert plant.setting.level2.guide.model == "stick"
    model = plant._timeline._model(0)
    assert model.contact == ContactLaw.steel_line(plant.mech.roller_width, 35.0)
    assert model.model is plant.setting.level2
    with pytest.raises(SceneError, match="contact_damping must not be negative"):
        CamBarPlant.from_scene(write(tmp_path, "", 'l_F = "100 mm"', 'l_F = "100 mm"\ncontact_damping = "-1 s/m"'))


@pytest.mark.parametrize("kw, message", [
    ({"k": -1000.0}, "cam-bar parameter k must not be negative, got -1000.0 N/m"),
    ({"l4": float("nan")}, "cam-bar parameter l4 must be a finite number, got nan m"),
    ({"mu": float("inf")}, "cam-bar parameter mu must be a finite number, got inf"),
    ({"J4": -1.0}, "cam-bar parameter J4 must be positive, got -1.0 kg*m^2"),
    ({"J3": 0.0}, "cam-bar parameter J3 must be positive, got 0.0 kg*m^2"),
    ({"a3": -1.0}, "cam-bar parameter a3 must not be negative, got -1.0 m"),
    ({"J3": 0.01}, "J3 = 0.01 kg*m^2 is the follower's inertia about its pivot B0: it cannot be below m3·a3² = 0.015379"),
    ({"F_c_travel": 0.05}, "F_c_travel (50 mm) is longer than the stroke s_H (42 mm)"),
    ({"a3": 0.156}, "a3 = 156 mm puts the follower's centre of gravity where the default J3 = m3·L3²/3 = 0.0205053"),
])
def test_a_bad_parameter_is_named_with_its_unit(kw, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        PinInsertionMechanism(**kw)


def test_a_sign_change_pair_inside_one_scan_step_at_a_program_boundary_is_found():
    """At 285-300 rpm without the spring the moment turns positive about 0.08° before the dwell ends at 180° and
    jumps back across the boundary: both sign changes lie inside one 0.1° scan step (they cancelled); the scan now
    includes the point just before every program boundary."""
    from rig.plants.cam_bar.switches import flank_switch_angles
    from rig.plants.cam_bar.scene_io import cam_bar_from_scene
    mech, _ = cam_bar_from_scene("data/scenes/pin_insertion.toml")
    found = np.degrees(flank_switch_angles(mech, 0.0, False, 300 * 2 * np.pi / 60, 3600))
    assert np.any(np.abs(found - 180.0) < 1e-6) and np.any((found > 179.85) & (found < 179.99))
    assert np.any(np.abs(found - 320.0) < 1e-6) and np.any((found > 319.9) & (found < 319.99))
