"""Draw DigiForce evaluation elements (program config dicts) on a force–displacement axis.

Geometry is read from the ``elements`` list of the program config stored in the recording
(attachment ``device/program/<n>.json``), in SI like the curves, with the keys of
``firmware_sim.digiforce`` (docs/digiforce.md): window ``x_min x_max y_min y_max entry exit``;
trapezoid ``axis start end lower upper entry exit``; threshold ``axis value direction [range]``;
envelope ``references [{x, y}] dx dy``. It is drawn scaled by the display factors ``sx``, ``sy``
(display = SI × factor) of the axes. Unknown kinds, disabled elements and elements without drawable
geometry are skipped and reported as notes. Failed elements (``failed``) are drawn thick and red and
labelled with what failed.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.patches import Polygon

SIDES = ("bottom", "right", "top", "left")        # edge i runs from corner i to corner i+1
_ROLE_STYLE = {"entry": dict(color="tab:green", lw=3.0), "exit": dict(color="black", lw=3.0, ls="--")}
FAILED = "#d62728"


@dataclass(frozen=True)
class Style:
    """How one element is drawn: scale factors of X and Y (display = SI × factor), and its failure label
    (None: it passed or is not judged here)."""

    sx: float = 1.0
    sy: float = 1.0
    failed: str | None = None

    def color(self, normal: str) -> str:
        return FAILED if self.failed is not None else normal

    @property
    def lw(self) -> float:
        return 1.8 if self.failed is not None else 1.2      # stands out, yet a curve on it stays visible

    def label(self, e: Mapping) -> str:
        name = str(e.get("name", e.get("kind")))
        return name if self.failed is None else f"{name} ✗ {self.failed}"


LABEL_Z = 6        # element labels above the curves (lines 2-4), so that curves never hide them


def _label(ax: Axes, text: str, where: tuple[float, float], color: str, style: Style, **kw: Any) -> None:
    bold = {"fontweight": "bold", "bbox": dict(boxstyle="round,pad=0.15", fc="white", ec=FAILED, lw=0.8, alpha=0.9)} \
        if style.failed is not None else {"bbox": dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.75)}
    ax.annotate(text, where, fontsize=7 if style.failed is None else 7.5, color=color, textcoords="offset points",
                zorder=LABEL_Z, **(dict(xytext=(2, 2)) | kw | bold))


def _region(ax: Axes, e: Mapping, corners: Sequence[tuple[float, float]], color: str, style: Style) -> None:
    """Quadrilateral with corners counter-clockwise from bottom-left; entry/exit sides highlighted. A failed
    one is drawn thick and red with its label inside, at the top corner nearer the middle of the axes."""
    pts = np.asarray(corners, dtype=float) * [style.sx, style.sy]
    color = style.color(color)
    ax.add_patch(Polygon(pts, closed=True, fill=False, ec=color, lw=style.lw, zorder=3 if style.failed else 2))
    for role in ("entry", "exit"):
        side = e.get(role)
        if side in SIDES:
            i = SIDES.index(side)
            seg = pts[[i, (i + 1) % 4]]
            ax.plot(seg[:, 0], seg[:, 1], **_ROLE_STYLE[role])
    if style.failed is None:
        _label(ax, style.label(e), tuple(pts[3]), color, style)
        return
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    right = pts[3, 0] > (x0 + x1) / 2             # a region on the right: label aligned with its right edge
    band = 0.08 * (y1 - y0)                       # about a label's height
    top, bottom = max(pts[2, 1], pts[3, 1]), min(pts[0, 1], pts[1, 1])
    crowd = {side: _points_in(ax, pts[:, 0].min(), pts[:, 0].max(), lo, lo + band) if inside else np.inf
             for side, lo, inside in (("above", top, top + band < y1), ("below", bottom - band, bottom - band > y0))}
    above = crowd["above"] <= crowd["below"]      # outside the region, never over it: the side with less curve
    corner = (pts[2] if right else pts[3]) if above else (pts[1] if right else pts[0])
    _label(ax, style.label(e), tuple(corner), color, style, xytext=(0, 3 if above else -3),
           ha="right" if right else "left", va="bottom" if above else "top")


def _points_in(ax: Axes, xa: float, xb: float, ya: float, yb: float) -> int:
    """How many points of the lines drawn so far (the curves) lie in the box [xa, xb] × [ya, yb]."""
    count = 0
    for line in ax.get_lines():
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        count += int(np.count_nonzero((x >= xa) & (x <= xb) & (y >= ya) & (y <= yb)))
    return count


def _window(ax: Axes, e: Mapping, style: Style) -> None:
    x0, x1, y0, y1 = e["x_min"], e["x_max"], e["y_min"], e["y_max"]
    _region(ax, e, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)], "0.3", style)


def _trapezoid(ax: Axes, e: Mapping, style: Style) -> None:
    s, t, (l0, l1), (u0, u1) = e["start"], e["end"], e["lower"], e["upper"]
    corners = [(s, l0), (t, l1), (t, u1), (s, u0)] if e.get("axis", "y") == "y" else \
        [(l0, s), (u0, s), (u1, t), (l1, t)]
    _region(ax, e, corners, "tab:orange", style)


def _threshold(ax: Axes, e: Mapping, style: Style) -> None:
    axis, value = e["axis"], float(e["value"])
    lo, hi = e.get("range") or (None, None)
    color = style.color("tab:purple")
    line = dict(color=color, ls=":" if style.failed is None else "--", lw=1.5 if style.failed is None else 1.8)
    if axis == "x":
        value *= style.sx
        y0, y1 = (lim if v is None else v * style.sy for v, lim in zip((lo, hi), ax.get_ylim()))
        ax.plot([value, value], [y0, y1], **line)
        where, align = (value, y1), "left"
    elif axis == "y":
        value *= style.sy
        left, right = ax.get_xlim()
        x0, x1 = (lim if v is None else v * style.sx for v, lim in zip((lo, hi), (left, right)))
        ax.plot([x0, x1], [value, value], **line)
        if x0 - left > 0.2 * (right - left):      # a line from inside the axes: label before its start, off the
            text = f"{e.get('name', 'threshold')} ({e.get('direction', '')})" if style.failed is None \
                else style.label(e)                # windows that usually sit at the line's end
            _label(ax, text, (x0, value), color, style, xytext=(-3, 0), ha="right", va="center")
            return
        where, align = (x1, value), "right"       # label ends at the line's end: stays inside the axes
    else:
        raise ValueError(f"axis must be 'x' or 'y', got {axis!r}")
    text = f"{e.get('name', 'threshold')} ({e.get('direction', '')})" if style.failed is None else style.label(e)
    _label(ax, text, where, color, style, xytext=(0, 2), ha=align, va="bottom")


def _envelope(ax: Axes, e: Mapping, style: Style) -> None:
    dx, dy = float(e.get("dx", 0.0)) * style.sx, float(e.get("dy", 0.0)) * style.sy
    color = style.color("tab:gray")
    for ref in e["references"]:
        x, y = np.asarray(ref["x"], dtype=float) * style.sx, np.asarray(ref["y"], dtype=float) * style.sy
        ax.fill_between(x, y - dy, y + dy, color=color, alpha=0.25, lw=0)
        if dx:
            ax.fill_betweenx(y, x - dx, x + dx, color=color, alpha=0.25, lw=0)
        ax.plot(x, y, color=color, lw=0.8 if style.failed is None else 1.6, ls="--")
    if style.failed is not None:
        ref = e["references"][0]
        _label(ax, style.label(e), (ref["x"][0] * style.sx, ref["y"][0] * style.sy), color, style)


DRAWERS: dict[str, Callable[[Axes, Mapping, Style], None]] = {
    "window": _window, "trapezoid": _trapezoid, "threshold": _threshold, "envelope": _envelope}


def draw_elements(ax: Axes, elements: Sequence[Mapping[str, Any]], sx: float = 1.0, sy: float = 1.0,
                  failed: Mapping[str, str] | None = None) -> list[str]:
    """Draw every element it can (thresholds last, across the data limits; failed ones on top), X scaled by
    ``sx`` and Y by ``sy``; ``failed``: ``{element name: short label}`` of the elements to highlight.
    Returns notes on the elements it skipped."""
    notes, failed = [], failed or {}
    order = sorted(elements, key=lambda e: (e.get("name") in failed, e.get("kind") == "threshold"))
    for e in order:
        kind, name = str(e.get("kind")), e.get("name", "?")
        drawer = DRAWERS.get(kind)
        if drawer is None:
            notes.append(f"element {name!r}: kind {kind!r} not drawn (unknown kind)")
        elif e.get("enabled", True) is False:
            notes.append(f"element {name!r} ({kind}) is disabled, not drawn")
        else:
            try:
                drawer(ax, e, Style(sx, sy, failed.get(name)))
            except (KeyError, TypeError, ValueError) as exc:
                notes.append(f"element {name!r} ({kind}) not drawn: missing or bad geometry ({exc!r})")
    return notes
