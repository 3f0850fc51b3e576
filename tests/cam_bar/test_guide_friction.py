"""Slider-guide friction at level 2 (rig.plants.cam_bar.guide_friction): the Karnopp stick-slip model holds the
slider where the regularised friction lets the roller creep across the groove clearance."""
import warnings

import numpy as np
import pytest

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.guide_friction import GuideFriction
from rig.plants.cam_bar.level2 import ContactLaw, Level2
from rig.plants.cam_bar.level2_model import Level2Model
from rig.plants.cam_bar.scene_io import read_level2_model
from rig.plants.cam_bar.plant import DEMO_SPEED
from rig.scene import SceneError, load_scene

from tests.cam_bar.test_cam_bar_scene import write

NO_SPRING = dict(k=0.0, Me_0=0.0)    # the roller floats in the clearance through the upper dwell


def _gap(guide: GuideFriction) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    mech = PinInsertionMechanism(**NO_SPRING)
    model = Level2(mech, DEMO_SPEED, model=Level2Model(guide=guide))
    t = np.linspace(0.0, 0.4, 8001)
    sig = model.signals(t, model.simulate((0.0, 0.4), t_eval=t, rtol=1e-7, atol=1e-12).solution.y)
    return np.degrees(sig["phi"]), -sig["delta_w"], sig["v"]


def test_stick_holds_the_slider_where_the_regularised_guide_creeps():
    """150 rpm without the spring: the roller bounces off the working flank at the start of the upper dwell and
    comes to rest in the gap. Regularised, it never rests: gravity drives it across at a steady ~0.5 mm/s;
    with stick-slip it is held (creep bounded by stick_speed·relax_time = 0.1 µm)."""
    late = {}
    for model in ("regularised", "stick"):
        phi, u, v = _gap(GuideFriction(model))
        k = (phi > 209.0) & (phi < 219.0)
        assert np.all(u[k] > 1e-6) and np.all(u[k] < 0.05e-3)                 # in the gap, no flank touched
        late[model] = (np.ptp(u[k]), np.max(np.abs(v[k])))
    assert late["regularised"][0] > 1.5e-6 and late["regularised"][1] > 3e-4     # creeps ~2 µm at > 0.3 mm/s
    assert late["stick"][0] < 0.05e-6 and late["stick"][1] < 1e-4                 # held (inside the stick band)


def test_energy_balance_closes_with_stick_slip():
    mech = PinInsertionMechanism(**NO_SPRING)
    stick = Level2Model(guide=GuideFriction("stick"))
    base = ContactLaw.steel_line(mech.roller_width, stick.contact_damping)
    model = Level2(mech, DEMO_SPEED, ContactLaw(base.stiffness * 0.01, base.exponent, base.damping * 0.1), energy=True,
                   max_penetration=1e-3, model=stick)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = model.simulate((0.0, 0.4), method="DP45", rtol=1e-8, atol=1e-12).solution
    energy = model.energies(sol.t[[0, -1]], sol.y[:, [0, -1]])
    change = sum(v[1] - v[0] for v in energy.values())
    w_drive, w_load, dissipated = sol.y[2:, -1]
    assert dissipated > 1e-3
    assert w_drive + w_load - dissipated - change == pytest.approx(0.0, abs=1e-4 * dissipated)


def test_scene_table_and_bad_values(tmp_path):
    scene = write(tmp_path, '\n[plant.guide]\nmodel = "stick"\nstatic = 0.15\nstick_speed = "0.05 mm/s"\n',
                  "[[plant.cam_program]]", "[[plant.cam_program]]")
    guide = read_level2_model(scene).guide
    assert guide == GuideFriction("stick", 0.15, 5e-5) and guide.static_coefficient(0.1) == 0.15
    assert GuideFriction().static_coefficient(0.1) == 0.1
    path = tmp_path / "scene.toml"
    text = path.read_text()
    for old, new, match in (('model = "stick"', 'model = "lugre"', "friction model"),
                            ('static = 0.15', 'static = -0.1', "static"), ('static = 0.15', 'mu_s = 0.1', "unknown key")):
        path.write_text(text.replace(old, new))
        with pytest.raises(SceneError, match=match):
            read_level2_model(load_scene(path))
