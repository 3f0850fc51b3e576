"""Every truth signal a plant of any scene produces has an SI unit, so every report axis names its unit."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig.analysis.units import SIGNAL_LABEL, SIGNAL_SI
from rig.runner.plants import make_plant
from rig.scene import load_scene

SCENES = sorted((Path(__file__).resolve().parents[2] / "data" / "scenes").glob("*.toml"))


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_every_truth_signal_has_a_unit(path):
    scene = load_scene(path)
    plant = make_plant(scene.section("scene")["plant"], scene)
    truth = plant.advance(np.arange(1, 21) * 1e-4)
    signals = [k for k, v in truth.items() if k != "t" and np.ndim(v) == 1]
    assert not (missing := sorted(set(signals) - set(SIGNAL_SI))), f"{path.name}: no SI unit for {missing}"
    recorded = scene.section("recording").get("truth_signals") if "recording" in scene.data else None
    unnamed = sorted(k for k in (recorded or signals) if k in signals and k not in SIGNAL_LABEL)
    assert not unnamed, f"{path.name}: recorded truth signals without a legend label: {unnamed}"


def test_strain_is_shown_in_micrometres_per_metre_and_named_strain():
    from rig.analysis.units import QUANTITY, SIGNAL_SI, unit
    u = unit(SIGNAL_SI["leaf_strain"])
    assert (u.label, u.ascii, u.factor) == ("µm/m", "um/m", 1e6) and QUANTITY[SIGNAL_SI["leaf_strain"]] == "strain"


def test_linear_accelerations_follow_the_lengths_in_mm():
    """Lengths shown in mm, speeds in mm/s: accelerations in mm/s² beside them (they were m/s²)."""
    from rig.analysis.units import SIGNAL_SI, unit
    assert (unit(SIGNAL_SI["a"]).label, unit(SIGNAL_SI["v"]).label, unit(SIGNAL_SI["s"]).label) == ("mm/s²", "mm/s", "mm")


@pytest.mark.parametrize("plant, meaning", [("cam_bar", "s: stroke s of the slider (gripper)"),
                                            ("lab_bench", "s: follower stroke s")])
def test_a_truth_legend_names_its_own_plants_meaning(tmp_path, monkeypatch, plant, meaning):
    """A cam-bar report's 's' is the slider's stroke, a lab report's the follower's: each legend says only its own
    (both said "stroke s (cam bar: slider/gripper; lab: follower)")."""
    import rig.analysis.plots as plots
    from rig.analysis.units import DisplayUnits, signal_label
    figures = []
    monkeypatch.setattr(plots, "save", lambda fig, path, **kw: figures.append(fig) or path)
    t = np.linspace(0.0, 1.0, 50)
    plots.truth_panels({"t": t, "s": 0.02 * t, "v": 0.02 + 0 * t + t}, ["s", "v"], tmp_path / "truth.png",
                       DisplayUnits(), plant=plant)
    legends = [text.get_text().replace("\n ", "") for ax in figures[0].axes for text in ax.get_legend().get_texts()]
    assert meaning in legends and not any("cam bar:" in x or "lab:" in x for x in legends)
    assert signal_label("s") == "stroke s" and signal_label("unknown", plant) is None
