"""Results of one curve: per-element verdicts, process values, global OK."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .curve import Curve, nan_to_none


@dataclass(frozen=True)
class ElementResult:
    """Verdict of one evaluation element; ``reason`` (which rule failed and where) is empty when it passed;
    ``at``: the (x, y) where it failed, when there is such a point (not part of :meth:`to_dict`)."""

    name: str
    kind: str
    ok: bool
    reason: str = ""
    at: tuple[float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "kind": self.kind, "ok": self.ok, "reason": self.reason}


@dataclass
class CurveResult:
    """One measurement: number (counts from 1), program, global OK, elements, process values, curve."""

    number: int
    program: int
    ok: bool
    elements: list[ElementResult]
    process_values: dict[str, float]
    curve: Curve
    t_start: float
    t_end: float

    def to_dict(self, include_curve: bool = True) -> dict[str, Any]:
        """JSON-serialisable form (undefined process values as null)."""
        out = {"number": self.number, "program": self.program, "ok": self.ok,
               "elements": [e.to_dict() for e in self.elements],
               "process_values": {k: nan_to_none(v) for k, v in self.process_values.items()},
               "t_start": self.t_start, "t_end": self.t_end, **self.curve.flags}
        if include_curve:
            out["curve"] = self.curve.to_dict()
        return out
