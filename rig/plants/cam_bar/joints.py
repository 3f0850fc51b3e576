"""Clearances of the rod's pin joints at level 2 — a reduced model (scene table ``[plant.joints]``).

The rod (4) is pinned to the follower at C and to the gripper slider at D. Each pin sits in its bore with a
diametral clearance; the sources give none (assumption: a fit like H7/g6 on an 8 mm pin leaves 5…29 µm). Along
the rod the two clearances act in series: in tension the pins bear on the far sides of their bores and the rod is
effectively longer by half the summed clearance, in compression shorter by as much. When the rod force changes
sign the gripper therefore jumps by the summed clearance times ∂s/∂l4 = −1/cos ϑ (≈ 1, the rod lies nearly
along the guide) — the "clearances not taken up in the same direction" of the thesis.

Reduced model (not extra degrees of freedom): the take-up follows the rod tension T at the sensor section
instantly, Δl = ½(c_C + c_D)·tanh(T/F_b), F_b = ``force_band`` (a stand-in for the pins' contact compliance);
the gripper moves by Δs = −Δl/cos ϑ on top of level 2's motion. Neglected: the slider's inertia across the gap
(impacts in the pins) and the feedback of that motion on the follower and the groove contact — first order in
c_j/stroke ≈ 1e-3.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rig.scene import Field, read_subtable

SCHEMA = {
    "follower": Field("m", 0.0, "diametral clearance of the rod's pin at the follower (C)"),
    "slider": Field("m", 0.0, "diametral clearance of the rod's pin at the gripper slider (D)"),
    "force_band": Field("N", 1.0, "rod force over which the pins move across their clearance"),
}


@dataclass(frozen=True)
class JointClearance:
    """Diametral clearances of the rod's pins (m) and the take-up force band (N)."""

    follower: float = 0.0
    slider: float = 0.0
    force_band: float = 1.0

    def __post_init__(self) -> None:
        if not (self.follower >= 0.0 and self.slider >= 0.0 and self.force_band > 0.0):
            raise ValueError(f"joint clearances must not be negative and force_band must be positive, got "
                             f"{self.follower!r} m, {self.slider!r} m, {self.force_band!r} N")

    def stroke_offset(self, tension: np.ndarray, cos_theta: np.ndarray) -> np.ndarray:
        """Δs (m) of the gripper for rod tension ``tension`` (N, > 0 pulling) and rod direction cos ϑ."""
        dl = 0.5 * (self.follower + self.slider) * np.tanh(np.asarray(tension, dtype=float) / self.force_band)
        return -dl / np.asarray(cos_theta, dtype=float)


def read_joints(table: Any, where: str) -> JointClearance | None:
    """A :class:`JointClearance` from a ``[plant.joints]`` table (``None``: rigid joints)."""
    return read_subtable(table, SCHEMA, where, "joints", lambda v: JointClearance(**v), None)
