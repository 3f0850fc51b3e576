"""Plants by name, as a scene's ``[scene] plant`` selects them (like python-can interfaces by name)."""
from __future__ import annotations

from typing import Any, Callable

from rig.fidelity import Fidelity, choose
from rig.scene import Scene, SceneError


def _cam_bar(scene: Scene, nominal: bool, fidelity: Fidelity) -> Any:
    from rig.plants.cam_bar.plant import CamBarPlant
    setting: dict[str, Any] = {"fidelity": fidelity.level}
    if fidelity.method is not None:
        setting.update(method=fidelity.method, method_options=dict(fidelity.options))
    return CamBarPlant.from_scene(scene, nominal, **setting)


def _clutch_dynamic(scene: Scene, nominal: bool, fidelity: Fidelity) -> Any:
    from rig.analysis.clutch_metrics import stimuli
    from rig.analysis.stand_comparison import check_rows
    from rig.plants.clutch.stand import ClutchStand
    stand = ClutchStand.from_scene(scene)   # the scene checked first: stimuli() reads its loads as given
    check_rows(scene, stimuli(scene)[0])    # the [[comparison]] the report will fill: checked before anything is recorded
    if fidelity.method is not None:      # chosen from the work-precision data, else the scene's [plant] method
        stand.method = fidelity.method
    if fidelity.options:                 # chosen from the work-precision data (else the scene's [plant] rtol/atol)
        stand.rtol, stand.atol = fidelity.options["rtol"], fidelity.options["atol"]
    return stand


def _clutch_static(scene: Scene, nominal: bool, fidelity: Fidelity) -> Any:
    from rig.plants.clutch.static_rig import rig_from_scene
    return rig_from_scene(scene)


def _lab_bench(scene: Scene, nominal: bool, fidelity: Fidelity) -> Any:
    from rig.analysis.lab_report import read_lab_section
    from rig.plants.lab_bench import LabBench
    read_lab_section(scene)                 # the sheets the report will fill: checked before anything is recorded
    return LabBench.from_scene(scene)


#: builders take the scene, ``nominal`` (True: the design without per-cycle variation, the host's theory) and
#: the run's fidelity (level and solver setting, :mod:`rig.fidelity`)
PLANTS: dict[str, Callable[[Scene, bool, Fidelity], Any]] = {
    "cam_bar": _cam_bar, "clutch_dynamic": _clutch_dynamic, "clutch_static": _clutch_static,
    "lab_bench": _lab_bench}


#: top-level scene sections each plant reads (the runner's own: rig.runner.config.RUNNER_SECTIONS)
PLANT_SECTIONS: dict[str, tuple[str, ...]] = {
    "cam_bar": ("plant", "speed"), "clutch_dynamic": ("plant", "motor", "load", "comparison"),
    "clutch_static": ("plant", "program"), "lab_bench": ("plant", "speed", "lab")}


def _cam_bar_drawn(scene: Scene) -> list[str]:
    from rig.plants.cam_bar.scene_io import drawn_per_cycle
    return drawn_per_cycle(scene)


#: what a plant's scene draws per cycle on the device's plant only (the host's theory is the nominal machine)
DRAWN_PER_CYCLE: dict[str, Callable[[Scene], list[str]]] = {"cam_bar": _cam_bar_drawn}


def truth_caveat(kind: str, scene: Scene) -> str:
    """What a run's recorded truth is not, for a plant of ``kind`` built from ``scene`` (empty: it is the plant's).
    The host records its theory, the nominal machine (:func:`make_plant` ``nominal``), as the truth; per-cycle
    variation acts on the device's plant only, so with it the truth is not what the measured curves came from."""
    drawn = DRAWN_PER_CYCLE.get(kind, lambda s: [])(scene)
    if not drawn:
        return ""
    return (f"/plant/truth and the plant events are the nominal machine's (the host's theory): [plant.variation] "
            f"draws {', '.join(drawn)} per cycle on the device's plant only, so the measured curves scatter about them "
            "(and a fidelity level chosen on the nominal machine may miss flank switches only a varied cycle makes)")


def make_plant(kind: str, scene: Scene, nominal: bool = False, fidelity: Fidelity | None = None) -> Any:
    """A fresh plant of ``kind`` built from ``scene`` (each call gives an independent instance);
    ``nominal`` leaves out the scene's per-cycle variation (the theory the host compares against);
    ``fidelity`` (default: :func:`rig.fidelity.choose` on the scene) sets its level and solver."""
    if not isinstance(kind, str) or kind not in PLANTS:
        raise SceneError(f"{scene.path} [scene]: plant {kind!r} is not one of {sorted(PLANTS)}")
    return PLANTS[kind](scene, nominal, choose(scene, kind) if fidelity is None else fidelity)
