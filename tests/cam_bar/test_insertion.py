"""The pin's force–travel law (rig.plants.cam_bar.insertion) at levels 1 and 2."""
from math import radians

import numpy as np
import pytest

from rig.motion import ConstantSpeed
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.scene_io import mechanism_from_scene
from rig.plants.cam_bar.insertion import InsertionLaw
from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.plant import DEMO_SPEED
from rig.motion.speed import RPM
from rig.scene import SceneError, load_scene

from tests.cam_bar.test_cam_bar_scene import write


def test_bump_is_smooth_and_peaks_at_f_c_and_step_is_the_constant_window():
    law, travel = InsertionLaw(), 0.005
    x = np.linspace(-0.001, 0.006, 70001)
    w = law.weight(x, travel)
    assert w.max() == pytest.approx(1.0) and x[np.argmax(w)] == pytest.approx(0.0025, abs=1e-6)
    assert w[x <= 0.0].max() == 0.0 and w[x >= travel].max() == pytest.approx(0.0, abs=1e-12)
    slope = np.diff(w) / np.diff(x)
    assert np.max(np.abs(np.diff(slope))) < 1e-2 * np.max(np.abs(slope))   # no jump in F or dF/ds
    assert np.all(InsertionLaw("step").weight(x[x >= 0], travel) == 1.0)
    lopsided = InsertionLaw(build_up=0.2, release=0.3)
    assert np.all(lopsided.weight(np.linspace(0.001, 0.0035, 11), travel) == pytest.approx(1.0))  # plateau
    for bad in (dict(law="ramp"), dict(build_up=0.0), dict(build_up=0.7, release=0.5)):
        with pytest.raises(ValueError, match="insertion"):
            InsertionLaw(**bad)


def test_level1_force_follows_the_law_during_the_rise_only():
    mech = PinInsertionMechanism()
    phi = np.linspace(0.0, 2 * np.pi, 7201)
    st = mech.state(phi)
    ks = mech.kinetostatics(phi, DEMO_SPEED.omega)
    expected = np.where(st.s_p > 0, mech.F_c * mech.insertion.weight(st.s - (0.042 - mech.F_c_travel), 0.005), 0)
    np.testing.assert_allclose(ks.F_c, expected, atol=1e-12)
    assert ks.F_c.max() == pytest.approx(mech.F_c, rel=1e-3)
    assert np.all(ks.F_c[np.degrees(phi) > 180.0] == 0.0)                  # return stroke: no force


def _run(mech, a_deg, b_deg, speed=DEMO_SPEED):
    w = speed.nominal_omega
    model = Level2(mech, speed)
    t = np.linspace(radians(a_deg) / w, radians(b_deg) / w, 2001)
    run = model.simulate((t[0], t[-1]), t_eval=t, rtol=1e-7, atol=1e-12)
    sig = model.signals(t, run.solution.y)
    return sig, mech.kinetostatics(sig["phi"], w)


def test_level2_follows_level1_with_the_law_and_rings_with_the_step():
    """Nominal machine, end of the rise and upper dwell: the bump leaves no contact ringing (R23 within a few N of
    level 1), the constant-F_c window's steps ring it by tens of N; quasi-statically (30 rpm) the levels agree."""
    sig, ks = _run(PinInsertionMechanism(), 140.0, 220.0)
    assert np.max(np.abs(sig["R23"] - ks.R23n)) < 10.0
    assert np.max(np.abs(sig["F_rod"] - ks.F_rod)) < 1.0
    sig_s, ks_s = _run(PinInsertionMechanism(insertion=InsertionLaw("step")), 140.0, 220.0)
    assert np.max(np.abs(sig_s["R23"] - ks_s.R23n)) > 50.0
    sig, ks = _run(PinInsertionMechanism(), 140.0, 185.0, ConstantSpeed(30 * RPM))
    assert np.max(np.abs(sig["R23"] - ks.R23n)) < 0.01 * np.max(np.abs(ks.R23n))
    assert np.max(np.abs(sig["F_c"] - ks.F_c)) < 0.5    # the actual stroke lags by the contact deflection (µm)


def test_scene_table(tmp_path):
    scene = write(tmp_path, '\n[plant.insertion]\nlaw = "step"\n', "[[plant.cam_program]]", "[[plant.cam_program]]")
    assert mechanism_from_scene(scene).insertion == InsertionLaw("step")
    text = tmp_path / "scene.toml"
    base = text.read_text()
    for table, match in (('law = "ramp"', "insertion law"), ('lead = 0.1', "unknown key 'lead'")):
        text.write_text(base.replace('law = "step"', table))
        with pytest.raises(SceneError, match=match):
            mechanism_from_scene(load_scene(text))
