"""Per-curve verdicts, per-set process-value statistics and event counts (offline or live, plain data).

Results are device result dicts (``CurveResult.to_dict()``): ``number``, ``program``, ``ok``,
``elements`` (list of ``{name, kind, ok, reason}``) and ``process_values`` (``{name: value}``).
"""
from __future__ import annotations

from collections import Counter
from typing import Iterable, Mapping, Sequence

import numpy as np

from rig.analysis.capability import MIN_SET_SIZE, describe
from rig.analysis.normality import normality
from rig.analysis.trend import trend

Limits = Mapping[str, tuple[float | None, float | None]]


def curve_verdicts(results: Iterable[Mapping]) -> list[dict]:
    """OK/NOK per curve and the failing elements with their reasons."""
    out = []
    for r in results:
        failed = [{"name": e.get("name"), "kind": e.get("kind"), "reason": e.get("reason")}
                  for e in r.get("elements", []) if not e.get("ok", True)]
        out.append({"number": r.get("number"), "program": r.get("program"), "ok": bool(r["ok"]), "failed": failed})
    return out


def process_values(results: Sequence[Mapping]) -> dict[str, np.ndarray]:
    """Table of process values in curve order; a value missing from a curve is NaN."""
    names = sorted({k for r in results for k in r.get("process_values", {})})
    return {n: np.array([np.nan if (v := r.get("process_values", {}).get(n)) is None else float(v)
                         for r in results]) for n in names}


def limits_from_program(program: Mapping | None) -> dict[str, tuple[float | None, float | None]]:
    """Process-value limits ``{name: (lower, upper)}`` from a program config's ``limits`` table."""
    limits = (program or {}).get("limits", {}) or {}
    out = {}
    for name, pair in limits.items():
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise ValueError(f"program limits: {name!r} must be [lower, upper], got {pair!r}")
        out[name] = (None if pair[0] is None else float(pair[0]), None if pair[1] is None else float(pair[1]))
    return out


def set_statistics(results: Sequence[Mapping], limits: Limits | None = None) -> dict:
    """Statistics of one set of curves (one program): counts, NOK per element, and per process value
    mean/σ/min/max, ±3σ band, Cp/Cpk against ``limits``, normality and trend checks.

    A set with fewer than 50 curves carries a warning; values with < 3 finite entries get only counts.
    """
    verdicts = curve_verdicts(results)
    nok_by_element = Counter(f["name"] for v in verdicts for f in v["failed"])
    warnings = []
    if len(results) < MIN_SET_SIZE:
        warnings.append(f"only {len(results)} measurements in the set (< {MIN_SET_SIZE}): "
                        f"statistics and capability are indicative only")
    values = {}
    for name, v in process_values(results).items():
        finite = v[np.isfinite(v)]
        if finite.size < 3:
            warnings.append(f"{name}: only {finite.size} finite values, no statistics")
            continue
        entry = describe(v, (limits or {}).get(name), name)
        entry["normality"] = normality(finite)
        entry["trend"] = trend(finite)
        entry["warnings"] = [w for w in entry["warnings"] if "measurements" not in w]
        values[name] = entry
    return {"n": len(results), "ok": sum(v["ok"] for v in verdicts), "nok": sum(not v["ok"] for v in verdicts),
            "nok_by_element": dict(nok_by_element), "values": values, "warnings": warnings}


def statistics_by_program(results: Sequence[Mapping], programs: Mapping[int, Mapping] | None = None) -> dict[int, dict]:
    """:func:`set_statistics` for each program number, limits from that program's config."""
    groups: dict[int, list[Mapping]] = {}
    for r in results:
        groups.setdefault(int(r.get("program", 0)), []).append(r)
    return {p: set_statistics(rs, limits_from_program((programs or {}).get(p))) for p, rs in sorted(groups.items())}


def event_counts(events: Iterable[Mapping]) -> dict[str, int]:
    """Number of events of each kind."""
    return dict(Counter(str(e["kind"]) for e in events))
