"""Clearances of the rod's pin joints at level 2 as degrees of freedom (scene table ``[plant.joints]``).

The rod (4) is pinned to the follower at C and to the gripper slider at D. Each pin sits in its bore with a
diametral clearance; the sources give none (assumption: a fit like H7/g6 on an 8 mm pin leaves 5…29 µm). Along
the rod the two clearances act in series: the distance |CD| may lie anywhere in l4 ± ½(c_C + c_D) without a
force ("free play"); beyond it the pins bear on their bores and the rod force follows a linear Hunt–Crossley law
T = k·δ·(1 + α·δ̇) on the penetration δ past the free play (tension > 0 when |CD| > l4 + play, compression
beyond the other side, never pulling the pins back across the gap).

With joints the slider is a body of its own: level 2 gains the state (z, τ·ż), z = s − s_r(ψ) the slider's
stroke s against the stroke s_r(ψ) a rigid rod would give at the follower's actual angle ψ. The rod is lumped
into its two pins (½m4 at C moves with the follower, ½m4 at D with the slider; the rod's own rotary inertia
J4 − m4·l4²/4 about its centre and the rod's axial compliance beside the pins' are neglected), so its force is
the same along it. The sensor reads T (plus its preload).

Assumptions (no source gives them): k = 4e7 N/m — two Ø8 × 10 mm steel pins in line contact (Palmgren,
≈ 2e8 N/m each at 30 N) in series with a Ø6 × 100 mm steel rod (EA/l ≈ 6e7 N/m); α = 20 s/m as the roller
contact (≈ 5 % of critical for the slider on the pins at 30 N).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rig.scene import Field, read_subtable

#: N/m: the stiffest rod the model takes — a steel bar of 1 m² section 0.2 m long (E·A/l); 1e15 N/m hung the run in
#: its solver-setting check, whose explicit reference then needs steps of nanoseconds (an audit)
STIFFEST = 1e12

SCHEMA = {
    "follower": Field("m", 0.0, "diametral clearance of the rod's pin at the follower (C)", minimum=0.0),
    "slider": Field("m", 0.0, "diametral clearance of the rod's pin at the gripper slider (D)", minimum=0.0),
    "stiffness": Field("N/m", 4e7, "axial stiffness of the rod with both pins bearing", positive=True,
                       maximum=STIFFEST, says="must be positive and at most 1e12 N/m (a steel bar of 1 m² section "
                                              "0.2 m long)"),
    "damping": Field("s/m", 20.0, "Hunt-Crossley damping alpha of the pins' contact", minimum=0.0),
}


@dataclass(frozen=True)
class JointClearance:
    """Diametral clearances of the rod's pins (m), the rod's axial stiffness with the pins bearing (N/m) and the
    pins' Hunt–Crossley damping α (s/m)."""

    follower: float = 0.0
    slider: float = 0.0
    stiffness: float = 4e7
    damping: float = 20.0

    def __post_init__(self) -> None:
        if not (self.follower >= 0.0 and self.slider >= 0.0 and self.stiffness > 0.0 and self.damping >= 0.0):
            raise ValueError(f"joint clearances must not be negative, the stiffness must be positive and the damping "
                             f"not negative, got {self.follower!r} m, {self.slider!r} m, {self.stiffness!r} N/m, "
                             f"{self.damping!r} s/m")

    @property
    def play(self) -> float:
        """Half the free play of |CD| about l4 (m): ½(c_C + c_D)."""
        return 0.5 * (self.follower + self.slider)

    def stretch(self, tension: float) -> float:
        """Static |CD| − l4 (m) under rod tension ``tension`` (N, > 0 pulling)."""
        if tension == 0.0:
            return 0.0
        return math.copysign(self.play + abs(tension) / self.stiffness, tension)


def read_joints(table: Any, where: str) -> JointClearance | None:
    """A :class:`JointClearance` from a ``[plant.joints]`` table (``None``: rigid joints)."""
    return read_subtable(table, SCHEMA, where, "joints", lambda v: JointClearance(**v), None)
