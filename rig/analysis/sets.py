"""Per-curve verdicts, per-set process-value statistics and event counts (offline or live, plain data).

Results are device result dicts (``CurveResult.to_dict()``): ``number``, ``program``, ``ok``,
``elements`` (list of ``{name, kind, ok, reason}``) and ``process_values`` (``{name: value}``). The
recorder marks a result whose process values did not all arrive with ``complete: false`` and
``missing: [names]`` (absent keys: complete); the values that did arrive are used, the missing ones
count as absent even if a placeholder is present.
"""
from __future__ import annotations

from collections import Counter
from typing import Iterable, Mapping, Sequence

import numpy as np

from rig.analysis.capability import MIN_SET_SIZE, describe
from rig.analysis.normality import normality
from rig.analysis.trend import trend
from rig.analysis.units import DisplayUnits, Unit, display_units

Limits = Mapping[str, tuple[float | None, float | None]]


def missing_values(result: Mapping) -> list[str]:
    """Names of the process values the recorder marked as not arrived (``[]`` for a complete result)."""
    return [str(n) for n in result.get("missing", [])] if result.get("complete", True) is False else []


def curve_verdicts(results: Iterable[Mapping]) -> list[dict]:
    """OK/NOK per curve, the failing elements with their reasons, completeness (missing values) and ``memory``:
    "cut" when the curve filled the unit's curve memory and was cut there, "thinned" when it was decimated to fit,
    else ""."""
    out = []
    for r in results:
        failed = [{"name": e.get("name"), "kind": e.get("kind"), "reason": e.get("reason")}
                  for e in r.get("elements", []) if not e.get("ok", True)]
        out.append({"number": r.get("number"), "program": r.get("program"), "ok": bool(r["ok"]), "failed": failed,
                    "complete": r.get("complete", True) is not False, "missing": missing_values(r),
                    "memory": memory_note(r)})
    return out


#: what a NOK reason starts with when the curve filled the unit's curve memory and was cut there
CUT_BY_MEMORY = "the curve was cut by the full curve memory"


def cut_reason(memory: str, reason: str) -> str:
    """A (non-empty) reason of a curve whose ``memory`` note (:func:`memory_note`) is "cut", prefixed with
    :data:`CUT_BY_MEMORY`; others unchanged."""
    return f"{CUT_BY_MEMORY}; {reason}" if memory == "cut" and reason else reason


def memory_warning(verdicts: Iterable[Mapping]) -> str | None:
    """The warning (console and report) about curves cut by the unit's full curve memory; None without any."""
    cut = [v["number"] for v in verdicts if v.get("memory") == "cut"]
    if not cut:
        return None
    return (f"{len(cut)} curve(s) filled the unit's curve memory and were cut there (curve "
            f"{', '.join(map(str, cut[:10]))}{' …' if len(cut) > 10 else ''}): elements beyond the cut saw no data "
            "and their process values describe the cut curve — lower the sample rate, sample by ΔX or set the "
            "program's overflow to \"decimate\"")


def memory_note(result: Mapping) -> str:
    """"cut" (the curve filled the unit's memory and stops there), "thinned" (decimated to fit) or ""."""
    return "cut" if result.get("memory_full") else "thinned" if result.get("decimated") else ""


def incomplete_results(results: Iterable[Mapping]) -> list[dict]:
    """``{number, program, missing}`` of each result marked incomplete, in curve order."""
    return [{"number": r.get("number"), "program": r.get("program"), "missing": missing_values(r)}
            for r in results if r.get("complete", True) is False]


def curves_not_recorded(results: Iterable[Mapping], events: Iterable[Mapping]) -> list[int]:
    """Numbers of the curves the unit judged (a result) whose samples were not recorded: their frames did not all
    arrive (an ``incomplete_curve`` event), in order. A curve cut by a stop before its result is not among them."""
    judged = {r.get("number") for r in results}
    return sorted(judged & {e.get("number") for e in events if e.get("kind") == "incomplete_curve"})


def _value(result: Mapping, name: str) -> float:
    """One process value of a result (its unit), NaN when absent, null or marked missing."""
    v = result.get("process_values", {}).get(name)
    return np.nan if v is None or name in missing_values(result) else float(v)


def process_values(results: Sequence[Mapping]) -> dict[str, np.ndarray]:
    """Table of process values in curve order; a value absent from or missing in a curve is NaN."""
    names = sorted({k for r in results for k in (*r.get("process_values", {}), *missing_values(r))})
    return {n: np.array([_value(r, n) for r in results]) for n in names}


def _display(units: DisplayUnits | Mapping[str, str] | None) -> DisplayUnits:
    """Display units as given, or channel unit labels (``{"x": "m", "y": "N"}``: shown as they are)."""
    if isinstance(units, DisplayUnits):
        return units
    labels = dict(units or {})
    return DisplayUnits({ch: Unit(u, u, 1.0, u) for ch, u in labels.items()})


def counts_warning(counts: Mapping[str, int]) -> str | None:
    """Warning naming the process values and their n when not all values have the same n, else None."""
    groups: dict[int, list[str]] = {}
    for name, n in counts.items():
        groups.setdefault(n, []).append(name)
    if len(groups) < 2:
        return None
    return "process values have different n: " + "; ".join(
        f"n={n}: {', '.join(names)}" for n, names in sorted(groups.items(), key=lambda g: -g[0]))


def limits_from_program(program: Mapping | None) -> dict[str, tuple[float | None, float | None]]:
    """Process-value limits ``{name: (lower, upper)}`` from a program config's ``limits`` table."""
    limits = (program or {}).get("limits", {}) or {}
    out = {}
    for name, pair in limits.items():
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise ValueError(f"program limits: {name!r} must be [lower, upper], got {pair!r}")
        out[name] = (None if pair[0] is None else float(pair[0]), None if pair[1] is None else float(pair[1]))
    return out


def _scaled(limits: tuple[float | None, float | None] | None, u: Unit) -> tuple[float | None, float | None] | None:
    return None if limits is None else (u(limits[0]), u(limits[1]))


def _unit_slip(name: str, x: np.ndarray, limits: tuple[float | None, float | None] | None, unit: str) -> str | None:
    """A warning when every value lies outside limits of another order of magnitude (≥ 100× apart): a limit written
    in the wrong unit ("41.5 m" for mm) gives Cp/Cpk that mean nothing (Cpk −2.6e5) and nothing else says so."""
    bounds = [b for b in (limits or ()) if b is not None and b != 0.0]
    typical = float(np.median(np.abs(x))) if x.size else 0.0
    if not bounds or typical == 0.0:
        return None
    ratio = max(abs(b) for b in bounds) / typical
    lo, hi = limits
    outside = np.all(((x < lo) if lo is not None else False) | ((x > hi) if hi is not None else False))
    if not outside or 0.01 < ratio < 100.0:
        return None
    text = " … ".join("—" if b is None else f"{b:.4g}" for b in (lo, hi))
    return (f"{name}: every value lies outside its limits {text} {unit}, which are {ratio:.3g}× the measured values "
            f"(median {typical:.4g} {unit}): a limit in the wrong unit (m for mm)? Cp/Cpk against them mean nothing")


def set_statistics(results: Sequence[Mapping], limits: Limits | None = None,
                   units: DisplayUnits | Mapping[str, str] | None = None) -> dict:
    """Statistics of one set of curves (one program): counts, NOK per element, incomplete results, and
    per process value n (curves that contributed it), unit, mean/σ/min/max, ±3σ band, Cp/Cpk against
    ``limits`` (SI), normality and trend checks.

    ``units``: the display units (rig.analysis.units.DisplayUnits): every value, limit and band is given
    in its display unit (``unit``: its label, ``unit_ascii``, ``factor``: display = SI × factor), Cp and
    Cpk do not depend on it; a plain ``{"x": "m", "y": "N"}`` only labels the SI values.
    A set with fewer than 50 curves carries a warning, and so do values of different n; values with
    < 3 finite entries get only that warning.
    """
    du = _display(units)
    verdicts = curve_verdicts(results)
    nok_by_element = Counter(f["name"] for v in verdicts for f in v["failed"])
    small = (f"only {len(results)} measurements in the set (< {MIN_SET_SIZE}): statistics and capability are "
             f"indicative only") if len(results) < MIN_SET_SIZE else None
    warnings = [small] if small else []
    values = {}
    table = process_values(results)
    finite_n = {name: int(np.count_nonzero(np.isfinite(v))) for name, v in table.items()}
    unequal = counts_warning(finite_n)
    if unequal:
        warnings.append(unequal)
    few = {name: n for name, n in finite_n.items() if n < 3}
    if few:
        counts = sorted(set(few.values()))
        warnings.append(f"no set statistics (±3σ, Cp/Cpk, normality, trend) for "
                        f"{'any process value' if len(few) == len(table) else ', '.join(few)}: "
                        f"{' or '.join(map(str, counts))} finite value{'s' if counts != [1] else ''}, 3 are needed")
    for name, v in table.items():
        if name in few:
            continue
        u = du.value(name)
        shown = u(v)
        scaled = _scaled((limits or {}).get(name), u)
        entry = describe(shown, scaled, name)
        slip = _unit_slip(name, shown[np.isfinite(shown)], scaled, u.label)
        if slip:
            warnings.append(slip)
        entry["normality"] = normality(shown[np.isfinite(shown)])
        entry["trend"] = trend(shown[np.isfinite(shown)])
        entry["warnings"] = [w for w in entry["warnings"] if "measurements" not in w]
        entry.update(unit=u.label, unit_ascii=u.ascii, factor=u.factor)
        values[name] = entry
    return {"n": len(results), "ok": sum(v["ok"] for v in verdicts), "nok": sum(not v["ok"] for v in verdicts),
            "incomplete": sum(not v["complete"] for v in verdicts), "nok_by_element": dict(nok_by_element),
            "values": values, "warnings": warnings, "small_set": small}


def by_program(results: Iterable[Mapping]) -> dict[int, list[Mapping]]:
    """Results grouped by program number (ascending), curve order kept."""
    groups: dict[int, list[Mapping]] = {}
    for r in results:
        groups.setdefault(int(r.get("program", 0)), []).append(r)
    return dict(sorted(groups.items()))


def statistics_by_program(results: Sequence[Mapping], programs: Mapping[int, Mapping] | None = None,
                          units: Mapping[int, DisplayUnits] | None = None) -> dict[int, dict]:
    """:func:`set_statistics` for each program number, limits from that program's config; display units
    from ``units`` (by program) or else from the program alone (rig.analysis.units.display_units)."""
    programs, units = programs or {}, units or {}
    return {p: set_statistics(rs, limits_from_program(programs.get(p)),
                              units.get(p) or display_units(programs.get(p)))
            for p, rs in by_program(results).items()}


def event_counts(events: Iterable[Mapping]) -> dict[str, int]:
    """Number of events of each kind."""
    return dict(Counter(str(e["kind"]) for e in events))


def live_pairs_dropped(recorded: list[dict]) -> int:
    """Live pairs the unit did not send, all reasons: its cumulative count (``total`` of each report, the link
    summary's ``live_dropped``) at the latest report recorded — right also when reports between were lost (a
    damaged part of a recording); 0 without any."""
    totals = [int(e["total"]) for e in recorded if e.get("kind") == "live_dropped" and "total" in e]
    totals += [int(e["live_dropped"]) for e in recorded if e.get("kind") == "link_summary" and "live_dropped" in e]
    return max(totals, default=0)
