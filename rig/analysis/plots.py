"""PNG plots for reports (matplotlib, Agg backend). Each function saves one figure and returns its path."""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rig.analysis.elements_plot import draw_elements  # noqa: E402
from rig.recorder import CurveRecord  # noqa: E402


def _save(fig: plt.Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def force_displacement(curves: Sequence[CurveRecord], elements: list, path: Path, title: str,
                       nok: set[int] = frozenset(), units: tuple[str, str] = ("SI", "SI")) -> tuple[Path, list[str]]:
    """Y over X of the curves (NOK in red, drawn on top) with the program's evaluation elements."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for c in sorted(curves, key=lambda c: c.number in nok):
        bad = c.number in nok
        ax.plot(c.x, c.y, lw=0.8, color="tab:red" if bad else "tab:blue", alpha=0.9 if bad else 0.5)
    notes = draw_elements(ax, elements)
    ax.set(xlabel=f"X ({units[0]})", ylabel=f"Y ({units[1]})", title=title)
    ax.grid(alpha=0.3)
    return _save(fig, path), notes


def signal_over(curve: CurveRecord, axis: str, path: Path) -> Path:
    """Y over time (s) or over cam angle (deg), with the theory if it has that abscissa."""
    fig, ax = plt.subplots(figsize=(7, 3.5))
    if axis == "t":
        ax.plot(curve.t, curve.y, label="measured")
        if "y" in curve.theory:
            ax.plot(curve.theory.get("t", curve.t), curve.theory["y"], "--", label="theory")
        ax.set_xlabel("t (s)")
    else:
        ax.plot(np.degrees(curve.angle), curve.y, label="measured")
        th_angle = curve.theory.get("angle", curve.angle if "t" not in curve.theory else None)
        if "y" in curve.theory and th_angle is not None:
            ax.plot(np.degrees(th_angle), curve.theory["y"], "--", label="theory")
        ax.set_xlabel("cam angle (deg)")
    ax.set(ylabel="Y (SI)", title=f"curve {curve.number}")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def histogram(values: np.ndarray, stats: Mapping, path: Path) -> Path:
    """Histogram of one process value with its limits (red) and mean ± 3σ (dashed)."""
    fig, ax = plt.subplots(figsize=(6, 3.5))
    v = values[np.isfinite(values)]
    ax.hist(v, bins=max(5, min(40, int(np.sqrt(v.size)) + 1)), color="tab:blue", alpha=0.7)
    for key, style in (("lsl", "r-"), ("usl", "r-"), ("minus_3sigma", "k--"), ("plus_3sigma", "k--"),
                       ("mean", "k-")):
        if stats.get(key) is not None:
            ax.axvline(stats[key], color=style[0], ls=style[1:], lw=1)
    ax.set(title=f"{stats['name']}  (n={stats['n']}, Cp={_f(stats['cp'])}, Cpk={_f(stats['cpk'])})",
           xlabel=stats["name"], ylabel="count")
    return _save(fig, path)


def series(data: Mapping[str, np.ndarray], names: Sequence[str], path: Path, title: str, ylabel: str) -> Path:
    """Several signals of a bulk series over time (for truth, transducers or extension sections)."""
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for n in names:
        ax.plot(data["t"], data[n], lw=0.8, label=n)
    ax.set(xlabel="t (s)", ylabel=ylabel, title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def _f(v: float | None) -> str:
    return "—" if v is None else f"{v:.3g}"
