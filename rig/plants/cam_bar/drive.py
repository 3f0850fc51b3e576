"""Cam-shaft drive at level 2 (scene table ``[plant.drive]``): the cam speed as the machine makes it.

Off by default: the cam turns by the scene's speed profile (:mod:`rig.motion.speed`). With a drive the cam
angle and speed are states of level 2, driven by an asynchronous motor through a torsionally compliant shaft
(MODELS §3.4 "optional cam-speed variation (motor characteristic, §4.3)"; the thesis notes the real cam speed
was not constant and the original experiment had no speed measurement):

* motor (linear working part of its characteristic, referred to the cam shaft through the gear, bounded by its
  pull-out torque): M_m = b·(ω_s − ω_m) clipped to ±M_max, ω_s the synchronous speed (default: the speed
  profile's nominal speed), b the slope (N·m·s/rad); rotor + gear inertia J_m;
* shaft: torque T_s = k·(φ_m − φ) + c·(ω_m − ω) (k N·m/rad, c N·m·s/rad);
* cam: J_c·ω̇ = T_s − T_d, T_d the drive torque the roller contact takes from the cam (level 2's).

States appended after (e, τ·ė): (φ, ω, φ_m, ω_m). Start ``"rest"``: both at rest at the speed profile's φ0;
``"running"``: both at the speed profile's nominal speed. The sources give none of these numbers; the defaults
are assumptions for a 0.37 kW, 1400 rpm motor geared down to the cam (i ≈ 9): rated torque at the cam 24 N·m
at 5 % slip (b = 29 N·m·s/rad), pull-out torque 2.5× rated (60 N·m), rotor and gear 0.07 kg·m² at the cam, a cam
plate of 0.01 kg·m², a Ø20 mm × 300 mm steel shaft (4190 N·m/rad), 5 % damping of the shaft mode.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rig.scene import Field, read_subtable

STARTS = {"rest": 0, "running": 1}
SCHEMA = {
    "synchronous_speed": Field("rad/s", None, "motor synchronous speed at the cam shaft (default: [speed])"),
    "slope": Field("N*m*s/rad", 29.0, "slope b of the motor's torque-speed line at the cam shaft"),
    "max_torque": Field("N*m", 60.0, "pull-out torque bounding the line, at the cam shaft"),
    "motor_inertia": Field("kg*m^2", 0.07, "rotor and gear inertia referred to the cam shaft"),
    "cam_inertia": Field("kg*m^2", 0.01, "cam plate and shaft inertia"),
    "shaft_stiffness": Field("N*m/rad", 4190.0, "torsional stiffness between gear and cam"),
    "shaft_damping": Field("N*m*s/rad", 0.6, "torsional damping between gear and cam"),
    "start": Field(None, "rest", "\"rest\" (start-up from standstill) or \"running\" (at the nominal speed)"),
}


@dataclass(frozen=True)
class CamDrive:
    """Motor, shaft and cam inertia of the cam drive (SI; see the module docstring)."""

    synchronous_speed: float | None = None
    slope: float = 29.0
    max_torque: float = 60.0
    motor_inertia: float = 0.07
    cam_inertia: float = 0.01
    shaft_stiffness: float = 4190.0
    shaft_damping: float = 0.6
    start: str = "rest"

    def __post_init__(self) -> None:
        if self.synchronous_speed is not None and not self.synchronous_speed > 0.0:
            raise ValueError(f"cam drive: synchronous_speed must be positive, got {self.synchronous_speed!r}")
        for name in ("slope", "max_torque", "motor_inertia", "cam_inertia", "shaft_stiffness"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"cam drive: {name} must be positive, got {getattr(self, name)!r}")
        if not self.shaft_damping >= 0.0:
            raise ValueError(f"cam drive: shaft_damping must not be negative, got {self.shaft_damping!r}")
        if self.start not in STARTS:
            raise ValueError(f"cam drive: start must be one of {', '.join(STARTS)}, got {self.start!r}")

    def synchronous(self, nominal: float) -> float:
        """ω_s (rad/s), defaulting to the speed profile's ``nominal`` speed."""
        return nominal if self.synchronous_speed is None else self.synchronous_speed


def read_drive(table: Any, where: str) -> CamDrive | None:
    """A :class:`CamDrive` from a ``[plant.drive]`` table (``None``: no drive, the speed profile turns the cam)."""
    return read_subtable(table, SCHEMA, where, "drive", lambda v: CamDrive(**{**v, "start": str(v["start"])}), None)
