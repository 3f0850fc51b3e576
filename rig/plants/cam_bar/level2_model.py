"""The model assumptions of level 2 that are not the machine: how the roller contact dissipates and how the slider
guide's friction is modelled (scene: ``contact_damping`` and ``[plant.guide]`` of [plant], read into the run's
:class:`~rig.plants.cam_bar.plant.Setting`). The machine itself (geometry, masses, spring, clearances, roller
width, friction coefficient μ, cam drive) is :class:`~rig.plants.cam_bar.mechanism.PinInsertionMechanism`."""
from __future__ import annotations

from dataclasses import dataclass, field

from rig.plants.cam_bar.guide_friction import GuideFriction

CONTACT_DAMPING = 20.0      # s/m: Hunt–Crossley α, ~10 % of critical for the contact mode (assumption)


@dataclass(frozen=True)
class Level2Model:
    """Hunt–Crossley damping ``contact_damping`` α (s/m) of the roller/flank contact and the slider-guide friction
    model ``guide``."""

    contact_damping: float = CONTACT_DAMPING
    guide: GuideFriction = field(default_factory=GuideFriction)

    def __post_init__(self) -> None:
        if not self.contact_damping >= 0.0:
            raise ValueError(f"contact_damping must not be negative, got {self.contact_damping!r} s/m")
