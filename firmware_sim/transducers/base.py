"""What every simulated transducer has: its SI description, random generator, switches and faults."""
from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from rig.scene import Field

from .faults import Fault, FaultSchedule

# description keys every transducer accepts (free text, no effect on behaviour)
DESCRIPTION_FIELDS: dict[str, Field] = {
    "model": Field(None, "", "manufacturer/type the description imitates"),
    "notes": Field(None, "", "sources and assumptions"),
}


class Transducer:
    """Base of the transducer classes: validated description ``p`` (SI), ``rng``, ``name``, switches, faults.

    Subclasses set ``QUANTITY_UNIT``, ``SCHEMA`` (including :data:`DESCRIPTION_FIELDS`) and ``FAULTS``;
    :func:`.description.register` sets ``TYPE``.
    """

    QUANTITY_UNIT: ClassVar[str]
    SCHEMA: ClassVar[dict[str, Field]]
    FAULTS: ClassVar[dict[str, dict[str, Field]]]
    TYPE: ClassVar[str]

    def __init__(self, params: dict[str, Any], rng: np.random.Generator, name: str = "",
                 errors_enabled: bool = True, dynamics_enabled: bool = True) -> None:
        self.p = params
        self.name = name or self.TYPE
        self.rng = rng
        self.errors_enabled = bool(errors_enabled)
        self.dynamics_enabled = bool(dynamics_enabled)
        self.faults = FaultSchedule(self.name, self.FAULTS)

    def inject(self, fault: str, at: float = 0.0, until: float = math.inf, *, units_required: bool = False,
               **params: Any) -> Fault:
        """Schedule a fault (one of ``FAULTS``) active for ``at <= t < until`` [s] (:meth:`FaultSchedule.inject`)."""
        return self.faults.inject(fault, at, until, units_required=units_required, **params)

    def _positive(self, key: str, unit: str) -> float:
        """The description value ``key`` (SI, ``unit`` for the message); ``ValueError`` unless it is > 0."""
        value = self.p[key]
        if not value > 0.0:
            raise ValueError(f"{self.name}: {key} must be positive, got {value} {unit}")
        return value

    def _samples(self, t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Times ``t`` [s] and quantity ``q`` (SI) as 1-D float arrays of equal length."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        q = np.atleast_1d(np.asarray(q, dtype=float))
        if t.shape != q.shape or t.ndim != 1:
            raise ValueError(f"{self.name}: t and q must be 1-D arrays of equal length, got {t.shape} and {q.shape}")
        return t, q
