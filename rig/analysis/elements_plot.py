"""Draw DigiForce evaluation elements (program config dicts) on a force–displacement axis.

Geometry is read from the ``elements`` list of the program config stored in the recording
(attachment ``device/program/<n>.json``), in SI like the curves, with the keys of
``firmware_sim.digiforce`` (docs/digiforce.md): window ``x_min x_max y_min y_max entry exit``;
trapezoid ``axis start end lower upper entry exit``; threshold ``axis value direction [range]``;
envelope ``references [{x, y}] dx dy``. Unknown kinds, disabled elements and elements without
drawable geometry are skipped and reported as notes.
"""
from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.patches import Polygon

SIDES = ("bottom", "right", "top", "left")        # edge i runs from corner i to corner i+1
_ROLE_STYLE = {"entry": dict(color="tab:green", lw=3.0), "exit": dict(color="tab:red", lw=3.0, ls="--")}


def _region(ax: Axes, e: Mapping, corners: Sequence[tuple[float, float]], color: str) -> None:
    """Quadrilateral with corners counter-clockwise from bottom-left; entry/exit sides highlighted."""
    pts = np.asarray(corners, dtype=float)
    ax.add_patch(Polygon(pts, closed=True, fill=False, ec=color, lw=1.2))
    for role in ("entry", "exit"):
        side = e.get(role)
        if side in SIDES:
            i = SIDES.index(side)
            seg = pts[[i, (i + 1) % 4]]
            ax.plot(seg[:, 0], seg[:, 1], **_ROLE_STYLE[role])
    ax.annotate(str(e.get("name", e["kind"])), tuple(pts[3]), fontsize=7, color=color,
                xytext=(2, 2), textcoords="offset points")


def _window(ax: Axes, e: Mapping) -> None:
    x0, x1, y0, y1 = e["x_min"], e["x_max"], e["y_min"], e["y_max"]
    _region(ax, e, [(x0, y0), (x1, y0), (x1, y1), (x0, y1)], "tab:blue")


def _trapezoid(ax: Axes, e: Mapping) -> None:
    s, t, (l0, l1), (u0, u1) = e["start"], e["end"], e["lower"], e["upper"]
    corners = [(s, l0), (t, l1), (t, u1), (s, u0)] if e.get("axis", "y") == "y" else \
        [(l0, s), (u0, s), (u1, t), (l1, t)]
    _region(ax, e, corners, "tab:orange")


def _threshold(ax: Axes, e: Mapping) -> None:
    axis, value = e["axis"], float(e["value"])
    lo, hi = e.get("range") or (None, None)
    if axis == "x":
        y0, y1 = ax.get_ylim() if lo is None else (lo, hi)
        ax.plot([value, value], [y0, y1], color="tab:purple", ls=":", lw=1.5)
        where, align = (value, y1), "left"
    elif axis == "y":
        x0, x1 = ax.get_xlim() if lo is None else (lo, hi)
        ax.plot([x0, x1], [value, value], color="tab:purple", ls=":", lw=1.5)
        where, align = (x1, value), "right"       # label ends at the line's end: stays inside the axes
    else:
        raise ValueError(f"axis must be 'x' or 'y', got {axis!r}")
    ax.annotate(f"{e.get('name', 'threshold')} ({e.get('direction', '')})", where, fontsize=7, color="tab:purple",
                xytext=(0, 2), textcoords="offset points", ha=align, va="bottom")


def _envelope(ax: Axes, e: Mapping) -> None:
    dx, dy = float(e.get("dx", 0.0)), float(e.get("dy", 0.0))
    for ref in e["references"]:
        x, y = np.asarray(ref["x"], dtype=float), np.asarray(ref["y"], dtype=float)
        ax.fill_between(x, y - dy, y + dy, color="tab:gray", alpha=0.25, lw=0)
        if dx:
            ax.fill_betweenx(y, x - dx, x + dx, color="tab:gray", alpha=0.25, lw=0)
        ax.plot(x, y, color="tab:gray", lw=0.8, ls="--")


DRAWERS: dict[str, Callable[[Axes, Mapping], None]] = {
    "window": _window, "trapezoid": _trapezoid, "threshold": _threshold, "envelope": _envelope}


def draw_elements(ax: Axes, elements: Sequence[Mapping[str, Any]]) -> list[str]:
    """Draw every element it can (thresholds last, across the data limits); return notes on skipped ones."""
    notes = []
    for e in sorted(elements, key=lambda e: e.get("kind") == "threshold"):
        kind, name = str(e.get("kind")), e.get("name", "?")
        drawer = DRAWERS.get(kind)
        if drawer is None:
            notes.append(f"element {name!r}: kind {kind!r} not drawn (unknown kind)")
        elif e.get("enabled", True) is False:
            notes.append(f"element {name!r} ({kind}) is disabled, not drawn")
        else:
            try:
                drawer(ax, e)
            except (KeyError, TypeError, ValueError) as exc:
                notes.append(f"element {name!r} ({kind}) not drawn: missing or bad geometry ({exc!r})")
    return notes
