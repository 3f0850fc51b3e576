"""Statistics per program: counts (total, OK, NOK, per element) and per process value mean, standard
deviation (sample, ddof = 1), min, max, Cp and Cpk against the program's limits."""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from .results import CurveResult


def capability(values: np.ndarray, lower: float | None, upper: float | None) -> tuple[float | None, float | None]:
    """Cp = (USL - LSL) / 6σ (both limits needed), Cpk = min(USL - μ, μ - LSL) / 3σ (over the given limits)."""
    if values.size < 2 or (lower is None and upper is None):
        return None, None
    mu, sigma = float(values.mean()), float(values.std(ddof=1))
    if sigma == 0.0:
        return None, None
    cp = (upper - lower) / (6 * sigma) if lower is not None and upper is not None else None
    sides = [d for d in ((upper - mu) if upper is not None else None,
                         (mu - lower) if lower is not None else None) if d is not None]
    return cp, min(sides) / (3 * sigma)


class ProgramStatistics:
    """Accumulates the results of one program until reset."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.total = self.ok = 0
        self.elements: dict[str, dict[str, int]] = {}
        self.values: dict[str, list[float]] = {}

    def add(self, result: CurveResult) -> None:
        self.total += 1
        self.ok += int(result.ok)
        for e in result.elements:
            counts = self.elements.setdefault(e.name, {"ok": 0, "nok": 0})
            counts["ok" if e.ok else "nok"] += 1
        for name, value in result.process_values.items():
            if not math.isnan(value):
                self.values.setdefault(name, []).append(value)

    def summary(self, limits: Mapping[str, list[float | None]]) -> dict[str, Any]:
        """JSON-serialisable counts and per-value statistics."""
        values = {}
        for name, vals in sorted(self.values.items()):
            a = np.asarray(vals)
            lower, upper = limits.get(name, [None, None])
            cp, cpk = capability(a, lower, upper)
            values[name] = {"n": int(a.size), "mean": float(a.mean()),
                            "std": float(a.std(ddof=1)) if a.size > 1 else None,
                            "min": float(a.min()), "max": float(a.max()), "lower": lower, "upper": upper,
                            "cp": cp, "cpk": cpk}
        return {"total": self.total, "ok": self.ok, "nok": self.total - self.ok,
                "elements": {k: dict(v) for k, v in self.elements.items()}, "values": values}
