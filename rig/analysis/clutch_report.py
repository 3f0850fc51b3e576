"""Report section for clutch-stand recordings: torque over time and over relative angle, speeds of both
halves, disengagements, overshoot/settling of the torque and the hysteresis-loop area."""
from __future__ import annotations

import numpy as np

from rig.analysis.clutch_metrics import loop_energy, step_metrics
from rig.analysis.plots import figure, save
from rig.analysis.report import Block, Heading, ReportContext, Table, Text, fmt, register_section


def _encoders(series: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Common times and the angles of the driving (1) and driven (2) halves from the encoder blocks (rad)."""
    e1, e2 = series.get("/stand/encoder1"), series.get("/stand/encoder2")
    if not e1 or not e2 or e1["t"].size < 2 or e2["t"].size < 2:
        return None
    t = e1["t"]
    return t, e1["angle"], np.interp(t, e2["t"], e2["angle"])


def clutch_section(ctx: ReportContext) -> list[Block]:
    series = ctx.recording.series
    torque = series.get("/stand/torque")
    if not torque or torque["t"].size < 2:
        return []
    t, m = torque["t"], torque["torque"]
    blocks: list[Block] = [Heading("Clutch stand")]
    fig, ax = figure(size=(8, 3.5))
    ax.plot(t, m, lw=0.8, label="torque meter (measured)")
    truth = ctx.recording.truth
    if "M_t" in truth:
        ax.plot(truth["t"], truth["M_t"], lw=0.8, ls="--", label="plant truth")
    ax.set(xlabel="t (s)", ylabel="torque (N·m)", title="Torque over time")
    ax.grid(alpha=0.3)
    ax.legend()
    blocks.append(ctx.figure(save(fig, ctx.figure_path("clutch_torque_time")), "Torque over time"))

    sm = step_metrics(t, m)
    rows = [["peak torque (N·m)", fmt(float(sm.peak))], ["time of peak (s)", fmt(float(sm.t_peak))],
            ["overshoot", fmt(float(sm.overshoot))], ["settling time, 2 % band (s)", fmt(float(sm.settling_time))],
            ["final torque (N·m)", fmt(float(sm.final))]]
    enc = _encoders(series)
    if enc is not None:
        te, a1, a2 = enc
        rel = a1 - a2
        m_e = np.interp(te, t, m)
        fig, ax = figure(size=(6, 4))
        ax.plot(np.degrees(rel), m_e, lw=0.8)
        ax.set(xlabel="relative angle φ1 − φ3 (deg)", ylabel="torque (N·m)", title="Torque over relative angle")
        ax.grid(alpha=0.3)
        blocks.append(ctx.figure(save(fig, ctx.figure_path("clutch_torque_angle")),
                                 "Torque over relative angle (encoders on both halves)"))
        fig, ax = figure(size=(8, 3.5))
        ax.plot(te, np.gradient(a1, te), lw=0.8, label="driving half ω1 (encoder)")
        ax.plot(te, np.gradient(a2, te), lw=0.8, label="driven half ω3 (encoder)")
        ax.set(xlabel="t (s)", ylabel="speed (rad/s)", title="Speeds of both halves")
        ax.grid(alpha=0.3)
        ax.legend()
        blocks.append(ctx.figure(save(fig, ctx.figure_path("clutch_speeds")), "Speeds of both halves"))
        rows.append(["hysteresis-loop energy ∮T dφ (J)", fmt(float(loop_energy(rel, m_e)))])
        rows.append(["max relative angle (deg)", fmt(float(np.degrees(np.max(np.abs(rel)))))])
    blocks.append(Table(["metric", "value"], rows))
    events = [e for e in ctx.recording.events if e.get("kind") in ("disengagement", "shutdown")]
    if events:
        blocks.append(Table(["t (s)", "event", "details"],
                            [[fmt(e["t"]), e["kind"], ", ".join(f"{k}={fmt(v)}" for k, v in e.items()
                                                                  if k not in ("t", "kind"))] for e in events]))
    else:
        blocks.append(Text("No disengagement: the relative angle never passed a lobe apex."))
    return blocks


register_section("clutch", clutch_section)
