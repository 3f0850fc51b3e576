"""Map plots of a sweep: a heat map per metric over the first two parameters (one per combination of the
others), a line per metric for a one-parameter sweep."""
from __future__ import annotations

import itertools
import re
from pathlib import Path
from typing import Any

import numpy as np

from rig.sweep.metrics import METRICS
from rig.sweep.run import SweepResult, levels_text
from rig.units import split_quantity

MAX_MAPS = 24  # per metric: combinations of the third and later parameters drawn


def _label(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_")


def _value_text(value: float, integer: bool) -> str:
    return "failed" if np.isnan(value) else f"{value:.0f}" if integer else f"{value:.3g}"


def _no_value_note(ax: Any, values: np.ndarray) -> None:
    """Write on the axes that no point gave a finite value (the chart would be empty, or look like a result)."""
    if np.isfinite(values).any():
        return
    ax.text(0.5, 0.5, "no finite value: every point failed\n(sweep.csv's error column says why)",
            transform=ax.transAxes, ha="center", va="center", fontsize=10, color="C3",
            bbox={"facecolor": "w", "edgecolor": "C3"})


def _integer_scale(z: np.ndarray, cmap: str):
    """A count's colours: one per whole number from the smallest to the largest value, the colour bar ticked at
    the whole numbers (not at 0.25, 0.75 …); (norm, ticks) or (None, None) when every point failed."""
    from matplotlib import colormaps
    from matplotlib.colors import BoundaryNorm
    if not np.isfinite(z).any():
        return None, None
    lo, hi = int(np.nanmin(z)), int(np.nanmax(z))
    ticks = np.arange(lo, hi + 1)
    if ticks.size > 12:                             # many counts: a whole-number subset of ticks
        ticks = ticks[::int(np.ceil(ticks.size / 12))]
    return BoundaryNorm(np.arange(lo - 0.5, hi + 1.0), colormaps[cmap].N), ticks


def _positions(values: tuple) -> tuple[list[float] | None, str]:
    """A parameter's values as numbers on one axis and their common unit (``"1.09 N/mm"``, ``"1.89 N/mm"`` →
    [1.09, 1.89], "N/mm"); (None, "") for words or values written in different units."""
    numbers, units = [], set()
    for v in values:
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            numbers.append(float(v))
            units.add("")
            continue
        split = split_quantity(str(v))
        if split is None:
            return None, ""
        numbers.append(split[0])
        units.add(split[1])
    return (numbers, units.pop()) if len(units) == 1 else (None, "")


def plot_sweep(result: SweepResult, out_dir: Path) -> list[Path]:
    """PNG maps of every metric; returns the files written. A count (:attr:`Metric.integer`) is drawn and labelled in
    whole numbers."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    out_dir.mkdir(parents=True, exist_ok=True)
    params, written = result.params, []
    index = {point: i for i, point in enumerate(result.points)}
    for metric in result.metrics:
        shown, integer = METRICS[metric].display, METRICS[metric].integer
        label = f"{metric}" + (f" ({shown.label})" if shown.label else "")
        title = f"{label}, model level {levels_text(result.levels)}"
        if len(params) == 1:
            p = params[0]
            y = [shown(result.values[index[(v,)]][metric]) for v in p.values]
            fig, ax = plt.subplots(figsize=(6, 4))
            x, unit = _positions(p.values)
            xs = list(range(len(y))) if x is None else x
            order = np.argsort(xs, kind="stable")       # the line joins the points from left to right (values may
            ax.plot(np.asarray(xs)[order], np.asarray(y, dtype=float)[order], "o-")     # be typed in any order)
            levels = [result.levels[index[(v,)]] for v in p.values]
            if len(set(levels)) > 1:          # points of different model levels on one line: each says its own
                for xi, yi, level in zip(xs, y, levels):
                    ax.annotate(f"L{level}", (xi, yi), textcoords="offset points", xytext=(0, 6), ha="center",
                                fontsize=8)
            _no_value_note(ax, np.asarray(y, dtype=float))
            failed = [xi for xi, yi in zip(xs, y) if np.isnan(yi)]
            if failed and len(failed) < len(y):    # a failed point is shown where it would be, not left out
                ax.plot(failed, [0.0] * len(failed), "x", color="tab:red", ms=9, mew=2, clip_on=False,
                        transform=ax.get_xaxis_transform(), label="failed (sweep.csv's error column)")
                ax.legend(fontsize=8, loc="best")
            if x is None:                     # words, or values in different units: in order, evenly spaced
                ax.set_xticks(range(len(y)), [_label(v) for v in p.values])
            elif len(xs) <= 12:               # few points: a tick at each value swept (seeds: whole numbers)
                ax.set_xticks(sorted(set(xs)), [f"{v:g}" for v in sorted(set(xs))])
            ax.set_xlabel(p.key + (f" ({unit})" if unit else ""))
            ax.set_ylabel(label)
            ax.set_title(title, fontsize=9)
            if integer:
                ax.yaxis.set_major_locator(MaxNLocator(integer=True))
                finite = np.asarray(y, dtype=float)[np.isfinite(np.asarray(y, dtype=float))]
                if finite.size and np.ptp(finite) < 2:   # a flat count: whole-number ticks need two whole numbers
                    ax.set_ylim(finite.min() - 1.0, finite.max() + 1.0)     # in the range, and a margin round it
            ax.grid(True)
            path = out_dir / f"{metric}.png"
            fig.tight_layout()
            fig.savefig(path, dpi=100)
            plt.close(fig)
            written.append(path)
            continue
        px, py, rest = params[0], params[1], params[2:]
        for combo in itertools.islice(itertools.product(*(p.values for p in rest)), MAX_MAPS):
            z = shown(np.array([[result.values[index[(vx, vy) + combo]][metric] for vx in px.values]
                                for vy in py.values]))
            fig, ax = plt.subplots(figsize=(max(5.0, 2.0 + 0.9 * len(px.values)), max(3.5, 1.8 + 0.45 * len(py.values))))
            norm, ticks = _integer_scale(z, "viridis") if integer else (None, None)
            image = ax.imshow(z, origin="lower", aspect="auto", cmap="viridis", norm=norm)
            level = np.array([[result.levels[index[(vx, vy) + combo]] for vx in px.values] for vy in py.values])
            mixed = len(set(result.levels)) > 1         # cells of different model levels: each says its own
            for (j, i), v in np.ndenumerate(z):
                ax.text(i, j, _value_text(v, integer) + (f"\nL{level[j, i]}" if mixed else ""), ha="center",
                        va="center", fontsize=8, color="w" if np.isnan(v) or v < np.nanmean(z) else "k")
            ax.set_xticks(range(len(px.values)), [_label(v) for v in px.values])
            ax.set_yticks(range(len(py.values)), [_label(v) for v in py.values])
            ax.set_xlabel(px.key)
            ax.set_ylabel(py.key)
            fixed = ", ".join(f"{p.key} = {_label(v)}" for p, v in zip(rest, combo))
            ax.set_title(title + (f"\n{fixed}" if fixed else ""), fontsize=9)
            _no_value_note(ax, z)
            bar = fig.colorbar(image, ax=ax, ticks=ticks)
            if integer:
                bar.ax.minorticks_off()
            fig.tight_layout()
            suffix = "".join(f"__{_slug(p.key)}_{_slug(_label(v))}" for p, v in zip(rest, combo))
            path = out_dir / f"{metric}{suffix}.png"
            fig.savefig(path, dpi=100)
            plt.close(fig)
            written.append(path)
    return written
