"""Demo helpers for the ``rig`` CLI: a text summary and a one-revolution plot of the cam-bar plant, both from the
level-1 model (kinetostatics of the nominal machine at constant speed), whatever level a run uses."""
from __future__ import annotations

from math import degrees, tau
from pathlib import Path
from typing import Sequence

import numpy as np

from rig.fidelity import SAME_RUN
from rig.motion.speed import RPM
from rig.plants.cam_bar.mechanism import PinInsertionMechanism

LEVEL1 = "level 1 (kinetostatic, nominal machine, constant speed)"


def _angles(values: np.ndarray) -> str:
    """Angles (rad) in degrees, one decimal — more where two neighbours would read alike (a sign change just before
    a program boundary and the jump back across it: 319.96°, 320.00°, not 320.0°, 320.0°)."""
    shown = [degrees(a) for a in values]
    places = 1
    while places < 4 and len({f"{a:.{places}f}" for a in shown}) < len(shown):
        places += 1
    return ", ".join(f"{a:.{places}f}°" for a in shown) or "none"


def run_level_note(run_level: int | None) -> list[str]:
    """The line saying the level-1 summary is not the run's own model (none for no run, nor for a run at a level
    that simulates the same run as level 1: a forced level 0, :data:`rig.fidelity.SAME_RUN`)."""
    if run_level is None or run_level in SAME_RUN["cam_bar"]:
        return []
    return [f"  (this run is level {run_level}: these level-1 numbers are not its own; its own are the set statistics "
            f"and events below)"]


#: the spring rates of the thesis machine (N/m): as drawn, the design's, as found, as mounted (MODELS §3.1)
STUDY_RATES = (1090.0, 1190.0, 1680.0, 1890.0)


def flank_switch_table(mech: PinInsertionMechanism, omega: float,
                       rates: Sequence[float] = STUDY_RATES) -> dict[str, np.ndarray]:
    """Flank-switch angles (rad) at ``omega`` (rad/s) without the spring and with each of ``rates`` (N/m)."""
    table = {"no spring": mech.flank_switch_angles(omega, spring=False)}
    for k in rates:
        table[f"k = {k / 1e3:.2f} N/mm"] = mech.flank_switch_angles(omega, k=k)
    return table


def _rate_label(mech: PinInsertionMechanism, label: str) -> str:
    """A flank-switch row's label (:func:`flank_switch_table`), '… (mounted)' on the row of the mounted spring
    rate."""
    return f"{label} (mounted)" if label == f"k = {mech.k / 1e3:.2f} N/mm" else label


def summary_table(mech: PinInsertionMechanism, omega: float, run_level: int | None = None,
                  rates: Sequence[float] = STUDY_RATES) -> str:
    """Level-1 stroke, follower swing, max |R23|, rod force, flank switches per spring rate (``rates``, N/m), b_min,
    spring design (text) at the constant cam speed ``omega`` (rad/s); ``run_level``: the level of the run it is
    printed for (a note when that is not 1)."""
    phi = np.linspace(0.0, tau, 3600, endpoint=False)
    st = mech.state(phi, omega)
    ks = mech.kinetostatics(phi, omega)
    design = mech.spring_rate_design()
    rpm = omega / RPM
    lines = [
        f"{LEVEL1}: pin-insertion cam-bar mechanism at {rpm:.1f} rpm",
        *run_level_note(run_level),
        f"  mounted spring           {mech.k / 1e3:8.2f} N/mm",
        f"  slider (gripper) stroke  {np.ptp(st.s) * 1e3:8.3f} mm",
        f"  follower swing           {degrees(np.ptp(st.psi)):8.3f}°  (ψ {degrees(st.psi.min()):.2f}°"
        f" … {degrees(st.psi.max()):.2f}°)",
        f"  max |R23|                {np.max(np.abs(ks.R23n)):8.2f} N",
        f"  rod force at sensor      {ks.F_rod.min():8.2f} … {ks.F_rod.max():.2f} N (preload {mech.sensor_preload:g} N)",
        f"  drive torque             {ks.drive_torque.min():8.3f} … {ks.drive_torque.max():.3f} N·m",
        f"  max pressure angle       {degrees(ks.pressure_angle.max()):8.2f}°",
        f"  b_min (slider guide)     {np.nanmax(ks.b_min) * 1e3:8.2f} mm",
        f"  spring design k          {design.k / 1e3:8.3f} N/mm (thesis, travel {design.travel_thesis * 1e3:g} mm);"
        f" {design.k_geometry / 1e3:.3f} N/mm for the follower's travel {design.travel_geometry * 1e3:.2f} mm",
        "  level-1 flank switches: cam angles φ where the contact force R23 changes sign (there the roller would",
        "  leave its flank; level 2 simulates the crossing itself), without the spring and per spring rate k:",
    ]
    for label, angles in flank_switch_table(mech, omega, rates).items():
        lines.append(f"    {_rate_label(mech, label):<24} {_angles(angles)}")
    return "\n".join(lines)


def plot_cycle(mech: PinInsertionMechanism, omega: float, path: str | Path) -> Path:
    """PNG of the level-1 s, ψ, R23 and M_Σ over one cam revolution at ``omega`` (rad/s); returns the path
    written."""
    from rig.analysis.plots import figure, write_tight

    phi = np.linspace(0.0, tau, 1441)
    st = mech.state(phi)
    ks = mech.kinetostatics(phi, omega)
    deg = np.degrees(phi)
    fig, axes = figure(4, 1, size=(8, 9), sharex=True)
    for ax, y, label in zip(axes, (st.s * 1e3, np.degrees(st.psi), ks.R23n, ks.M_sigma),
                            ("s (mm)", "ψ (°)", "R23 (N)", "moment (N·m)")):
        ax.plot(deg, y, label="M_Σ (with the spring)" if ax is axes[3] else label.split(" (")[0])
        ax.set_ylabel(label)
        ax.grid(True)
    axes[2].axhline(0.0, color="k", lw=0.8)
    axes[3].plot(deg, ks.M23, "--", label="M23 (without the spring)")
    axes[3].axhline(0.0, color="k", lw=0.8)
    axes[3].legend(loc="upper left", bbox_to_anchor=(0.0, -0.28), ncol=2, frameon=False)   # below: no curve hidden
    axes[-1].set_xlabel("cam angle φ (°)")
    fig.suptitle(f"pin-insertion mechanism, {omega / RPM:.0f} rpm, k = {mech.k / 1e3:.2f} N/mm\n{LEVEL1}")
    w, h = fig.get_size_inches()        # margins in inches (tight_layout drew the figure twice: 0.3 s of the demo)
    fig.subplots_adjust(left=0.9 / w, right=1 - 0.2 / w, bottom=1.05 / h, top=1 - 0.75 / h, hspace=0.12)
    return write_tight(fig, path, tight=False)
