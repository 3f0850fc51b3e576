"""Statistics per program: counts (total, OK, NOK, per element) and per process value mean, standard
deviation (sample, ddof = 1), min, max, Cp and Cpk against the program's limits.

Kept as running sums, as an instrument keeps them: a fixed few numbers per process value whatever the
number of curves (Welford's update for mean and variance, numerically stable over any run length)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from .results import CurveResult


def capability(mu: float, sigma: float | None, lower: float | None,
               upper: float | None) -> tuple[float | None, float | None]:
    """Cp = (USL - LSL) / 6σ (both limits needed), Cpk = min(USL - μ, μ - LSL) / 3σ (over the given limits)."""
    if not sigma or (lower is None and upper is None):
        return None, None
    cp = (upper - lower) / (6 * sigma) if lower is not None and upper is not None else None
    sides = [d for d in ((upper - mu) if upper is not None else None,
                         (mu - lower) if lower is not None else None) if d is not None]
    return cp, min(sides) / (3 * sigma)


@dataclass
class RunningValue:
    """Count, mean, sum of squared deviations (Welford), min and max of one process value."""

    n: int = 0
    mean: float = 0.0
    m2: float = 0.0
    min: float = math.inf
    max: float = -math.inf

    def add(self, value: float) -> None:
        self.n += 1
        delta = value - self.mean
        self.mean += delta / self.n
        self.m2 += delta * (value - self.mean)
        self.min, self.max = min(self.min, value), max(self.max, value)

    @property
    def std(self) -> float | None:
        """Sample standard deviation (ddof = 1); None below two values."""
        return math.sqrt(self.m2 / (self.n - 1)) if self.n > 1 else None


class ProgramStatistics:
    """Accumulates the results of one program until reset."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.total = self.ok = 0
        self.elements: dict[str, dict[str, int]] = {}
        self.values: dict[str, RunningValue] = {}

    def add(self, result: CurveResult) -> None:
        self.total += 1
        self.ok += int(result.ok)
        for e in result.elements:
            counts = self.elements.setdefault(e.name, {"ok": 0, "nok": 0})
            counts["ok" if e.ok else "nok"] += 1
        for name, value in result.process_values.items():
            if not math.isnan(value):
                self.values.setdefault(name, RunningValue()).add(float(value))

    def summary(self, limits: Mapping[str, list[float | None]]) -> dict[str, Any]:
        """JSON-serialisable counts and per-value statistics."""
        values = {}
        for name, v in sorted(self.values.items()):
            lower, upper = limits.get(name, [None, None])
            cp, cpk = capability(v.mean, v.std, lower, upper)
            values[name] = {"n": v.n, "mean": v.mean, "std": v.std, "min": v.min, "max": v.max,
                            "lower": lower, "upper": upper, "cp": cp, "cpk": cpk}
        return {"total": self.total, "ok": self.ok, "nok": self.total - self.ok,
                "elements": {k: dict(v) for k, v in self.elements.items()}, "values": values}
