"""The pin's force–travel law over the pierce travel (scene table ``[plant.insertion]``).

The thesis gives one number: the force for the pin to pierce the housing, F_c = 40 N (measured), acting
over the end of the rise (MODELS §3.1: from "pin pierces housing" to the end of the rise, window length
``F_c_travel``). It gives no force–travel curve. A piercing force builds up while the pin tip penetrates
and falls once it has broken through; we take the smooth bump (``law = "bump"``, the default)

    F(x) = F_c · S(x / (a·T)) · S((T − x) / (b·T)),   x = s − (s_top − T) ∈ [0, T],

T = ``F_c_travel``, S(u) = 10u³ − 15u⁴ + 6u⁵ clipped to [0, 1] (the 3-4-5 law: F, dF/ds and d²F/ds² continuous),
a = ``build_up`` and b = ``release`` fractions of T (defaults ½ and ½: F peaks at F_c half-way). The shape and
fractions are assumptions (scene keys). ``law = "step"`` is the window of constant F_c (the thesis's
formulation; at level 2 its steps ring the roller contact ±100 N at 656 Hz).

The force acts on the slider along +x (against the rise) only while the cam is in its rise: level 1 keys it on
s' > 0, level 2 on "φ in a rise segment" and the actual stroke.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rig.scene import Field, read_subtable

LAWS = {"bump": 0, "step": 1}      # codes of the compiled kernel (level2_kernel.INS_LAW)
SCHEMA = {
    "law": Field(None, "bump", "force-travel law: \"bump\" (smooth, default) or \"step\" (constant F_c)"),
    "build_up": Field("1", 0.5, "fraction of F_c_travel over which the force builds up (bump)"),
    "release": Field("1", 0.5, "fraction of F_c_travel before the top over which it falls to zero (bump)"),
}


def smoothstep(u: np.ndarray) -> np.ndarray:
    """3-4-5 step: 0 for u ≤ 0, 1 for u ≥ 1, C² in between."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (10.0 + u * (-15.0 + 6.0 * u))


@dataclass(frozen=True)
class InsertionLaw:
    """Shape of the insertion force over the pierce travel: ``law`` ("bump" or "step"), and for the bump the
    fractions ``build_up`` and ``release`` of the travel (each in (0, 1], summing to ≤ 1)."""

    law: str = "bump"
    build_up: float = 0.5
    release: float = 0.5

    def __post_init__(self) -> None:
        if self.law not in LAWS:
            raise ValueError(f"insertion law must be one of {', '.join(LAWS)}, got {self.law!r}")
        if not (0.0 < self.build_up <= 1.0 and 0.0 < self.release <= 1.0
                and self.build_up + self.release <= 1.0 + 1e-12):
            raise ValueError(f"insertion build_up and release must be fractions in (0, 1] summing to at most 1, "
                             f"got {self.build_up!r} and {self.release!r}")

    @property
    def code(self) -> int:
        return LAWS[self.law]

    def weight(self, x: np.ndarray, travel: float) -> np.ndarray:
        """F/F_c at pierce travel ``x`` (m, 0 where the window opens) for window length ``travel`` (m)."""
        x = np.asarray(x, dtype=float)
        inside = x >= 0.0
        if self.law == "step" or travel <= 0.0:
            return np.where(inside, 1.0, 0.0)
        w = smoothstep(x / (self.build_up * travel)) * smoothstep((travel - x) / (self.release * travel))
        return np.where(inside, w, 0.0)

    def force(self, s: np.ndarray, top: float, travel: float, f_c: float) -> np.ndarray:
        """F (N) at stroke ``s`` (m) below the top of the rise ``top`` (m), window ``travel`` (m), peak ``f_c``."""
        return f_c * self.weight(np.asarray(s, dtype=float) - (top - travel), travel)


def read_insertion(table: Any, where: str) -> InsertionLaw:
    """An :class:`InsertionLaw` from a ``[plant.insertion]`` table (``None``: the default bump)."""
    return read_subtable(table, SCHEMA, where, "insertion",
                         lambda v: InsertionLaw(str(v["law"]), v["build_up"], v["release"]), InsertionLaw())
