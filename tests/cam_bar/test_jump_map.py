"""The "where does it jump" map (rig.plants.cam_bar.jump_map): the phenomena appear where the model predicts them
— flank switches at the drawn spring and high speed, gripper deviation of the order of clearance × L3/l3 when the
roller crosses the groove — and vanish with a stiffer spring or at a lower speed."""
import numpy as np

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.jump_map import jump_map, plot


def test_switches_at_the_drawn_spring_and_high_speed_only(tmp_path):
    mech = PinInsertionMechanism()
    result = jump_map(mech, speeds=(150.0, 300.0), rates=(1090.0, 1890.0), clearances=(0.05e-3,), samples=721)
    sw = result.switches[:, :, 0]
    assert sw[1, 0] >= 2 and sw[0, 0] == 0 and sw[1, 1] == 0 and sw[0, 1] == 0
    ratio = result.gripper[1, 0, 0] / 0.05e-3                          # the roller crossed the groove
    assert 0.5 * mech.L3 / mech.l3 < ratio < 1.5 * mech.L3 / mech.l3
    assert np.all(result.gripper[0, :, 0] < 5e-6)                      # 150 rpm: contact held, µm only
    assert result.gap[1, 0, 0] >= 0.05e-3 > result.gap[1, 1, 0] > 0.0  # stiffer spring: lifts, never arrives
    assert plot(result, tmp_path / "map.png").stat().st_size > 1000
