"""The sensor preload is an offset of the rod-force reading: it leaves the level-2 motion and contact force alone,
and the rod tension stays below it up to 150 rpm (docs/cam-bar.md, 'The sensor preload')."""
import numpy as np

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.plant import DEMO_SPEED
from rig.motion.speed import RPM


def test_preload_offsets_the_reading_only():
    t = np.linspace(0.0, 0.4, 2001)
    sig = {}
    for preload in (0.0, -25.0):
        model = Level2(PinInsertionMechanism(sensor_preload=preload), DEMO_SPEED)
        sig[preload] = model.signals(t, model.simulate((0.0, 0.4), t_eval=t, rtol=1e-7, atol=1e-12).solution.y)
    np.testing.assert_array_equal(sig[0.0]["R23"], sig[-25.0]["R23"])
    np.testing.assert_allclose(sig[-25.0]["F_rod"] - sig[0.0]["F_rod"], -25.0, atol=1e-9)


def test_rod_tension_stays_below_the_preload_up_to_150_rpm_and_not_beyond():
    phi = np.linspace(0.0, 2 * np.pi, 3601)
    peak = {rpm: PinInsertionMechanism().kinetostatics(phi, rpm * RPM).rod_tension.max()
            for rpm in (100, 150, 200)}
    assert peak[100] < peak[150] < 25.0 < peak[200]
