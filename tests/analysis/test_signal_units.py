"""Every truth signal a plant of any scene produces has an SI unit, so every report axis names its unit."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig.analysis.units import SIGNAL_SI
from rig.runner.plants import make_plant
from rig.scene import load_scene

SCENES = sorted((Path(__file__).resolve().parents[2] / "data" / "scenes").glob("*.toml"))


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_every_truth_signal_has_a_unit(path):
    scene = load_scene(path)
    plant = make_plant(scene.section("scene")["plant"], scene)
    truth = plant.advance(np.arange(1, 21) * 1e-4)
    missing = sorted(k for k, v in truth.items() if k != "t" and np.ndim(v) == 1 and k not in SIGNAL_SI)
    assert not missing, f"{path.name}: truth signals without an SI unit: {missing}"
