"""CSV export of curves and results for spreadsheets (long format, SI units, comma-separated)."""
from __future__ import annotations

import csv
from itertools import repeat
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from rig.analysis.sets import process_values
from rig.recorder import CurveRecord


def _cells(values: np.ndarray) -> list[str]:
    """Shortest round-trip text of each value (``repr``), empty for NaN."""
    return [repr(v) if v == v else "" for v in values.tolist()]


def export_curves(curves: Sequence[CurveRecord], path: Path) -> Path:
    """One row per sample: curve, program, i, t, x, y, angle (empty when not measured)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["curve", "program", "i", "t_s", "x", "y", "angle_rad"])
        for c in curves:
            angle = _cells(c.angle) if c.angle is not None else [""] * c.t.size
            w.writerows(zip(repeat(c.number), repeat(c.program), range(c.t.size), _cells(c.t), _cells(c.x),
                            _cells(c.y), angle))
    return path


def export_results(results: Sequence[Mapping], path: Path) -> Path:
    """One row per curve: number, program, ok, failed elements, then every process value."""
    table = process_values(results)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["curve", "program", "ok", "failed_elements", *table])
        for i, r in enumerate(results):
            failed = ";".join(str(e.get("name")) for e in r.get("elements", []) if not e.get("ok", True))
            w.writerow([r.get("number"), r.get("program"), int(bool(r["ok"])), failed,
                        *("" if np.isnan(v[i]) else repr(float(v[i])) for v in table.values())])
    return path
