"""What a stand or lab recording (no curves) shows at a glance: its console lines and its numeric key results —
for ``rig run``/``rig record`` and for the batch analysis (``rig analyse``)."""
from __future__ import annotations

import re
from typing import TYPE_CHECKING

from rig.scene import SceneError

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
    """Key results of a stand or lab run as numbers, ``{key: (value, unit)}``: a dynamic stand's metrics as
    ``stand.<name>`` (:meth:`Metric.number`: counts, shutdown 1/0; e.g. ``stand.start_up_peak_torque``), a lab
    sheet's result numbers as ``lab.<sheet>.<name>`` (units: :func:`~rig.analysis.lab_report.value_unit`; e.g.
    ``lab.cardan_joint.ratio_max``); names in snake case. Empty for other recordings."""
    if rec.curves:
        return {}
    from rig.analysis.clutch_report import stand_results
    from rig.analysis.lab_report import lab_sheets, value_unit
    res = stand_results(rec)
    if res is not None:
        return {"stand." + _snake(m.name): (number, m.unit) for m in res[1] if (number := m.number()) is not None}
    try:
        sheets = lab_sheets(rec) or []
    except (SceneError, ValueError):
        return {}                                  # the lab's console line says why there is no sheet
    return {f"lab.{_snake(sheet.title)}.{_snake(name)}": (float(v), value_unit(name)) for sheet in sheets
            for name, v in sheet.values.items()}


def _snake(name: str) -> str:
    return re.sub(r"\W+", "_", name.lower()).strip("_")
