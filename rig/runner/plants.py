"""Plants by name, as a scene's ``[scene] plant`` selects them (like python-can interfaces by name)."""
from __future__ import annotations

from typing import Any, Callable

from rig.scene import Scene, SceneError


def _cam_bar(scene: Scene) -> Any:
    from rig.plants.cam_bar import PinInsertionMechanism
    return PinInsertionMechanism.from_scene(scene)


def _clutch_dynamic(scene: Scene) -> Any:
    from rig.plants.clutch.stand import ClutchStand
    return ClutchStand.from_scene(scene)


def _clutch_static(scene: Scene) -> Any:
    from rig.plants.clutch.static_rig import rig_from_scene
    return rig_from_scene(scene)


PLANTS: dict[str, Callable[[Scene], Any]] = {
    "cam_bar": _cam_bar, "clutch_dynamic": _clutch_dynamic, "clutch_static": _clutch_static}


def make_plant(kind: str, scene: Scene) -> Any:
    """A fresh plant of ``kind`` built from ``scene`` (each call gives an independent instance)."""
    if kind not in PLANTS:
        raise SceneError(f"{scene.path} [scene]: plant {kind!r} is not one of {sorted(PLANTS)}")
    return PLANTS[kind](scene)
