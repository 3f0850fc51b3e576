"""PNG plots for reports (matplotlib, Agg). Each public function saves one figure and returns its path.

Figures are plain :class:`matplotlib.figure.Figure` objects (no pyplot bookkeeping) with fixed margins
in inches and fixed title heights: ``tight_layout`` or automatic title placement would draw every
figure an extra time, which made report writing several times slower.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping, Sequence

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from rig.analysis.elements_plot import draw_elements
from rig.recorder import CurveRecord

DPI = 90
MARGINS = (0.8, 0.2, 0.55, 0.4)    # inches around the axes grid: left, right, bottom, top
ENVELOPE_BUCKETS = 1500            # long signals are drawn as their min/max over this many time buckets


def figure(nrows: int = 1, ncols: int = 1, size: tuple[float, float] = (7, 4.5), **kw: Any) -> tuple[Figure, Any]:
    """A figure (inches) and its axes like ``plt.subplots``, titles at a fixed height above the axes."""
    with matplotlib.rc_context({"axes.titley": 1.0}):
        fig = Figure(figsize=size)
        return fig, fig.subplots(nrows, ncols, **kw)


def save(fig: Figure, path: Path, wspace: float = 0.25, hspace: float = 0.3) -> Path:
    """Place the axes with :data:`MARGINS` (spacing as fractions of an axes) and write the PNG."""
    w, h = fig.get_size_inches()
    left, right, bottom, top = MARGINS
    fig.subplots_adjust(left=left / w, right=1 - right / w, bottom=bottom / h, top=1 - top / h,
                        wspace=wspace, hspace=hspace)
    fig.savefig(path, dpi=DPI)
    return path


def _style(bad: bool, single: bool) -> dict:
    """Line style of a measured curve: NOK red, OK blue, faint when many curves overlap."""
    return {"lw": 0.8, "color": "tab:red" if bad else "tab:blue", "alpha": 0.9 if bad or single else 0.5}


def _xy(ax: Axes, curves: Sequence[CurveRecord], elements: list, nok: set[int], units: tuple[str, str]) -> list[str]:
    """Y over X of the curves (NOK red, on top) with the evaluation elements; notes on skipped elements."""
    for c in sorted(curves, key=lambda c: c.number in nok):
        ax.plot(c.x, c.y, **_style(c.number in nok, len(curves) == 1))
    notes = draw_elements(ax, elements)
    ax.set(xlabel=f"X ({units[0]})", ylabel=f"Y ({units[1]})")
    ax.grid(alpha=0.3)
    return notes


def _theory_abscissa(curve: CurveRecord, axis: str) -> np.ndarray | None:
    """Abscissa of the curve's Y theory: time since the curve start (s) or cam angle (deg); None if absent."""
    if "y" not in curve.theory:
        return None
    if axis == "t":
        return curve.theory.get("t", curve.t) - curve.t[0]
    angle = curve.theory.get("angle", curve.angle if "t" not in curve.theory else None)
    return None if angle is None else np.degrees(angle)


def _over(ax: Axes, curves: Sequence[CurveRecord], axis: str, nok: set[int], y_unit: str) -> None:
    """Measured Y (NOK red) and its theory (dashed) over time since the curve start or over cam angle."""
    for c in sorted(curves, key=lambda c: c.number in nok):
        s = c.t - c.t[0] if axis == "t" else np.degrees(c.angle)
        ax.plot(s, c.y, **_style(c.number in nok, len(curves) == 1))
        th = _theory_abscissa(c, axis)
        if th is not None:
            ax.plot(th, c.theory["y"], "--", lw=0.8, color="k", alpha=0.7 if len(curves) == 1 else 0.25)
    ax.set(xlabel="time since curve start (s)" if axis == "t" else "cam angle (deg)", ylabel=f"Y ({y_unit})")
    ax.grid(alpha=0.3)


def _axes_of(curves: Sequence[CurveRecord]) -> list[str]:
    """Abscissae to draw Y over: time, and cam angle when every curve has a measured angle."""
    return ["t", "angle"] if all(c.angle is not None for c in curves) else ["t"]


def force_displacement(curves: Sequence[CurveRecord], elements: list, path: Path, title: str,
                       nok: set[int] = frozenset(), units: tuple[str, str] = ("SI", "SI")) -> tuple[Path, list[str]]:
    """Y over X of the curves (NOK in red, drawn on top) with the program's evaluation elements."""
    fig, ax = figure(size=(7, 4.5))
    notes = _xy(ax, curves, elements, nok, units)
    ax.set_title(title)
    return save(fig, path), notes


def signals_over(curves: Sequence[CurveRecord], path: Path, title: str, nok: set[int] = frozenset(),
                 y_unit: str = "SI") -> Path:
    """Y of all curves over time since each curve's start and over cam angle (if measured), theory dashed."""
    axes = _axes_of(curves)
    fig, axs = figure(1, len(axes), size=(5.5 * len(axes), 3.8), sharey=True, squeeze=False)
    for ax, axis in zip(axs[0], axes):
        _over(ax, curves, axis, nok, y_unit)
    axs[0, 0].set_title(title, loc="left")
    for ax in axs[0, 1:]:
        ax.set_ylabel("")
    return save(fig, path, wspace=0.08)


def curve_panels(curve: CurveRecord, elements: list, path: Path, nok: set[int] = frozenset(),
                 units: tuple[str, str] = ("SI", "SI")) -> Path:
    """One curve: Y over X with the elements, Y over time and over cam angle (if measured) with theory."""
    axes = _axes_of([curve])
    fig, axs = figure(1, 1 + len(axes), size=(4.2 * (1 + len(axes)), 3.5), sharey=True, squeeze=False)
    _xy(axs[0, 0], [curve], elements, nok, units)
    for ax, axis in zip(axs[0, 1:], axes):
        _over(ax, [curve], axis, nok, units[1])
        ax.set_ylabel("")
    verdict = "NOK" if curve.number in nok else "OK"
    axs[0, 0].set_title(f"curve {curve.number} ({verdict})", loc="left")
    return save(fig, path, wspace=0.08)


def _histogram(ax: Axes, values: np.ndarray, stats: Mapping) -> None:
    """Histogram of one process value with its limits (red), mean (black) and mean ± 3σ (dashed)."""
    v = values[np.isfinite(values)]
    ax.hist(v, bins=max(5, min(40, int(np.sqrt(v.size)) + 1)), color="tab:blue", alpha=0.7)
    for key, style in (("lsl", "r-"), ("usl", "r-"), ("minus_3sigma", "k--"), ("plus_3sigma", "k--"),
                       ("mean", "k-")):
        if stats.get(key) is not None:
            ax.axvline(stats[key], color=style[0], ls=style[1:], lw=1)
    unit = f" ({stats['unit']})" if stats.get("unit") else ""
    ax.set_title(f"{stats['name']}: n={stats['n']}, Cp={_f(stats['cp'])}, Cpk={_f(stats['cpk'])}", fontsize=9)
    ax.set_xlabel(f"{stats['name']}{unit}", fontsize=9)
    ax.xaxis.set_major_locator(MaxNLocator(5))
    ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 4))
    ax.tick_params(labelsize=8)


def histograms(table: Mapping[str, np.ndarray], stats: Mapping[str, Mapping], path: Path, ncols: int = 3) -> Path:
    """Grid of histograms, one per process value in ``stats`` (values from ``table``), see :func:`_histogram`."""
    names = list(stats)
    ncols = min(ncols, len(names))
    nrows = math.ceil(len(names) / ncols)
    fig, axs = figure(nrows, ncols, size=(4.2 * ncols, 2.6 * nrows), squeeze=False)
    for ax, name in zip(axs.flat, names):
        _histogram(ax, table[name], stats[name])
    for ax in axs[:, 0]:
        ax.set_ylabel("count")
    for ax in axs.flat[len(names):]:
        ax.set_visible(False)
    return save(fig, path, wspace=0.3, hspace=0.75)


def envelope(t: np.ndarray, y: np.ndarray, buckets: int = ENVELOPE_BUCKETS) -> tuple[np.ndarray, np.ndarray]:
    """Min and max of ``y`` in each of ``buckets`` equal runs of samples, in time order (plus the tail).

    Drawn at a width of fewer than ``buckets`` pixels this is the same picture as all samples.
    """
    k = t.size // buckets
    if k < 3:
        return t, y
    m = k * buckets
    tb, yb = t[:m].reshape(buckets, k), y[:m].reshape(buckets, k)
    lo, hi = np.argmin(yb, axis=1), np.argmax(yb, axis=1)
    idx = np.sort(np.column_stack([lo, hi]), axis=1)
    rows = np.arange(buckets)[:, None]
    return np.concatenate([tb[rows, idx].ravel(), t[m:]]), np.concatenate([yb[rows, idx].ravel(), y[m:]])


def series(data: Mapping[str, np.ndarray], names: Sequence[str], path: Path, title: str, ylabel: str) -> Path:
    """Several signals of a bulk series over time (for truth, transducers or extension sections)."""
    fig, ax = figure(size=(7, 3.5))
    for n in names:
        ax.plot(*envelope(data["t"], data[n]), lw=0.8, label=n)
    ax.set(xlabel="t (s)", ylabel=ylabel, title=title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save(fig, path)


def _f(v: float | None) -> str:
    return "—" if v is None else f"{v:.3g}"
