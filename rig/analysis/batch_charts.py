"""Charts of a batch analysis (``rig analyse``): one PNG per population (scene, model level, machine), each
process value (and stand or lab result) per recording against the run's wall-clock start — "what happened across
last month's recordings" at a glance — with the population's mean, its ±3σ band and the program's limits.

Each recording is a point at its mean with a line over its min … max (a recording of many curves) and is drawn red
where it holds NOK curves; the first panel is the share of NOK curves per recording. Recordings without a start
time (a lost metadata record) put the axis in the order given instead. Copies of a run and unreadable files are
not drawn (as they are not counted).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from rig.analysis.batch import BatchResult, RecordingSummary

MAX_PANELS = 12            # value panels per population chart (the table has every value)
PANEL = (4.6, 2.0)         # inches per panel: width, height
NOK_COLOR = "tab:red"


@dataclass(frozen=True)
class BatchChart:
    """One population's chart: ``path`` and the values it leaves out (beyond :data:`MAX_PANELS`)."""

    group: str
    path: Path
    omitted: tuple[str, ...]


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.-]+", "_", text).strip("_")[:80] or "population"


def _abscissa(rows: list["RecordingSummary"]) -> tuple[np.ndarray, str]:
    """Each row's wall-clock start (datetime64) where every row has one, else its place in the order given."""
    try:
        starts = [int(r.started) for r in rows]
    except ValueError:
        return np.arange(1, len(rows) + 1), "recording (in the order given)"
    return np.array(starts, dtype="datetime64[ns]"), "run's wall-clock start (UTC)"


def _limits(rows: list["RecordingSummary"], name: str, factors: list[float]) -> tuple[tuple, bool]:
    """The limits every row's program gives ``name`` in the population's unit, and whether they disagree."""
    seen = {tuple(None if b is None else round(b * f, 12) for b in r.limits[name])
            for r, f in zip(rows, factors) if name in r.limits}
    return (seen.pop() if len(seen) == 1 else (None, None)), len(seen) > 1


def _panel(ax, x: np.ndarray, rows: list["RecordingSummary"], name: str, result: "BatchResult") -> set[str]:
    """One value's panel; returns what it draws of the legend's shared entries (:data:`LEGEND`)."""
    from rig.analysis.batch import unit_factor
    from rig.analysis.numbers import plural
    combined, unit = result.combined[(rows[0].group, name)]
    mine = [(i, r) for i, r in enumerate(rows) if name in r.values]
    at = x[[i for i, _ in mine]]
    factors = [1.0 if r.values[name][1] == unit else unit_factor(r.values[name][1], unit) for _, r in mine]
    mean = np.array([float(r.values[name][0].mean[0]) * f for (_, r), f in zip(mine, factors)])
    lo = np.array([float(r.values[name][0].minimum[0]) * f for (_, r), f in zip(mine, factors)])
    hi = np.array([float(r.values[name][0].maximum[0]) * f for (_, r), f in zip(mine, factors)])
    bad = np.array([r.nok > 0 for _, r in mine])
    drawn = {"mean"}
    ax.vlines(at, lo, hi, color="0.6", linewidth=0.8, zorder=1)
    ax.plot(at[~bad], mean[~bad], ".", color="tab:blue", zorder=2)
    if bad.any():
        ax.plot(at[bad], mean[bad], ".", color=NOK_COLOR, zorder=3)
        drawn.add("nok")
    mu = float(combined.mean[0])
    ax.axhline(mu, color="black", linewidth=1.0)
    if combined.n > 1:
        sigma = float(combined.std(1)[0])
        for band in (mu - 3 * sigma, mu + 3 * sigma):
            ax.axhline(band, color="black", linewidth=0.8, linestyle="--")
        drawn.add("band")
    (lsl, usl), differ = _limits([r for _, r in mine], name, factors)
    for bound in (lsl, usl):
        if bound is not None:
            ax.axhline(bound, color=NOK_COLOR, linewidth=1.0)
            drawn.add("limits")
    note = "; limits differ between recordings: not drawn" if differ else ""
    ax.set_title(f"{name}: n = {combined.n} in {plural(len(mine), 'recording')}{note}", fontsize=9, loc="left")
    ax.set_ylabel(f"{name.split('.', 1)[-1]} ({unit})" if unit else name.split(".", 1)[-1], fontsize=8)
    return drawn


#: the legend's entries: (key, colour, line style, marker, label)
LEGEND = (("mean", "0.6", "-", ".", "a recording: mean, min … max"),
          ("nok", NOK_COLOR, "", ".", "a recording with NOK curves"),
          ("mean", "black", "-", "", "mean of all recordings"),
          ("band", "black", "--", "", "mean ± 3σ of all"),
          ("limits", NOK_COLOR, "-", "", "the program's limits"))


def _nok_panel(ax, x: np.ndarray, rows: list["RecordingSummary"]) -> None:
    share = np.array([100.0 * r.nok / (r.ok + r.nok) if r.ok + r.nok else np.nan for r in rows])
    judged = sum(r.ok + r.nok for r in rows)
    some = share > 0
    ax.plot(x[~some], share[~some], ".", color="black")
    ax.plot(x[some], share[some], ".", color=NOK_COLOR)
    ax.set_ylim(-5, 105)
    ax.set_title(f"NOK share per recording: {sum(r.nok for r in rows)} NOK of {judged} judged curves", fontsize=9,
                 loc="left")
    ax.set_ylabel("NOK (%)", fontsize=8)


def population_chart(result: "BatchResult", group: str, path: Path) -> BatchChart | None:
    """The chart of one population (:attr:`RecordingSummary.group`) written to ``path``; None where it has nothing to
    draw (no value and no judged curve: e.g. a lab recording whose sheet could not be made)."""
    from rig.analysis.plots import save
    drawn = population_figure(result, group)
    if drawn is None:
        return None
    fig, omitted = drawn
    save(fig, path, hspace=0.55, wspace=0.25, bottom=0.95, top=0.55)
    return BatchChart(group, path, omitted)


def population_figure(result: "BatchResult", group: str) -> tuple["Figure", tuple[str, ...]] | None:
    """The figure of :func:`population_chart`, not yet placed or written, and the values it leaves out (None: nothing
    to draw)."""
    from matplotlib.dates import AutoDateLocator, ConciseDateFormatter

    from rig.analysis.numbers import plural
    from rig.analysis.plots import figure
    rows = [r for r in result.recordings if not r.error and not r.copy_of and r.group == group]
    x, xlabel = _abscissa(rows)
    order = np.argsort(x, kind="stable")
    rows, x = [rows[i] for i in order], x[order]
    names = sorted({n for r in rows for n in r.values}, key=lambda n: (not n.startswith("p"), n))
    shown, omitted = names[:MAX_PANELS], tuple(names[MAX_PANELS:])
    judged = any(r.ok + r.nok for r in rows)
    panels = int(judged) + len(shown)
    if not panels:
        return None
    ncols = 1 if panels <= 3 else 2
    nrows = -(-panels // ncols)
    fig, axes = figure(nrows, ncols, size=(PANEL[0] * ncols + 1.2, PANEL[1] * nrows + 1.1), sharex=True,
                       squeeze=False)
    flat = list(axes.ravel())
    if judged:
        _nok_panel(flat.pop(0), x, rows)
    drawn: set[str] = set()
    for ax, name in zip(flat, shown):
        drawn |= _panel(ax, x, rows, name, result)
    for ax in flat[len(shown):]:
        ax.set_visible(False)
    visible = [ax for ax in axes.ravel() if ax.get_visible()]
    for ax in visible:
        ax.tick_params(labelsize=7)
        ax.grid(True, linewidth=0.3, alpha=0.5)
    if x.dtype.kind == "M":
        if x[-1] == x[0]:                         # one start time: an hour about it, not years
            visible[0].set_xlim(x[0] - np.timedelta64(30, "m"), x[0] + np.timedelta64(30, "m"))
        locator = AutoDateLocator(maxticks=6)
        for ax in visible:
            ax.xaxis.set_major_locator(locator)
            ax.xaxis.set_major_formatter(ConciseDateFormatter(locator))
    for column in axes.T:                         # the lowest shown panel of each column carries the axis
        last = [ax for ax in column if ax.get_visible()][-1]
        last.set_xlabel(xlabel, fontsize=8)
        last.tick_params(labelbottom=True)
    entries = [(c, ls, m, label) for key, c, ls, m, label in LEGEND if key in drawn]
    if entries:
        fig.legend([_line(c, ls, m) for c, ls, m, _ in entries], [label for *_, label in entries],
                   loc="lower center", ncol=3, fontsize=7, frameon=False)
    fig.suptitle(f"{group}: {plural(len(rows), 'recording')}", fontsize=10, x=0.01, ha="left", y=0.995)
    return fig, omitted


def _line(color: str, style: str, marker: str):
    from matplotlib.lines import Line2D
    dot = NOK_COLOR if color == NOK_COLOR else "tab:blue"      # a recording's dot over its grey min … max line
    return Line2D([], [], color=color, linestyle=style or "none", marker=marker or None, markerfacecolor=dot,
                  markeredgecolor=dot)


def write_charts(result: "BatchResult", folder: Path) -> list[BatchChart]:
    """:func:`population_chart` of every population with a readable recording and something to draw, as
    ``folder/<population>.png``."""
    groups = sorted({r.group for r in result.recordings if not r.error and not r.copy_of})
    for old in folder.glob("*.png") if folder.is_dir() else ():     # an earlier analysis's charts: not this one's
        old.unlink()
    names: dict[str, int] = {}
    out = []
    for group in groups:
        slug = _slug(group)
        names[slug] = names.get(slug, 0) + 1
        name = slug if names[slug] == 1 else f"{slug}_{names[slug]}"
        folder.mkdir(parents=True, exist_ok=True)
        chart = population_chart(result, group, folder / f"{name}.png")
        out += [chart] if chart is not None else []
    return out
