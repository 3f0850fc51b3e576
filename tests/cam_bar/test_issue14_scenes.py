"""The machine as drawn / as found / as tested / as designed (issue 14): scenes and the as-drawn flank switches."""
from math import tau
from pathlib import Path

import pytest

from rig.plants.cam_bar.plant import CamBarPlant
from rig.recorder import read_recording
from rig.runner import run_scene
from rig.scene import load_scene

SCENES = Path(__file__).resolve().parents[2] / "data" / "scenes"
MACHINES = {"as_drawn": (1090.0, 300.0), "as_found": (1680.0, 300.0), "as_tested": (1890.0, 150.0),
            "design": (1190.0, 300.0)}


@pytest.mark.parametrize("name", MACHINES)
def test_scene_is_the_machine_it_names(name):
    plant = CamBarPlant.from_scene(load_scene(SCENES / f"pin_insertion_{name}.toml"))
    mech = plant.mech
    k, rpm = MACHINES[name]
    assert plant.setting.fidelity == 2 and plant.setting.level2.guide.model == "stick"
    assert mech.k == pytest.approx(k) and plant.speed.nominal_omega == pytest.approx(rpm * tau / 60)
    assert (mech.cam_drive is not None) == (name == "as_tested")


def test_as_drawn_records_flank_switches(tmp_path):
    out = tmp_path / "drawn.mcap"
    run_scene(SCENES / "pin_insertion_as_drawn.toml", out, cycles=1)
    switches = [e for e in read_recording(out).events if e["kind"] == "flank_switch"]
    assert len(switches) >= 2
    # the event's phi is the arrival on the other flank; left_phi where the roller left its flank — the angle to
    # compare with level 1's sign change of the contact force (the arrival is 15° later, after the flight)
    plant = CamBarPlant.from_scene(load_scene(SCENES / "pin_insertion_as_drawn.toml"), nominal=True, fidelity=1)
    level1 = plant.mech.flank_switch_angles(300 * tau / 60)             # the scene's 300 pins/min
    first = switches[0]
    assert first["to"] == "other" and first["flight"] > 0.0
    assert abs(first["left_phi"] - level1[0]) < 0.01 and first["phi"] - first["left_phi"] > 0.2   # rad
    # the report says where: each event with its angles in degrees (table and events.csv), not only counts
    from rig.analysis.report import write_report
    text = write_report(out, tmp_path / "report", fmt="md").read_text(encoding="utf-8")
    where = f"phi {first['phi'] * 360 / tau:.4g}°, left_phi {first['left_phi'] * 360 / tau:.4g}°"
    assert f"| flank_switch | {where}, flight {first['flight']:.4g} s, to other |" in text
    lines = (tmp_path / "report" / "events.csv").read_text(encoding="utf-8").splitlines()
    assert len(lines) == 1 + len(read_recording(out).events) and any(where in line for line in lines)
    assert "[events.csv](events.csv)" in text


def test_worn_pins_strike_where_the_rod_force_reverses(tmp_path):
    """The as-tested machine with 0.05 mm pins: the slider flies across the play and the recorded rod force (truth and
    the device's curve) shows the impacts, far beyond the rigid rod's -55 N; the impact lifts the roller."""
    from rig.plants.cam_bar.joints import JointClearance
    scene = SCENES / "pin_insertion_worn_pins.toml"
    assert CamBarPlant.from_scene(load_scene(scene)).mech.joints == JointClearance(5e-5, 5e-5, 4e7)
    out = tmp_path / "worn.mcap"
    run_scene(scene, out, cycles=1)
    rec = read_recording(out)
    assert rec.truth["F_rod"].min() < -150.0 and rec.truth["R23"].min() == 0.0
    assert rec.curves[0].y.min() < -150.0


def test_a_trigger_chattering_at_a_crawl_is_named_not_the_transmit_period(tmp_path, monkeypatch):
    """The worn-pin machine at 1 rpm: its pins' play makes the start/stop trigger fire again and again, 4 curves in
    one 100 ms transmit cycle, and the run said "tx_period = 0.1 s is too long … shorten tx_period (e.g. "100 ms")"
    (an audit). It now names the trigger."""
    from rig.bench import setting_check
    from rig.runner import run_scene
    from rig.runner.errors import BusTooSlow
    # the solver setting unchecked at 1 rpm (its check, a level-2 reference at 1e-10, is 30 s of this test's 35)
    monkeypatch.setattr(setting_check, "at_this_point", lambda scene, method, options, tolerance: (options, "", True))
    text = (SCENES / "pin_insertion_worn_pins.toml").read_text()
    assert 'speed = "150 rpm"' in text
    path = tmp_path / "crawl.toml"
    path.write_text(text.replace('speed = "150 rpm"', 'speed = "1 rpm"', 1))
    with pytest.raises(BusTooSlow, match=r"one transmit cycle of the unit \(0.1 s\) measured 4 curves at once.*raise "
                                         r"\[links.can\] tx_curves, else .*start/stop trigger firing again and "
                                         r"again") as info:
        run_scene(path, tmp_path / "crawl.mcap")
    assert "tx_period" not in str(info.value)
