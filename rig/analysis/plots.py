"""PNG plots for reports (matplotlib, Agg). Each public function saves one figure and returns its path.

Figures are plain :class:`matplotlib.figure.Figure` objects (no pyplot bookkeeping) with fixed margins
in inches and fixed title heights: ``tight_layout`` or automatic title placement would draw every
figure an extra time, which made report writing several times slower.

Data come in SI and are drawn in display units (rig.analysis.units); every axis is labelled with its
quantity and unit.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Any, Callable, Mapping, NamedTuple, Sequence

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from rig.analysis.capability import MIN_SET_SIZE, index_text
from rig.analysis.elements_plot import FAILED, draw_elements
from rig.analysis.units import QUANTITY, DisplayUnits, Unit, signal_label
from rig.recorder import CurveRecord

DPI = 90
MARGINS = (0.85, 0.2, 0.55, 0.4)   # inches around the axes grid: left, right, bottom, top
ENVELOPE_BUCKETS = 1500            # long signals are drawn as their min/max over this many time buckets
OVERLAY_POINTS = 600_000           # points of an overlay of curves beyond which each is drawn as its envelope
OK_COLOR, NOK_COLOR = "tab:blue", FAILED
THEORY_COLOR = "tab:orange"    # a single curve's theory, dashed over the measured trace (it coincides with it often)
REASON_LINE = 0.17                 # inches per line of reasons under a curve's panels
#: vertices per piece a long line is drawn in (matplotlib's agg.path.chunksize): the rasteriser's memory otherwise
#: grows with the length drawn — an overlay of 5000 curves took +580 MB of RSS to draw, +10 MB in pieces
PATH_CHUNK = 20_000
matplotlib.rcParams["agg.path.chunksize"] = PATH_CHUNK     # read when a figure is drawn, and when a line is made


def figure(nrows: int = 1, ncols: int = 1, size: tuple[float, float] = (7, 4.5), **kw: Any) -> tuple[Figure, Any]:
    """A figure (inches) and its axes like ``plt.subplots``, titles at a fixed height above the axes."""
    with matplotlib.rc_context({"axes.titley": 1.0, "axes.formatter.useoffset": False}):
        fig = Figure(figsize=size)
        return fig, fig.subplots(nrows, ncols, **kw)


def save(fig: Figure, path: Path, wspace: float = 0.25, hspace: float = 0.3, bottom: float | None = None,
         left: float | None = None, right: float | None = None, top: float | None = None) -> Path:
    """Place the axes with :data:`MARGINS` (``bottom``/``left``/``right``/``top``: other margins in inches, e.g. for
    a legend beside the axes or a figure title; spacing as fractions of an axes) and write the PNG."""
    w, h = fig.get_size_inches()
    m_left, m_right, m_bottom, m_top = MARGINS
    left, bottom = m_left if left is None else left, m_bottom if bottom is None else bottom
    right, top = m_right if right is None else right, m_top if top is None else top
    fig.subplots_adjust(left=left / w, right=1 - right / w, bottom=bottom / h, top=1 - top / h,
                        wspace=wspace, hspace=hspace)
    separate_labels(fig)
    fig.savefig(path, dpi=DPI)
    for ax in fig.axes:     # its drawn data go now, not when the garbage collector next meets the figure's cycles
        for artist in [*ax.lines, *ax.collections, *ax.patches, *ax.images]:
            artist.remove()     # (fig.clear() made every axes anew, ticks and all: 0.1 s per figure)
    return path


def _marker_boxes(ax: Axes) -> list:
    """Display-space boxes of the lone markers of ``ax`` (failure marks: markers without a line, or one point)."""
    from matplotlib.transforms import Bbox
    boxes = []
    for line in ax.lines:
        lone = line.get_linestyle() in ("None", "none", "", " ") or len(line.get_xdata()) == 1
        if lone and line.get_marker() not in (None, "None", "none", ""):
            half = line.get_markersize() * ax.figure.dpi / 72.0 / 2.0 + 1.0
            for x, y in ax.transData.transform(np.column_stack(line.get_data())):
                boxes.append(Bbox([[x - half, y - half], [x + half, y + half]]))
    return boxes


def separate_labels(fig: Figure) -> None:
    """Move each annotation (element labels) that overlaps an earlier one of its axes, or a failure mark, down
    below it, so no label hides another or a mark (display space, after the layout)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.text import Annotation
    labelled = [(anns, marks) for ax in fig.axes if (anns := [t for t in ax.texts if isinstance(t, Annotation)])
                and ((marks := _marker_boxes(ax)) or len(anns) > 1)]
    if not labelled:                   # nothing can overlap: no renderer needed
        return
    renderer = FigureCanvasAgg(fig).get_renderer()
    for anns, placed in labelled:
        for ann in anns:
            for _ in range(12):
                box = ann.get_window_extent(renderer)
                hit = next((b for b in placed if b.overlaps(box)), None)
                if hit is None:
                    break
                dx, dy = ann.xyann
                ann.xyann = (dx, dy - (box.y1 - hit.y0 + 2.0) * 72.0 / fig.dpi)     # points
            placed.append(ann.get_window_extent(renderer))


def write_tight(fig: Figure, path: str | Path, dpi: int = 100, tight: bool = True) -> Path:
    """A stand-alone chart (not the report's fixed-margin layout): tight layout (unless the figure placed its axes
    itself, ``tight=False``), parent directories made, PNG written, figure closed (a pyplot figure is released
    by pyplot; a plain :class:`Figure` needs nothing)."""
    if tight:
        fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    if getattr(fig.canvas, "manager", None) is not None:
        import matplotlib.pyplot as plt
        plt.close(fig)
    return path


def _ticks(ax: Axes, x: int = 6, y: int = 6) -> None:
    """At most ``x``/``y`` tick labels per axis (they never overlap at the figure sizes used here)."""
    ax.xaxis.set_major_locator(MaxNLocator(x))
    ax.yaxis.set_major_locator(MaxNLocator(y))


def channel_label(units: DisplayUnits, ch: str) -> str:
    """``"displacement X (mm)"``: what the channel measures, the channel and its display unit."""
    u = units.channel(ch)
    quantity = {"length": "displacement"}.get(QUANTITY.get(u.si, ""), QUANTITY.get(u.si, ""))
    return u.axis(f"{quantity} {ch.upper()}".strip())


def _style(bad: bool, single: bool) -> dict:
    """Line style of a measured curve: NOK red, OK blue, faint when many curves overlap; a curve drawn
    alone is dark (its failed elements are the red)."""
    if single:
        return {"lw": 0.9, "color": "0.15", "alpha": 0.95, "zorder": 4}
    return {"lw": 1.0 if bad else 0.8, "color": NOK_COLOR if bad else OK_COLOR, "alpha": 0.95 if bad else 0.45,
            "zorder": 4 if bad else 1}


def _legend(ax: Axes, curves: Sequence[CurveRecord], nok: set[int], theory: bool = False) -> None:
    n_nok = sum(c.number in nok for c in curves)
    handles = [Line2D([], [], color=OK_COLOR, lw=1.2, label=f"OK ({len(curves) - n_nok})")] if len(curves) > n_nok \
        else []
    if n_nok:
        handles.append(Line2D([], [], color=NOK_COLOR, lw=1.5, label=f"NOK ({n_nok})"))
    if theory:
        handles.append(Line2D([], [], color="k", ls="--", lw=0.8, label="theory"))
    ax.legend(handles=handles, fontsize=7, loc="best", framealpha=0.85)


class _Overlay:
    """Polylines joined into one as they are added (NaN between them): one artist instead of one per curve (fast to
    draw). Beyond :data:`OVERLAY_POINTS` points in all (``sizes``: each polyline's), each polyline is drawn as the min
    and max of its y in equal runs of samples (:func:`envelope`: every peak kept; a long recording's thousands of
    curves drew tens of millions of points, ≈ 0.7 GB and 4 s per figure for 2000 curves), reduced as it is added: only
    one full polyline is held at a time, in a buffer filled in place (no small arrays held between the curves' large
    transient ones: they fragmented the heap)."""

    def __init__(self, sizes: Sequence[int]):
        n = len(sizes)
        self.buckets = max(OVERLAY_POINTS // (2 * n), 1) if n and sum(sizes) > OVERLAY_POINTS else 0
        room = sum(min(k, 2 * self.buckets + 2) if self.buckets else k for k in sizes) + n
        self.x, self.y, self.at = np.full(room, np.nan), np.full(room, np.nan), 0

    def add(self, x: Any, y: Any) -> None:
        x, y = np.asarray(x, float), np.asarray(y, float)
        if self.buckets:
            x, y = envelope(x, y, self.buckets)
        self.x[self.at:self.at + x.size], self.y[self.at:self.at + y.size] = x, y
        self.at += x.size + 1                                 # a NaN between polylines

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x[:self.at], self.y[:self.at]


class _Layer(NamedTuple):
    """One artist of an overlay: its axes, the curves it draws (in order), ``xy(curve) -> (x, y)``, ``size(curve)``
    (points of that polyline, known without reading the curve) and the line's style."""

    ax: Axes
    members: list
    xy: Callable[[Any], tuple[Any, Any]]
    size: Callable[[Any], int]
    style: dict


def _draw_layers(curves: Sequence[CurveRecord], layers: Sequence[_Layer]) -> None:
    """Draw the layers with members, in order, each as one artist, from one pass over ``curves``: a curve read again
    from its recording (:mod:`rig.recorder.curves`) is decoded once for all the layers, not once per layer."""
    live = [layer for layer in layers if layer.members]
    overlays = [_Overlay([layer.size(c) for c in layer.members]) for layer in live]
    members = [{id(c) for c in layer.members} for layer in live]
    for c in curves:
        for layer, overlay, ids in zip(live, overlays, members):
            if id(c) in ids:
                overlay.add(*layer.xy(c))
    for layer, overlay in zip(live, overlays):
        layer.ax.plot(*overlay.arrays(), **layer.style)


def _group_layers(ax: Axes, curves: Sequence[CurveRecord], nok: set[int], xy: Any) -> list[_Layer]:
    """The OK curves, then the NOK ones on top: ``xy(curve) -> (x, y)`` with as many points as ``curve.t``."""
    single = len(curves) == 1
    return [_Layer(ax, [c for c in curves if (c.number in nok) == bad], xy, lambda c: c.samples, _style(bad, single))
            for bad in (False, True)]


def _plot_groups(ax: Axes, curves: Sequence[CurveRecord], nok: set[int], xy: Any) -> None:
    """Draw ``xy(curve) -> (x, y)`` (as many points as ``curve.t``) of the OK curves, then of the NOK ones on top,
    one artist each; ``xy`` is called once per curve."""
    _draw_layers(curves, _group_layers(ax, curves, nok, xy))


def _xy(ax: Axes, curves: Sequence[CurveRecord], elements: list, nok: set[int], units: DisplayUnits,
        failed: Mapping[str, str] | None = None, marks: Sequence[tuple[float, float]] = ()) -> list[str]:
    """Y over X of the curves (NOK red, on top) with the evaluation elements (failed ones highlighted) and
    the points where they failed (``marks``, SI); notes on skipped elements."""
    ux, uy = units.channel("x"), units.channel("y")
    _plot_groups(ax, curves, nok, lambda c: (ux(c.x), uy(c.y)))
    notes = draw_elements(ax, elements, ux.factor, uy.factor, failed)
    for x, y in marks:
        ax.plot([ux(x)], [uy(y)], marker="X", ms=10, mfc=NOK_COLOR, mec="white", mew=1.0, zorder=6)
    ax.set(xlabel=channel_label(units, "x"), ylabel=channel_label(units, "y"))
    _ticks(ax)
    ax.grid(alpha=0.3)
    return notes


def _has_theory_abscissa(curve: CurveRecord, axis: str) -> bool:
    """:func:`_theory_abscissa` is not None, told without reading the curve's arrays."""
    held = curve.theory_sizes
    return "y" in held and (axis == "t" or "angle" in held or ("t" not in held and curve.has_angle))


def _theory_abscissa(curve: CurveRecord, axis: str) -> np.ndarray | None:
    """Abscissa of the curve's Y theory: time since the curve start (s) or cam angle (rad); None if absent."""
    if "y" not in curve.theory:
        return None
    if axis == "t":
        return curve.theory.get("t", curve.t) - curve.t[0]
    return curve.theory.get("angle", curve.angle if "t" not in curve.theory else None)


def _over(ax: Axes, curves: Sequence[CurveRecord], axis: str, nok: set[int], units: DisplayUnits) -> None:
    """Measured Y (NOK red) and its theory (dashed) over time since the curve start or over cam angle."""
    uy, ut, ua = units.channel("y"), units.of("s"), units.of("rad")
    u = ut if axis == "t" else ua
    one = len(curves) == 1
    theory = _Layer(ax, [c for c in curves if _has_theory_abscissa(c, axis)],
                    lambda c: (u(_theory_abscissa(c, axis)), uy(c.theory["y"])), lambda c: c.theory_sizes["y"],
                    {"ls": "--", "lw": 0.8, "color": THEORY_COLOR if one else "k", "alpha": 0.9 if one else 0.25,
                     "zorder": 5})
    measured = _group_layers(ax, curves, nok, lambda c: (u(c.t - c.t[0] if axis == "t" else c.angle), uy(c.y)))
    _draw_layers(curves, [*measured, theory])            # one pass: each curve's arrays used once for both
    ax.set(xlabel=u.axis("time since curve start") if axis == "t" else u.axis("cam angle"),
           ylabel=channel_label(units, "y"))
    _ticks(ax)
    ax.grid(alpha=0.3)


def _axes_of(curves: Sequence[CurveRecord]) -> list[str]:
    """Abscissae to draw Y over: time, and cam angle when every curve has a measured angle."""
    return ["t", "angle"] if all(c.has_angle for c in curves) else ["t"]


def force_displacement(curves: Sequence[CurveRecord], elements: list, path: Path, title: str,
                       nok: set[int] = frozenset(), units: DisplayUnits | None = None,
                       failed: Mapping[str, str] | None = None) -> tuple[Path, list[str]]:
    """Y over X of the curves (NOK in red, drawn on top) with the program's evaluation elements (``failed``:
    ``{name: label}`` of those to highlight)."""
    units = units or DisplayUnits()
    fig, ax = figure(size=(7.5, 4.8))
    notes = _xy(ax, curves, elements, nok, units, failed)
    _legend(ax, curves, nok)
    ax.set_title(title, loc="left", fontsize=10)
    return save(fig, path), notes


def signals_over(curves: Sequence[CurveRecord], path: Path, title: str, nok: set[int] = frozenset(),
                 units: DisplayUnits | None = None) -> Path:
    """Y of all curves over time since each curve's start and over cam angle (if measured), theory dashed."""
    units = units or DisplayUnits()
    axes = _axes_of(curves)
    fig, axs = figure(1, len(axes), size=(5.6 * len(axes), 3.9), sharey=True, squeeze=False)
    for ax, axis in zip(axs[0], axes):
        _over(ax, curves, axis, nok, units)
    axs[0, 0].set_title(title, loc="left", fontsize=10)
    _legend(axs[0, -1], curves, nok, theory=any("y" in c.theory_sizes for c in curves))
    for ax in axs[0, 1:]:
        ax.set_ylabel("")
    return save(fig, path, wspace=0.08)


def theory_residuals(curves: Sequence[CurveRecord], path: Path, title: str, nok: set[int] = frozenset(),
                     units: DisplayUnits | None = None,
                     lags: Mapping[tuple[int, str], float] | None = None) -> Path | None:
    """Measurement minus theory of X and Y for every curve over the time since its start (the theory interpolated
    to the measured samples, delayed by the curve's ``lags[(number, channel)]`` (s) where given; NOK red), with the
    mean over the curves; None when no curve has a theory."""
    lags = lags or {}
    units = units or DisplayUnits()
    channels = [ch for ch in ("x", "y") if any(ch in c.theory_sizes for c in curves)]
    if not channels:
        return None
    fig, axs = figure(len(channels), 1, size=(9.0, 0.9 + 2.3 * len(channels)), sharex=True, squeeze=False)
    ut = units.of("s")
    layers, sums = [], []
    for ax, ch in zip(axs[:, 0], channels):
        u = units.channel(ch)
        with_theory = [c for c in curves if ch in c.theory_sizes]
        n = min(c.samples for c in with_theory)            # the mean over the samples every curve has
        total, counts = np.zeros(n), np.zeros(n, dtype=np.int64)

        def residual(c: CurveRecord, ch=ch, u=u, n=n, total=total, counts=counts) -> tuple[np.ndarray, np.ndarray]:
            """The curve's residual over its time, added to the running mean's sums as it is made."""
            th_t = np.asarray(c.theory.get("t", c.t), dtype=float)
            at = c.t - lags.get((c.number, ch), 0.0)      # no theory before its first or after its last sample
            res = u(np.where((at >= th_t[0]) & (at <= th_t[-1]),
                             np.asarray(getattr(c, ch), float) - np.interp(at, th_t, np.asarray(c.theory[ch], float)),
                             np.nan))
            finite = np.isfinite(res[:n])
            total[finite] += res[:n][finite]
            counts[finite] += 1
            return ut(c.t - c.t[0]), res

        layers += _group_layers(ax, with_theory, nok, residual)
        sums.append((with_theory[0], n, total, counts))
    _draw_layers(curves, layers)                          # one pass for both channels: each curve decoded once
    for ax, ch, (first, n, total, counts) in zip(axs[:, 0], channels, sums):
        u = units.channel(ch)
        mean = np.where(counts > 0, total / np.maximum(counts, 1), np.nan)
        ax.plot(ut(first.t[:n] - first.t[0]), mean, color="k", lw=1.0, label="mean over the curves", zorder=5)
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_ylabel(u.axis(f"{ch.upper()} − theory"), fontsize=9)
        _ticks(ax, 8, 5)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axs[-1, 0].set_xlabel(ut.axis("time since curve start"))
    axs[0, 0].set_title(title, loc="left", fontsize=10)
    return save(fig, path, hspace=0.12)


def curve_panels(curve: CurveRecord, elements: list, path: Path, nok: set[int] = frozenset(),
                 units: DisplayUnits | None = None, failed: Mapping[str, str] | None = None,
                 reasons: Sequence[str] = (), marks: Sequence[tuple[float, float]] = ()) -> Path:
    """One curve: Y over X with the elements, Y over time and over cam angle (if measured) with theory.
    A NOK curve: ``failed`` elements highlighted, ``marks`` (SI points) where they failed, ``reasons``
    written under the panels."""
    units = units or DisplayUnits()
    axes = _axes_of([curve])
    width = 5.6 + 3.7 * len(axes)
    chars = int((width - MARGINS[0] - 0.3) * 13.5)      # 8 pt monospace: 0.6·8 pt = 1/15 in a character, with room
    lines = [line for r in reasons for line in textwrap.wrap(r, chars, subsequent_indent="    ")]
    bottom = MARGINS[2] + (0.15 + REASON_LINE * len(lines) if lines else 0.0)
    fig, axs = figure(1, 1 + len(axes), size=(width, 3.9 + bottom - MARGINS[2]), sharey=True, squeeze=False,
                      gridspec_kw={"width_ratios": [1.5] + [1.0] * len(axes)})
    _xy(axs[0, 0], [curve], elements, nok, units, failed, marks)
    for ax, axis in zip(axs[0, 1:], axes):
        _over(ax, [curve], axis, nok, units)
        ax.set_ylabel("")
    bad = curve.number in nok
    if "y" in curve.theory:                # what the dashed line is (the overlays say it in their legend too)
        axs[0, -1].legend(handles=[Line2D([], [], color=_style(bad, True)["color"], lw=1.2, label="measured"),
                                   Line2D([], [], color=THEORY_COLOR, ls="--", lw=0.8, label="theory")],
                          fontsize=7, loc="best", framealpha=0.85)
    axs[0, 0].set_title(f"curve {curve.number}: {'NOK' if bad else 'OK'}", loc="left", fontsize=10,
                        fontweight="bold", color=NOK_COLOR if bad else "tab:green")
    for i, line in enumerate(lines):
        fig.text(MARGINS[0] / width, (bottom - MARGINS[2] - 0.05 - REASON_LINE * (i + 0.5)) / fig.get_figheight(),
                 line, fontsize=8, color=NOK_COLOR if bad else "k", va="center", family="monospace")
    return save(fig, path, wspace=0.08, bottom=bottom)


def _bars(ax: Axes, values: np.ndarray, edges: np.ndarray) -> None:
    """Histogram bars of ``values`` over ``edges`` as one collection (one artist for all bars, white lines between
    them; ``ax.hist`` makes a patch per bar, which costs most of a histogram grid's drawing)."""
    from matplotlib.collections import PolyCollection
    counts = np.histogram(values, edges)[0].astype(float)
    x0, x1, zero = edges[:-1], edges[1:], np.zeros(counts.size)
    verts = np.stack([np.column_stack(c) for c in ((x0, zero), (x0, counts), (x1, counts), (x1, zero))], axis=1)
    ax.add_collection(PolyCollection(verts, facecolors="tab:blue", edgecolors="white", linewidths=0.6, alpha=0.7))
    ax.autoscale_view()


def _histogram(ax: Axes, values: np.ndarray, stats: Mapping) -> None:
    """Histogram of one process value (SI ``values``; ``stats`` in display units with its ``factor``) with
    its limits (red), mean (black) and mean ± 3σ (dashed)."""
    v = values[np.isfinite(values)] * stats.get("factor", 1.0)
    bins = max(5, min(40, int(np.sqrt(v.size)) + 1))
    spread = stats.get("spread", v.size > 0 and np.ptp(v) > 0)
    if v.size and not spread:                     # one value repeated: a narrow bar at it, not a made-up width
        limits = [stats[k] for k in ("lsl", "usl") if stats.get(k) is not None]
        half = max([abs(v[0] - lim) * 1.2 for lim in limits] + [abs(v[0]) * 1e-3, 1e-12])
        _bars(ax, v, np.linspace(v[0] - half, v[0] + half, 42))
    else:                                         # bars at least 1/60 of the shown range wide: visible even when
        marks = [stats[k] for k in ("lsl", "usl", "minus_3sigma", "plus_3sigma") if stats.get(k) is not None]
        span = max([v.max()] + marks) - min([v.min()] + marks)          # limits far from the data widen the axis
        width = max(np.ptp(v) / bins, span / 60.0)
        count = max(1, int(np.ceil(np.ptp(v) / width)))
        edges = 0.5 * (v.min() + v.max()) + (np.arange(count + 1) - count / 2) * width
        _bars(ax, v, edges)                                      # bins apart: equal widths show
    for key, style in (("lsl", "r-"), ("usl", "r-"), ("minus_3sigma", "k--"), ("plus_3sigma", "k--"),
                       ("mean", "k-")):
        if stats.get(key) is not None:
            ax.axvline(stats[key], color=style[0], ls=style[1:], lw=1.2 if style[0] == "r" else 1)
    for key, name in (("lsl", "LSL"), ("usl", "USL")):              # the limits' values, named on their lines
        if stats.get(key) is not None:
            ax.annotate(f"{name} {stats[key]:.4g}", (stats[key], 0.97), xycoords=("data", "axes fraction"),
                        xytext=(-2 if key == "lsl" else 2, 0), textcoords="offset points", fontsize=7.5, color="r",
                        ha="right" if key == "lsl" else "left", va="top", rotation=90, annotation_clip=False)
    unit = f" ({stats['unit']})" if stats.get("unit") else ""
    if not spread and (stats.get("cp") is not None or stats.get("cpk") is not None):
        cap = ", Cp/Cpk n/a (no spread)"
    elif stats.get("cp") is not None or stats.get("cpk") is not None:
        cap = f", Cp {index_text(stats['cp'])}, Cpk {index_text(stats['cpk'])}" + (
            f" (indicative: n < {MIN_SET_SIZE})" if stats["n"] < MIN_SET_SIZE else "")
    else:
        cap = ""
    ax.set_title(f"{stats['name']}: n = {stats['n']}{cap}", fontsize=9, loc="left")
    ax.set_xlabel(f"{stats['name']}{unit}", fontsize=9)
    ax.xaxis.set_major_locator(MaxNLocator(4))
    ax.yaxis.set_major_locator(MaxNLocator(4, integer=True))
    ax.set_ylim(0.0, ax.get_ylim()[1] * 1.25)                  # room for the limit labels above the bars
    ax.ticklabel_format(axis="x", style="plain", useOffset=False)
    ax.tick_params(labelsize=8)


def histograms(table: Mapping[str, np.ndarray], stats: Mapping[str, Mapping], path: Path, ncols: int = 3) -> Path:
    """Grid of histograms, one per process value in ``stats`` (values from ``table``), see :func:`_histogram`."""
    names = list(stats)
    ncols = min(ncols, len(names))
    nrows = math.ceil(len(names) / ncols)
    fig, axs = figure(nrows, ncols, size=(4.3 * ncols, 2.7 * nrows), squeeze=False)
    for ax, name in zip(axs.flat, names):
        _histogram(ax, table[name], stats[name])
    for ax in axs[:, 0]:
        ax.set_ylabel("count")
    for ax in axs.flat[len(names):]:
        ax.set_visible(False)
    return save(fig, path, wspace=0.3, hspace=0.8, left=0.6)


def envelope(t: np.ndarray, y: np.ndarray, buckets: int = ENVELOPE_BUCKETS) -> tuple[np.ndarray, np.ndarray]:
    """Min and max of ``y`` in each of at most ``buckets`` equal runs of samples and in the shorter run left over
    (fewer samples than a run: the picture keeps its resolution to the end), in time order: at most
    ``2 (buckets + 1)`` points.

    Drawn at a width of fewer than ``buckets`` pixels this is the same picture as all samples.
    """
    k = -(-t.size // buckets)                       # samples per run, rounded up
    if k < 3:
        return t, y
    runs = t.size // k
    m = k * runs
    tb, yb = t[:m].reshape(runs, k), y[:m].reshape(runs, k)
    lo, hi = np.argmin(yb, axis=1), np.argmax(yb, axis=1)
    idx = np.sort(np.column_stack([lo, hi]), axis=1)
    rows = np.arange(runs)[:, None]
    tail = np.unique([m + np.argmin(y[m:]), m + np.argmax(y[m:])]) if m < t.size else np.array([], dtype=int)
    return np.concatenate([tb[rows, idx].ravel(), t[tail]]), np.concatenate([yb[rows, idx].ravel(), y[tail]])


def series(data: Mapping[str, np.ndarray], names: Sequence[str], path: Path, title: str, ylabel: str) -> Path:
    """Several signals of a bulk series over time (for transducers or extension sections)."""
    fig, ax = figure(size=(7, 3.5))
    for n in names:
        ax.plot(*envelope(data["t"], data[n]), lw=0.8, label=n)
    ax.set(xlabel="t (s)", ylabel=ylabel, title=title)
    _ticks(ax)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return save(fig, path)


SCALE_SPLIT = 4.0     # signals of one unit whose ranges differ by more than this get separate axes


def truth_groups(data: Mapping[str, np.ndarray], names: Sequence[str], units: DisplayUnits
                 ) -> list[tuple[Unit, str, list[str]]]:
    """Signals grouped by display unit, then split where their ranges differ by more than
    :data:`SCALE_SPLIT` (a 9° follower swing is not drawn on the axis of a 360° cam angle):
    ``[(unit, quantity, names)]`` in the order the units first appear, the largest range first within a unit, each
    axis's names in their order in ``names``."""
    by_unit: dict[str, tuple[Unit, list[str]]] = {}
    for n in names:
        u = units.signal(n)
        by_unit.setdefault(u.label, (u, []))[1].append(n)
    out = []
    for u, members in by_unit.values():
        quantity = QUANTITY.get(u.si, "value")
        span = {n: float(np.ptp(u(data[n]))) if data[n].size else 0.0 for n in members}
        groups: list[list[str]] = [[]]
        for n in sorted(members, key=lambda n: -span[n]):
            if groups[-1] and span[n] * SCALE_SPLIT < span[groups[-1][0]]:
                groups.append([])
            groups[-1].append(n)
        out += [(u, quantity, sorted(g, key=members.index)) for g in groups]   # each axis in the recording's order:
    return out                                                              # ω1 before ω3 (its colour) on every run


def truth_panels(data: Mapping[str, np.ndarray], names: Sequence[str], path: Path, units: DisplayUnits,
                 window: tuple[float, float] | None = None, title: str = "plant truth", plant: str | None = None
                 ) -> tuple[Path, list[list[str]], list[str]]:
    """Plant truth signals over time, one axis per display unit (and per scale, :func:`truth_groups`),
    stacked with a common time axis; ``window``: the time range shown (s); ``plant``: whose signals they are (the
    legend says what each is for that plant, :func:`~rig.analysis.units.signal_label`). A signal constant over the window gets
    no axis, nor does one equal to an earlier signal of its unit. Returns the chart, the signals of each axis top to
    bottom, and what was not drawn (``name = value unit``, ``name equals other``)."""
    t = data["t"]
    keep = slice(None) if window is None else (t >= window[0]) & (t <= window[1])
    shown = {n: np.asarray(data[n])[keep] for n in names}
    tt = t[keep]
    constant = [n for n in names if shown[n].size and np.ptp(shown[n]) <= 1e-12 * max(1.0, float(np.abs(shown[n]).max()))]
    undrawn = [f"{n} = {units.signal(n).text(float(shown[n][0]))}" for n in constant]
    same = {n: next(m for m in names if units.signal(m).si == units.signal(n).si and np.array_equal(shown[m], shown[n]))
            for n in names}                        # a signal equal to an earlier one of its unit is drawn once, as it
    undrawn += [f"{n} equals {m}" for n, m in same.items() if m != n and n not in constant]
    drawn = [n for n in names if n not in constant and same[n] == n]
    groups = truth_groups(shown, drawn, units) or truth_groups(shown, names, units)
    fig, axs = figure(len(groups), 1, size=(10.8, 0.6 + 1.55 * len(groups)), sharex=True, squeeze=False)
    for ax, (u, quantity, members) in zip(axs[:, 0], groups):
        for n in members:
            what = signal_label(n, plant)
            label = f"{n}: {what}" if what else n
            ax.plot(*envelope(tt, u(shown[n])), lw=0.9, label=textwrap.fill(label, 34, subsequent_indent="  "))
        ax.set_ylabel(u.axis(quantity), fontsize=8)
        lo, hi = ax.get_ylim()
        if hi - lo < 1e-9 * max(1.0, abs(hi)):         # a constant signal: a readable band around it
            mid = (hi + lo) / 2
            ax.set_ylim(mid - 0.05 * max(abs(mid), 1e-9), mid + 0.05 * max(abs(mid), 1e-9))
        ax.yaxis.set_major_locator(MaxNLocator(4))
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)
    axs[-1, 0].set_xlabel(units.of("s").axis("time"))
    axs[-1, 0].xaxis.set_major_locator(MaxNLocator(8))
    axs[0, 0].set_title(title, loc="left", fontsize=10)
    path = save(fig, path, hspace=0.12, left=1.0, right=2.8)      # legends beside the axes: no data hidden
    return path, [members for _, _, members in groups], undrawn


def _f(v: float | None, digits: int = 3) -> str:
    return "—" if v is None else f"{v:.{digits}g}"
