"""HTML or Markdown report of a recording: tables, PNG plots, CSV export; extensible by sections.

A *section* is a function ``(ctx: ReportContext) -> list[Block]``; it returns ``[]`` when it does not
apply (e.g. no curves). Other modules add sections with :func:`register_section` (a clutch recording
adds torque vs time, etc.).
"""
from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from rig.analysis import plots
from rig.analysis.device import agreement_text
from rig.analysis.export import export_curves, export_results
from rig.analysis.sets import by_program, process_values
from rig.analysis.summary import analyse
from rig.recorder import Recording, read_recording
from rig.recorder.completeness import losses


@dataclass
class Heading:
    text: str
    level: int = 2


@dataclass
class Text:
    text: str


@dataclass
class Table:
    headers: list[str]
    rows: list[list[Any]]


@dataclass
class Figure:
    path: str          # relative to the report directory
    caption: str


Block = Heading | Text | Table | Figure


@dataclass
class ReportContext:
    """What sections see: the recording, its analysis, the output directory and a figure counter."""

    recording: Recording
    analysis: dict
    out_dir: Path
    max_curve_plots: int = 4
    _count: list[int] = field(default_factory=lambda: [0])

    def figure_path(self, stem: str) -> Path:
        self._count[0] += 1
        return self.out_dir / f"{self._count[0]:03d}_{stem}.png"

    def figure(self, path: Path, caption: str) -> Figure:
        return Figure(path.relative_to(self.out_dir).as_posix(), caption)


Section = Callable[[ReportContext], list[Block]]
SECTIONS: list[tuple[str, Section]] = []


def register_section(name: str, section: Section) -> None:
    """Append a section to the default report (replacing one of the same name)."""
    SECTIONS[:] = [(n, s) for n, s in SECTIONS if n != name] + [(name, section)]


def fmt(v: Any) -> str:
    """Table cell text: numbers to 4 significant digits, None as a dash."""
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


# -- default sections ------------------------------------------------------------------------------
def _complete(rec: Recording) -> str:
    """The overview's ``complete`` cell: yes, or why not (truncated file, interrupted run)."""
    if rec.complete:
        return "yes"
    return "no: " + ", ".join(why for why, applies in (("file truncated (run killed or file cut)", rec.truncated),
                                                       (f"run interrupted ({rec.interrupted})", rec.interrupted))
                              if applies)


def overview(ctx: ReportContext) -> list[Block]:
    rec = ctx.recording
    meta = rec.metadata.get("rig", {})
    rows = [[k, v] for k, v in sorted(meta.items())]
    rows += [["messages", rec.summary()], ["complete", _complete(rec)]]
    blocks: list[Block] = [Heading("Recording", 2), Text(f"File: {rec.path}"), Table(["key", "value"], rows)]
    lost = losses(rec)
    if lost:
        blocks += [Text("Warning: this recording is incomplete; the report shows what it holds."),
                   Table(["what is incomplete or lost"], [[line] for line in lost])]
    return blocks


def _completeness(verdict: dict) -> str:
    """Verdict-table cell: ``yes`` or the process values that did not arrive."""
    return "yes" if verdict["complete"] else f"no, missing {', '.join(verdict['missing']) or '(not named)'}"


def verdicts(ctx: ReportContext) -> list[Block]:
    rows = [[v["number"], v["program"], "OK" if v["ok"] else "NOK",
             "; ".join(f"{f['name']} ({f['reason']})" if f.get("reason") else str(f["name"]) for f in v["failed"]),
             _completeness(v)]
            for v in ctx.analysis["verdicts"]]
    if not rows:
        return []
    blocks: list[Block] = [Heading("Curves: OK / NOK")]
    if ctx.analysis["incomplete"]:
        blocks.append(Text(f"Warning: {len(ctx.analysis['incomplete'])} incomplete result(s); their missing "
                           "process values are left out of the statistics, the values that arrived are used."))
    return blocks + [Table(["curve", "program", "result", "failing elements", "complete"], rows)]


def _device_table(agreement: dict) -> list[Block]:
    """Host vs device n, mean and σ per compared process value (when the comparison was made)."""
    if not agreement["comparable"]:
        return []
    rows = [[name, v["host"]["n"], v["device"]["n"], v["host"]["mean"], v["device"]["mean"], v["host"]["std"],
             v["device"]["std"], ", ".join(v["differs"]) or "equal"] for name, v in agreement["values"].items()]
    blocks: list[Block] = [Table(["value", "n host", "n device", "mean host", "mean device", "σ host", "σ device",
                                  "agreement"], [[fmt(c) for c in r] for r in rows])]
    if agreement["device_only"]:
        blocks.append(Text(f"Kept by the device but not sent to the host (not compared): "
                           f"{', '.join(agreement['device_only'])}."))
    return blocks


def _values_table(values: dict) -> Table:
    """One row per process value: n, unit, descriptive statistics, capability, normality and trend checks."""
    rows = [[name, v["n"], v["unit"], v["mean"], v["std"], v["min"], v["max"], v["minus_3sigma"], v["plus_3sigma"],
             v["lsl"], v["usl"], v["cp"], v["cpk"], v["band_within_limits"], v["normality"]["shapiro_p"],
             v["normality"]["anderson_p"], v["normality"]["normal"], v["trend"]["slope_p"], v["trend"]["runs"]["p"],
             v["trend"]["drift"]] for name, v in values.items()]
    return Table(["value", "n", "unit", "mean", "σ", "min", "max", "μ−3σ", "μ+3σ", "LSL", "USL", "Cp", "Cpk",
                  "±3σ in limits", "Shapiro p", "A–D p", "normal", "trend p", "runs p", "drift"],
                 [[fmt(c) for c in r] for r in rows])


def set_statistics(ctx: ReportContext) -> list[Block]:
    blocks: list[Block] = []
    for program, s in ctx.analysis["sets"].items():
        blocks += [Heading(f"Set statistics, program {program}"),
                   Text(f"{s['n']} curves, {s['ok']} OK, {s['nok']} NOK, {s['incomplete']} incomplete; "
                        f"NOK by element: {', '.join(f'{k}: {v}' for k, v in s['nok_by_element'].items()) or 'none'}")]
        blocks += [Text(f"Warning: {w}") for w in s["warnings"]]
        if s["values"]:
            blocks.append(_values_table(s["values"]))
            table = process_values(by_program(ctx.recording.results)[program])
            path = plots.histograms(table, s["values"], ctx.figure_path(f"hist_p{program}"))
            blocks.append(ctx.figure(path, f"Program {program}: histogram of each process value with its limits "
                                           "(red), mean (black) and μ ± 3σ (dashed)"))
        agreement = s["device_agreement"]
        blocks += [Text(f"Device statistics: {agreement_text(agreement)}")] + _device_table(agreement)
    return blocks


def _elements(rec: Recording, program: int) -> list:
    return rec.programs.get(program, {}).get("elements", [])


def _units(rec: Recording, program: int) -> tuple[str, str]:
    """Engineering units of the X and Y channels from the program config (``channels.<ch>.unit``)."""
    channels = rec.programs.get(program, {}).get("channels", {})
    return channels.get("x", {}).get("unit", "SI"), channels.get("y", {}).get("unit", "SI")


def curves(ctx: ReportContext) -> list[Block]:
    rec = ctx.recording
    if not rec.curves:
        return []
    nok = {v["number"] for v in ctx.analysis["verdicts"] if not v["ok"]}
    blocks: list[Block] = [Heading("Curves")]
    for program in sorted({c.program for c in rec.curves}):
        chosen = [c for c in rec.curves if c.program == program]
        units = _units(rec, program)
        path, notes = plots.force_displacement(chosen, _elements(rec, program), ctx.figure_path(f"xy_p{program}"),
                                               f"program {program}: {len(chosen)} curves (NOK red)", nok, units)
        blocks.append(ctx.figure(path, f"Program {program}: Y over X with evaluation elements "
                                       "(entry side green, exit side red dashed)"))
        blocks += [Text(f"Note: {n}") for n in notes]
        path = plots.signals_over(chosen, ctx.figure_path(f"ys_p{program}"),
                                  f"program {program}: {len(chosen)} curves (NOK red)", nok, units[1])
        blocks.append(ctx.figure(path, f"Program {program}: Y over time since each curve's start and over cam "
                                       "angle, all curves (NOK red), theory dashed"))
    shown = sorted(rec.curves, key=lambda c: (c.number not in nok, c.number))[:ctx.max_curve_plots]
    if len(shown) < len(rec.curves):
        blocks.append(Text(f"Individual plots for {len(shown)} of {len(rec.curves)} curves (NOK first); "
                           "the plots above show all of them."))
    for c in sorted(shown, key=lambda c: c.number):
        path = plots.curve_panels(c, _elements(rec, c.program), ctx.figure_path(f"curve_c{c.number}"), nok,
                                  _units(rec, c.program))
        blocks.append(ctx.figure(path, f"Curve {c.number}: Y over X with evaluation elements, over time and over "
                                       "cam angle (theory dashed)"))
    return blocks


def theory(ctx: ReportContext) -> list[Block]:
    rows = [[r["curve"], r["signal"], r.get("lag_time"), None if r.get("lag_angle") is None
             else float(np.degrees(r["lag_angle"])), r.get("angle_method"), r.get("rms_before"), r.get("rms_after"),
             r.get("peak_difference"), r.get("error")] for r in ctx.analysis["theory"]]
    if not rows:
        return []
    return [Heading("Theory vs measurement"),
            Text("Lag > 0: the measurement is late. RMS deviation before and after removing the time lag."),
            Table(["curve", "signal", "lag (s)", "lag (deg)", "angle method", "RMS before", "RMS after",
                   "peak diff", "error"], [[fmt(c) for c in r] for r in rows])]


def events(ctx: ReportContext) -> list[Block]:
    counts = ctx.analysis["events"]
    return [Heading("Events"), Table(["kind", "count"], [[k, v] for k, v in sorted(counts.items())])] if counts else []


def truth(ctx: ReportContext) -> list[Block]:
    data = ctx.recording.truth
    names = [n for n in data if n != "t"]
    if not names:
        return []
    path = plots.series(data, names[:6], ctx.figure_path("truth"), "plant truth", "SI")
    return [Heading("Plant truth"), ctx.figure(path, f"Plant truth signals ({', '.join(names[:6])})")]


def exports(ctx: ReportContext) -> list[Block]:
    rec = ctx.recording
    files = []
    if rec.curves:
        files.append(export_curves(rec.curves, ctx.out_dir / "curves.csv"))
    if rec.results:
        files.append(export_results(rec.results, ctx.out_dir / "results.csv"))
    return [Heading("Exports"), Table(["file"], [[f.name] for f in files])] if files else []


for _name, _section in (("overview", overview), ("verdicts", verdicts), ("statistics", set_statistics),
                        ("curves", curves), ("theory", theory), ("events", events), ("truth", truth),
                        ("exports", exports)):
    register_section(_name, _section)


# -- rendering -------------------------------------------------------------------------------------
def _markdown(title: str, blocks: Sequence[Block]) -> str:
    out = [f"# {title}", ""]
    for b in blocks:
        if isinstance(b, Heading):
            out += ["#" * b.level + " " + b.text, ""]
        elif isinstance(b, Text):
            out += [b.text, ""]
        elif isinstance(b, Table):
            out += ["| " + " | ".join(b.headers) + " |", "|" + "---|" * len(b.headers)]
            out += ["| " + " | ".join(fmt(c).replace("|", "\\|") for c in r) + " |" for r in b.rows] + [""]
        elif isinstance(b, Figure):
            out += [f"![{b.caption}]({b.path})", "", f"*{b.caption}*", ""]
    return "\n".join(out)


def _html(title: str, blocks: Sequence[Block]) -> str:
    e = html.escape
    out = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{e(title)}</title>",
           "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
           "font-size:small}td,th{border:1px solid #ccc;padding:2px 6px}</style></head><body>", f"<h1>{e(title)}</h1>"]
    for b in blocks:
        if isinstance(b, Heading):
            out.append(f"<h{b.level}>{e(b.text)}</h{b.level}>")
        elif isinstance(b, Text):
            out.append(f"<p>{e(b.text)}</p>")
        elif isinstance(b, Table):
            out.append("<table><tr>" + "".join(f"<th>{e(h)}</th>" for h in b.headers) + "</tr>")
            out += ["<tr>" + "".join(f"<td>{e(fmt(c))}</td>" for c in r) + "</tr>" for r in b.rows]
            out.append("</table>")
        elif isinstance(b, Figure):
            out.append(f"<figure><img src='{e(b.path)}' alt='{e(b.caption)}'><figcaption>{e(b.caption)}"
                       "</figcaption></figure>")
    return "\n".join(out + ["</body></html>"])


def write_report(recording_or_path: Recording | str | Path, out_dir: str | Path, fmt: str = "html",
                 sections: Sequence[tuple[str, Section]] | None = None, max_curve_plots: int = 4,
                 analysis: dict | None = None) -> Path:
    """Write ``report.html`` or ``report.md`` with PNG plots and CSV files into ``out_dir``; return its path.

    ``analysis``: the :func:`analyse` result of this recording if the caller already has it (it is
    computed here otherwise). ``max_curve_plots``: curves (NOK first) that get their own figure.
    """
    if fmt not in ("html", "md"):
        raise ValueError(f"report format must be 'html' or 'md', got {fmt!r}")
    rec = recording_or_path if isinstance(recording_or_path, Recording) else read_recording(recording_or_path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ctx = ReportContext(rec, analyse(rec) if analysis is None else analysis, out, max_curve_plots)
    blocks: list[Block] = []
    for _, section in (SECTIONS if sections is None else sections):
        blocks += section(ctx)
    title = f"Rig report: {rec.path.name}"
    path = out / f"report.{fmt}"
    path.write_text(_markdown(title, blocks) if fmt == "md" else _html(title, blocks), encoding="utf-8")
    return path

from rig.analysis import clutch_report as _clutch_report  # noqa: E402,F401  (registers its section)
from rig.analysis import static_clutch_report as _static_clutch_report  # noqa: E402,F401  (registers its section)
