"""Lab sheets of the course labs (docs/labs.md) from a lab-bench recording, as the student fills them in.

Measured: what the host recorded from the CAN frames (the encoders' counts and edge times, the torque: the topics of
the transducers the scene wires to the plant signals ``phi_in``, ``phi_out``, ``torque``, whichever messages they
fill; ``/stand/lab_speed``, ``/stand/lab_display``, ``/stand/lab_motion``). Theory: the host's
nominal model in ``/plant/truth`` and the mechanism rebuilt from the recorded scene (rig.plants.lab_bench).
A scene lists its sheets in ``[lab] sheets``; each is a table, a figure and one summary line.
"""
from __future__ import annotations

import logging
import textwrap
from dataclasses import dataclass, field, replace
from math import cos, degrees, inf, radians, tau
from typing import Any, Callable

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from firmware_sim.transducers import REGISTRY
from firmware_sim.transducers.description import described, read_description, resolve_path, validate
from firmware_sim.transducers.encoder import power_on
from rig.analysis.export import cells, export_table
from rig.analysis.numbers import fixed
from rig.analysis.plots import figure, save
from rig.analysis.report_blocks import Block, Heading, ReportContext, Table, Text, fmt
from rig.plants.lab_bench import KINDS, LabBench
from rig.recorder import Recording
from rig.recorder.schemas import measuring
from rig.scene import Field, Scene, SceneError, read_table
from rig.analysis.units import unit as display_unit
from rig.units import UnitError, to_si, ureg

log = logging.getLogger(__name__)

RPM = tau / 60.0          # rad/s per rpm
LEGEND_WIDTH = 30         # characters per line of a legend entry beside a sheet's axes (2.3 in at "small")
STEP = radians(10.0)      # the sheets' angle step: 36 points per turn
TORQUE_PLACES = 4         # decimals of the cam-torque table's torque columns (N·m): one precision per column
LAB_SCHEMA = {"sheets": Field(None, doc="lab sheets of the run: speed, cam_follower, cam_torque, cardan, geneva"),
              "readings": Field(None, None, "times (with units) at which the speed sheet reads every instrument")}


@dataclass
class Sheet:
    """One filled-in lab sheet: its table, notes, a one-line result and the figure's drawing function."""

    title: str
    headers: list[str]
    rows: list[list[Any]]
    result: str
    notes: list[str] = field(default_factory=list)
    draw: Callable[[Any], None] | None = None
    values: dict[str, float] = field(default_factory=dict)     # the result line's numbers (unit: value_unit)
    panels: int = 1                      # stacked axes of the figure (draw gets a list of them when more than one)
    key: str = ""                        # its name in [lab] sheets (:data:`SHEETS`), set by :func:`lab_sheets`
    csv: tuple[list[str], list[list[Any]]] | None = None    # the table for lab_<key>.csv where the shown one joins
    #                                                         several numbers in a cell: one number per column


#: SI units of the sheets' result numbers (Sheet.values); names starting "error" or "class" are ratios
VALUE_UNITS = {"counter_rpm": "rpm", "truth_rpm": "rpm", "resolution_rpm": "rpm", "ds_max": "m", "lag": "s",
               "offset": "m", "rest_max": "m", "deviation_max": "N*m", "peak": "N*m", "work_per_turn": "J",
               "lag_error_max": "rad", "angle_error_max": "rad"}


def value_unit(name: str) -> str:
    """SI unit of the sheet result number ``name`` ("1": a ratio or a count); ``…_theory`` has its measured value's."""
    return VALUE_UNITS.get(name.removesuffix("_theory"), "1")


def shown_value(name: str, value: float) -> tuple[float, str]:
    """A sheet result number in its display unit, as the sheets show it (rig.analysis.units' rules): lengths in mm,
    angles in °, errors and relative deviations (``*_rel``) in %; (value, unit label)."""
    si = value_unit(name)
    if si == "1":
        return (100.0 * value, "%") if name.startswith(("error", "class")) or name.endswith("_rel") else (value, "")
    shown = display_unit(si)
    return float(shown(value)), shown.label


@dataclass
class Lab:
    """A lab-bench recording with its scene: the bench (theory), [lab], the transducer tables."""

    rec: Recording
    scene: Scene
    bench: LabBench
    lab: dict[str, Any]

    def description(self, to: str) -> dict[str, Any]:
        """The description of the transducer wired to ``to`` with the scene's overrides on top (as written)."""
        return _description(self.scene, to)

    def setting(self, to: str, key: str, unit: str) -> float:
        """A description value (SI) of the transducer wired to ``to``, its scene override first."""
        return _setting(self.scene, to, key, unit)

    def readings(self, topic: str, name: str) -> dict[str, np.ndarray]:
        """The recorded block ``topic`` that has field ``name``; SceneError naming what is missing."""
        block = self.rec.series.get(topic)
        if block is None or name not in block:
            raise SceneError(f"{self.rec.path}: no {name} readings ({topic}: is the transducer wired?)")
        return block

    def wired(self, signal: str) -> tuple[str, str]:
        """(``to``, recording topic) of the scene's transducer measuring the plant ``signal`` into a CAN reading (the
        sheets find their channels by what is measured, whichever message the scene routes it to)."""
        found = measuring(self.scene.data.get("transducers", {}), signal)
        if found is None:
            raise SceneError(f"{self.scene.path}: no transducer measures {signal!r} into a CAN reading "
                             "([transducers.*] signal and to)")
        return found

    def clipped(self, signal: str, values: np.ndarray, unit: str, scale: float = 1.0) -> str:
        """"" or a sentence saying how many ``values`` of the transducer measuring ``signal`` sit at its output
        limits (``clip_low``/``clip_high``: the input was beyond its range, the reading is the limit), shown in
        ``unit`` (SI × ``scale``)."""
        to = self.wired(signal)[0]
        try:                    # the output limits (V) through the output's linear map onto the measured range
            low, high = (self.setting(to, k, unit="V") for k in ("clip_low", "clip_high"))
            out = [self.setting(to, k, unit="V") for k in ("output_at_min", "output_at_max")]
            span = [self.setting(to, k, unit="1") for k in ("range_min", "range_max")]
        except (SceneError, ValueError, KeyError, TypeError):
            return ""
        low, high = (span[0] + (v - out[0]) / (out[1] - out[0]) * (span[1] - span[0]) for v in (low, high))
        near = 1e-6 * max(1.0, abs(low) if np.isfinite(low) else 0.0, abs(high) if np.isfinite(high) else 0.0)
        at = [(n, limit) for n, limit in ((int(np.count_nonzero(values <= low + near)), low),      # within the CAN
                                          (int(np.count_nonzero(values >= high - near)), high))    # field's rounding
              if n and np.isfinite(limit)]
        if not at:
            return ""
        where = " and ".join(f"{n} at {limit * scale:.4g} {unit}" for n, limit in at)
        return (f"{sum(n for n, _ in at)} of {values.size} readings sit at the transducer's output limit ({where}): "
                f"the input was beyond its range there, the reading is the limit — the comparison with the theory "
                f"(and any lag or offset fitted to it) is not a measurement there")

    def angle(self, signal: str = "phi_in") -> tuple[np.ndarray, np.ndarray]:
        """Angle (rad) of the shaft whose plant ``signal`` an encoder measures, at each edge that changed its count:
        (edge times s, angles rad), strictly increasing in time. The count starts at the shaft's angle at power-on
        (the zero marks aligned, as the lab sheet asks); the disc's lines sit at whole ×4 steps Δ = 2π/(4·ppr), so
        an edge is where the shaft crosses one of them, not at the power-on angle plus whole counts: with the card
        at k0 = ⌊θ_on/Δ⌋ at power-on, the ×N count (d = 4/N steps each) reaches R at the line
        ((⌈k0/d⌉ + R − 1)·d + 1)·Δ turning forwards (the shipped benches)."""
        to, topic = self.wired(signal)
        block = self.readings(topic, "edge_time")
        edge, angle = block["edge_time"], block["angle"]
        ok = np.isfinite(edge)
        edge, angle = edge[ok], angle[ok]
        keep = np.r_[True, np.diff(edge) > 0]
        return edge[keep], angle[keep] + self._line_offset(to, signal)

    def _line_offset(self, to: str, signal: str) -> float:
        """Angle (rad) to add to the driver's count angle R·d·Δ to give the disc line an edge of count R sits at: the
        card's start k0 by the encoder's own power-on rule (:func:`~firmware_sim.transducers.encoder.power_on`) from
        the plant's ``signal`` at the machine's first three sample times (the recording's sample rate); the angle at
        power-on where the description has no ppr or multiplier."""
        try:
            first = np.arange(1, 4) / float(self.rec.metadata["rig"]["sample_rate"])    # Hz, as the run had it
            ppr = int(round(self.setting(to, "ppr", unit="1")))
            d = 4 // int(round(self.setting(to, "multiplier", unit="1")))
            mount = self.setting(to, "mount_angle", unit="rad")
        except (SceneError, ValueError, KeyError, TypeError):
            return float(self.bench.truth(np.zeros(1))[signal][0])
        step = 2.0 * np.pi / (4 * ppr)
        _, k0 = power_on(first, self.bench.truth(first)[signal] + mount, step)
        return (-(-k0 // d) - 1) * d * step + step - mount


def _wired(scene: Scene, to: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """(description as written, the scene's overrides) of the transducer wired to ``to`` (e.g. 'can.LabSpeed.Pulses')."""
    table = next((t for t in scene.data.get("transducers", {}).values() if t.get("to") == to), None)
    if table is None:
        raise SceneError(f"{scene.path}: no transducer wired to {to!r}")
    return read_description(resolve_path(described(scene, table["description"]))), dict(table.get("overrides", {}))


def _description(scene: Scene, to: str) -> dict[str, Any]:
    """The description of the scene's transducer wired to ``to`` with the scene's overrides on top (as written)."""
    description, overrides = _wired(scene, to)
    return {**description, **overrides}


def _setting(scene: Scene, to: str, key: str, unit: str) -> float:
    """A description value (SI) of the scene's transducer wired to ``to`` as the transducer itself reads it: its
    scene override first, in any spelling the transducer's schema takes (``gate_time = "0.5 s"`` or
    ``gate_time_ms = 500``)."""
    description, overrides = _wired(scene, to)
    table = dict(description)
    cls = REGISTRY.get(table.pop("type", None))
    for flag in ("errors_enabled", "dynamics_enabled"):
        overrides.pop(flag, None)
    if cls is not None and key in cls.SCHEMA:
        return float(validate(table, overrides, cls.SCHEMA, f"{scene.path} [transducers] wired to {to}")[key])
    return to_si({**description, **overrides}.get(key), unit, what=f"{scene.path} [transducers] {key}")


def _check_reading_times(scene: Scene, times: list[float], where: str) -> None:
    """The speed sheet's reading times lie where every instrument has a reading: from the end of the pulse counter's
    first gate (its count is 0 before it) to the end of the run; SceneError naming the reading otherwise."""
    gate = _setting(scene, "can.LabSpeed.Pulses", "gate_time", "s")
    spelled = {k: v for k, v in scene.section("scene").items() if k == "duration" or k.startswith("duration_")}
    duration = read_table(spelled, {"duration": Field("s", None, "the run's length")}, f"{scene.path} [scene]")["duration"]
    end = inf if duration is None else duration                     # (duration = "6 s" or duration_s = 6, as the runner)
    for i, at in enumerate(times):
        if not gate <= at <= end:
            raise SceneError(f"{where}: readings[{i}] = {at:g} s is outside the run's readings: the pulse counter's "
                             f"first gate ends at {gate:g} s (it shows 0 before) and the run at {end:g} s")


def read_lab_section(scene: Scene) -> dict[str, Any]:
    """The scene's [lab] table, checked: known sheets, reading times with a time unit (the speed sheet needs at
    least one). ``rig run`` checks it before anything is recorded; SceneError naming the key otherwise."""
    where = f"{scene.path} [lab]"
    lab = read_table(scene.data.get("lab", {}), LAB_SCHEMA, where)
    unknown = [s for s in lab["sheets"] if s not in SHEETS] if isinstance(lab["sheets"], list) else [lab["sheets"]]
    if unknown:
        raise SceneError(f"{where}: unknown sheet(s) {unknown} (known: {', '.join(SHEETS)})")
    kind = scene.section("plant").get("kind")
    for sheet in lab["sheets"] if kind in KINDS else ():        # an unknown kind: the [plant] check says so
        if SHEET_PLANTS.get(sheet, kind) != kind:
            raise SceneError(f"{where}: sheet {sheet!r} needs a bench of [plant] kind = {SHEET_PLANTS[sheet]!r}, this "
                             f"scene's is {kind!r} (sheets for it: "
                             f"{', '.join(n for n in SHEETS if SHEET_PLANTS.get(n, kind) == kind)})")
    readings = lab["readings"] or []
    if not isinstance(readings, list):
        raise SceneError(f"{where}: 'readings' must be a list of times, e.g. [\"2.5 s\"]")
    try:
        lab["readings"] = [to_si(v, "s", what=f"{where} readings[{i}]") for i, v in enumerate(readings)]
    except UnitError as exc:
        raise SceneError(str(exc)) from None
    if "speed" in lab["sheets"]:
        if not lab["readings"]:
            raise SceneError(f"{where}: the speed sheet needs 'readings' (times, e.g. [\"2.5 s\"])")
        _check_reading_times(scene, lab["readings"], where)
    return lab


def read_lab(rec: Recording) -> Lab | None:
    """The lab of a recording; None when it is not a lab-bench recording (or holds no scene to say so);
    SceneError when its scene or [lab] is invalid."""
    if not rec.scene_text:
        return None
    scene = rec.scene()
    if scene.data.get("scene", {}).get("plant") != "lab_bench":
        return None
    return Lab(rec, scene, LabBench.from_scene(scene), read_lab_section(scene))


def _latest(t: np.ndarray, values: np.ndarray, at: float) -> float:
    """The latest reading at or before ``at`` (s); NaN before the first."""
    i = int(np.searchsorted(t, at, side="right")) - 1
    return float(values[i]) if i >= 0 else float("nan")


def _last_turn(t_edge: np.ndarray, angle: np.ndarray, start: float = 0.0) -> np.ndarray:
    """The 36 angles (rad, multiples of 10°) of the last whole turn the encoder saw with 10° to spare on both
    sides, and those two neighbours (for central differences): 38 angles. The turn begins at ``start`` (rad)."""
    end = np.floor((angle[-1] - STEP - start) / tau) * tau + start
    if end - tau - STEP < angle[0]:
        raise SceneError("the recording holds less than one whole turn of the input shaft (plus 10° each side)")
    return end - tau + STEP * np.arange(-1, 37)


def _dbc_signal(to: str) -> Any:
    """The DBC's signal a scene wires to as ``can.Message.Signal``."""
    from rig.dbc import load_dbc
    _, message, signal = to.split(".")
    return load_dbc().get_message_by_name(message).get_signal_by_name(signal)


def _counter_wrap() -> int:
    """The pulse counts the lab's counter holds (its DBC signal ``LabSpeed.Pulses``, counted modulo this)."""
    return 2 ** _dbc_signal("can.LabSpeed.Pulses").length


def _at_field_limit(to: str, values: list[float], unit: float = 1.0) -> bool:
    """Whether any of ``values`` (SI / ``unit``) of the signed CAN signal ``to`` (``can.Message.Signal``) sits at its
    field's limit: the unit sent the limit for a quantity beyond the field's range."""
    from rig.dbc import at_field_limit
    return bool(np.any(at_field_limit(_dbc_signal(to), np.asarray(values, float) * unit)))


def class_bound(lab: Lab, to: str, reading: float, counter_step: float) -> float:
    """Largest error (fraction of the reading) the data sheet allows the instrument wired to ``to`` reading
    ``reading`` (rad/s) against the counter, worst case: gain error, non-linearity (a fraction of full scale), half
    the dial step (``resolution``, in output units: mapped to the input through the range) and the counter's own
    step ``counter_step`` (rad/s). Keys the description lacks count 0."""
    desc = lab.description(to)

    def base(key: str) -> Any:
        return ureg.Quantity(desc[key]).to_base_units()

    gain = to_si(desc.get("gain_error_max", 0.0), "1", what=f"{to} gain_error_max")
    linear = to_si(desc.get("nonlinearity_max", 0.0), "1", what=f"{to} nonlinearity_max")
    span_in = to_si(desc["range_max"], "rad/s", what=f"{to} range_max") - \
        to_si(desc["range_min"], "rad/s", what=f"{to} range_min")
    dial = 0.0
    if "resolution" in desc:
        step, span_out = base("resolution"), base("output_at_max") - base("output_at_min")
        if step.dimensionality != span_out.dimensionality:
            raise SceneError(f"{lab.scene.path}: the resolution of the transducer wired to {to} ({desc['resolution']}) "
                             f"is not in its output's units ({desc['output_at_max']})")
        dial = float(step.magnitude / span_out.magnitude) * span_in
    return gain + (linear * span_in + 0.5 * dial + counter_step) / reading


def speed_sheet(lab: Lab) -> Sheet:
    """Three readings of each instrument against the pulse counter (rpm), error of each and of the mean, and
    whether that error is within the instrument's data-sheet class (:func:`class_bound`)."""
    rec = lab.rec
    holes = lab.setting("can.LabSpeed.Pulses", "holes", "1")
    gate = lab.setting("can.LabSpeed.Pulses", "gate_time", "s")
    times = lab.lab["readings"]
    pulses = rec.series.get("/stand/lab_speed", {})
    display = rec.series.get("/stand/lab_display", {})
    counter = [_latest(pulses["t"], pulses["pulses"], at) / (holes * gate) * 60.0 for at in times]
    empty = [at for at, c in zip(times, counter) if not c > 0.0]    # no pulse (or no count): no reference speed
    if empty:                                                       # (a ZeroDivisionError before)
        raise ValueError(f"the pulse counter counted no pulse in its gate before the reading at t = {empty[0]:.4g} s "
                         f"(one pulse per gate of {gate * 1e3:.4g} ms with the disc's {holes:.0f} holes is "
                         f"{60.0 / (holes * gate):.4g} rpm): the shaft too slow for this gate, or at rest — the sheet "
                         f"has no reference speed there (lengthen the counter's gate_time, or move the reading)")
    truth = rec.truth
    rows = [["pulse counter (N / (z·T))"] + [fmt(v) for v in counter] + [fmt(np.mean(counter)), "reference", ""]]
    n = len(times)
    table = [["pulse counter (N / (z·T))", *_csv(counter), *[None] * n, _csv(np.mean(counter)), None, None, None,
              None, None]]
    instruments = [("tachogenerator", pulses, "tacho", "can.LabSpeed.Tacho"),
                   ("mechanical tachometer", display, "tachometer", "can.LabDisplay.Tachometer"),
                   ("stroboscope (60·f_x)", display, "strobe", "can.LabDisplay.Strobe")]
    resolution = 60.0 / (holes * gate)
    reads = {name: [_latest(block["t"], block[key], at) / RPM for at in times]
             for name, block, key, _ in instruments if key in block}
    # the counter holds its pulses modulo 2^16: wrapped k times where the instruments read about k ranges above it
    # (rounded: robust to their few per cent)
    held = _counter_wrap()                                            # pulses the counter holds
    wrap = held / (holes * gate) * 60.0                               # rpm: the speed whose pulses fill the counter
    fastest = max((float(np.mean(r)) for r in reads.values()), default=0.0)
    wrapped = round((fastest - float(np.mean(counter))) / wrap) >= 1
    errors, bounds, classes, verdicts = {}, {}, {}, {}
    for name, block, key, to in instruments:
        if name not in reads:
            continue
        read = reads[name]
        errors[name] = (np.mean(read) - np.mean(counter)) / np.mean(counter)
        bounds[name] = class_bound(lab, to, float(np.mean(counter)) * RPM, resolution * RPM)
        classes[name] = lab.setting(to, "gain_error_max", "1")
        top = lab.setting(to, "range_max", "rad/s") / RPM
        verdicts[name] = within = ("not judged: the counter wrapped" if wrapped else
                                   "not judged: its readings sit at the CAN field's limit"
                                   if _at_field_limit(to, read, RPM) else
                                   f"beyond its range (to {top:.6g} rpm): no class holds there"
                                   if max(np.mean(counter), np.mean(read)) > top else
                                   "within" if abs(errors[name]) <= bounds[name] else "OUTSIDE")
        rows.append([name] + [f"{fmt(v)} ({fixed(100 * (v - c) / c, 2, sign=True)} %)" for v, c in zip(read, counter)]
                    + [fmt(np.mean(read)), f"{fixed(100 * errors[name], 2, sign=True)} %",
                       f"±{100 * bounds[name]:.2f} % (class ±{100 * classes[name]:.2g} %): {within}"])
        table.append([name, *_csv(read), *_csv([100 * (v - c) / c for v, c in zip(read, counter)]),
                      _csv(np.mean(read)), _csv(100 * errors[name]), _csv(100 * bounds[name]),
                      _csv(100 * classes[name]), {"within": "yes", "OUTSIDE": "no"}.get(within, within.split(":")[0]),
                      None])
    gate_truth = []                 # the truth over the gate whose count the reading shows: the last one completed
    for at in times:                # before that count's message (gates run from t = 0), not the second before it
        end = np.floor(_latest(pulses["t"], pulses["t"], at) / gate + 1e-9) * gate
        gate_truth.append(float(np.mean(truth["omega_in"][(truth["t"] > end - gate) & (truth["t"] <= end)])) / RPM)
    rows.append(["plant truth (mean over the gate)"] + [fmt(v) for v in gate_truth]
                + [fmt(np.mean(gate_truth)),
                   f"{fixed(100 * (np.mean(counter) - np.mean(gate_truth)) / np.mean(gate_truth), 2, sign=True)} % (counter)",
                   ""])
    at_reading = np.interp(times, truth["t"], truth["omega_in"]) / RPM
    rows.append(["plant truth at the reading"] + [fmt(v) for v in at_reading] + [fmt(np.mean(at_reading)), "", ""])
    table += [["plant truth (mean over the gate)", *_csv(gate_truth), *[None] * n, _csv(np.mean(gate_truth)), None,
               None, None, None, _csv(100 * (np.mean(counter) - np.mean(gate_truth)) / np.mean(gate_truth))],
              ["plant truth at the reading", *_csv(at_reading), *[None] * n, _csv(np.mean(at_reading)), None, None,
               None, None, None]]
    moved = float(np.max(np.abs(at_reading - np.asarray(gate_truth))))
    beyond = ([f"The instruments read up to {fastest:.6g} rpm, beyond the counter's range: {held} pulses "
               f"per gate = {wrap:.6g} rpm, where it wraps (its reading is the pulses modulo that) — the counter is "
               f"wrong here, not the instruments, which are not judged against it; shorten the gate or use a disc with "
               f"fewer holes."] if wrapped else [])
    drift = ([f"The shaft speed at the readings differs from its mean over the counted gates by up to {moved:.3g} rpm "
              f"(more than the counter's {resolution:.3g} rpm step): the instruments read the speed of the moment, the "
              f"counter that of the last completed gate, so their errors against it include the speed's change — "
              f"a limit exceeded here is not the instrument's fault alone."] if moved > resolution else [])

    def draw(ax: Any) -> None:
        ax.plot(truth["t"], truth["omega_in"] / RPM, color="0.5", lw=0.8, label="plant truth")
        counted = pulses["t"] >= gate                            # the counter shows 0 until its first gate ends
        ax.step(pulses["t"][counted], pulses["pulses"][counted] / (holes * gate) * 60.0, where="post",
                label="pulse counter")
        for name, block, key, _ in instruments:
            if key in block:
                (line,) = ax.plot(block["t"], block[key] / RPM, lw=0.8, label=name)
                ax.plot(times, reads[name], "x", ms=8, color=line.get_color())     # each one's readings, the table's
        ax.plot(times, counter, "kx", ms=8, label="readings (× on each instrument)")
        ax.set(xlabel="time (s)", ylabel="speed (rpm)", title="Speed measurement")

    return Sheet("Speed measurement", ["instrument", *[f"reading {i + 1} (rpm)" for i in range(len(times))],
                                       "mean (rpm)", "error of the mean vs counter", "worst-case limit (data sheet + dials)"], rows,
                 "; ".join(f"{k} {100 * v:+.2f} % ({verdicts[k]} its worst-case ±{100 * bounds[k]:.2f} %)"
                           if verdicts[k] in ("within", "OUTSIDE") else f"{k} {100 * v:+.2f} % ({verdicts[k]})"
                           for k, v in errors.items()) + " against the counter"
                 + (f" (the shaft's speed at the readings differs from the counted gates' by up to {moved:.3g} rpm: "
                    "these errors include that change)" if drift else "")
                 + (f" (the counter wrapped: the instruments read beyond its range of {wrap:.6g} rpm)" if beyond
                    else ""),
                 [f"Counter resolution: one pulse in the gate = 60/(z·T) = {resolution:.4g} rpm "
                  f"(z = {holes:g} holes, T = {gate:g} s).", *drift, *beyond,
                  "The stroboscope's image also stands still at f_i/k: a reading near 1/k of the others means the "
                  "flash rate was a sub-multiple (its 'divisor').",
                  "Worst-case limit against the counter: the data-sheet class (gain error) + non-linearity × full "
                  "scale + half the dial step + one counter step, each from the instrument's description "
                  "(data/devices)."], draw,
                 {"counter_rpm": float(np.mean(counter)), "truth_rpm": float(np.mean(gate_truth)),
                  "resolution_rpm": resolution, **{f"error {k}": float(v) for k, v in errors.items()},
                  **{f"class {k}": float(v) for k, v in bounds.items()}},
                 csv=(["instrument", *[f"reading {i + 1} (rpm)" for i in range(n)],
                       *[f"reading {i + 1} error vs counter (%)" for i in range(n)], "mean (rpm)",
                       "error of the mean vs counter (%)", "worst-case limit (%)", "data-sheet class (%)",
                       "within the limit", "counter error vs it (%)"], table))


def _csv(v: Any) -> Any:
    """CSV cells of a number or a list of them, to 6 significant digits (:func:`rig.analysis.export.cells`)."""
    out = cells(np.atleast_1d(np.asarray(v, dtype=float)), 6)
    return out if np.ndim(v) else out[0]


def cam_follower_sheet(lab: Lab) -> Sheet:
    """Follower position every 10° of cam angle, differenced numerically against the law's s, s', s''."""
    program = lab.bench.mechanism
    t_edge, phi = lab.angle("phi_in")
    motion = lab.readings("/stand/lab_motion", "displacement")
    grid = _last_turn(t_edge, phi)
    s = np.interp(np.interp(grid, phi, t_edge), motion["t"], motion["displacement"])
    d1 = (s[2:] - s[:-2]) / (2 * STEP)
    d2 = (s[2:] - 2 * s[1:-1] + s[:-2]) / STEP ** 2
    law = program.evaluate(grid[1:-1])
    exact = program.evaluate(grid)
    law_d2 = (exact.s[2:] - 2 * exact.s[1:-1] + exact.s[:-2]) / STEP ** 2       # the law differenced the same way
    rows = [[f"{np.degrees(p) % 360:.0f}", fixed(1e3 * a, 3), fixed(1e3 * b, 3), fixed(1e6 * (a - b), 1, sign=True),
             fixed(1e3 * c, 3), fixed(1e3 * e, 3), fixed(1e3 * f, 2), fixed(1e3 * g, 2)]
            for p, a, b, c, e, f, g in zip(grid[1:-1], s[1:-1], law.s, d1, law.s_p, d2, law.s_pp)]
    peak1, peak2 = np.max(np.abs(law.s_p)), np.max(np.abs(law.s_pp))
    # the difference as a reading lag and an offset: s − law ≈ −(ω τ)·s' + c by least squares, and what remains
    diff = s[1:-1] - law.s
    (slope, offset), *_ = np.linalg.lstsq(np.column_stack([law.s_p, np.ones_like(diff)]), diff, rcond=None)
    lag = -slope / lab.bench.speed.nominal_omega
    rest = diff - slope * law.s_p - offset
    values = {"ds_max": float(np.max(np.abs(s[1:-1] - law.s))), "lag": float(lag), "offset": float(offset),
              "rest_max": float(np.max(np.abs(rest))),
              "d1_rel": float(np.max(np.abs(d1 - law.s_p)) / peak1), "d2_rel": float(np.max(np.abs(d2 - law.s_pp)) / peak2),
              "law_d2_rel": float(np.max(np.abs(law_d2 - law.s_pp)) / peak2)}
    clipped = lab.clipped("s", motion["displacement"], "mm", 1e3)
    result = (f"{clipped}; " if clipped else "") + (
              f"max |s − law| {1e6 * np.max(np.abs(s[1:-1] - law.s)):.1f} µm = a reading lag of {1e3 * lag:.2f} ms "
              f"and an offset of {1e6 * offset:+.1f} µm (least squares) with {1e6 * np.max(np.abs(rest)):.1f} µm left; s' within "
              f"{100 * np.max(np.abs(d1 - law.s_p)) / peak1:.1f} %, s'' within {100 * np.max(np.abs(d2 - law.s_pp)) / peak2:.1f} % "
              f"of their peaks (the law itself differenced at 10°: s'' within "
              f"{100 * np.max(np.abs(law_d2 - law.s_pp)) / peak2:.1f} %)")

    def draw(axes: list[Any]) -> None:
        fine = np.linspace(0, tau, 721)
        m = program.evaluate(fine)
        deg = np.degrees(grid[1:-1]) % 360
        order = np.argsort(deg)
        for ax, (values, law_values, label, unit) in zip(axes, ((s[1:-1], m.s, "s", "mm"), (d1, m.s_p, "s'", "mm/rad"),
                                                               (d2, m.s_pp, "s''", "mm/rad²"))):
            line, = ax.plot(np.degrees(fine), 1e3 * law_values, lw=0.9, label=f"law {label}")
            ax.plot(deg[order], 1e3 * values[order], "o", ms=3, color=line.get_color(), label=f"measured {label}")
            ax.set_ylabel(f"{label} ({unit})")
        axes[0].set_title("Cam follower: position every 10°, its first and second differences")
        axes[-1].set_xlabel("cam angle (°)")

    return Sheet("Cam follower", ["cam angle (°)", "s measured (mm)", "s law (mm)", "difference (µm)",
                                  "ds/dφ numerical (mm/rad)", "ds/dφ law (mm/rad)", "d²s/dφ² numerical (mm/rad²)",
                                  "d²s/dφ² law (mm/rad²)"], rows, result,
                 ["Central differences at h = 10°: the truncation error of s'' is h²/12·s'''' — see the law "
                  "differenced the same way in the result line; the rest is the LVDT and the encoder.",
                  f"Positions read on the last whole turn the encoder saw (with 10° to spare on each side, for the "
                  f"differences): from {float(np.interp(grid[0], phi, t_edge)):.3g} s to "
                  f"{float(np.interp(grid[-1], phi, t_edge)):.3g} s (the cam-shaft torque sheet averages over every "
                  f"turn from the first whole one on)."], draw, values,
                 panels=3)


def cam_torque_sheet(lab: Lab) -> Sheet:
    """Cam-shaft torque from the torque transducer, averaged per 10° of cam angle, against theory."""
    truth = lab.rec.truth
    t_edge, phi = lab.angle("phi_in")
    torque = lab.readings(lab.wired("torque")[1], "torque")
    inside = (torque["t"] >= t_edge[0]) & (torque["t"] <= t_edge[-1])
    angle = np.interp(torque["t"][inside], t_edge, phi)
    whole = angle >= np.ceil(angle[0] / tau) * tau                  # from the first whole turn on
    angle, measured = angle[whole], torque["torque"][inside][whole]
    bins = np.floor((angle % tau) / STEP).astype(int)
    theory_at = lambda p: np.interp(p, truth["phi_in"], truth["torque"])      # noqa: E731
    rows, spans, dev, means = [], [], [], []          # spans: the rows with the angles as numbers (the CSV)
    for k in range(36):
        here = bins == k
        if not here.any():
            continue
        mean = float(np.mean(measured[here]))
        theory = float(np.mean(theory_at(angle[here])))
        dev.append(mean - theory)
        means.append((10 * k + 5, mean))
        cells = [fixed(mean, TORQUE_PLACES), fixed(theory, TORQUE_PLACES), fixed(mean - theory, TORQUE_PLACES,
                                                                                   sign=True), int(here.sum())]
        rows.append([f"{10 * k}–{10 * k + 10}", *cells])
        spans.append([10 * k, 10 * k + 10, *cells])
    turns = np.floor((angle[-1] - angle[0]) / tau)
    span = angle <= angle[0] + turns * tau                          # whole turns only
    work = float(np.trapezoid(measured[span], angle[span])) if turns >= 1 else float("nan")
    # the theory over the same turns: the change of the cam's and follower's energy there (0 at constant speed, where
    # spring, mass and weight give back what they take; a speed ripple leaves ½J·Δω² and ½m·Δv²)
    expected = float(np.trapezoid(theory_at(angle[span]), angle[span])) if turns >= 1 else float("nan")
    peak = float(np.max(np.abs(truth["torque"])))
    clipped = lab.clipped("torque", torque["torque"], "N·m")
    result = (f"{clipped}; " if clipped else "") + (
              f"max |measured − theory| per 10° bin {np.max(np.abs(dev)):.4f} N·m ({100 * np.max(np.abs(dev)) / peak:.1f} % "
              f"of the {peak:.3g} N·m peak); work per turn ∮M dφ = {work / max(turns, 1e-9):.4f} J (theory over the same "
              f"turns {fixed(expected / max(turns, 1e-9), 4)} J: the cam's and follower's energy change, 0 at constant speed)")

    def draw(ax: Any) -> None:
        fine = np.linspace(angle[0], angle[0] + tau, 721)
        order = np.argsort(fine % tau)
        ax.plot(np.degrees(fine % tau)[order], theory_at(fine)[order], "-", lw=0.9, color="tab:red",
                label="theory M = F·ds/dφ + J·ω̇", zorder=1)
        ax.plot(np.degrees(angle % tau), measured, ".", ms=3, color="tab:blue", alpha=0.5, label="measured",
                zorder=2)                       # visible where it lies on the theory (at 1 px it was lost under it)
        ax.plot(*zip(*means), "s", ms=3.5, mfc="none", color="k", label="measured, 10° means",
                zorder=3)
        ax.set(xlabel="cam angle (°)", ylabel="torque (N·m)", title="Cam-shaft torque")

    headers = ["cam angle (°)", "measured mean (N·m)", "theory (N·m)", "difference (N·m)", "readings"]
    return Sheet("Cam-shaft torque", headers, rows, result,
                 ["The torque shaft is elastic: its 1 kHz bandwidth and the reading rate set how fast a torque "
                  "change is seen.",
                  f"Readings from the first whole turn on ({np.degrees(angle[0]):.0f}° of cam angle, "
                  f"{float(np.interp(angle[0], phi, t_edge)):.3g} s: the start before it is left out), over "
                  f"{(angle[-1] - angle[0]) / tau:.2f} turns: a bin the turns pass more often holds more readings "
                  f"(the last column); the work per turn over the {turns:.0f} whole one(s)."], draw,
                 {"deviation_max": float(np.max(np.abs(dev))), "peak": peak, "work_per_turn": work / max(turns, 1.0),
                  "work_per_turn_theory": expected / max(turns, 1.0)},
                 csv=(["cam angle from (°)", "cam angle to (°)", *headers[1:]], spans))


def cardan_sheet(lab: Lab) -> Sheet:
    """Output angle and speed ratio ω2/ω1 at 36 points of the input turn, against the closed forms."""
    cardan = lab.bench.mechanism
    t1, phi1 = lab.angle("phi_in")
    t2, phi2 = lab.angle("phi_out")
    grid = _last_turn(t1, phi1)
    if np.any(np.diff(phi1) <= 0) or np.any(np.diff(phi2) <= 0):
        raise ValueError("a Cardan shaft turned back: the sheet needs both shafts turning one way (a speed profile "
                         "that stays above 0)")
    # the angles between readings as cubic splines through them (a straight line missed the output angle by up to
    # h²/8·max|φ2''|: 0.66° at 6000 rpm, 36° of input between the 1 kHz readings; an audit)
    time_at, output_at = CubicSpline(phi1, t1), CubicSpline(t2, phi2)
    out = output_at(time_at(grid))
    ratio = (out[2:] - out[:-2]) / (2 * STEP)
    theory = cardan.speed_ratio(grid[1:-1])
    exact_out = cardan.output_angle(grid)
    differenced = (exact_out[2:] - exact_out[:-2]) / (2 * STEP)     # the closed form through the same differences
    lag = out[1:-1] - grid[1:-1]
    lag_theory = exact_out[1:-1] - grid[1:-1]
    rows = [[f"{np.degrees(p) % 360:.0f}", fixed(np.degrees(a), 3, sign=True), fixed(np.degrees(b), 3, sign=True),
             fixed(c, 4), fixed(e, 4), fixed(100 * (c - e) / e, 2, sign=True), fixed(d, 4)]
            for p, a, b, c, d, e in zip(grid[1:-1], lag, lag_theory, ratio, theory, differenced)]
    a = cardan.shaft_angle
    turn = output_at(time_at([grid[1], grid[1] + tau]))     # φ2 over one whole input turn
    spacing = float(np.median(np.diff(phi1[phi1 >= grid[0]])))          # input angle between readings (rad)
    sparse = ([f"The readings lie {np.degrees(spacing):.3g}° of input angle apart, more than the table's "
               f"{np.degrees(STEP):.3g}° step: its rows between them are the spline's, not measured — read the "
               f"encoders faster or turn the input slower."] if spacing > STEP else [])
    mean = (turn[1] - turn[0]) / tau
    result = (f"ω2/ω1 from {ratio.min():.4f} to {ratio.max():.4f} (the closed form differenced the same way: "
              f"{differenced.min():.4f} to {differenced.max():.4f}; exact cos α = {cos(a):.4f}, 1/cos α = "
              f"{1 / cos(a):.4f}); mean over the turn {mean:.5f} (theory 1)"
              + (f" (the readings lie {np.degrees(spacing):.3g}° apart, more than the table's step)" if sparse else ""))

    def draw(ax: Any) -> None:
        fine = np.linspace(0, tau, 721)
        ax.plot(np.degrees(fine), cardan.speed_ratio(fine), lw=0.9, label="theory cos α/(1 − sin²α cos²φ1)")
        ax.plot(np.degrees(grid[1:-1]) % 360, ratio, "o", ms=3, label="measured (two encoders, 36 points)")
        ax.axhline(cos(a), ls=":", color="0.5", label=f"extremes cos α = {cos(a):.4f} and 1/cos α = {1 / cos(a):.4f}")
        ax.axhline(1 / cos(a), ls=":", color="0.5")
        ax.set(xlabel="input angle φ1 (°)", ylabel="ω2/ω1", title=f"Cardan joint at α = {np.degrees(a):.3g}°")

    return Sheet("Cardan joint", ["φ1 (°)", "φ2 − φ1 measured (°)", "φ2 − φ1 theory (°)",
                                  "ω2/ω1 measured", "ω2/ω1 theory, same differences", "measurement error (%)",
                                  "ω2/ω1 theory, exact"], rows, result,
                 ["ω2/ω1 by central differences of the output angle over ±10° of input angle. The measurement "
                  "error is against the closed-form φ2 differenced the same way; the exact ratio differs from that "
                  f"by the differences' own truncation (up to {100 * np.max(np.abs(differenced / theory - 1)):.2f} %).",
                  f"The encoders are read every {np.degrees(spacing):.3g}° of input angle; the angles at the table's "
                  "points are cubic splines through the readings (each the angle of its latest edge, at that edge's "
                  "time).", *sparse],
                 draw,
                 {"ratio_min": float(ratio.min()), "ratio_max": float(ratio.max()), "ratio_mean": float(mean),
                  "lag_error_max": float(np.max(np.abs(lag - lag_theory))),
                  "ratio_error_max": float(np.max(np.abs(ratio / differenced - 1)))})


def _counted(t: np.ndarray, edge: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """An encoder's angle at times ``t`` from its count changes (``edge`` s, ``angle`` rad): interpolated between
    readings that follow each other at the reading rate (a moving shaft), the last count held across a longer
    gap (a shaft at rest, e.g. a Geneva wheel in its dwell, does not creep between its last and next count)."""
    i = np.clip(np.searchsorted(edge, t, side="right") - 1, 0, edge.size - 2)
    gap = edge[i + 1] - edge[i]
    moving = gap <= 2.0 * np.median(np.diff(edge))
    return np.where(moving & (t >= edge[i]), np.interp(t, edge, angle), angle[i])


def _counted_motion_ratio(geneva: Any, count: float) -> float:
    """The share of a crank turn (at constant crank speed) in which the wheel moves from ``count`` (rad) past one dwell
    to ``count`` before the next: the motion a counting encoder sees when both of its ends fall on a count boundary,
    the shortest it can see."""
    end = np.pi / geneva.slots
    phi = brentq(lambda p: float(geneva.kinematics(p).angle) + end - count, -geneva.engagement_half_angle, 0.0,
                 xtol=1e-14)
    return -2.0 * phi / tau


def geneva_sheet(lab: Lab) -> Sheet:
    """Wheel angle every 10° of crank and the measured motion and dwell times against k_m = (z − 2)/(2z)."""
    geneva, truth = lab.bench.mechanism, lab.rec.truth
    t1, phi1 = lab.angle("phi_in")
    t2, phi2 = lab.angle("phi_out")
    grid = _last_turn(t1, phi1, start=np.pi)[1:-1]              # from the middle of a dwell
    wheel = _counted(np.interp(grid, phi1, t1), t2, phi2)
    theory = np.interp(grid, truth["phi_in"], truth["phi_out"])
    wheel_rel, theory_rel = wheel - wheel[0], theory - theory[0]      # both from the first row (the encoder's zero
                                                                      # is arbitrary)
    rows = [[fixed((np.degrees(p) + 180) % 360 - 180, 0), fixed(np.degrees(a), 2), fixed(np.degrees(b), 2),
             fixed(np.degrees(a - b), 3, sign=True)] for p, a, b in zip(grid, wheel_rel, theory_rel)]
    timing = geneva.timing(lab.bench.speed.nominal_omega)
    count = tau / (lab.setting(lab.wired("phi_out")[0], "ppr", "1") * 4)          # rad per ×4 count of the wheel encoder
    index = tau / geneva.slots
    read = lab.readings(lab.wired("phi_out")[1], "edge_time")["t"]      # the wheel encoder's reading times
    rest = 0.5 * timing.dwell_time
    gaps = np.r_[[-1] if t2[0] - read[0] > rest else [],                # dwells between two indexings (the readings
                 np.flatnonzero(np.diff(t2) > rest),                      # before the first count change and after the
                 [t2.size - 1] if read[-1] - t2[-1] > rest else []].astype(int)    # last one too, when as long)
    runs = [(a + 1, b) for a, b in zip(gaps[:-1], gaps[1:])]            # whole indexings: first to last count change,
    motion = [t2[b] - t2[a] for a, b in runs if abs(phi2[b] - phi2[a]) >= 0.5 * index]   # not a count flickering at rest
    measured = float(np.mean(motion)) if motion else float("nan")
    one_count = _counted_motion_ratio(geneva, count)
    # the card latches only its latest edge: the reading after the motion's first count change shows the last edge
    # before it, up to one reading interval later (at 2000 rpm, 0.5 ms of a 30 ms period: k_m read 0.2779 below the
    # whole-count bound 0.2798 with no word; an audit)
    late = float(np.median(np.diff(read))) / timing.period
    low = one_count - late
    k_m = measured / timing.period
    outside = bool(motion) and not low - 1e-9 <= k_m <= timing.motion_ratio + 1e-9     # (no indexing: NaN, no band)
    result = (f"motion {1e3 * measured:.2f} ms, dwell {1e3 * (timing.period - measured):.2f} ms of "
              f"{1e3 * timing.period:.2f} ms: k_m = {k_m:.4f} (theory (z − 2)/(2z) = "
              f"{timing.motion_ratio:.4f}; seen by a counting encoder, from the first to the last count change, "
              f"between {low:.4f} (a whole count at both ends: {one_count:.4f}, less the first change seen up to one "
              f"reading late: {late:.4f}) and {timing.motion_ratio:.4f}{' — OUTSIDE that band' if outside else ''})")

    def draw(ax: Any) -> None:
        crank = np.degrees(grid - grid[0]) - 180.0
        ax.plot(crank, np.degrees(theory - theory[0]), "-", lw=0.9, label="theory")
        ax.plot(crank, np.degrees(wheel - wheel[0]), "o", ms=3, label="measured (wheel encoder)")
        ax.set(xlabel="crank angle from the centre line (°)", ylabel="wheel angle (°)", title=f"Geneva drive, z = {geneva.slots}")

    return Sheet("Geneva drive", ["crank angle from the centre line (°)", "wheel measured (°)", "wheel theory (°)",
                                  "difference (°)"], rows, result,
                 [f"Motion time: from the first to the last count change of the wheel encoder "
                  f"({tau / count:.0f} counts per turn) in each index, averaged over {len(motion)} indexings; the wheel "
                  "enters and leaves its motion tangentially (zero speed), so a counting encoder sees it start "
                  "late and stop early.",
                  f"The wheel encoder is read every {1e3 * late * timing.period:.3g} ms and latches only its latest "
                  f"edge: the reading after the motion's first count change shows a later edge when the wheel has "
                  f"moved on by more than a count, so the motion seen may be up to one reading interval "
                  f"({100 * late:.2g} % of the period) shorter; the last change is seen exactly (the wheel then "
                  f"rests)."], draw,
                 {"k_m": k_m, "k_m_theory": timing.motion_ratio, "k_m_one_count": float(one_count),
                  "k_m_low": float(low),
                  "indexings": float(len(motion)), "angle_error_max": float(np.max(np.abs(wheel_rel - theory_rel)))})


SHEETS: dict[str, Callable[[Lab], Sheet]] = {"speed": speed_sheet, "cam_follower": cam_follower_sheet,
                                             "cam_torque": cam_torque_sheet, "cardan": cardan_sheet,
                                             "geneva": geneva_sheet}


#: the bench (``[plant] kind``) a sheet needs; a sheet not named here works on any bench
SHEET_PLANTS = {"cam_follower": "cam", "cam_torque": "cam", "cardan": "cardan", "geneva": "geneva"}


def lab_sheets(rec: Recording) -> list[Sheet] | None:
    """The filled-in sheets of a lab recording (None: not a lab-bench recording)."""
    lab = read_lab(rec)
    return None if lab is None else [replace(SHEETS[name](lab), key=name) for name in lab.lab["sheets"]]


def summary_lines(sheets: list[Sheet], rec: Recording | None = None) -> list[str]:
    """Console lines of a lab run: each sheet's result (its :func:`lab_sheets`), then :func:`lab_warnings`."""
    return [f"lab sheet {s.key} ({s.title.lower()}): {s.result}" for s in sheets] + [
        f"warning: {w}" for w in (lab_warnings(rec) if rec is not None else [])]


def lab_warnings(rec: Recording) -> list[str]:
    """What makes a lab run's sheets not hold: a follower that would lift off (:func:`lift_warning`), a counter card
    that lost the shaft (:func:`encoder_warnings`), readings at their CAN field's limit (:func:`limit_warnings`)."""
    lift = lift_warning(rec)
    return ([lift] if lift else []) + encoder_warnings(rec) + limit_warnings(rec)


def limit_warnings(rec: Recording) -> list[str]:
    """One line per signal whose readings sat at its CAN field's limit (``reading_at_limit`` events; the count from
    ``link_summary``): the quantity was beyond what the frame carries, so sheet values taken from it are the limit."""
    totals = next((e.get("readings_at_limit", {}) for e in rec.events if e.get("kind") == "link_summary"), {})
    lines = []
    for e in (e for e in rec.events if e.get("kind") == "reading_at_limit"):
        key = f"{e.get('message', '?')}.{e.get('signal', '?')}"
        value = f"{e.get('limit', float('nan')):g} {e.get('unit', '')}".rstrip()
        lines.append(f"{key} read {value}, the limit of its CAN field, from t = {e['t']:.4g} s "
                     f"({totals.get(key, '?')} readings in all): the quantity was beyond what the frame carries, so "
                     f"sheet values taken from it are the limit, not the measurement")
    return lines


def encoder_warnings(rec: Recording) -> list[str]:
    """One line per counter whose card counted illegal transitions (``encoder_illegal`` events): from there its count
    may be off the shaft, and so may every sheet value taken from it (an output encoder at a Cardan angle of 89.9°
    sees 2.35 M edges/s against its card's 1 MHz: the sheet read a mean ratio of 0.38 instead of 1)."""
    return [f"counter {e.get('message', '?')} counted illegal transitions from t = {e['t']:.4g} s (edges faster than "
            f"its card follows, or glitches): from there its count may be off the shaft, and so may the sheet values "
            f"taken from it" for e in rec.events if e.get("kind") == "encoder_illegal"]


def lift_warning(rec: Recording) -> str | None:
    """What the ``follower_lift`` events of a cam bench say (None without any): the follower would leave the cam."""
    lifts = [e for e in rec.events if e.get("kind") == "follower_lift"]
    if not lifts:
        return None
    worst = min(lifts, key=lambda e: e.get("force", 0.0))
    nan = float("nan")
    return (f"the follower would lift off the cam {len(lifts)} time(s) (from cam angle "
            f"{degrees(worst.get('cam_angle', nan)):.4g}° at t = {worst['t']:.4g} s, the contact force its law needs "
            f"down to {worst.get('force', nan):.3g} N at {degrees(worst.get('min_cam_angle', nan)):.4g}°, t = "
            f"{worst.get('min_t', nan):.4g} s): spring and weight do not hold it on the cam at this speed, so the bench's "
            f"law-following model and these sheets' theory do not hold there (lower the speed, or stiffen or preload "
            f"the spring)")


def lab_section(ctx: ReportContext) -> list[Block]:
    try:
        sheets = lab_sheets(ctx.recording)
    except (SceneError, ValueError) as exc:
        log.warning("lab: no sheet in the report (%s)", exc)       # on the console too: the report leaves it out
        return [Heading("Lab sheets"), Text(f"No lab sheet: {exc}", "warning"),   # and what may have caused it
                *[Text(f"Warning: {w}.", "warning") for w in lab_warnings(ctx.recording)]]
    if sheets is None:
        return []
    blocks: list[Block] = [Heading("Lab sheets"), Table(["sheet", "result"], [[sheet.title, sheet.result]
                                                                               for sheet in sheets])]
    blocks += [Text(f"Warning: {w}.", "warning") for w in lab_warnings(ctx.recording)]
    for sheet in sheets:
        blocks += [Heading(sheet.title, 3), Text(sheet.result)]
        if sheet.draw is not None:
            fig, axes = figure(sheet.panels, size=(9, 4.2 if sheet.panels == 1 else 2.4 * sheet.panels),
                               sharex=sheet.panels > 1, squeeze=False)
            panels = list(axes[:, 0])
            sheet.draw(panels if sheet.panels > 1 else panels[0])
            for ax in panels:
                ax.grid(alpha=0.3)
                handles, labels = ax.get_legend_handles_labels()      # wrapped to fit the margin beside the axes
                ax.legend(handles, [textwrap.fill(text, LEGEND_WIDTH) for text in labels], fontsize="small",
                          loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
            path = save(fig, ctx.figure_path(f"lab_{sheet.key}"), right=2.3)        # legend beside the axes: no data hidden
            blocks.append(ctx.figure(path, sheet.title))
        blocks.append(Table(sheet.headers, sheet.rows))
        headers, rows = sheet.csv or (sheet.headers, sheet.rows)
        ctx.exported.append((export_table(headers, rows, ctx.out_dir / f"lab_{sheet.key}.csv"),
                             f"the {sheet.title.lower()} sheet's table" + (", one number per column" if sheet.csv
                                                                           else ", as above")))
        blocks += [Text(note, "note") for note in sheet.notes]
    return blocks

