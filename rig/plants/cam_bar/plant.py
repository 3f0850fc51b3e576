"""The cam-bar plant a run steps: a mechanism (its description, :mod:`.mechanism`) simulated in a setting.

Like scipy's problems and methods: :class:`PinInsertionMechanism` describes the machine (geometry, masses,
spring, contact, loads, the cam program, the optional cam drive) and carries its models at a given cam speed
(level 0 kinematics, level 1 kinetostatics; level 2 in :mod:`.level2`); :class:`Setting` says how a run
simulates it (the speed profile the cam is turned with, the level, the solver of level 2, the per-cycle
variation and its generator); :class:`CamBarPlant` composes the two behind the runner's interface
(``advance(t)`` → truth signals, ``events``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rig.motion.speed import RPM, ConstantSpeed, SpeedProfile
from rig.plants.cam_bar.level2_model import Level2Model
from rig.plants.cam_bar.timeline import Timeline
from rig.plants.cam_bar.variation import CyclePlant, CycleVariation
from rig.plants.events import Event

DEMO_SPEED = ConstantSpeed(150 * RPM)  # the demo machine's cam speed (MODELS §3.1), the default setting

if TYPE_CHECKING:
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism
    from rig.scene import Scene


@dataclass(frozen=True)
class Setting:
    """How a run simulates a mechanism: the cam turns by ``speed`` (:mod:`rig.motion.speed`; with a cam drive its
    φ0 and nominal speed start the drive); ``fidelity`` 0/1 (level-1 truth) or 2 (groove dynamics, integrated by
    ``method`` with ``method_options``: a name of :data:`rig.solvers.METHODS`, under the model assumptions
    ``level2``: :mod:`.level2_model`); ``variation`` with its generator
    ``rng`` draws every cam revolution's deviations (:mod:`.variation`; without it all cycles are identical)."""

    speed: SpeedProfile = DEMO_SPEED
    fidelity: int = 1
    method: str = "DP45"
    method_options: dict[str, float] = field(default_factory=lambda: {"rtol": 1e-7, "atol": 1e-12})
    level2: Level2Model = field(default_factory=Level2Model)
    variation: CycleVariation | None = None
    rng: np.random.Generator | None = None

    def __post_init__(self) -> None:
        if self.fidelity not in (0, 1, 2):
            raise ValueError(f"fidelity must be 0, 1 or 2, got {self.fidelity!r}")
        if self.variation is not None and self.rng is None:
            raise ValueError("variation needs a numpy Generator (rng) to draw the per-cycle deviations")


class CamBarPlant:
    """A mechanism in a setting, stepped by the runner: truth signals (SI) at increasing times and the events
    crossed (flank switches, acceleration jumps; :mod:`.timeline`)."""

    def __init__(self, mech: "PinInsertionMechanism", setting: Setting = Setting()):
        self.mech, self.setting = mech, setting
        self.cycles = None if setting.variation is None else \
            CyclePlant(mech, setting.variation, setting.rng, setting.fidelity)
        if setting.fidelity == 2:
            from rig.plants.cam_bar.level2_timeline import Level2Timeline
            self._timeline: Timeline = Level2Timeline(mech, setting.speed, self.cycles, setting.method,
                                                      setting.method_options, setting.level2)
        else:
            self._timeline = Timeline(mech, setting.speed, self.cycles)

    @classmethod
    def from_scene(cls, scene: "Scene", nominal: bool = False, **setting: Any) -> "CamBarPlant":
        """The plant of a scene ([plant], [speed], [scene] fidelity/questions/seed); ``nominal`` leaves out the
        per-cycle variation; ``setting`` overrides the scene's (e.g. ``fidelity``, ``method``)."""
        from rig.plants.cam_bar.scene_io import mechanism_from_scene, read_setting
        kw = read_setting(scene)
        if nominal:
            kw.update(variation=None, rng=None)
        return cls(mechanism_from_scene(scene), Setting(**{**kw, **setting}))

    def advance(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """Physical truth (SI) at increasing times ``t`` (s), continuing from the previous call."""
        return self._timeline.advance(np.asarray(t, dtype=float))

    @property
    def speed(self) -> SpeedProfile:
        """The speed profile the cam turns by (the setting's)."""
        return self.setting.speed

    @property
    def events(self) -> list[Event]:
        """Flank switches and acceleration-jump crossings found so far, in time order."""
        return list(self._timeline.events)
