"""Design limits of cam mechanisms (MODELS §2): permissible pressure angle and the undercut radius."""
from __future__ import annotations

from math import radians

from rig.mechanisms.checks import positive

UNDERCUT_FACTOR = 0.7  # the pitch curve must keep ρ ≥ r_R/0.7 (MODELS §2)


def pressure_angle_limit(follower: str, high_speed: bool = True) -> float:
    """Permissible pressure angle (rad): 30° for a translating follower or an oscillating one at high speed,
    45° for an oscillating follower at low speed."""
    if follower == "translating":
        return radians(30.0)
    if follower == "oscillating":
        return radians(30.0 if high_speed else 45.0)
    raise ValueError(f"follower must be 'translating' or 'oscillating', got {follower!r}")


def undercut_radius(roller_radius: float) -> float:
    """Smallest admissible |ρ| of the pitch curve (m) for a roller of radius ``roller_radius`` (m): r_R/0.7."""
    return positive(roller_radius, "roller radius (m)") / UNDERCUT_FACTOR
