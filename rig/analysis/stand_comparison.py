"""Thesis against rig for a dynamic-stand run: the scene's ``[[comparison]]`` rows and ``comparison.csv`` (issue 14;
the report's table of them is drawn by :func:`rig.analysis.clutch_report.comparison_section`).

Each row names a quantity the source reports, its value as printed (with units: ``thesis = "14.5 N*m"``), which
stand result it is compared with (``rig``: a result name of :func:`rig.analysis.clutch_report.stand_results` such
as ``"start-up: peak torque"`` or ``"disengagements"`` (a count; ``"shutdown"``: 1 required, 0 not); ``part``: ``"value"``, ``"time"`` — when it happened — or
``"time_after"`` — after its stimulus), whether the scene's unknown parameters were fitted on it (``fitted``) or the
rig's value follows from what the scene sets rather than from the model (``input``: a load the scene applies, a
stimulus chosen for that outcome — shown, never counted as a prediction) and an optional ``note``. The rig value is given in the thesis's unit; a result that does not exist in the run is "n/a"
with the reason. Whether the rig agrees is judged by the row's ``tolerance``: a fraction (``"15 %"``), a value in
the thesis's unit (``"20 ms"``) or a bound (``"at most"``, ``"at least"``: the thesis value is a limit); without
one a count (a thesis value without unit) must match exactly and other rows are not judged.
"""
from __future__ import annotations

import csv
import difflib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from rig.analysis.clutch_metrics import Metric, Stimulus, result_names, stimulus_label
from rig.analysis.numbers import plural
from rig.analysis.units import same_kind
from rig.scene import Field, Scene, SceneError, read_table
from rig.units import UnitError, to_si

PARTS = ("value", "time", "time_after")
ROW_SCHEMA = {
    "quantity": Field(None, doc="what the source reports"),
    "thesis": Field(None, doc="the source's value with its unit, e.g. \"14.5 N*m\" (a count: a plain number)"),
    "rig": Field(None, doc="stand result it is compared with, e.g. \"start-up: peak torque\""),
    "part": Field(None, "value", "value, time (when it happened) or time_after (after its stimulus)"),
    "fitted": Field(None, False, "true if the scene's unknown parameters were fitted on this quantity"),
    "input": Field(None, False, "true if the rig's value follows from what the scene sets (a load it applies, a "
                   "stimulus chosen for that outcome), not from the model: not a prediction"),
    "note": Field(None, "", "what else to know"),
    "after": Field(None, None, "a stand result the thesis value follows (e.g. \"disengagements\"): a run where it is "
                   "0 or missing shows another event, and the row is not judged"),
    "tolerance": Field(None, None, "how close agrees: \"15 %\", a value in the thesis's unit, \"at most\" or "
                       "\"at least\" (default: a count exactly, else not judged)"),
}
BOUNDS = ("at most", "at least")
#: a result the run names otherwise when it has none of the kind: a run without disengagement has no "relative slip"
#: but its net relative angle change (0 lobes slipped, the elastic deflection) is the value to judge
ALIASES = {"relative slip": ("relative angle change",)}
SI = {"N·m": "N*m", "s": "s", "°": "deg", "%": "1", "rad/s": "rad/s", "J": "J", "": "1"}   # result units


@dataclass(frozen=True)
class Row:
    """One compared quantity: the thesis value and the rig's, both in ``unit`` (rig: None = n/a, with ``why``)."""

    quantity: str
    unit: str
    thesis: float
    rig: float | None
    fitted: bool
    why: str
    agrees: bool | None = None     # None: not judged (no tolerance) or n/a
    tolerance: str = ""            # as the scene writes it; "exact" for a count without one; "" not judged
    beyond: float | None = None    # rig None: the run ended before the result, which lies above this (in unit)
    input: bool = False            # the rig's value follows from the scene's settings: not a prediction

    @property
    def basis(self) -> str:
        """What the row is: "fitted" (the scene's unknowns were fitted on it), "input" (follows from the scene's
        settings) or "predicted"."""
        return "fitted" if self.fitted else "input" if self.input else "predicted"

    def rig_text(self) -> str:
        """The rig value with at least 4 significant digits and as many as the printed thesis value has (rig 100.05
        beside thesis 100.18, not 100), ``> bound`` for a result the run ended before, or n/a."""
        digits = max(4, len(f"{abs(self.thesis):g}".split("e")[0].replace(".", "").lstrip("0")))
        if self.rig is not None:
            return f"{self.rig:.{digits}g}"
        return f"> {self.beyond:.{digits}g}" if self.beyond is not None else "n/a"

    @property
    def verdict(self) -> str:
        if self.rig is None:                 # no value, but perhaps known to lie beyond a bound
            return "NO" if self.agrees is False else "n/a"
        return "-" if self.agrees is None else "yes" if self.agrees else "NO"

    @property
    def shown_unit(self) -> str:
        """`` N·m`` (a leading space; the scene's ``N*m`` as the console and report write it), ``°`` for ``deg``, ""
        for a count."""
        if self.unit in ("deg", "°"):
            return "°"
        return f" {self.unit.replace('*', '·')}" if self.unit else ""

    @property
    def difference(self) -> tuple[float, float | None] | None:
        """(rig − thesis in the row's unit, the same in % of the thesis value — None for a count or a thesis of 0);
        None without a rig value."""
        if self.rig is None:
            return None
        d = self.rig - self.thesis
        return d, (100 * d / abs(self.thesis) if self.thesis and self.unit else None)

    @property
    def deviation(self) -> str:
        """:attr:`difference` as text: rig − thesis in the row's unit, and its share (empty when n/a)."""
        difference = self.difference
        if difference is None:
            return ""
        d, share = difference
        return f"{d:+.3g}{self.shown_unit}" + ("" if share is None else f" ({share:+.3g} %)")


def read_rows(scene: Scene) -> list[dict[str, Any]]:
    """The scene's ``[[comparison]]`` rows, checked (empty without them)."""
    rows = scene.data.get("comparison", [])
    if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
        raise SceneError(f"{scene.path}: 'comparison' must be an array of tables ([[comparison]])")
    out = []
    for i, table in enumerate(rows):
        row = read_table(table, ROW_SCHEMA, f"{scene.path} [[comparison]] {i + 1}")
        if row["part"] not in PARTS:
            raise SceneError(f"{scene.path} [[comparison]] {i + 1}: part {row['part']!r} is not one of {PARTS}")
        out.append(row)
    return out


def _split(text: str, where: str) -> tuple[float, str, str]:
    """(number as written, unit as written, SI unit) of a thesis value such as "46.6 ms" or "2"."""
    text = str(text)                                    # a TOML number too (thesis = 2)
    m = re.fullmatch(r"\s*([-+0-9.eE]+)\s*(.*?)\s*", text)
    if m is None:
        raise SceneError(f"{where}: thesis value {text!r} is not a number with a unit")
    number, unit = float(m.group(1)), m.group(2)
    if not unit and not number.is_integer():        # 0.0466 read as a count, or 14.5 compared with a torque (an audit)
        raise SceneError(f"{where}: thesis value {text!r} has no unit, which makes it a count, and it is not a whole "
                         f"number: write its unit, e.g. \"{text} N*m\" or \"{text} ms\"")
    for si in ("N*m", "s", "rad", "rad/s", "J", "1"):
        try:
            to_si(f"1 {unit}" if unit else 1.0, si)
            return number, unit, si
        except UnitError:
            continue
    raise SceneError(f"{where}: unit {unit!r} of {text!r} is not a torque, time, angle, speed, energy or count")


@dataclass(frozen=True)
class Thesis:
    """One [[comparison]] row read: its spec, the thesis number and unit as written, the SI unit, and ``scale`` (SI
    per written unit); ``where`` names the row in errors."""

    spec: dict[str, Any]
    number: float
    unit: str
    si: str
    scale: float
    where: str

    @property
    def si_value(self) -> float:
        return self.number * self.scale


def _theses(scene: Scene) -> list[Thesis]:
    """The scene's [[comparison]] rows with their thesis values read."""
    out = []
    for spec in read_rows(scene):
        where = f"{scene.path} [[comparison]] {spec['quantity']!r}"
        number, unit, si = _split(spec["thesis"], where)
        out.append(Thesis(spec, number, unit, si, to_si(f"1 {unit}", si) if unit else 1.0, where))
    return out


def check_rows(scene: Scene, stimuli: list[Stimulus]) -> None:
    """Read every [[comparison]] row as :func:`compare` will — thesis value, unit, tolerance, and the stand results
    it names (``rig``, ``after``: one of :func:`rig.analysis.clutch_metrics.result_names` for the scene's
    ``stimuli``) — so a mistake is a SceneError naming the scene before anything is recorded."""
    known = result_names(stimuli)
    for th in _theses(scene):
        _agrees(th.spec["tolerance"], th.number, th.unit, th.si, th.scale, th.number, th.where)
        for key in ("rig", "after"):
            name = th.spec[key]
            if name and name not in known:
                close = difflib.get_close_matches(str(name), known, n=1, cutoff=0.6)
                raise SceneError(f"{th.where}: {key} = {name!r} is no result of this stand"
                                 + (f" (did you mean {close[0]!r}?)" if close else "")
                                 + f"; its results: {', '.join(known)}")


def _origins(stimuli: list[Stimulus]) -> Callable[[str], float]:
    """Time (s) of the stimulus a result named ``"<stimulus>: …"`` is measured from (0: the run's start)."""
    starts = {stimulus_label(s): s.time for s in stimuli}
    return lambda rig: next((t for label, t in starts.items() if rig.startswith(label + ":")), 0.0)


def compare(scene: Scene, stimuli: list[Stimulus], metrics: list[Metric]) -> list[Row]:
    """The rows of ``scene`` with the rig's values from the run's ``metrics`` (stimuli: for ``time_after``)."""
    by_name = {m.name: m for m in metrics}
    origin_of = _origins(stimuli)
    rows = []
    for th in _theses(scene):
        spec, number, unit, si, scale, where = th.spec, th.number, th.unit, th.si, th.scale, th.where
        metric, value, why = next((by_name[n] for n in (spec["rig"], *ALIASES.get(spec["rig"], ())) if n in by_name),
                                  None), None, ""
        after = by_name.get(spec["after"]) if spec["after"] else None
        if spec["after"] and not (after is not None and after.number()):
            metric, why = None, (f"the thesis value follows {spec['after']}, and this run has "
                                 f"{'none' if after is None else after.value_text()}: another event, not judged")
        if metric is None:
            why = why or f"no result {spec['rig']!r} in this run"
        elif spec["part"] == "value" and not same_kind(si, SI.get(metric.unit, metric.unit) or "1"):
            metric, why = None, (f"the thesis value {spec['thesis']!r} is {'a count' if si == '1' else f'in {unit}'}, "
                                 f"the rig's {metric.name!r} in {metric.unit or 'counts'}: not compared (write the "
                                 f"thesis with its unit)")
        elif spec["part"] == "value":
            value = metric.number()                          # a count "3, at …": 3; shutdown "required": 1
            if value is not None and not isinstance(metric.value, str):
                value = value * to_si(1.0, si, SI.get(metric.unit, metric.unit)) / scale
            why = "" if value is not None else metric.reference
            if value is not None and metric.name != spec["rig"]:
                why = f"the run's {metric.name!r}: it has no {spec['rig']!r} (no disengagement)"
        elif metric.at is None:
            why = f"{spec['rig']!r} has no time"
        else:
            value = (metric.at - (origin_of(spec["rig"]) if spec["part"] == "time_after" else 0.0)) / scale
        agrees = None if value is None else _agrees(spec["tolerance"], number, unit, si, scale, value, where)
        beyond = None
        if value is None and metric is not None and metric.exceeds is not None and spec["part"] == "value":
            beyond = metric.exceeds * to_si(1.0, si, SI.get(metric.unit, metric.unit)) / scale
            if str(spec["tolerance"]).strip() == "at most" and beyond > number:
                agrees = False                     # not reached when the run ended, already past the bound
        tolerance = str(spec["tolerance"]).strip() if spec["tolerance"] is not None else "" if unit else "exact"
        rows.append(Row(spec["quantity"], unit, number, value, bool(spec["fitted"]), why or spec["note"], agrees,
                        tolerance, beyond, bool(spec["input"])))
    return rows


@dataclass(frozen=True)
class Mark:
    """A thesis value drawn on the torque–time chart: a ``point`` (t, torque), a ``time`` (vertical line at t) or a
    ``level`` (horizontal line at a torque); SI (s, N·m)."""

    kind: str
    label: str
    t: float | None = None
    torque: float | None = None


def thesis_marks(scene: Scene, stimuli: list[Stimulus]) -> list[Mark]:
    """The scene's thesis values that have a place on the torque–time chart: a torque with its time (two rows of one
    rig result: value and time) as a point, a torque alone as a level, a time or a duration after its stimulus as a
    vertical line."""
    origin_of = _origins(stimuli)
    theses = _theses(scene)
    when = {th.spec["rig"]: (th.si_value + (origin_of(th.spec["rig"]) if th.spec["part"] == "time_after" else 0.0),
                             th.spec["thesis"]) for th in theses if th.spec["part"] != "value"}
    torques = {th.spec["rig"] for th in theses if th.spec["part"] == "value" and th.si == "N*m"}
    marks = []
    for th in theses:
        rig, part = th.spec["rig"], th.spec["part"]
        label = f"thesis: {th.spec['quantity']} {th.spec['thesis']}".replace("*", "·")
        if part == "value" and th.si == "N*m":
            marks.append(Mark("point", f"{label} at {when[rig][1]}", when[rig][0], th.si_value) if rig in when
                         else Mark("level", label, torque=th.si_value))
        elif part == "value" and th.si == "s":             # a duration from the result's stimulus
            marks.append(Mark("time", label, origin_of(rig) + th.si_value))
        elif part != "value" and rig not in torques:       # a time without its torque
            marks.append(Mark("time", label, when[rig][0]))
    return marks


def _agrees(tolerance: Any, thesis: float, unit: str, si: str, scale: float, rig: float, where: str) -> bool | None:
    """Whether ``rig`` agrees with ``thesis`` (both in ``unit``: ``scale`` of ``si``, its SI unit, per unit) under
    ``tolerance`` (module docstring)."""
    if tolerance is None:
        return rig == thesis if not unit else None
    text = str(tolerance).strip()
    if text in BOUNDS:
        return rig <= thesis if text == "at most" else rig >= thesis
    try:
        if text.endswith("%"):
            return abs(rig - thesis) <= to_si(text, "1") * abs(thesis)
        return abs(rig - thesis) <= to_si(text, si) / scale
    except UnitError as exc:
        raise SceneError(f"{where}: tolerance {text!r}: {exc} (use \"15 %\", a value in {unit or 'counts'}, "
                         f"\"at most\" or \"at least\")") from None


def write_csv(rows: list[Row], path: Path) -> Path:
    """``comparison.csv``: quantity, unit, thesis, rig (a number; empty: no value), rig beyond (X where the run ended
    before the result, which lies beyond X; else empty), agrees (yes / NO / - not judged / n/a), fitted (1/0), note,
    deviation (rig − thesis, in the row's unit), deviation [%] (of the thesis value; empty for a count or a thesis
    of 0), tolerance (as the scene writes it; "exact" for a count), basis (fitted / input / predicted). Every cell of
    the number columns is a number or empty (a spreadsheet reads them as numbers)."""
    def number(x: float | None, form: str = ".6g") -> str:
        return "" if x is None else f"{x:{form}}"

    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["quantity", "unit", "thesis", "rig", "rig beyond", "agrees", "fitted", "note", "deviation",
                    "deviation [%]", "tolerance", "basis"])
        for r in rows:
            d, share = r.difference or (None, None)
            w.writerow([r.quantity, r.unit, f"{r.thesis:g}", number(r.rig), number(r.beyond), r.verdict,
                        int(r.fitted), r.why, number(d), number(share, ".4g"), r.tolerance, r.basis])
    return path


def _inputs_text(group: list[Row], alone: bool) -> str:
    """The judged rows set by the scene's inputs: they check nothing of the model, so ``alone`` (no prediction or
    fitted row beside them) the line says first that the run checks nothing."""
    shown = sum(bool(r.agrees) for r in group)
    n = len(group)
    shown_text = "shown as set" if shown == n else "not shown as set" if n == 1 else f"{shown} of them shown as set"
    if alone:
        return (f"no check of the model here — its {plural(n, 'row')} {'is' if n == 1 else 'are'} set by the scene's inputs, "
                f"{shown_text}")
    return f"{plural(n, 'row')} set by the scene's inputs, {shown_text} (no check of the model)"


def agreement_text(rows: list[Row]) -> str:
    """One line: how many judged predictions agree with the thesis, how many fitted rows the run reproduces (a row
    fitted on this run agreeing says little) and how many rows set by the scene's inputs it shows as set (they check
    nothing of the model: with nothing else judged the line says so first), and which rows do not agree."""
    counts, details = agreement_parts(rows)
    return "; ".join(p for p in (counts, details) if p)


def agreement_parts(rows: list[Row]) -> tuple[str, str]:
    """:func:`agreement_text` in two: the counts (a report's headline) and the rows that disagree or have no value
    in this run (empty when none)."""
    judged = [r for r in rows if r.agrees is not None]
    off = [r for r in judged if not r.agrees]
    missing = [r for r in rows if r.rig is None and r.agrees is None]
    inputs = [r for r in judged if r.basis == "input"]
    parts = [f"{sum(bool(r.agrees) for r in group)} of {len(group)} {what}" for group, what in (
        ([r for r in judged if r.basis == "predicted"], "predictions agree with the thesis"),
        ([r for r in judged if r.basis == "fitted"], "rows fitted on this run reproduced"))
        if group]
    if inputs:
        parts.append(_inputs_text(inputs, alone=not parts))
    counts = "; ".join(parts) or ("no row judged (no row has a value in this run)" if len(missing) == len(rows) else
                                  "no row judged (no tolerances)")
    details = []
    if off:
        details.append("DISAGREE: " + "; ".join(f"{r.quantity} (thesis {r.thesis:g}{r.shown_unit}, "
                                                f"rig {r.rig_text()}{r.shown_unit})" for r in off))
    if missing:             # a result the run does not have is named (a misspelt rig = "…" was never said)
        details.append("n/a in this run: " + ", ".join(r.quantity + (f" ({r.why})" if r.why.startswith("no result ")
                                                                     else "") for r in missing))
    return counts, "; ".join(details)
