"""The "where does it jump" map (rig.plants.cam_bar.jump_map): the phenomena appear where the model predicts them
— flank switches at the drawn spring and high speed, gripper deviation of the order of clearance × L3/l3 when the
roller crosses the groove — and vanish with a stiffer spring or at a lower speed."""
from pathlib import Path

import numpy as np
import pytest

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.scene_io import mechanism_from_scene
from rig.plants.cam_bar.jump_map import jump_map, plot
from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.plant import DEMO_SPEED
from rig.scene import load_scene

ROOT = Path(__file__).resolve().parents[2]


def test_switches_at_the_drawn_spring_and_high_speed_only(tmp_path):
    """The map of the machine as drawn (its scene) through the sweep machinery (its results are the same on every
    executor: tests/sweep)."""
    scene = load_scene(ROOT / "data" / "scenes" / "pin_insertion_as_drawn.toml")
    mech = mechanism_from_scene(scene)
    grid = dict(speeds=(150.0, 300.0), rates=(1090.0, 1890.0), clearances=(0.05e-3,))
    result = jump_map(scene, **grid)
    assert not result.errors.any()
    sw = result.switches[:, :, 0]
    assert sw[1, 0] >= 2 and sw[0, 0] == 0 and sw[1, 1] == 0 and sw[0, 1] == 0
    ratio = result.gripper[1, 0, 0] / 0.05e-3                          # the roller crossed the groove
    assert 0.5 * mech.L3 / mech.l3 < ratio < 1.5 * mech.L3 / mech.l3
    assert np.all(result.gripper[0, :, 0] < 5e-6)                      # 150 rpm: contact held, µm only
    assert result.gap[1, 0, 0] >= 0.05e-3 > result.gap[1, 1, 0] > 0.0  # stiffer spring: lifts, never arrives
    assert plot(result, tmp_path / "map.png").stat().st_size > 1000


def test_upper_dwell_gripper_vibration_of_clearance_times_lever_ratio_when_the_roller_is_free():
    """Without the spring (the roller free in its clearance) the roller moves across a good part of the groove in the
    upper dwell and the gripper by L3/l3 ≈ 4 times that (150 rpm: 25 µm → 100 µm); the mounted 1.89 N/mm spring
    holds the roller and the gripper moves by well under a micrometre."""
    moves = {}
    for k, me0 in ((0.0, 0.0), (1890.0, 20.0)):
        mech = PinInsertionMechanism(k=k, Me_0=me0)
        model = Level2(mech, DEMO_SPEED)
        t = np.linspace(0.0, 0.4, 8001)
        sig = model.signals(t, model.simulate((0.0, 0.4), t_eval=t, rtol=1e-7, atol=1e-12).solution.y)
        phi = np.degrees(sig["cam_angle"])
        dwell = (phi > 180.0) & (phi < 220.0)
        moves[k] = (np.ptp((sig["s"] - mech.state(sig["phi"]).s)[dwell]), np.ptp(sig["delta_w"][dwell]))
    lever = PinInsertionMechanism().L3 / PinInsertionMechanism().l3
    gripper, roller = moves[0.0]
    assert roller > 0.3 * 0.05e-3 and gripper / roller == pytest.approx(lever, rel=0.15)
    assert moves[1890.0][0] < 1e-6


def test_ctrl_c_while_the_workers_close_keeps_the_map(tmp_path, monkeypatch, capsys):
    """Ctrl-C after the map's last point, while the workers closed: the map was lost (a leftover). Its table and chart
    are written, one line says so, status 130."""
    from rig.executors.serial import SerialExecutor
    from rig.plants.cam_bar import jump_map as module

    def close(self):
        raise KeyboardInterrupt
    monkeypatch.setattr(SerialExecutor, "close", close)
    small = module.jump_map
    monkeypatch.setattr(module, "jump_map", lambda scene, executor: small(
        scene, speeds=(150.0,), rates=(1890.0,), clearances=(0.05e-3,), revolutions=1, executor=executor))
    with pytest.raises(SystemExit) as stop:
        module.main(["--executor", "serial", "-o", str(tmp_path / "map.png")])
    assert stop.value.code == 130
    out, err = capsys.readouterr()
    assert "clearance 0.05 mm" in out and f"map: {tmp_path / 'map.png'}" in out
    assert (tmp_path / "map.png").read_bytes().startswith(b"\x89PNG")
    assert "interrupted while the workers closed, after the map's last point" in err
