"""Report section and console summary for dynamic clutch-stand recordings.

The key results (:func:`rig.analysis.clutch_metrics.stand_metrics`) are judged against what the
recorded scene did to the stand (:func:`stimuli`): a start from rest, load steps, a stop, shocks, or a
quasi-static sweep of a blocked half — so an overshoot is given only after a step, a settling time only
when the torque settles inside the run, and each value says what it is relative to. Speeds are the
host's encoder speeds (``/stand/encoder<n>`` ``speed``: mixed frequency/period method on the latched
edge times, :class:`drivers.encoder.SpeedEstimator`); angles are taken at the edge times, where the
count is exact.
"""
from __future__ import annotations

import math
import textwrap
from typing import Any

import numpy as np

from drivers.encoder import EDGE_TOLERANCE, SpeedEstimator
from rig.analysis.clutch_metrics import APEX, LOBE, Metric, StandRecord, Stimulus, stand_metrics, stimuli
from rig.analysis.event_text import event_details
from rig.analysis.plots import figure, save
from rig.analysis.report_blocks import Banner, Block, Heading, Link, ReportContext, Table, Text
from rig.analysis.stand_comparison import agreement_parts, agreement_text, compare, thesis_marks, write_csv
from rig.analysis.units import display_units, scene_device_config
from rig.recorder import Recording
from rig.recorder.schemas import measuring
from rig.scene import Scene, SceneError, read_table

BAND = 0.05        # settling band: ±5 % of the step (or of the shock)
DWELL = 0.05       # s the torque must stay inside the band (and the window of final levels)


def _scene(rec: Recording) -> Scene | None:
    try:
        return rec.scene()
    except SceneError:
        return None


def _when(s: Stimulus) -> str:
    """'stop at 0.5 s', 'shock from 0.1 s to 0.155 s' (a pulse's span, shaded on the chart)."""
    if s.kind == "shock" and s.duration:
        return f"shock from {s.time:.4g} s to {s.time + s.duration:.4g} s (shaded)"
    return f"{s.kind} at {s.time:.4g} s"


def _edge_points(e: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(time s, angle rad) where an encoder's count is exact: its distinct edge times, led by the first
    reading. The reading times are bus arrival times; the edge times are the device's."""
    t, c, et, a = e["t"], e["count"], e["edge_time"], e["angle"]
    moved = np.flatnonzero(c != 0)
    ok = np.isfinite(et) & (et <= t + EDGE_TOLERANCE) & (np.arange(t.size) >= (moved[0] if moved.size else t.size))
    ev = np.where(ok, et, -np.inf)
    new = ev > np.maximum.accumulate(np.concatenate(([-np.inf], ev)))[:-1]
    pts_t, pts_a = et[new], a[new]
    if not new[0]:                    # the first reading: no edge since power-on yet, the count is its start value
        lead = t[0] if not pts_t.size else min(t[0], pts_t[0] - 1e-9)
        pts_t, pts_a = np.concatenate(([lead], pts_t)), np.concatenate(([a[0]], pts_a))
    return pts_t, pts_a


def _speeds(e: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(stamp s, ω rad/s, reading time s, method) of an encoder: the host's recorded estimate, or (older
    recordings) the same estimator run on the recorded counts and edge times."""
    if "speed" in e and "speed_time" in e and "speed_method" in e:
        return e["speed_time"], e["speed"], e["t"], e["speed_method"].astype(np.int8)
    est = SpeedEstimator(_rad_per_count(e) or 1.0).update(e["t"], e["count"].astype(np.int64), e["edge_time"])
    return est.time, est.speed, e["t"], est.method


def _rad_per_count(e: dict[str, np.ndarray] | None) -> float | None:
    """The encoder's signed resolution (rad per count: negative for an encoder counting against the angle) as its
    record gives it (angle over count); None before any count."""
    if not e or "count" not in e or "angle" not in e:
        return None
    i = np.flatnonzero(e["count"])
    return float(e["angle"][i[0]] / e["count"][i[0]]) if i.size else None


#: what the dynamic stand's record is made of: plant signal measured → its default topic (a recording without its scene)
STAND_SIGNALS = {"M_t": "/stand/torque", "phi1": "/stand/encoder1", "phi3": "/stand/encoder2"}


def stand_topics(rec: Recording) -> dict[str, str]:
    """The recording topic of each of :data:`STAND_SIGNALS`: that of the transducer the scene wires to the signal
    (whichever CAN message it fills), else the default."""
    scene = _scene(rec)
    wired = scene.data.get("transducers", {}) if scene is not None else {}
    return {signal: (found[1] if (found := measuring(wired, signal)) else default)
            for signal, default in STAND_SIGNALS.items()}


def stand_record(rec: Recording) -> StandRecord | None:
    """The measured signals of a dynamic-stand recording (None: no torque readings, or another plant's); the driving
    half's encoder is the one measuring φ1, the driven half's φ3, as the scene wires them."""
    topics = stand_topics(rec)
    torque = rec.series.get(topics["M_t"])
    if not torque or torque["t"].size < 2 or rec.metadata.get("rig", {}).get("plant", "clutch_dynamic") != "clutch_dynamic":
        return None
    encs = {i: rec.series.get(topics[signal]) for i, signal in ((1, "phi1"), (2, "phi3"))}
    encs = {i: e for i, e in encs.items() if e and e["t"].size >= 2}
    t_angle = rel = None
    if len(encs) == 2:
        (t1, a1), (t3, a3) = _edge_points(encs[1]), _edge_points(encs[2])
        t_angle = np.union1d(t1, t3)
        offset = 0.0
        if "phi_r" in rec.truth and rec.truth["phi_r"].size:     # the angle at power-on, where the counts are 0
            truth_t = rec.truth["t"]
            offset = float(rec.truth["phi_r"][0])
            if _lost_start(rec):            # the counts are not 0 where the kept readings begin (they count from
                at = max(float(truth_t[0]), float(t1[0]), float(t3[0]))           # power-on): the offset that meets
                offset = float(np.interp(at, truth_t, rec.truth["phi_r"]) - (np.interp(at, t1, a1)    # the truth
                                                                              - np.interp(at, t3, a3)))  # there
        rel = np.interp(t_angle, t1, a1) - np.interp(t_angle, t3, a3) + offset
    speeds = {("ω1" if i == 1 else "ω3"): _speeds(e) for i, e in encs.items()}
    last = [float(_edge_points(e)[0][-1]) for e in encs.values() if np.any(e["count"] != 0)]
    end = max([float(torque["t"][-1])] + [float(e["t"][-1]) for e in encs.values()])
    return StandRecord(torque["t"], torque["torque"], t_angle, rel, speeds, max(last) if last else None, end)


def coupling_period(scene: Scene) -> tuple[float, float]:
    """(period of the coupling in φ_r, its first apex), rad: flat tappets 120°/60°, leaf springs 2φ_d/φ_d."""
    from rig.plants.clutch.stand import plant_schema
    p = scene.read("plant", plant_schema(scene))
    if p["variant"] != "leaf_spring":
        return LOBE, APEX
    from rig.plants.clutch.variants import LeafSpringClutch
    apex = read_table(p["leaf"], LeafSpringClutch.SCHEMA, f"{scene.path} [plant.leaf]")["apex"]
    return 2.0 * apex, apex


def stand_results(rec: Recording, data: StandRecord | None = None) -> tuple[list[Stimulus], list[Metric]] | None:
    """Stimuli of the recorded scene and the key results of the run (None: not a dynamic-stand recording); ``data``:
    its :func:`stand_record` where the caller has it already."""
    data = data if data is not None else stand_record(rec)
    if data is None:
        return None
    scene = _scene(rec)
    stim: list[Stimulus] = []
    rule: dict[str, Any] = {"shutdown_count": None, "shutdown_window": None, "trip_on_shutdown": False}
    lobe, apex = LOBE, APEX
    if scene is not None and scene.data.get("scene", {}).get("plant") == "clutch_dynamic":
        try:
            stim, rule = stimuli(scene)
            lobe, apex = coupling_period(scene)
        except (SceneError, ValueError):
            pass                                    # results without stimuli: no step figures, no shutdown rule
    model = sum(1 for e in rec.events if e.get("kind") == "disengagement")
    speed = display_units(None, None, scene_device_config(rec.scene_text)[2]).of("rad/s")    # as the truth charts
    return stim, stand_metrics(data, stim, rule["shutdown_count"], rule["shutdown_window"], BAND, DWELL,
                               model_disengagements=model if "phi_r" in rec.truth else None,
                               trips_motor=bool(rule["trip_on_shutdown"]), lobe=lobe, apex=apex, speed=speed)


def summary_lines(rec: Recording, stim: list[Stimulus], metrics: list[Metric]) -> list[str]:
    """Console lines of a dynamic-stand run (its :func:`stand_results`): what the scene did, then each key result
    with its reference."""
    lines = ["clutch stand: " + ("; ".join(f"{s.text} at {s.time:.4g} s" for s in stim) or "no stimulus known")]
    width = max(len(m.name) for m in metrics)
    lines += [f"  {m.name:<{width}}  {m.value_text()}  ({m.reference})" for m in metrics]
    scene = _scene(rec)
    if scene is not None and scene.data.get("comparison"):
        lines.append(f"  thesis against rig: {agreement_text(compare(scene, stim, metrics))} (comparison.csv)")
    return lines + [f"  warning: {text}" for text in lost_start_warnings(rec) + stall_warnings(rec)]


def lost_start_warnings(rec: Recording, data: StandRecord | None = None) -> list[str]:
    """A recording whose stand readings begin late (its first chunk lost): what its results cover (they said "at
    power-on" and "of the run" of the first reading kept; an audit). ``data``: its :func:`stand_record`, if at hand
    (else made only for such a recording)."""
    if not _lost_start(rec):
        return []
    data = data if data is not None else stand_record(rec)
    if data is None:
        return []
    return [f"the stand's readings begin at {data.t[0]:.4g} s: the run's start was lost, so \"at power-on\" and "
            f"\"since power-on\" below mean that first reading, and the counts and extremes cover "
            f"{data.t[0]:.4g} … {data.end:.4g} s only"]


START_KEPT = 0.5     # s: stand readings that begin later than this come from a recording that lost its start


def _lost_start(rec: Recording) -> bool:
    """Whether an incomplete recording lost the start of its stand readings (they begin after :data:`START_KEPT`)."""
    torque = rec.series.get(stand_topics(rec)["M_t"]) or {}
    return not rec.complete and "t" in torque and torque["t"].size > 0 and float(torque["t"][0]) > START_KEPT


def stall_warnings(rec: Recording) -> list[str]:
    """What the ``motor_below_load`` events say: the motor's stall torque is below the brake's holding torque, the
    stand cannot start (and a regularised brake's creep is the model's)."""
    return [f"the motor's stall torque {e['motor_stall_torque']:.4g} N·m is below the {e['brake_torque']:.4g} N·m the "
            "brake holds at rest: the stand cannot start"
            + (f"; the regularised (tanh) brake lets it creep at {e['creep_speed']:.3g} rad/s, the model's, not the "
               "stand's" if "creep_speed" in e else "")
            for e in rec.events if e.get("kind") == "motor_below_load"]


def _torque_figure(ctx: ReportContext, data: StandRecord, stim: list[Stimulus]) -> Block:
    fig, ax = figure(size=(10.5, 3.8))
    ax.plot(data.t, data.torque, lw=1.2, color="tab:blue", label="torque meter (measured)", zorder=2)
    truth = ctx.recording.truth
    if "M_t" in truth:          # thin and dashed on top: where it coincides with the measurement both stay visible
        ax.plot(truth["t"], truth["M_t"], lw=0.7, ls="--", color="k", label="plant truth", zorder=3)
    later = [s for s in stim if s.time > 0]
    for s in later:
        ax.axvline(s.time, color="0.4", lw=0.7, ls=":")
        ax.annotate(s.kind, (s.time, 1.0), xycoords=("data", "axes fraction"), fontsize="small",
                    ha="left", va="top", color="0.3")
        if s.kind == "shock" and s.duration:       # the pulse's end too: its span shaded between the two
            ax.axvline(s.time + s.duration, color="0.4", lw=0.7, ls=":")
            ax.axvspan(s.time, s.time + s.duration, color="0.5", alpha=0.08, lw=0)
    scene = _scene(ctx.recording)
    marks = []
    if scene is not None and scene.data.get("comparison"):
        try:
            marks = thesis_marks(scene, stim)
        except SceneError:          # the comparison section names the bad row
            marks = []
    for m, colour in zip(marks, ("tab:red", "tab:purple", "tab:brown", "tab:olive", "tab:cyan", "tab:pink")):
        label = textwrap.fill(m.label, 34, subsequent_indent="  ")
        if m.kind == "point":
            ax.plot([m.t], [m.torque], "x", ms=9, mew=2, color=colour, label=label, zorder=4)
        elif m.kind == "level":
            ax.axhline(m.torque, color=colour, lw=0.9, ls="-.", label=label)
        else:
            ax.axvline(m.t, color=colour, lw=0.9, ls="-.", label=label)
    ax.set(xlabel="t (s)", ylabel="torque M_t (N·m)", title="Torque over time", xlim=(0.0, data.end))
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
    caption = "Torque over time, measured (solid) and the plant model (dashed)"
    if later:
        caption += f"; dotted: what the scene changes ({', '.join(_when(s) for s in later)})"
    if marks:
        caption += "; dash-dotted lines and crosses: the thesis's values (Thesis against rig, below)"
    return ctx.figure(save(fig, ctx.figure_path("clutch_torque_time"), right=3.2), caption)


def _speed_figure(ctx: ReportContext, data: StandRecord) -> Block:
    rec = ctx.recording
    unit = display_units(None, None, scene_device_config(rec.scene_text)[2]).of("rad/s")   # as the truth charts
    fig, ax = figure(size=(8, 3.5))
    truth = rec.truth
    for name, (ts, w, _, _) in data.speeds.items():
        key, colour = ("omega1", "tab:blue") if name == "ω1" else ("omega3", "tab:orange")
        ok = np.isfinite(w)
        o = np.argsort(ts[ok], kind="stable")
        ax.plot(ts[ok][o], unit(w[ok][o]), lw=0.9, color=colour,
                label=f"{'driving' if name == 'ω1' else 'driven'} half {name} (encoder)")
        if key in truth:
            ax.plot(truth["t"], unit(truth[key]), lw=0.7, ls="--", color="0.2" if name == "ω1" else "0.55",
                    label=f"{name} plant truth")
    ax.set(xlabel="t (s)", ylabel=unit.axis("speed"), title="Speeds of both halves", xlim=(0.0, data.end))
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    rad = _rad_per_count(rec.series.get(stand_topics(rec)["phi1"]))
    switch = (f" (frequency above {unit.text(SpeedEstimator(abs(rad)).switch_speed, 3)} for the driving half's "
              f"{2 * np.pi / abs(rad):.0f} counts per turn, period below)") if rad else ""
    return ctx.figure(save(fig, ctx.figure_path("clutch_speeds")),
                      "Speeds of both halves from the encoders: mixed frequency/period method on the latched edge "
                      f"times{switch}, each mean speed drawn at the middle of its window")


def _static_characteristic(scene: Scene | None) -> Any:
    """The static characteristic T(φ_r) of the scene's coupling (loading/unloading branches), None without one."""
    if scene is None:
        return None
    from rig.plants.clutch.stand import ClutchStand
    from rig.plants.clutch.variants import FlatTappetCharacteristic
    try:
        dyn = ClutchStand.from_scene(scene).dynamics
    except (SceneError, ValueError):
        return None
    return FlatTappetCharacteristic(dyn.clutch) if hasattr(dyn, "clutch") else getattr(dyn, "leaf", None)


def _verdict(metrics: list[Metric]) -> Banner | None:
    """The stand's outcome in one line: disengagements, the shutdown rule's verdict (red when it requires a
    shutdown) and the torque peak."""
    by = {m.name: m for m in metrics}
    parts = [f"{name} {by[name].value_text()}" for name in ("disengagements", "shutdown", "max torque")
             if name in by and by[name].value is not None]
    if not parts:
        return None
    shutdown = by.get("shutdown")
    return Banner("Clutch stand: " + "; ".join(parts), not (shutdown is not None and shutdown.value == "required"))


def clutch_section(ctx: ReportContext) -> list[Block]:
    data = stand_record(ctx.recording)
    if data is None:
        return []
    stim, metrics = stand_results(ctx.recording, data) or ([], [])
    blocks: list[Block] = [Heading("Clutch stand")]
    banner = _verdict(metrics)
    scene = _scene(ctx.recording)
    details = ""
    if banner is not None and scene is not None and scene.data.get("comparison"):
        try:                                   # the thesis comparison's outcome up front (its table is below):
            rows = compare(scene, stim, metrics)       # a row that disagrees turns the banner red and is named
            counts, details = agreement_parts(rows)    # under it (in the banner they made a bold paragraph)
            banner.text += f"; thesis against rig: {counts}"
            banner.ok = banner.ok and not any(r.agrees is False for r in rows)
        except SceneError:
            pass
    if banner is not None:
        blocks.append(banner)
    if details:
        blocks.append(Text(f"Thesis against rig: {details} (Thesis against rig, below).", "" if banner.ok else "warning"))
    blocks += [Text(f"Warning: {text}.", "warning") for text in lost_start_warnings(ctx.recording, data)]
    if stim:
        blocks.append(Text("The scene: " + "; ".join(f"{s.text} at {s.time:.4g} s" for s in stim) + "."))
    blocks.append(Table(["result", "value", "relative to / definition"],
                        [[m.name, m.value_text(), m.reference] for m in metrics]))
    blocks.append(_torque_figure(ctx, data, stim))
    if data.rel_angle is not None:
        fig, ax = figure(size=(6, 4.5))
        ax.plot(np.degrees(np.interp(data.t, data.t_angle, data.rel_angle)), data.torque, lw=0.8,
                label="measured (torque meter over the encoders' φ1 − φ3)")
        static = _static_characteristic(scene)
        if static is not None:
            phi = np.linspace(static.phi_min, static.apex, 241)
            for direction, ls, what in ((1.0, "--", "loading"), (-1.0, ":", "unloading")):
                ax.plot(np.degrees(phi), static.torque(phi, direction), ls, color="k", lw=1.0,
                        label=f"static characteristic at standstill, {what} (model, one lobe)")
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), frameon=False)   # below: in
            # the axes it hid the peaks of a run that slips lobe after lobe
        ax.set(xlabel="relative angle φ1 − φ3 (°)", ylabel="torque M_t (N·m)", title="Torque over relative angle")
        ax.grid(alpha=0.3)
        try:
            lobe, apex = coupling_period(scene) if scene is not None else (LOBE, APEX)
        except (SceneError, ValueError):
            lobe, apex = LOBE, APEX
        blocks.append(ctx.figure(save(fig, ctx.figure_path("clutch_torque_angle"), bottom=1.05 if static else None),
                                 "Torque over relative angle (encoders on both halves, angle at power-on from the "
                                 f"scene; apexes at {math.degrees(apex):.4g}° + k·{math.degrees(lobe):.4g}°)"
                                 + ("; the model's branches are those of the coupling at standstill: while the stand "
                                    "turns, inertia and the tappets' centrifugal load move them, so a point off the "
                                    "drawn band at speed is no disagreement" if static is not None else "")))
    if data.speeds:
        blocks.append(_speed_figure(ctx, data))
    events = [e for e in ctx.recording.events if e.get("kind") in ("disengagement", "shutdown")]
    if events:
        blocks.append(Text("Model events (the host's plant model of the scene):"))
        blocks.append(Table(["t (s)", "event", "details"],
                            [[f"{e['t']:.6g}", e["kind"], event_details(e, ctx.main_units)] for e in events]))
    return blocks



def comparison_section(ctx: ReportContext) -> list[Block]:
    """Thesis against rig (and comparison.csv in the report directory) for a stand scene with [[comparison]]."""
    scene = _scene(ctx.recording)
    if scene is None or not scene.data.get("comparison"):
        return []
    results = stand_results(ctx.recording)
    if results is None:
        return []
    rows = compare(scene, *results)
    write_csv(rows, ctx.out_dir / "comparison.csv")
    fitted = [r.quantity for r in rows if r.basis == "fitted"]
    inputs = [r.quantity for r in rows if r.basis == "input"]
    text = " ".join(part for part in (
        ("Fitted on this run: " + ", ".join(fitted) + ".") if fitted else "Nothing was fitted on this run.",
        ("Set by the scene's inputs (a load it applies, a stimulus chosen for that outcome; they check nothing of the "
         "model): " + ", ".join(inputs) + ".") if inputs else "",
        "The other rows are predictions." if len(fitted) + len(inputs) < len(rows) else "No row is a prediction.")
        if part)
    agreement = agreement_text(rows)
    notes = any(r.why for r in rows)
    return [Heading("Thesis against rig"),
            Text(agreement[:1].upper() + agreement[1:] + ".", "warning" if any(r.agrees is False for r in rows)
                 else "note"),
            Text(text + " Agreement is judged by each row's tolerance (a share of the thesis value, a value, or a "
                 "bound: the thesis value is a limit; a count exactly); deviation = rig − thesis."),
            Table(["quantity", "unit", "thesis", "rig", "deviation", "tolerance", "agrees", "basis"]
                  + (["note"] if notes else []),
                  [[r.quantity, {"deg": "°"}.get(r.unit, r.unit.replace("*", "·")), f"{r.thesis:g}", r.rig_text(),
                    r.deviation, r.tolerance or "— (not judged)", r.verdict, r.basis]
                   + ([r.why] if notes else []) for r in rows]),
            Table(["file", "contents"], [[Link("comparison.csv", "comparison.csv"), "this table, with the unrounded rig "
                                                                                   "values"]])]
