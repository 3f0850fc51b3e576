"""Work–precision chart as SciML presents it: error against wall time and error against RHS evaluations, log–log,
one curve per method in sweep order (ours solid, peers dashed); only runs whose error the reference resolves
(status ok)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from rig.bench.harness import OURS, TARGET, Result  # noqa: E402
from rig.bench.peers import NO_RESTARTS  # noqa: E402


def plot(result: Result, path: Path, target: float = TARGET) -> None:
    """Write the two-panel chart of ``result`` to ``path`` (PNG), the ``target`` error marked."""
    fig = figure(result, target)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure(result: Result, target: float = TARGET) -> "plt.Figure":
    """The two-panel chart: error against wall time and against RHS calls, one curve per method with ``ok`` rows
    (ours solid, peers dashed, a peer stepping across the contact onsets dotted in its sibling's colour)."""
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.2))
    methods = list(dict.fromkeys(r.method for r in result.rows))
    bases = list(dict.fromkeys(m.removesuffix(NO_RESTARTS) for m in methods))
    palette = [*plt.get_cmap("tab10").colors, "black", "olive", "navy", "peru", "teal"]
    if len(bases) > len(palette):
        raise ValueError(f"work-precision chart: {len(bases)} methods, colours for {len(palette)}")
    colour_of = dict(zip(bases, palette))
    for method in methods:
        rows = [r for r in result.rows if r.method == method and r.status == "ok"]     # in sweep order
        if not rows:
            continue
        variant = method.endswith(NO_RESTARTS)
        style = dict(color=colour_of[method.removesuffix(NO_RESTARTS)],
                     marker="^" if variant else "o" if method in OURS else "s", ms=4,
                     ls=":" if variant else "-" if method in OURS else "--", lw=1.6 if method in OURS else 1.0,
                     label=method)
        axes[0].loglog([r.wall_s for r in rows], [r.error for r in rows], **style)
        axes[1].loglog([r.nfev for r in rows], [r.error for r in rows], **style)
    ref = result.reference
    for ax, xlabel in zip(axes, ("wall time per run [s] (best of repeats)", "right-hand-side evaluations")):
        ax.axhline(target, color="k", ls=":", lw=0.8)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(f"relative max error in {result.problem.quantity}")
        ax.grid(True, which="both", lw=0.3, alpha=0.5)
    handles, labels = axes[0].get_legend_handles_labels()
    columns = 6
    rows_of_legend = -(-len(labels) // columns)
    if handles:                               # below both panels: inside one it hid curves
        fig.legend(handles, labels, loc="lower center", ncol=min(columns, len(labels)), fontsize=8, frameon=False)
    failed = sorted({r.method for r in result.rows if r.status.startswith(("diverged", "failed", "inaccurate"))})
    note = f"reference {ref.label}, confirmations within {ref.uncertainty:.1e}"
    if not ref.confirmed:
        note = "REFERENCE NOT CONFIRMED: " + note
    if failed:
        note += ("; some settings diverged, failed or were inaccurate (those points not drawn, see the CSV): "
                 + ", ".join(failed))
    slow = sorted({r.method for r in result.rows if r.status.startswith("timeout")})
    if slow:
        note += "; stopped at the time limit from some setting on (not drawn): " + ", ".join(slow)
    fig.suptitle(f"{result.problem.title}\n" + textwrap.fill(note, 170), fontsize=9,
                 color="k" if ref.confirmed else "red")
    fig.tight_layout(rect=(0.0, 0.035 * rows_of_legend + 0.01, 1.0, 1.0))
    return fig
