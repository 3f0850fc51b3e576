"""Fixtures of the analysis tests."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig.recorder import Recorder


@pytest.fixture
def lost_curves(tmp_path: Path) -> Path:
    """A recording of 5 curves the unit judged OK whose curves 2 and 4 were lost on the way (``incomplete_curve``
    events, no samples; their results recorded)."""
    path = tmp_path / "lost.mcap"
    program = {"elements": [], "limits": {}}
    with Recorder(path, scene_text="[scene]\nname = \"s\"\nseed = 1\n", metadata={"seed": 1},
                  programs={1: program}) as rec:
        for k in range(1, 6):
            t = k + np.arange(0, 0.3, 2e-3)
            if k in (2, 4):
                rec.write_event(float(t[-1]), "incomplete_curve", number=k, problems=["pairs missing"])
            else:
                rec.write_curve(k, 1, t, 0.04 * (t - k), 40 * (t - k))
            rec.write_result({"number": k, "program": 1, "ok": True, "elements": [],
                              "process_values": {"y_max": 40.0 + k}}, t=float(t[-1]))
    return path
