"""Friction in the gripper slider's guide at level 2 (scene table ``[plant.guide]``).

Level 1 prescribes the motion, so the guide friction there is Coulomb's −μ|N|·sign(ẋ_D). At level 2 the
slider moves with the follower's dynamic deviation and two models are offered:

* ``"regularised"`` (default): μ·tanh(|ṡ|/v_s)·|N| against the motion, v_s = ``friction_speed`` of
  :class:`~rig.plants.cam_bar.level2.Level2` (1 mm/s). Smooth, but it holds nothing at rest: where the roller
  floats in the groove clearance (no spring, or after a flank switch) gravity and the follower's own load make
  it creep across the gap in the dwells (at 300 rpm without the spring, 22 µm over the upper dwell).
* ``"stick"``: Karnopp's stick–slip model. Outside the band |ṡ| ≤ ``stick_speed`` it is Coulomb friction μ|N|
  against the motion. Inside the band the guide holds if the friction force needed to hold the slider (its
  acceleration relaxing the band velocity, s̈ = −ṡ/``relax_time``) is within ``static``·|N|; otherwise the
  slider slips with μ|N| against the direction it is pushed. The residual creep of a held slider is bounded by
  stick_speed·relax_time (0.1 µm with the defaults).

``static`` μ_s defaults to the sliding coefficient μ (the sources give neither; MODELS §3.1 assumes μ = 0.1).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rig.scene import Field, read_subtable

MODELS = {"regularised": 0, "stick": 1}     # codes of the compiled kernel (level2_kernel.GUIDE_MODEL)
SCHEMA = {
    "model": Field(None, "regularised", "\"regularised\" (μ·tanh(|v|/v_s)) or \"stick\" (Karnopp stick-slip)"),
    "static": Field("1", None, "static friction coefficient μ_s (default: the sliding μ)"),
    "stick_speed": Field("m/s", 1e-4, "Karnopp band: below this slider speed the guide may hold"),
    "relax_time": Field("s", 1e-3, "time constant with which a held slider's band velocity decays"),
}


@dataclass(frozen=True)
class GuideFriction:
    """Slider-guide friction model at level 2 (see the module docstring); SI units."""

    model: str = "regularised"
    static: float | None = None
    stick_speed: float = 1e-4
    relax_time: float = 1e-3

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ValueError(f"guide friction model must be one of {', '.join(MODELS)}, got {self.model!r}")
        if self.static is not None and not self.static >= 0.0:
            raise ValueError(f"guide static friction coefficient must not be negative, got {self.static!r}")
        if not (self.stick_speed > 0.0 and self.relax_time > 0.0):
            raise ValueError(f"guide stick_speed and relax_time must be positive, got {self.stick_speed!r} m/s and "
                             f"{self.relax_time!r} s")

    @property
    def code(self) -> int:
        return MODELS[self.model]

    def static_coefficient(self, mu: float) -> float:
        """μ_s, defaulting to the sliding coefficient ``mu``."""
        return mu if self.static is None else self.static


def read_guide(table: Any, where: str) -> GuideFriction:
    """A :class:`GuideFriction` from a ``[plant.guide]`` table (``None``: the regularised default)."""
    return read_subtable(table, SCHEMA, where, "guide", lambda v: GuideFriction(
        str(v["model"]), v["static"], v["stick_speed"], v["relax_time"]), GuideFriction())
