"""What a stand or lab recording (no curves) shows at a glance: its console lines and its numeric key results —
for ``rig run``/``rig record`` and for the batch analysis (``rig analyse``)."""
from __future__ import annotations

import re
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rig.recorder import Recording


def stand_lines(rec: "Recording") -> list[str] | None:
    """Console lines of a stand run (clutch dynamic stand or static rig, lab bench): its key results, each with
    what it is relative to. None for a recording with curves or of no stand."""
    if rec.curves:
        return None
    from rig.analysis.clutch_report import summary_lines
    from rig.analysis.lab_report import summary_lines as lab_lines
    from rig.analysis.static_clutch_report import summary_lines as static_lines
    return lab_lines(rec) or summary_lines(rec) or static_lines(rec) or None


def stand_values(rec: "Recording") -> dict[str, tuple[float, str]]:
    """Key results of a dynamic-stand run as numbers (:meth:`Metric.number`: counts, shutdown 1/0),
    ``{"stand.<name>": (value, unit)}`` with names in snake case (``stand.start_up_peak_torque``,
    ``stand.final_speed_ω1``); empty for other recordings."""
    from rig.analysis.clutch_report import stand_results
    res = None if rec.curves else stand_results(rec)
    if res is None:
        return {}
    return {"stand." + re.sub(r"\W+", "_", m.name.lower()).strip("_"): (number, m.unit)
            for m in res[1] if (number := m.number()) is not None}
