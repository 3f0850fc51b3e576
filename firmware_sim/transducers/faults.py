"""Time-scheduled fault injection shared by all transducers."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from rig.scene import Field
from rig.units import to_si


@dataclass(frozen=True)
class Fault:
    """One injected fault: active for ``at <= t < until`` [s] with its parameters."""

    kind: str
    at: float
    until: float
    params: dict[str, Any] = field(default_factory=dict)


class FaultSchedule:
    """The faults injected into one transducer; ``known`` maps fault kind -> {parameter: Field}."""

    def __init__(self, owner: str, known: Mapping[str, Mapping[str, Field]]) -> None:
        self.owner = owner
        self.known = known
        self.faults: list[Fault] = []

    def inject(self, kind: str, at: float = 0.0, until: float = math.inf, *, units_required: bool = False,
               **params: Any) -> Fault:
        """Schedule ``kind``; parameters are SI numbers or quantity strings (``width="3 us"``; ``units_required``: a
        bare number for a parameter with a unit is refused, as in a scene).

        Unknown kinds or parameters, wrong units and values outside a parameter's range (a probability of 2, a
        negative rate, NaN) raise ``ValueError`` naming them.
        """
        if kind not in self.known:
            raise ValueError(f"{self.owner}: unknown fault {kind!r}; this transducer knows {sorted(self.known)}")
        fields = self.known[kind]
        unknown = set(params) - set(fields)
        if unknown:
            raise ValueError(f"{self.owner}: fault {kind!r} has no parameter(s) {sorted(unknown)}; "
                             f"known: {sorted(fields) or 'none'}")
        if not (math.isfinite(at) and until > at):
            raise ValueError(f"{self.owner}: fault {kind!r} needs a finite start time before its end, "
                             f"got at={at!r} s, until={until!r} s")
        values = {name: f.default for name, f in fields.items()}
        for name, v in params.items():
            f, what = fields[name], f"{self.owner}: fault {kind!r} parameter {name!r}"
            if isinstance(v, str):
                value = to_si(v, f.unit, what=what)
            elif isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ValueError(f"{what}: expected a number or a quantity, got {v!r}")
            elif units_required and f.unit not in (None, "1"):
                raise ValueError(f'{what}: {v!r} has no unit; write it with its unit, e.g. "{v} {f.unit}"')
            else:
                value = float(v)
            problem = "must be a finite number" if not math.isfinite(value) else f.out_of_range(value)
            if problem:
                raise ValueError(f"{what} {problem}, got {v!r}")
            values[name] = value
        fault = Fault(kind, float(at), float(until), values)
        self.faults.append(fault)
        return fault

    def clear(self) -> None:
        """Remove all scheduled faults."""
        self.faults.clear()

    def windows(self, kind: str, t: np.ndarray) -> list[tuple[np.ndarray, dict[str, Any]]]:
        """For each scheduled fault of ``kind`` overlapping ``t``: (mask of active samples, parameters)."""
        out = []
        for f in self.faults:
            if f.kind == kind:
                mask = (t >= f.at) & (t < f.until)
                if mask.any():
                    out.append((mask, f.params))
        return out
