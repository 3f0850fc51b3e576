"""Report section for static clutch rig recordings (MODELS.md §4.4).

Measured: the potentiometer angle read by the multimeter and the leaf strain from the half-bridge
amplifier (``/stand/static_rig``, sent in ``StaticRig`` CAN frames). The load is known from the weights on
the 1000 mm lever (the applied torque the host logs in ``/plant/truth``). Theory: the clutch's
loading/unloading characteristic rebuilt from the recorded scene (:mod:`rig.analysis.static_loops`).
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from rig.analysis.event_text import event_details
from rig.analysis.plots import figure, save
from rig.analysis.numbers import decimals, fixed, fixed_range
from rig.analysis.report_blocks import Block, Heading, ReportContext, Table, Text, fmt
from rig.analysis.static_loops import cycle_energy, cycles, reading_points, theory_cycle_energy
from rig.plants.clutch.static_rig import StaticClutchRig, rig_from_scene
from rig.recorder import Recording
from rig.scene import SceneError

TOPIC = "/stand/static_rig"


def static_rig(rec: Recording) -> StaticClutchRig:
    """The static rig of the recorded scene (theory side); SceneError if the recording has none."""
    return rig_from_scene(rec.scene())


def _limit(clutch: Any, short: bool = False) -> str:
    """Where the characteristic ends: the loading-branch peak the clutch disengages above, or for a measured table
    its highest torque (the measurements end there)."""
    from rig.plants.clutch.variants import TabulatedClutch
    if isinstance(clutch, TabulatedClutch):
        return (f"the table's highest torque ({clutch.peak_torque:.4g} N·m)" if short else
                f"holds only up to its table's highest torque, {clutch.peak_torque:.4g} N·m (the measurements end there)")
    return (f"the loading-branch peak ({clutch.peak_torque:.4g} N·m)" if short else
            f"disengages above its loading-branch peak, {clutch.peak_torque:.4g} N·m")


def _table_end(clutch: Any) -> str:
    """"table ends (highest measured torque)" for a measured table, whose highest torque is where the data end, not a
    capacity; "" for a characteristic with a loading-branch peak."""
    from rig.plants.clutch.variants import TabulatedClutch
    return "table ends (highest measured torque)" if isinstance(clutch, TabulatedClutch) else ""


def self_locking(clutch: Any) -> str:
    """"" or the sentence saying the clutch is self-locking: its unloading branch never rises above 0 N·m (the
    friction beats the spring's return: above μ_B = 0.188 for the reference flat tappet of the parameter studies),
    so an unloaded clutch stays where the load left it and does not spring back."""
    if not clutch.has_friction:
        return ""
    peak = float(clutch.branch_peak(-1.0)[1])
    if peak > 1e-9 * clutch.peak_torque:
        return ""
    peak = peak if peak < -1e-9 * clutch.peak_torque else 0.0        # (rounding residue: 0)
    return (f"self-locking: the unloading branch never rises above {peak:.3g} N·m (friction beats the spring's "
            f"return), so unloaded the clutch stays where the load left it; it does not spring back")


def cycle_table(rec: Recording, rig: StaticClutchRig) -> list[dict]:
    """Per loading/unloading cycle: torque extremes (N·m), measured/truth/theory loop energy (J; ``lossless``: the
    characteristic has no hysteresis, theory 0 — and a truth of rounding residue shown as 0), slip."""
    truth, readings = rec.truth, rec.series[TOPIC]
    t_m, phi_m = reading_points(readings["t"], readings["angle"])
    phi = float(rig.clutch.phi_min)
    rows = []
    found = cycles(truth["t"], truth["torque"])
    # the last cycle is cut when the run ended before its lever program did, on the way down (a program that ends
    # holding a load is whole)
    short = truth["t"][-1] < rig.duration - 1e-9
    for k, c in enumerate(found):
        cut = short and k == len(found) - 1 and truth["torque"][-1] > c.torque_min + 1e-9 * max(abs(c.torque_max), 1.0)
        e_theory, phi_next, slip = theory_cycle_energy(rig.clutch, phi, c.torque_min, c.torque_max)
        inside = (t_m >= c.start) & (t_m <= c.end)
        residue = 1e-6 * max(abs(c.torque_max), 1.0)       # J: a loop of no area, computed (frictionless)
        still = abs(e_theory) < residue                     # no loop: frictionless, or friction held the clutch
        e_truth = cycle_energy(truth["t"], truth["relative_angle"], truth["torque"], c)
        # the display's value at the cycle's ends too: a clutch that friction holds shows no new angle while it is
        # unloaded, and the loop closed from its last new reading cut the unloading off (a self-locking flat tappet
        # read 0.110 J against 0.146 J; an audit)
        ends = np.array([c.start, c.end])
        held = phi_m[np.maximum(np.searchsorted(t_m, ends, side="right") - 1, 0)]
        t_c = np.r_[c.start, t_m[inside], c.end]
        span = {"start": c.start, "end": c.end, "torque_min": c.torque_min, "torque_max": c.torque_max,
                "angle_min": float(phi_m[inside].min()) if inside.any() else None,
                "angle_max": float(phi_m[inside].max()) if inside.any() else None, "cut": cut}
        if cut:                   # the run ended on the way down: no closed loop to compare (one was, with the
            rows.append({**span, "measured": None, "truth": None, "theory": None, "lossless": False,   # full
                         "held": False, "disengaged": slip,                                         # theory's)
                         "torque_end": float(np.interp(c.end, truth["t"], truth["torque"]))})
            break
        rows.append({**span, "measured": cycle_energy(t_c, np.r_[held[0], phi_m[inside], held[1]],
                                              np.interp(t_c, truth["t"], truth["torque"]), c)
                     if inside.sum() >= 1 else None,
                     "truth": 0.0 if abs(e_truth) < residue else e_truth, "theory": 0.0 if still else e_theory,
                     "lossless": still and not rig.clutch.has_friction, "held": still and rig.clutch.has_friction,
                     "disengaged": slip})
        phi = phi_next
    return rows


def span_format(rows: list[dict]) -> Callable[[dict], str]:
    """``"0–60"``: a cycle's time span (s) to three significant digits of the run's end (a 120 s run in whole
    seconds, a 1.25 s run to 0.01 s; the first cycle starts at the first sample, 0.003333 s, shown as 0)."""
    places = decimals(max((abs(r["end"]) for r in rows), default=0.0))
    return lambda r: f"{fixed(r['start'], places)}–{fixed(r['end'], places)}"


def summary(rec: Recording) -> tuple[list[str], dict[str, tuple[float, str]]] | None:
    """Console lines of a static-rig run — per loading/unloading cycle the torque range, the measured angle range and
    the loop energy measured vs theory — and the same as numbers, ``cycle_<i>.<name>``: ``torque_max`` (N·m),
    ``loop_energy`` and ``loop_energy_theory`` (J), ``disengaged`` (1/0); None: not a static-rig recording."""
    readings = rec.series.get(TOPIC)
    if not readings or "angle" not in readings or readings["t"].size < 3 or "torque" not in rec.truth:
        return None
    try:
        rig = static_rig(rec)
        rows = cycle_table(rec, rig)
    except (SceneError, ValueError) as exc:
        return [f"static clutch rig: no cycle analysis ({exc})"], {}
    values: dict[str, tuple[float, str]] = {}
    for i, r in enumerate(rows, start=1):
        values.update({f"cycle_{i}.torque_max": (float(r["torque_max"]), "N·m"),
                       f"cycle_{i}.disengaged": (float(bool(r["disengaged"])), "")})
        if r["theory"] is not None:
            values[f"cycle_{i}.loop_energy_theory"] = (float(r["theory"]), "J")
        if r["measured"] is not None:
            values[f"cycle_{i}.loop_energy"] = (float(r["measured"]), "J")
    return _lines(rows, rig, rec.events), values


def no_loop(r: dict) -> str:
    """Why a cycle's measured loop energy is not compared with theory ('' when it is): the characteristic has no
    hysteresis (the measured loop is the readings' lag), or friction held the clutch (no loop; the readings' noise)."""
    if r["measured"] is None:
        return ""
    if r["lossless"]:
        return "no hysteresis in the characteristic: the measured loop is the readings' lag"
    return "friction held the clutch: no loop; the measured one is the readings' noise" if r["held"] else ""


def _lines(rows: list[dict], rig: StaticClutchRig, rec_events: list[dict]) -> list[str]:
    lines = [f"static clutch rig: {len(rows)} loading/unloading cycle(s); applied torque = lever force × arm (the "
             f"weights); loop energy ∮T dφ measured (multimeter angle) vs theory (characteristic); the model "
             f"{_limit(rig.clutch)}"] + ([f"  {locking}"] if (locking := self_locking(rig.clutch)) else [])
    span = span_format(rows)
    for i, r in enumerate(rows, start=1):
        angle = ("no reading" if r["angle_min"] is None
                 else f"{fixed_range(np.degrees(r['angle_min']), np.degrees(r['angle_max']))}°")
        why = no_loop(r)
        dev = ("" if r["measured"] is None else f" ({why})" if why
               else f" ({100 * (r['measured'] - r['theory']) / r['theory']:+.2f} %)")
        energy = "—" if r["measured"] is None else f"{r['measured']:.4g} J"
        loop = (f"cut by the run's end at {r['torque_end']:.4g} N·m on the way down: no closed loop, no energy "
                f"compared" if r["cut"] else f"loop energy {energy} vs {r['theory']:.4g} J{dev}")
        lines.append(f"  cycle {i} ({span(r)} s): applied torque {r['torque_min']:.4g} → "
                     f"{r['torque_max']:.4g} N·m, measured angle {angle}, {loop}, "
                     + ("disengaged (slipped a lobe)" if r["disengaged"] else "no disengagement"))
    within = [(r["start"], r["end"]) for r in rows]
    for e in rec_events:
        if e.get("kind") == "disengagement" and not any(a <= e["t"] <= b for a, b in within):
            lines.append(f"  disengaged at t = {e['t']:.4g} s, outside a whole loading/unloading cycle (the load "
                         f"rose there and did not come back down before the run ended)")
    return lines


def _torque_angle_figure(ctx: ReportContext, rig: StaticClutchRig, t_m: np.ndarray, phi_m: np.ndarray,
                         torque_m: np.ndarray) -> Block:
    truth, c = ctx.recording.truth, rig.clutch
    fig, ax = figure(size=(7, 4.5))
    grid = np.linspace(c.phi_min, c.apex, 400)
    lobes = range(int(max(np.max(truth["relative_angle"]), np.max(phi_m)) // c.period) + 1)
    for k in lobes:
        for direction, colour, label in ((1.0, "tab:red", "theory: loading branch"),
                                         (-1.0, "tab:blue", "theory: unloading branch")):
            ax.plot(np.degrees(grid + k * c.period), c.torque(grid, direction), color=colour, lw=0.9,
                    ls=":", label=label if k == 0 else None)
    ax.plot(np.degrees(truth["relative_angle"]), truth["torque"], color="0.5", lw=0.8, ls="--", label="plant truth")
    ax.plot(np.degrees(phi_m), torque_m, ".-", ms=2, lw=0.7, color="k", label="measured (multimeter angle)")
    peak = float(c.branch_peak(1.0)[1])
    top = 1.1 * max(float(np.max(truth["torque"])), peak)
    over = bool(np.any(truth["torque"] > peak))
    ends = _table_end(c)
    ax.axhline(peak, color="tab:red", lw=0.7, alpha=0.6,
               label=f"{ends or 'capacity (loading peak)'} {peak:.4g} N·m")
    if over:                                    # the lever's load beyond it is not the clutch's: shade, say so
        ax.axhspan(peak, top, color="tab:red", alpha=0.07, lw=0, label="overload: no equilibrium (see caption)")
    ax.set(xlabel="relative angle (°)", ylabel="torque = F·L (N·m)", title="Static rig: torque over relative angle",
           ylim=(min(0.0, float(np.min(truth["torque"]))), top))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncols=2, frameon=False)  # below: inside
    # it hid the slip plateau between the lobes
    caption = "Torque over relative angle: loading/unloading hysteresis loop, measured vs theory"
    if over and ends:
        caption += (f". The model's table ends at {peak:.4g} N·m, the highest torque measured: what the clutch does "
                    "beyond it is not known, so the points in the shaded band are the lever's load, not a torque the "
                    "clutch is known to carry")
    elif over:
        caption += (f". Above the capacity ({peak:.4g} N·m) the lever's load is more than the clutch holds: quasi-"
                    "statically there is no equilibrium (the clutch slips over the apex; on the rig the lever drops "
                    "onto its support). The model holds the angle at the peak while overloaded, so the points in the "
                    "shaded band are the lever's load, not a torque the clutch carries; when the load falls back "
                    "below the capacity the clutch has slipped one lobe, drawn as the step at the peak torque")
    return ctx.figure(save(fig, ctx.figure_path("static_torque_angle"), bottom=1.05), caption)


def _strain_figure(ctx: ReportContext, rig: StaticClutchRig) -> Block:
    readings, truth, c = ctx.recording.series[TOPIC], ctx.recording.truth, rig.clutch
    fig, ax = figure(size=(7, 4))
    local = np.linspace(c.phi_min, c.apex, 400)
    ax.plot(np.degrees(local), 1e6 * c.leaf_strain(local, rig.gauge_offset), ":", color="tab:red",
            label="theory ε(φ) at the gauges")
    if "leaf_strain" in truth:
        ax.plot(np.degrees(np.mod(truth["relative_angle"] - c.phi_min, c.period) + c.phi_min),
                1e6 * truth["leaf_strain"], "--", color="0.5", lw=0.8, label="plant truth")
    angle, strain = readings["angle"], readings["strain"]
    new = np.concatenate(([True], angle[1:] != angle[:-1]))     # the multimeter shows a new angle (as reading_points)
    ax.plot(np.degrees(np.mod(angle[new] - c.phi_min, c.period) + c.phi_min), 1e6 * strain[new],
            ".", ms=3, color="k", label="measured (bridge amplifier when the multimeter shows a new angle)")
    ax.set(xlabel="relative angle in the lobe (°)", ylabel="leaf strain (µm/m)", title="Leaf strain over angle")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return ctx.figure(save(fig, ctx.figure_path("static_leaf_strain")),
                      "Leaf strain over relative angle: each strain reading paired with the multimeter's angle when it "
                      "shows a new value (the multimeter holds each angle for several strain readings, whose strain "
                      "moves on meanwhile)")


def static_clutch_section(ctx: ReportContext) -> list[Block]:
    rec = ctx.recording
    readings = rec.series.get(TOPIC)
    if not readings or "angle" not in readings or readings["t"].size < 3 or "torque" not in rec.truth:
        return []
    blocks: list[Block] = [Heading("Static clutch rig")]
    try:
        rig = static_rig(rec)
    except SceneError as exc:
        return blocks + [Text(f"No theory: {exc}")]
    rows = []
    table = cycle_table(rec, rig)
    span = span_format(table)
    for i, r in enumerate(table, start=1):
        dev = (None if r["measured"] is None or r["lossless"] or r["held"]
               else (r["measured"] - r["theory"]) / r["theory"])
        rows.append([i, span(r), fmt(r["torque_min"]), fmt(r["torque_max"]),
                     "—" if r["angle_min"] is None else fixed_range(np.degrees(r["angle_min"]), np.degrees(r["angle_max"]),
                                                                   sep="–"),
                     fmt(r["measured"]), fmt(r["truth"]), fmt(r["theory"]),
                     "—" if dev is None else f"{100 * dev:+.2f} %", fmt(r["disengaged"])])
    # the results first (loop energies, disengagements), then how they were measured and the charts
    blocks.append(Heading("Hysteresis-loop energy ∮T dφ per cycle", 3))
    blocks.append(Table(["cycle", "t (s)", "applied T min (N·m)", "applied T max (N·m)", "measured angle (°)",
                         "measured (J)", "plant truth (J)", "theory (J)", "measured − theory", "disengaged"], rows))
    blocks += [Text(f"Cycle {i} was cut by the run's end at {r['torque_end']:.4g} N·m on the way down: no closed loop, "
                    "no energy compared.", "warning") for i, r in enumerate(table, start=1) if r["cut"]]
    blocks += [Text(f"Cycle {i}: measured {r['measured']:.4g} J against {fmt(r['theory'])} J, not compared — "
                    f"{no_loop(r)}.") for i, r in enumerate(table, start=1) if no_loop(r)]
    events = [e for e in rec.events if e.get("kind") in ("disengagement", "reengaged")]
    if events:
        blocks.append(Table(["t (s)", "event", "details"],
                            [[f"{e['t']:.6g}", e["kind"], event_details(e, ctx.main_units)] for e in events]))
    else:
        blocks.append(Text(f"No disengagement: the load stayed below {_limit(rig.clutch, short=True)}."))
    if locking := self_locking(rig.clutch):
        blocks.append(Text(f"The clutch is {locking}.", "warning"))
    t_m, phi_m = reading_points(readings["t"], readings["angle"])
    torque_m = np.interp(t_m, rec.truth["t"], rec.truth["torque"])
    blocks.append(Heading("Torque and angle", 3))
    blocks.append(Text("Torque = lever force × arm, known from the weights; angle = multimeter readings of the "
                       "potentiometer (each paired with the load when it first appears)."))
    blocks.append(_torque_angle_figure(ctx, rig, t_m, phi_m, torque_m))
    if "strain" in readings and hasattr(rig.clutch, "leaf_strain"):
        blocks.append(_strain_figure(ctx, rig))
    return blocks

