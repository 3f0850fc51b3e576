"""Rod pin-joint clearances (reduced model, rig.plants.cam_bar.joints) and the per-cycle clearance draw at level 2."""

import numpy as np
import pytest

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.plant import DEMO_SPEED, CamBarPlant, Setting
from rig.plants.cam_bar.joints import JointClearance
from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.variation import CycleVariation
from rig.scene import SceneError, load_scene

from tests.cam_bar.test_cam_bar_scene import write


def test_take_up_follows_the_rod_force_and_is_bounded_by_the_clearances():
    j = JointClearance(20e-6, 30e-6, force_band=2.0)
    ct = np.full(5, -0.99)                                           # rod lies nearly along the guide
    ds = j.stroke_offset(np.array([-100.0, -2.0, 0.0, 2.0, 100.0]), ct)
    assert ds[2] == 0.0 and ds[-1] == pytest.approx(25e-6 / 0.99) and ds[0] == pytest.approx(-ds[-1])
    assert np.all(np.diff(ds) > 0.0)                                 # tension lengthens the rod: larger stroke
    with pytest.raises(ValueError, match="joint clearances"):
        JointClearance(-1e-6)


def test_gripper_wanders_in_the_dwells_where_the_rod_is_unloaded():
    """Nominal machine: during the insertion the rod is in compression (the pins lie on one side); in the upper
    dwell its force rings about zero, so the pins move across their clearances and the gripper vibrates by a
    fraction of the summed clearance — rigid joints keep it still."""
    spread = {}
    for joints in (None, JointClearance(20e-6, 20e-6)):
        mech = PinInsertionMechanism(joints=joints)
        model = Level2(mech, DEMO_SPEED)
        t = np.linspace(0.0, 0.4, 8001)
        sig = model.signals(t, model.simulate((0.0, 0.4), t_eval=t, rtol=1e-7, atol=1e-12).solution.y)
        phi = np.degrees(sig["cam_angle"])
        ds = sig["s"] - mech.state(sig["phi"]).s
        dwell = (phi > 181.0) & (phi < 219.0)
        assert sig["rod_tension"].min() < -25.0                      # compression while the pin is inserted
        spread[joints is None] = np.ptp(ds[dwell])
    assert spread[True] < 0.1e-6
    assert 1e-6 < spread[False] <= 40e-6


def test_level2_cycles_draw_their_groove_clearance(tmp_path):
    variation = CycleVariation(clearance_lambda=1 / 20e-6)
    mech = CamBarPlant(PinInsertionMechanism(), Setting(fidelity=2, variation=variation, rng=np.random.default_rng(4)))
    for c in range(3):                                                # cycles advance: draw, then use
        take_up = mech.cycles.deviation(c).take_up
        assert mech.cycles.mechanism(c).clearance == take_up and 0.0 <= take_up <= 0.05e-3
        assert np.all(mech.cycles.stroke_deviation(c, np.linspace(0, 6, 7)) == 0.0)  # simulated, not offset
    level1 = CamBarPlant(mech.mech, Setting(fidelity=1, variation=variation, rng=np.random.default_rng(4)))
    assert level1.cycles.mechanism(0).clearance == mech.mech.clearance                # level 1: a take-up
    assert np.any(level1.cycles.stroke_deviation(0, np.linspace(0, 6, 7)) != 0.0)


def test_scene_table(tmp_path):
    scene = write(tmp_path, '\n[plant.joints]\nfollower = "0.02 mm"\nslider = "0.03 mm"\n',
                  "[[plant.cam_program]]", "[[plant.cam_program]]")
    assert PinInsertionMechanism.from_scene(scene).joints == JointClearance(20e-6, 30e-6)
    path = tmp_path / "scene.toml"
    path.write_text(path.read_text().replace('slider = "0.03 mm"', 'slider = "-0.03 mm"'))
    with pytest.raises(SceneError, match="joint clearances"):
        PinInsertionMechanism.from_scene(load_scene(path))
