"""The labels of failed evaluation elements stay off the elements they name: a small failed window at the end of the
stroke was hidden under its own label and the pierce threshold's (as_drawn scene, curve plots)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from rig.analysis.elements_plot import draw_elements  # noqa: E402

ELEMENTS = [    # the as_drawn scene's elements, SI
    {"kind": "window", "name": "insertion", "x_min": 0.036, "x_max": 0.043, "y_min": -75.0, "y_max": -40.0,
     "entry": "top", "exit": "top"},
    {"kind": "threshold", "name": "pierce", "axis": "y", "value": -45.0, "direction": "falling",
     "range": [0.030, 0.043]},
    {"kind": "window", "name": "return", "x_min": -0.001, "x_max": 0.043, "y_min": -60.0, "y_max": 0.0,
     "entry": "ignore", "exit": "ignore"},
]


def _overlap(a, b) -> float:
    """Area (display px²) shared by two bounding boxes."""
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return max(w, 0.0) * max(h, 0.0)


def test_failed_labels_do_not_cover_the_small_window():
    fig, ax = plt.subplots(figsize=(5.0, 3.2))
    x = np.linspace(1.0, 42.0, 2000)
    ax.plot(x, -70 + 60 * np.sin(x / 2.0) * x / 42, lw=0.8)          # a curve in mm / N, oscillating
    ax.set_xlim(-3, 45)
    ax.set_ylim(-270, 215)
    failed = {"insertion": "entry top", "pierce": "never crossed", "return": "check y_min"}
    draw_elements(ax, ELEMENTS, 1e3, 1.0, failed)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    labels = {t.get_text().split(" ")[0]: t.get_window_extent(renderer) for t in ax.texts}
    assert set(labels) == set(failed)
    window = next(p for p in ax.patches if isinstance(p, Polygon)
                  and np.allclose(p.get_xy()[0], (36.0, -75.0))).get_window_extent(renderer)
    for name, box in labels.items():
        assert _overlap(box, window) <= 2.0, f"the {name} label covers the insertion window"
    assert _overlap(labels["insertion"], labels["pierce"]) == 0.0
    plt.close(fig)
