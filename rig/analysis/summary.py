"""One-call analysis of a recording (or an in-memory Recording built live)."""
from __future__ import annotations

from rig.analysis.device import device_agreement, final_snapshot
from rig.analysis.lag import compare_theory
from rig.analysis.sets import (by_program, curve_verdicts, curves_not_recorded, event_counts, incomplete_results,
                               live_pairs_dropped, statistics_by_program)
from rig.analysis.units import DisplayUnits, recording_units
from rig.recorder import CurveRecord, Recording


def theory_comparison(curve: CurveRecord) -> list[dict]:
    """:func:`compare_theory` for each signal (``y``, ``x``) the curve's theory provides."""
    out = []
    for name in ("y", "x"):
        if name in curve.theory:
            try:
                res = compare_theory(curve.t, getattr(curve, name), curve.theory, name, angle=curve.angle)
            except ValueError as exc:
                res = {"signal": name, "error": str(exc)}
            out.append({"curve": curve.number, **res})
    return out


def program_units(rec: Recording) -> dict[int, DisplayUnits]:
    """Display units of every program the recording has results, curves or a configuration of."""
    numbers = {int(r.get("program", 0)) for r in rec.results} | {c.program for c in rec.curves} | set(rec.programs)
    return {p: recording_units(rec, p) for p in sorted(numbers)}


def program_sets(rec: Recording, units: dict[int, DisplayUnits] | None = None) -> dict[int, dict]:
    """Set statistics per program (in display units), each with its ``device_agreement`` against the
    device's final snapshot (in SI, as the device keeps it)."""
    sets = statistics_by_program(rec.results, rec.programs, units if units is not None else program_units(rec))
    for program, results in by_program(rec.results).items():
        agreement = device_agreement(results, final_snapshot(rec.statistics, program))
        if not rec.statistics and rec.serial_link_off and agreement["reason"]:
            agreement["reason"] = ("the scene's serial link is off ([links.serial] enabled = false): the host read no "
                                   "statistics back from the device")
        elif not rec.statistics and not rec.complete and agreement["reason"]:     # none read, the run ended early
            agreement["reason"] = ("the host reads the device's statistics at the end of a run, and this one did not "
                                   "end normally (killed, cut or interrupted): none were recorded")
        sets[program]["device_agreement"] = agreement
    return sets


def analyse(rec: Recording) -> dict:
    """Verdicts per curve, incomplete results, judged curves not recorded, display units per program, statistics per
    program (with the device comparison), theory vs measurement per curve, event counts, live pairs the unit did not
    send (all reasons)."""
    units = program_units(rec)
    return {
        "verdicts": curve_verdicts(rec.results),
        "incomplete": incomplete_results(rec.results),
        "not_recorded": curves_not_recorded(rec.results, rec.events),
        "units": units,
        "sets": program_sets(rec, units),
        "theory": [row for c in rec.curves for row in theory_comparison(c)],
        "events": event_counts(rec.events),
        "live_pairs_dropped": live_pairs_dropped(rec.events),
        "device_statistics": rec.statistics[-1] if rec.statistics else None,
    }
