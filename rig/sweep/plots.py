"""Map plots of a sweep: a heat map per metric over the first two parameters (one per combination of the
others), a line per metric for a one-parameter sweep."""
from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np

from rig.sweep.metrics import METRICS
from rig.sweep.run import SweepResult

MAX_MAPS = 24  # per metric: combinations of the third and later parameters drawn


def _label(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_")


def plot_sweep(result: SweepResult, out_dir: Path) -> list[Path]:
    """PNG maps of every metric; returns the files written."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    params, written = result.params, []
    index = {point: i for i, point in enumerate(result.points)}
    for metric in result.metrics:
        unit = METRICS[metric].unit
        title = f"{metric}" + (f" ({unit})" if unit != "1" else "")
        if len(params) == 1:
            p = params[0]
            y = [result.values[index[(v,)]][metric] for v in p.values]
            fig, ax = plt.subplots(figsize=(6, 4))
            ax.plot(range(len(y)), y, "o-")
            ax.set_xticks(range(len(y)), [_label(v) for v in p.values])
            ax.set_xlabel(p.key)
            ax.set_ylabel(title)
            ax.grid(True)
            path = out_dir / f"{metric}.png"
            fig.tight_layout()
            fig.savefig(path, dpi=100)
            plt.close(fig)
            written.append(path)
            continue
        px, py, rest = params[0], params[1], params[2:]
        for combo in itertools.islice(itertools.product(*(p.values for p in rest)), MAX_MAPS):
            z = np.array([[result.values[index[(vx, vy) + combo]][metric] for vx in px.values] for vy in py.values])
            fig, ax = plt.subplots(figsize=(max(5.0, 2.0 + 0.9 * len(px.values)), max(3.5, 1.8 + 0.45 * len(py.values))))
            image = ax.imshow(z, origin="lower", aspect="auto", cmap="viridis")
            for (j, i), v in np.ndenumerate(z):
                ax.text(i, j, "failed" if np.isnan(v) else f"{v:.3g}", ha="center", va="center", fontsize=8,
                        color="w" if np.isnan(v) or v < np.nanmean(z) else "k")
            ax.set_xticks(range(len(px.values)), [_label(v) for v in px.values])
            ax.set_yticks(range(len(py.values)), [_label(v) for v in py.values])
            ax.set_xlabel(px.key)
            ax.set_ylabel(py.key)
            fixed = ", ".join(f"{p.key} = {_label(v)}" for p, v in zip(rest, combo))
            ax.set_title(title + (f"\n{fixed}" if fixed else ""), fontsize=9)
            fig.colorbar(image, ax=ax)
            fig.tight_layout()
            suffix = "".join(f"__{_slug(p.key)}_{_slug(_label(v))}" for p, v in zip(rest, combo))
            path = out_dir / f"{metric}{suffix}.png"
            fig.savefig(path, dpi=100)
            plt.close(fig)
            written.append(path)
    return written
