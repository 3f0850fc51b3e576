"""HTML or Markdown report of a recording, laid out like an instrument's: the verdict first, details after.

1. **Verdict**: n, OK/NOK, Cp/Cpk of every process value that has limits (limits and values in display
   units), what failed and why (each NOK curve's failed elements with their reasons), warnings.
2. **NOK curves**: one figure per NOK curve (up to ``nok_plots``, the count says how many of how many),
   the failed elements drawn red and thick, labelled, and the points where they failed marked.
3. Details: process values (table, histograms, host vs device statistics), all curves overlaid (NOK red on
   top), individual OK curves only on demand (``ok_plots``), extension sections (clutch), theory vs
   measurement, events, plant truth (one axis per unit and scale), the recording, exports (CSV).

Numbers are shown in the display units (rig.analysis.units). A *section* is a function
``(ctx: ReportContext) -> list[Block]``; it returns ``[]`` when it does not apply (e.g. no curves).
The sections of the default report are listed here (the clutch, stand-comparison, static-clutch and lab sections come
from their own modules); :func:`register_section` adds others (before the closing details).
"""
from __future__ import annotations

import html
import math
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from rig.analysis import plots
from rig.analysis.capability import MIN_SET_SIZE, index_text
from rig.analysis.clutch_report import clutch_section, comparison_section
from rig.analysis.device import agreement_text
from rig.analysis.event_text import event_details
from rig.analysis.export import export_curves, export_events, export_results, export_series
from rig.analysis.lab_report import lab_section
from rig.analysis.normality import ANDERSON_P
from rig.analysis.numbers import decimals, fixed, row_places
from rig.analysis.report_blocks import (NOK_PLOTS, Banner, Block, Figure, Heading, Link, ReportContext, Section, Table,
                                        Text, fmt)
from rig.analysis.sets import by_program, cut_reason, live_pairs_dropped, memory_warning, process_values
from rig.analysis.static_clutch_report import static_clutch_section
from rig.analysis.summary import analyse
from rig.analysis.trend import drift_text
from rig.analysis.units import DisplayUnits
from rig.outputs import clear_previous, list_written
from rig.recorder import Recording, read_recording
from rig.recorder.completeness import file_problem, losses
from rig.recorder.reader import interruption_text
from rig.recorder.schemas import TRUTH
from rig.recorder.series import KEPT_BYTES, held_text

MANIFEST = ".mechrig-report"    # in a report directory: the files the last report wrote there
NOK_ROWS = 60         # rows of the "what failed and why" table (all of them are in results.csv)
CAPABLE, MARGINAL = 1.33, 1.0


SECTIONS: list[tuple[str, Section]] = []
TAIL = ("theory", "events", "truth", "overview", "exports")     # closing details: extensions go before them


def register_section(name: str, section: Section) -> None:
    """Add a section to the default report (replacing one of the same name): before the closing details
    (:data:`TAIL`), or at its place in the tail for those."""
    rest = [(n, s) for n, s in SECTIONS if n != name]
    if name in TAIL:
        SECTIONS[:] = rest + [(name, section)]
        return
    at = next((i for i, (n, _) in enumerate(rest) if n in TAIL), len(rest))
    SECTIONS[:] = rest[:at] + [(name, section)] + rest[at:]


def _num(v: float | None, digits: int = 4) -> str:
    return "—" if v is None or v != v else f"{v:.{digits}g}"


# -- 1. the verdict --------------------------------------------------------------------------------
def _outside(v: dict) -> bool:
    """Every value beyond a limit: no spread and the one value outside (σ = 0 gives Cpk = −∞)."""
    return not v["spread"] and v["cpk"] is not None and v["cpk"] < 0


def _capability(v: dict) -> str:
    if v["cpk"] is None:
        return "—"
    if _outside(v):
        return "NOT capable: every value outside the limits"
    if not v["spread"]:
        return "n/a: no spread (every value the same, at the instrument's resolution)"
    reads = "capable" if v["cpk"] >= CAPABLE else "marginal" if v["cpk"] >= MARGINAL else "NOT capable"
    if v.get("n", MIN_SET_SIZE) < MIN_SET_SIZE and reads != "NOT capable":    # (5 values read "capable" at Cpk 45
        return f"not judged: n = {v['n']} < {MIN_SET_SIZE} (reads {reads})"     # with σ the noise's)
    if v.get("n", MIN_SET_SIZE) < MIN_SET_SIZE:     # a warning is not held back; the page says why it differs
        return f"NOT capable (n = {v['n']} < {MIN_SET_SIZE}: indicative only; a warning is not held back)"
    return reads


def _indices(v: dict) -> list[Any]:
    """Cp and Cpk cells: n/a without spread (σ = 0 makes them infinite, which says nothing), except a Cpk of −∞:
    every value outside a limit."""
    if v["spread"]:
        return [index_text(v["cp"]), index_text(v["cpk"])]
    return ["n/a", "−∞" if _outside(v) else "n/a"]


def _limits_text(v: dict) -> str:
    lsl, usl, unit = v.get("lsl"), v.get("usl"), v.get("unit", "")
    if lsl is not None and usl is not None:
        text = f"{_num(lsl)} … {_num(usl)}"
    elif lsl is not None:
        text = f"≥ {_num(lsl)}"
    else:
        text = f"≤ {_num(usl)}"
    return f"{text} {unit}".rstrip()


def _limited(values: dict) -> dict:
    """The process values that have a limit."""
    return {name: v for name, v in values.items() if v.get("lsl") is not None or v.get("usl") is not None}


def _capability_table(values: dict) -> Table | None:
    rows = [[name, v["n"], _limits_text(v), f"{_num(v['mean'])} {v.get('unit', '')}".rstrip(),
             f"{_num(v['std'], 3)} {v.get('unit', '')}".rstrip(), *_indices(v), _normal_cell(v),
             _capability(v)] for name, v in _limited(values).items()]
    if not rows:
        return None
    return Table(["process value", "n", "limits", "mean", "σ", "Cp", "Cpk", "normal", f"Cpk ≥ {CAPABLE}"], rows)


def _normal_cell(v: dict) -> str:
    """``yes`` / ``no (Shapiro p …)`` / ``—`` (too few values to test)."""
    test = v.get("normality") or {}
    if test.get("normal") is None:
        return "—"
    if test["normal"]:
        return "yes"
    alpha, shapiro, anderson = test.get("alpha", 0.05), test.get("shapiro_p"), test.get("anderson_p")
    failed = [f"{name} p {cell}" for name, p, cell in (("Shapiro", shapiro, _num(shapiro, 2)),
                                                        ("A–D", anderson, _fmt_p(_anderson_cell(anderson))))
              if p is not None and p < alpha]
    return f"no ({', '.join(failed)})" if failed else "no"


def _fmt_p(p: Any) -> str:
    """A p-value, or the bound ("≤ 0.01") a table gives instead of one."""
    return p if isinstance(p, str) else _num(p, 2)


def _normality_caveat(values: dict) -> str | None:
    """A note when a limited value fails the normality tests: Cp/Cpk from mean and σ assume a normal law."""
    names = [name for name, v in _limited(values).items() if v.get("spread") and
             (v.get("normality") or {}).get("normal") is False]
    if not names:
        return None
    return (f"Cp and Cpk are computed from mean and σ, which assumes a normal distribution; {', '.join(names)} "
            f"fail{'s' if len(names) == 1 else ''} the normality tests, so {'its' if len(names) == 1 else 'their'} "
            "Cpk says less about the share outside the limits than the histogram and the ±3σ band do "
            "(Process values, below).")


def _failures(ctx: ReportContext) -> tuple[list[list[Any]], int]:
    """Rows of the "what failed and why" table (NOK or incomplete curves) and how many curves there are."""
    rows, curves = [], 0
    for v in ctx.analysis["verdicts"]:
        if v["ok"] and v["complete"]:
            continue
        curves += 1
        complete = _completeness(v)
        failed = v["failed"] or ([{"name": "—", "reason": "the device named no failing element"}]
                                 if not v["ok"] else [{"name": "", "reason": ""}])
        for f in failed:
            rows.append([v["number"], f["name"],
                         cut_reason(v.get("memory", ""), f.get("reason") or ("no reason recorded" if not v["ok"] else "")),
                         complete])
    return rows, curves


def _completeness(verdict: dict) -> str:
    """Table cell: ``yes`` or the process values that did not arrive."""
    return "yes" if verdict["complete"] else f"no, missing {', '.join(verdict['missing']) or '(not named)'}"


def verdict(ctx: ReportContext) -> list[Block]:
    a, rec = ctx.analysis, ctx.recording
    verdicts = a["verdicts"]
    if not verdicts and not rec.curves:
        return []
    n, nok = len(verdicts), sum(not v["ok"] for v in verdicts)
    names = {p: rec.programs.get(p, {}).get("name") for p in a["sets"]}
    what = ", ".join(f"program {p}" + (f" “{names[p]}”" if names.get(p) else "") for p in a["sets"])
    judged = {v["number"] for v in verdicts}
    unjudged = [c.number for c in rec.curves if c.number not in judged]
    lost = a["not_recorded"]
    text = (f"NOK: {nok} of {n} curves failed, {n - nok} OK" if nok else
            f"INCOMPLETE: the unit passed all {n} curves" if lost else f"OK: all {n} curves passed") + \
        (f" ({what})" if what else "") + \
        (f"; {len(unjudged)} recorded curve{'s' if len(unjudged) > 1 else ''} without a result, not judged "
         f"(curve {', '.join(map(str, unjudged[:10]))}{' …' if len(unjudged) > 10 else ''})" if unjudged else "")
    cut = [r["number"] for r in a["incomplete"]]
    if cut:                               # the unit's verdict arrived, not all of the result's process values
        text += (f"; {len(cut)} of them judged by the unit with an incomplete result (curve "
                 f"{', '.join(map(str, cut[:10]))}{' …' if len(cut) > 10 else ''}: process values missing)")
    if lost:                              # judged by the unit, but the host has not got their samples
        text += (f"; {len(lost)} curve{'s' if len(lost) > 1 else ''} not recorded, "
                 f"{'their' if len(lost) > 1 else 'its'} frames incomplete (curve {', '.join(map(str, lost[:10]))}"
                 f"{' …' if len(lost) > 10 else ''}: the incomplete_curve events)")
    blocks: list[Block] = [Heading("Verdict")]
    if not rec.complete:                  # a cut or interrupted recording: said before the verdict it qualifies
        why = _complete(rec).removeprefix("no: ")
        blocks.append(Text(f"Warning: incomplete recording, {why}: the verdict covers the {n} curves it holds; "
                           "what was lost is under Recording.", "warning"))
    blocks.append(Banner(text, nok == 0 and not lost))
    caveat = rec.metadata.get("rig", {}).get("fidelity_caveat")
    if caveat:                            # a forced model level below what the scene asks (rig.fidelity)
        blocks.append(Text(f"Model level: {caveat}.", "warning"))
    for program, s in a["sets"].items():
        table = _capability_table(s["values"])
        label = f"program {program}" if len(a["sets"]) > 1 else "the process"
        if table is not None:
            if s.get("small_set"):            # said before the table it qualifies, not after the failures
                blocks.append(Text(f"Warning: {s['small_set']}", "warning"))
            blocks += [Text(f"Capability of {label} against the program's limits (Cp needs both limits; capable: "
                            f"Cpk ≥ {CAPABLE}, marginal: {MARGINAL}…{CAPABLE}):"), table]
            caveat = _normality_caveat(s["values"])
            if caveat:
                blocks.append(Text(caveat, "note"))
        elif rec.programs.get(program, {}).get("limits"):
            blocks.append(Text(f"No Cp/Cpk for program {program}: it has limits "
                               f"({', '.join(rec.programs[program]['limits'])}), but the set has no statistics of "
                               "those process values (too few values: see the warnings below)."))
        else:
            blocks.append(Text(f"No limits in program {program}: no Cp/Cpk (set [device.config.limits])."))
        by_element = ", ".join(f"{k} {v}×" for k, v in s["nok_by_element"].items())
        if by_element:
            blocks.append(Text(f"Failed elements, program {program}: {by_element}."))
    rows, curves = _failures(ctx)
    if rows:
        shown = rows[:NOK_ROWS]
        blocks += [Heading("What failed and why", 3),
                   Table(["curve", "failed element", "reason", "complete"], shown)]
        if len(shown) < len(rows):
            blocks.append(Text(f"The first {len(shown)} of {len(rows)} rows ({curves} curves); results.csv has all "
                               "of them.", "note"))
    blocks += [Text(f"Warning: {w}", "warning") for w in _warnings(ctx)]
    return blocks


def _warnings(ctx: ReportContext) -> list[str]:
    a, out = ctx.analysis, []
    lost = losses(ctx.recording)
    if lost:
        out.append("this recording is incomplete; the report shows what it holds: " + "; ".join(lost))
    if a["incomplete"]:
        out.append(f"{len(a['incomplete'])} incomplete result(s); their missing process values are left out of "
                   "the statistics, the values that arrived are used")
    for program, s in a["sets"].items():
        out += [f"program {program}: {w}" if len(a["sets"]) > 1 else w for w in s["warnings"]
                if w != s.get("small_set") or _capability_table(s["values"]) is None]   # else said above its table
        agreement = s.get("device_agreement") or {}
        if agreement.get("comparable") and not agreement.get("equal"):
            out.append(f"device statistics: {agreement_text(agreement)}")
    cut = memory_warning(a["verdicts"])
    if cut:
        out.append(cut)
    mismatches = a["events"].get("verdict_mismatch", 0)
    if mismatches:
        out.append(f"{mismatches} curve(s) whose re-evaluation on the host differs from the device's verdict "
                   "(events verdict_mismatch); the device's verdict is shown")
    return out


# -- 2. NOK curves ---------------------------------------------------------------------------------
def _elements(rec: Recording, program: int) -> list:
    return rec.programs.get(program, {}).get("elements", [])


def _failure_marks(ctx: ReportContext, curve: Any) -> list[tuple[float, float]]:
    """Where the curve's failed elements failed (SI), from re-running the unit's evaluation on it."""
    program = ctx.recording.programs.get(curve.program)
    if not program or not program.get("elements"):
        return []
    try:
        from firmware_sim.digiforce.evaluation import Reevaluation
        verdicts = Reevaluation(program).verdicts(curve.t, curve.x, curve.y)
    except Exception:  # a hand-made program the unit's code cannot evaluate: no marks
        return []
    return [v.at for v in verdicts if v is not None and not v.ok and v.at is not None]


def _short_rule(reason: str) -> str:
    """The rule part of a reason (``"exit top"`` of ``"exit top: …"``; a threshold's "never crossed", an envelope's
    "outside"), for the label on the plot."""
    head = reason.split(":", 1)[0]
    if len(head) <= 24 and head != reason:
        return head
    return "never crossed" if "never crosses" in reason else "outside" if " lies " in reason else "failed"


def curve_figure(ctx: ReportContext, curve: Any, verdict_row: dict | None) -> Figure:
    failed = {f["name"]: f.get("reason") or "" for f in (verdict_row or {}).get("failed", [])}
    bad = curve.number in ctx.nok
    path = plots.curve_panels(curve, _elements(ctx.recording, curve.program), ctx.figure_path(f"curve_c{curve.number}"),
                              ctx.nok, ctx.units(curve.program), {k: _short_rule(r) for k, r in failed.items()},
                              [f"{k}: {r}" for k, r in failed.items()],
                              _failure_marks(ctx, curve) if bad else ())
    if bad:
        caption = f"Curve {curve.number}, NOK: " + (", ".join(f"{k} ({_short_rule(r)})" for k, r in failed.items())
                                                   or "the device named no failing element") + \
            " failed (why: under the plot; ✖ where)"
    else:
        caption = f"Curve {curve.number}, OK"
    return ctx.figure(path, caption + ". Y over X with the evaluation elements (failed ones red), over time and "
                                      "over cam angle (theory dashed).")


def nok_curves(ctx: ReportContext) -> list[Block]:
    rec = ctx.recording
    nok = [c for c in rec.curves if c.number in ctx.nok]
    if not nok:
        return []
    rows = {v["number"]: v for v in ctx.analysis["verdicts"]}
    shown = nok[:ctx.nok_plots]
    blocks: list[Block] = [Heading("NOK curves"),
                           Text(f"{len(shown)} of {len(nok)} NOK curves plotted" +
                                ("." if len(shown) == len(nok) else
                                 f" (the first {len(shown)}, more with --nok-plots N; all are red in the overlay "
                                 "below and listed in results.csv)."))]
    return blocks + [curve_figure(ctx, c, rows.get(c.number)) for c in shown]


# -- 3. details ------------------------------------------------------------------------------------
def _device_table(agreement: dict, units: DisplayUnits) -> list[Block]:
    """Host vs device n, mean and σ per compared process value (when the comparison was made), in display units
    (those of the program's channels: also where the host has too few values for statistics of its own)."""
    if not agreement["comparable"]:
        return []
    rows = []
    for name, v in agreement["values"].items():
        scale = units.value(name)
        mean, std = scale(v["host"]["mean"]), scale(v["host"]["std"])
        at, sd = _comparison_places(mean, std)     # host and device at one precision: "equal" values read equal
        rows.append([name, scale.label, v["host"]["n"], v["device"]["n"], fixed(mean, at),
                     fixed(scale(v["device"]["mean"]), at), fixed(std, sd), fixed(scale(v["device"]["std"]), sd),
                     ", ".join(v["differs"]) or "equal"])
    blocks: list[Block] = [Table(["value", "unit", "n host", "n device", "mean host", "mean device", "σ host",
                                  "σ device", "agreement"], rows)]
    if agreement["device_only"]:
        blocks.append(Text(f"Kept by the device but not sent to the host (not compared): "
                           f"{', '.join(agreement['device_only'])}."))
    return blocks


def _comparison_places(mean: float | None, std: float | None) -> tuple[int, int]:
    """Decimals of a host-vs-device row's means (:func:`row_places`, one more) and σ (three digits; the means' when
    σ is at rounding level: a device's 3e-17 beside the host's 0 is no spread either)."""
    if mean is None or std is None or mean != mean or std != std:
        return 4, 4
    places = row_places(mean, std) + 1
    return places, decimals(std, 3) if std > 1e-9 * abs(mean) else places


def _values_tables(values: dict) -> list[Table]:
    """Two tables of the process values, each fitting the page: descriptive statistics and capability, then the
    normality and trend checks (as one table of 20 columns the last ones were off the page)."""
    stats = [[name, v["n"], v["unit"], *_at_row_places(v, "mean"), v["std"],
              *_at_row_places(v, "min", "max", "minus_3sigma", "plus_3sigma", "lsl", "usl"), *_indices(v),
              v["band_within_limits"]] for name, v in values.items()]
    checks = [[name, v["n"], v["normality"]["shapiro_p"], _anderson_cell(v["normality"]["anderson_p"]),
               v["normality"]["normal"], v["trend"]["slope_p"], v["trend"]["runs"]["p"], drift_text(v["trend"])]
              for name, v in values.items()]
    return [Table(["value", "n", "unit", "mean", "σ", "min", "max", "μ−3σ", "μ+3σ", "LSL", "USL", "Cp", "Cpk",
                   "±3σ in limits"], stats),
            Table(["value", "n", "Shapiro p", "A–D p", "normal", "trend p", "runs p", "drift"], checks)]


def _at_row_places(v: dict, *keys: str) -> list[str | None]:
    """The row's values ``keys`` at its one precision (:func:`rig.analysis.numbers.row_places`; None stays empty)."""
    places = row_places(v["mean"], v["std"])
    return [None if v[k] is None else fixed(v[k], places) for k in keys]


def _anderson_cell(p: float | None) -> Any:
    """The A–D p-value, as a bound where scipy's table clips it (0.01 … 0.15)."""
    if p is None:
        return None
    return f"≤ {ANDERSON_P[0]}" if p <= ANDERSON_P[0] else f"≥ {ANDERSON_P[1]}" if p >= ANDERSON_P[1] else p


def set_statistics(ctx: ReportContext) -> list[Block]:
    blocks: list[Block] = []
    for program, s in ctx.analysis["sets"].items():
        blocks += [Heading(f"Process values, program {program}"),
                   Text(f"{s['n']} curves, {s['ok']} OK, {s['nok']} NOK, {s['incomplete']} incomplete; "
                        f"NOK by element: {', '.join(f'{k}: {v}' for k, v in s['nok_by_element'].items()) or 'none'}"
                        + (". Values in the units the scene writes them in; limits, mean and ±3σ band in the same "
                           "unit; then the normality and trend checks of each value." if s["values"] else "."))]
        if s["values"]:
            blocks += _values_tables(s["values"])
            table = process_values(by_program(ctx.recording.results)[program])
            path = plots.histograms(table, s["values"], ctx.figure_path(f"hist_p{program}"))
            blocks.append(ctx.figure(path, f"Program {program}: histogram of each process value with its limits "
                                           "(red), mean (black) and μ ± 3σ (dashed)"))
        agreement = s["device_agreement"]
        blocks += [Text(f"Device statistics: {agreement_text(agreement)}")] + _device_table(agreement, ctx.units(program))
    return blocks


def curves(ctx: ReportContext) -> list[Block]:
    rec = ctx.recording
    if not rec.curves:
        return []
    nok = ctx.nok
    blocks: list[Block] = []
    for program in sorted({c.program for c in rec.curves}):
        chosen = [c for c in rec.curves if c.program == program]
        units = ctx.units(program)
        n_nok = sum(c.number in nok for c in chosen)
        title = f"program {program}: {len(chosen)} curves, {n_nok} NOK (red, on top)"
        blocks.append(Heading(f"All curves, program {program}"))
        numbers = {c.number for c in chosen}
        counts: dict[str, int] = {}
        for v in ctx.analysis["verdicts"]:
            if v["number"] in numbers:
                for f in v["failed"]:
                    counts[f["name"]] = counts.get(f["name"], 0) + 1
        failed = {name: f"failed in {k} curve{'s' if k > 1 else ''}" for name, k in counts.items()}
        path, notes = plots.force_displacement(chosen, _elements(rec, program), ctx.figure_path(f"xy_p{program}"),
                                               title, nok, units, failed)
        blocks.append(ctx.figure(path, f"Program {program}: Y over X with the evaluation elements "
                                       "(windows grey, entry side green, exit side black dashed; an element some curve failed red "
                                       "and labelled with how many)"))
        blocks += [Text(f"Note: {n}", "note") for n in notes]
        path = plots.signals_over(chosen, ctx.figure_path(f"ys_p{program}"), title, nok, units)
        blocks.append(ctx.figure(path, f"Program {program}: Y over time since each curve's start and over cam "
                                       "angle, all curves (NOK red), theory dashed"))
    rows = {v["number"]: v for v in ctx.analysis["verdicts"]}
    ok = [c for c in rec.curves if c.number in rows and rows[c.number]["ok"]]
    shown = ok[:ctx.ok_plots]
    if ok:
        blocks.append(Text(f"Individual plots of OK curves: {len(shown)} of {len(ok)}" +
                           (" (more with --ok-plots N)." if len(shown) < len(ok) else "."), "note"))
    elif ctx.ok_plots:
        blocks.append(Text(f"Individual plots of OK curves: none asked for ({ctx.ok_plots}) could be drawn, no curve "
                           "is OK.", "note"))
    return blocks + [curve_figure(ctx, c, rows.get(c.number)) for c in shown]


def curve_table(ctx: ReportContext) -> list[Block]:
    """Every curve's verdict, failed elements and completeness (folded away in HTML)."""
    rows = [[v["number"], v["program"], "OK" if v["ok"] else "NOK",
             "; ".join(f"{f['name']} ({f['reason']})" if f.get("reason") else str(f["name"]) for f in v["failed"]),
             _completeness(v)]
            for v in ctx.analysis["verdicts"]]
    if not rows:
        return []
    return [Heading("Curve by curve"),
            Table(["curve", "program", "result", "failing elements", "complete"], rows,
                  collapsed=f"{len(rows)} curves: verdict, failed elements, completeness")]


def _truth_caveat(ctx: ReportContext) -> list[Block]:
    """What the recorded truth and theory are not (the recording's ``truth_caveat``: per-cycle variation on the
    device's plant only), said where they are shown; nothing otherwise."""
    caveat = ctx.recording.metadata.get("rig", {}).get("truth_caveat")
    if not caveat:
        return []
    if "truth_caveat" in ctx.said:          # once in full (it was in both sections, word for word)
        return [Text("Truth and theory: as said above (the caveat on the recorded truth and theory).", "note")]
    ctx.said.add("truth_caveat")
    return [Text(f"Truth and theory: {caveat}.")]


def theory(ctx: ReportContext) -> list[Block]:
    rows = ctx.analysis["theory"]
    ok = [r for r in rows if r.get("lag_time") is not None]
    if not rows:
        return []
    program, units = ctx.main_program, ctx.main_units
    table = []
    for signal in sorted({r["signal"] for r in ok}):
        rs = [r for r in ok if r["signal"] == signal]
        u = units.channel(signal)
        lag = np.array([r["lag_time"] for r in rs]) * 1e3
        angle = [np.degrees(r["lag_angle"]) for r in rs if r.get("lag_angle") is not None]
        table.append([signal.upper(), len(rs), float(lag.mean()), f"{lag.min():.3g} … {lag.max():.3g}",
                      float(np.mean(angle)) if angle else None, u.label,
                      float(np.mean([u(r["rms_before"]) for r in rs])), float(np.mean([u(r["rms_after"]) for r in rs])),
                      float(np.mean([u(r["peak_difference"]) for r in rs]))])
    blocks: list[Block] = [Heading("Theory vs measurement"), *_truth_caveat(ctx),
                           Text("Lag > 0: the measurement is late. RMS deviation before and after removing the time "
                                "lag, means over the curves."),
                           Table(["signal", "curves", "mean lag (ms)", "lag range (ms)", "mean lag (°)",
                                  "unit of the next three", "RMS before", "RMS after",
                                  "mean peak diff (max measured − max theory)"], table)]
    errors = [r for r in rows if r.get("error")]
    if errors:
        blocks.append(Text(f"Not compared for {len(errors)} curve/signal pair(s): {errors[0]['error']}", "note"))
    curves = [c for c in ctx.recording.curves if c.program == program]
    lags = {(r["curve"], r["signal"]): r["lag_time"] for r in ok}
    path = plots.theory_residuals(curves, ctx.figure_path("residuals"),
                                  f"program {program}: measurement − theory, each curve's lag removed", ctx.nok, units,
                                  lags)
    if path is not None:
        blocks.append(ctx.figure(path, "Measurement minus theory of every curve at its samples, the theory delayed by "
                                       "the curve's lag from the table (the transducers' filters delay the measurement; "
                                       "their delay would otherwise dominate), NOK red, and their mean (black): where "
                                       "and how far the measurement departs from the model. A departure every curve "
                                       "shares is mostly the measuring chain's static errors, which the theory leaves "
                                       "out: each transducer's zero offset, gain and non-linearity and the acquisition "
                                       "unit's input accuracy (offset and gain within its class), drawn once from the "
                                       "scene's seed (docs/transducers.md)"))
    return blocks


#: what an event kind means to the reader of a report (kinds not listed: the plant's or the link's own words)
EVENT_MEANING = {
    "flank_switch": "the roller changed groove flank. Level 1: the kinetostatic cam contact force changes sign at phi "
                    "(the roller would cross). Level 2 (groove dynamics): at the angle [phi] it reached the other flank "
                    "[to], having left the one it was on at [left_phi] (level 1's sign change) after a flight of "
                    "[flight]",
    "flank_bounce": "level 2: the roller left its flank at the angle [left_phi] and struck the same flank again at "
                    "[phi] after a flight of [flight] (a jump without a switch; after a switch back it bounces, each "
                    "flight shorter)",
    "accel_jump": "the cam program's acceleration jumps at this angle (a segment boundary)",
    "disengagement": "the clutch's safety stage let go (relative angle past the engagement)",
    "reengaged": "the clutch engaged again after a disengagement",
    "phase_boundary": "the tappets passed from the cam's phase-I arc to its fillet (or back): the clutch's "
                      "stiffness changes there (relative angle [phi_r])",
    "lobe_wrap": "the relative angle crossed a lobe boundary k·120° (the tappets at a lobe's base): at 0° that is "
                 "elastic deflection the other way (reverse torque), not a slip — a disengagement is an apex pass",
    "load_zone": "the load's angle-dependent torque changed zone",
    "shutdown": "repeated disengagements: the stand switched the motor off",
    "method_switch": "the explicit integration method met stiffness (its steps limited by stability, not accuracy: "
                     "why); the run went on with the implicit method [to], as LSODA switches",
    "curves_in_one_cycle": "two curves began in one machine cycle (less than half a cam revolution apart): the unit's "
                           "start/stop trigger fired twice (an X dropout, or chatter at a crawl); the run counts curves, "
                           "so it then has fewer machine cycles than curves",
    "encoder_illegal": "a counter card first counted illegal transitions (both encoder channels changed at once: a "
                       "glitch, or edges faster than it follows); it kept its count, which from there may be off the "
                       "shaft (the run's totals are in link_summary)",
    "reading_at_limit": "a reading first sat at the limit of its CAN field (the unit sends a value beyond the field's "
                        "range as the limit): the quantity was beyond what the frame carries, the reading is not it "
                        "(the run's totals per signal are in link_summary.readings_at_limit)",
    "input_overrange": "the acquisition unit's inputs saw samples beyond their measuring range and clipped them (the "
                      "unit's own count, read over serial at the end): curves measured then hold the range's limit",
    "follower_lift": "the lab cam's follower would lift off: the contact force its law needs went below zero (spring "
                     "and weight no longer hold it on the cam; the law-following model and the sheets' theory do "
                     "not hold there)",
    "cam_stalled": "the motor-driven cam stopped or turned back: its motor cannot carry the mechanism over the peak "
                   "drive torque ([plant.drive] max_torque or slope too low); the run went on, not at its scene's "
                   "speed",
    "motor_below_load": "the stand's motor stalls below the torque its shoe brakes hold at rest: the stand cannot "
                        "start. A stick-slip brake holds it; a regularised (tanh) brake lets it creep at the speed "
                        "[creep_speed], which is the model's regularisation, not the stand",
    "tappet_lift_off": "the cam–tappet contact force would be negative: the tappets' inertia and centrifugal force "
                       "beat the spring and they lift off the cam (at the speed [omega3] and relative angle [phi_r] where it "
                       "began). The model "
                       "has the tappets follow the cam (N_B held at 0, the spring's torque still passed on): torques, "
                       "speeds and disengagements from here are not the machine's",
    "statistics_not_read": "the unit's statistics could not be read over serial at the end (a served machine that "
                           "stopped after this host's curves): the report compares no device statistics",
    "curve_clipped": "pairs of a curve whose values (or times) did not fit the CAN frame's fields and were sent "
                     "saturated: the recorded curve holds the limit there, not the measurement",
    "live_dropped": "live X/Y pairs the unit did not send because the CAN bus was full; live data only feeds "
                    "displays, curves and results wait in the queue and are never dropped",
    "device_identified": "the host identified the acquisition unit on the serial link",
    "link_summary": "frame and byte counts of the links at the end of the run",
    "sequence_gap": "CAN frames missing between two sequence numbers",
    "result": "a result whose end marker did not come (the next curve came first, the bus time passed, or the "
              "reception ended): recorded incomplete; count = process values missing (frame_id: the Result frame)",
    "incomplete_curve": "a curve whose frames did not all arrive: its samples are not recorded, its result is",
    "result_missing": "a curve whose result did not arrive",
    "verdict_mismatch": "the host's re-evaluation of a curve differs from the device's verdict",
    "interrupted": "the run stopped early",
    "run_stopped": "the unit ended its run before it was complete and said why (TxStatus.StopCause: its operator "
                   "stopped it, its host left or stalled, the bus could not carry the curves, the scene's max_time, a "
                   "fault of the simulated machine)",
    "run_short": "the served machine ended its run before this host had recorded the scene's cycles or duration",
    "not_recorded": "the served machine went on after the curves this host was asked to record (rig record --cycles); "
                    "the later ones are in /can/raw only",
}


EVENT_ROWS = 200      # rows of the event-by-event table (every event is in events.csv)


def events(ctx: ReportContext) -> list[Block]:
    counts = ctx.analysis["events"]
    if not counts:
        return []
    rec = ctx.recording
    dropped = live_pairs_dropped(rec.events)
    rows = [[k, v, EVENT_MEANING.get(k, "") + (f" ({dropped} pairs in all)" if k == "live_dropped" else "")]
            for k, v in sorted(counts.items())]
    blocks: list[Block] = [Heading("Events"), Table(["kind", "count", "what it means"], rows)]
    if any("[" in row[2] for row in rows):
        blocks.append(Text("[name]: a field of the event, its value in the event's details below.", "note"))
    if rec.events:
        details = [event_details(e, ctx.main_units) for e in rec.events]
        ctx.exported.append((export_events(rec.events, details, ctx.out_dir / "events.csv"),
                             "one row per event: simulation time, kind, its details"))
        shown = min(len(rec.events), EVENT_ROWS)
        more = f"the first {shown} of {len(rec.events)}; all in " if shown < len(rec.events) else "also in "
        blocks.append(Table(["t (s)", "kind", "details"],
                            [[f"{e.get('t', math.nan):.6g}", e.get("kind", ""), d]
                             for e, d in zip(rec.events[:shown], details)],
                            collapsed=f"Event by event ({more}events.csv)"))
    return blocks


TRUTH_CYCLES = 3      # the plant truth chart shows this many machine cycles (the shapes stay visible)


def _of_simulated(rec: Recording, t: np.ndarray) -> str:
    """' of the 20.30 s recorded' (the recording's simulated time, its statistics read-back after the run included:
    the console's "20.29 s simulated" is the run's alone), else — a file its writer never closed — ' of the 20 s of
    truth recorded'."""
    sim = rec.simulation_time
    return f" of the {sim:.2f} s recorded" if sim is not None else f" of the {t[-1] - t[0]:.3g} s of truth recorded"


def _truth_window(rec: Recording, t: np.ndarray) -> tuple[tuple[float, float] | None, str]:
    """The part of the plant truth the chart shows (None: all of it, s) and its caption's span text."""
    starts = np.array([c.t_start for c in rec.curves if c.t_start is not None])
    if starts.size > TRUTH_CYCLES and t.size:
        period = float(np.median(np.diff(starts)))
        end = float(starts[0] + TRUTH_CYCLES * period)
        if end < t[-1]:
            return (float(t[0]), end), (f"the first {end - t[0]:.3g} s{_of_simulated(rec, t)} "
                                        f"(≈ {TRUTH_CYCLES} machine cycles of {period:.3g} s)")
    if not t.size:
        return None, ""
    sim = rec.simulation_time
    whole = f"{t[-1] - t[0]:.3g} s"
    return None, whole if sim is None or f"{sim:.3g} s" == whole else f"{whole}{_of_simulated(rec, t)}"


def truth(ctx: ReportContext) -> list[Block]:
    data = ctx.recording.truth
    names = [n for n in data if n != "t"]
    if not names or not data["t"].size:
        return []
    units = ctx.main_units
    unwrapped = "cam_angle" in names and "phi" in names
    if unwrapped:
        names.remove("phi")            # the unwrapped angle: a ramp that squeezes the wrapped one flat
    window, span = _truth_window(ctx.recording, data["t"])
    plant = ctx.recording.metadata.get("rig", {}).get("plant")
    path, panels, undrawn = plots.truth_panels(data, names, ctx.figure_path("truth"), units, window, plant=plant)
    axes = " | ".join(", ".join(members) for members in panels)
    constant = f"; not drawn (constant over it, or equal to a drawn signal): {', '.join(undrawn)}" if undrawn else ""
    ramp = "; not drawn: phi (the cam angle unwrapped, a ramp; cam_angle is drawn)" if unwrapped else ""
    return [Heading("Plant truth"), *_truth_caveat(ctx),
            ctx.figure(path, f"Plant truth over {span}, one axis per unit (split where ranges differ more than "
                             f"{plots.SCALE_SPLIT:g}×), top to bottom: {axes}{constant}{ramp}")]


#: units of the numeric ``rig`` metadata values (the recording keeps them as text, SI)
_META_UNITS = {"sample_rate": "Hz", "view_rate": "Hz", "duration": "s"}


def _meta_value(key: str, value: str) -> str:
    """A metadata value as a person reads it: with its unit, the wall-clock start as a UTC date (and its ns), a
    dash for null (e.g. the duration of a run given in cycles)."""
    if value in ("null", "None", ""):
        return "—"
    if key == "wall_clock_start":
        try:
            ns = int(value)
        except ValueError:
            return value
        stamp = datetime.fromtimestamp(ns // 1_000_000_000, timezone.utc).strftime("%Y-%m-%d %H:%M:%S")
        return f"{stamp}.{ns % 1_000_000_000:09d} UTC ({value} ns since 1970)"
    if key in _META_UNITS:
        try:
            return f"{float(value):g} {_META_UNITS[key]}"
        except ValueError:
            return value
    return value


def overview(ctx: ReportContext) -> list[Block]:
    rec = ctx.recording
    meta = rec.metadata.get("rig", {})
    rows = [[k, _meta_value(k, v)] for k, v in sorted(meta.items())]
    if _meta_value("duration", meta.get("duration", "")) == "—" and meta.get("cycles") not in (None, "null"):
        rows = [[k, f"— (the run was given as {meta['cycles']} cycles)" if k == "duration" else v] for k, v in rows]
    simulated = rec.end.get("simulation_time")
    if simulated is not None:
        rows.append(["simulated time", _meta_value("duration", simulated)])
    rows += [["messages", rec.summary()], ["complete", _complete(rec)]]
    blocks: list[Block] = [Heading("Recording"), Text(f"File: {rec.path}"), Table(["key", "value"], rows)]
    lost = losses(rec)
    if lost:
        blocks += [Text("Warning: this recording is incomplete; the report shows what it holds.", "warning"),
                   Table(["what is incomplete or lost"], [[line] for line in lost])]
    if rec.series_beyond:
        cut = min(b.t_first for b in rec.series_beyond.values())
        blocks += [Text(f"Read in bounded memory: every series is held up to t = {cut:.6g} s, where one topic's arrays "
                        f"reached {KEPT_BYTES / 2**20:g} MiB; the charts and analyses of these topics cover that span."),
                   Table(["topic beyond the memory held"],
                         [[held_text(t, rec.series.get(t, {}), b, series_export_name(rec, t))]
                          for t, b in rec.series_beyond.items()])]
    return blocks


def series_export_name(rec: Recording, topic: str) -> str | None:
    """The file the report's exports write a series topic to (every sample), or None where it is not exported."""
    if topic.startswith("/stand/"):
        return "stand_" + topic.removeprefix("/stand/") + ".csv"
    return "plant_truth.csv" if topic == TRUTH and not rec.curves else None


def _complete(rec: Recording) -> str:
    """The overview's ``complete`` cell: yes, or why not (truncated file, interrupted run)."""
    if rec.complete:
        return "yes"
    return "no: " + ", ".join(why for why, applies in (
        (file_problem(rec), rec.truncated),
        (rec.interrupted and interruption_text(rec.interrupted), rec.interrupted)) if applies)


def exports(ctx: ReportContext) -> list[Block]:
    rec = ctx.recording
    units = ctx.analysis.get("units")
    files = []
    if rec.curves:
        files.append((export_curves(rec.curves, ctx.out_dir / "curves.csv", units),
                      "one row per sample: curve, program, i, t, x, y, cam angle (units in the column names)"))
    if rec.results:
        files.append((export_results(rec.results, ctx.out_dir / "results.csv", units),
                      "one row per curve: OK/NOK, failed elements and why, completeness, process values"))
    files += ctx.exported                               # written by the sections (events.csv), not a stale copy
    units = ctx.main_units
    for topic in [*rec.series, *(t for t in rec.series_beyond if t not in rec.series)]:    # one held or not
        name = series_export_name(rec, topic)
        data = next(rec.series_blocks(topic), {}) if topic.startswith("/stand/") and name else {}
        if "t" in data and len(data["t"]):
            codes = ""
            if "speed_method" in data:
                from drivers.encoder import METHOD_NAMES
                codes = "; speed_method: " + ", ".join(f"{k} {v}" for k, v in sorted(METHOD_NAMES.items()))
            files.append((export_series(rec.series_blocks(topic), ctx.out_dir / name, units, topic),
                          f"{topic}: one row per reading ({', '.join(k for k in data if k != 't')}){codes}"))
    name = series_export_name(rec, TRUTH)                # a stand or lab run: what the plant did (the loads too)
    truth = next(rec.series_blocks(TRUTH), {}) if name else {}
    if "t" in truth and len(truth["t"]):
        files.append((export_series(rec.series_blocks(TRUTH), ctx.out_dir / name, units),
                      f"/plant/truth: one row per model sample ({', '.join(k for k in truth if k != 't')})"))
    return [Heading("Exports"), Table(["file", "contents"], [[Link(f.name, f.name), what] for f, what in files])
            ] if files else []


for _name, _section in (("verdict", verdict), ("nok_curves", nok_curves), ("statistics", set_statistics),
                        ("curves", curves), ("curve_table", curve_table), ("clutch", clutch_section),
                        ("stand_comparison", comparison_section), ("clutch_static", static_clutch_section),
                        ("lab_bench", lab_section), ("theory", theory), ("events", events), ("truth", truth),
                        ("overview", overview), ("exports", exports)):
    register_section(_name, _section)


# -- rendering -------------------------------------------------------------------------------------
def _markdown(title: str, blocks: Sequence[Block]) -> str:
    out = [f"# {title}", ""]
    for b in blocks:
        if isinstance(b, Heading):
            out += ["#" * b.level + " " + b.text, ""]
        elif isinstance(b, Banner):
            out += [f"**{b.text}**", ""]
        elif isinstance(b, Text):
            out += [b.text, ""]
        elif isinstance(b, Table):
            if b.collapsed:              # folded as in HTML (GitHub and most Markdown viewers render <details>)
                out += [f"<details><summary>{html.escape(b.collapsed)}</summary>", ""]
            out += ["| " + " | ".join(b.headers) + " |", "|" + "---|" * len(b.headers)]
            out += ["| " + " | ".join((f"[{c.text}]({c.href})" if isinstance(c, Link) else fmt(c)).replace("|", "\\|")
                                      for c in r) + " |" for r in b.rows] + [""]
            if b.collapsed:
                out += ["</details>", ""]
        elif isinstance(b, Figure):
            out += [f"![{b.caption}]({b.path})", "", f"*{b.caption}*", ""]
    return "\n".join(out)


STYLE = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;max-width:1240px;margin:1em auto;padding:0 1em;
color:#1d1d1d;line-height:1.35}
h1{font-size:1.45em;margin-bottom:.2em} h2{font-size:1.2em;border-bottom:2px solid #d8d8d8;padding-bottom:2px;
margin-top:1.8em} h3{font-size:1.02em;margin:1.2em 0 .3em}
.banner{font-size:1.45em;font-weight:700;padding:.45em .7em;border-radius:4px;margin:.4em 0 .8em}
.ok{background:#e1f3df;color:#17631a;border-left:8px solid #2e9b33}
.nok{background:#fde3e2;color:#9e1b1d;border-left:8px solid #d62728}
.scroll{overflow-x:auto} table{border-collapse:collapse;font-size:.82em;margin:.4em 0 .8em}
td,th{border:1px solid #cfcfcf;padding:2px 7px;vertical-align:top} th{background:#f2f2f2;text-align:left}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap} td.bad{color:#b01c1e;font-weight:600}
p.warning{color:#8a4b00;background:#fff5e0;padding:.2em .5em;border-left:4px solid #e59400}
p.note{color:#555;font-size:.92em} figure{margin:.8em 0 1.2em} img{max-width:100%;height:auto}
figcaption{font-size:.9em;color:#444} summary{cursor:pointer;color:#333;margin:.3em 0}
"""


def _cell(c: Any) -> str:
    if isinstance(c, Link):
        return f"<td><a href='{html.escape(c.href)}'>{html.escape(c.text)}</a></td>"
    text = html.escape(fmt(c))
    if isinstance(c, (int, float)) and not isinstance(c, bool):
        return f"<td class='num'>{text}</td>"
    if c == "NOK" or (isinstance(c, str) and c.startswith("NOT capable")):
        return f"<td class='bad'>{text}</td>"
    return f"<td>{text}</td>"


def _html(title: str, blocks: Sequence[Block]) -> str:
    e = html.escape
    out = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{e(title)}</title>",
           f"<style>{STYLE}</style></head><body>", f"<h1>{e(title)}</h1>"]
    for b in blocks:
        if isinstance(b, Heading):
            out.append(f"<h{b.level}>{e(b.text)}</h{b.level}>")
        elif isinstance(b, Banner):
            out.append(f"<div class='banner {'ok' if b.ok else 'nok'}'>{e(b.text)}</div>")
        elif isinstance(b, Text):
            out.append(f"<p class='{b.kind}'>{e(b.text)}</p>" if b.kind else f"<p>{e(b.text)}</p>")
        elif isinstance(b, Table):
            if b.collapsed:
                out.append(f"<details><summary>{e(b.collapsed)}</summary>")
            out.append("<div class='scroll'><table><tr>" + "".join(f"<th>{e(h)}</th>" for h in b.headers) + "</tr>")
            out += ["<tr>" + "".join(_cell(c) for c in r) + "</tr>" for r in b.rows]
            out.append("</table></div>" + ("</details>" if b.collapsed else ""))
        elif isinstance(b, Figure):
            out.append(f"<figure><a href='{e(b.path)}'><img src='{e(b.path)}' alt='{e(b.caption)}'></a>"
                       f"<figcaption>{e(b.caption)}</figcaption></figure>")
    return "\n".join(out + ["</body></html>"])


def write_report(recording_or_path: Recording | str | Path, out_dir: str | Path, fmt: str = "html",
                 sections: Sequence[tuple[str, Section]] | None = None, ok_plots: int = 0,
                 nok_plots: int = NOK_PLOTS, analysis: dict | None = None) -> Path:
    """Write ``report.html`` or ``report.md`` with PNG plots and CSV files into ``out_dir``; return its path.

    ``analysis``: the :func:`analyse` result of this recording if the caller already has it (it is
    computed here otherwise). ``nok_plots``: NOK curves that get their own figure (in curve order);
    ``ok_plots``: OK curves that do (none by default: OK curves are in the overlay).
    """
    if fmt not in ("html", "md"):
        raise ValueError(f"report format must be 'html' or 'md', got {fmt!r}")
    if ok_plots < 0 or nok_plots < 0:
        raise ValueError(f"numbers of curve plots must be >= 0, got ok_plots={ok_plots}, nok_plots={nok_plots}")
    rec = (recording_or_path if isinstance(recording_or_path, Recording)
           else read_recording(recording_or_path, can_frames=False))          # the report counts the bus frames
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    before = clear_previous(out, MANIFEST, lambda out: {p.name for p in out.glob("[0-9][0-9][0-9]_*.png")})
    ctx = ReportContext(rec, analyse(rec) if analysis is None else analysis, out, ok_plots, nok_plots)
    blocks: list[Block] = []
    for _, section in (SECTIONS if sections is None else sections):
        blocks += section(ctx)
    scene = rec.metadata.get("rig", {}).get("scene")
    title = f"Rig report: {rec.path.name}" + (f" (scene {scene})" if scene else "")
    path = out / f"report.{fmt}"
    path.write_text(_markdown(title, blocks) if fmt == "md" else _html(title, blocks), encoding="utf-8")
    list_written(out, MANIFEST, before)
    return path
