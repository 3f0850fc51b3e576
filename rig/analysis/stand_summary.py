"""What a stand or lab recording (no curves) shows at a glance: its console lines and its key results as numbers —
for ``rig run``/``rig record`` and for the batch analysis (``rig analyse``), computed once for both."""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rig.scene import SceneError

if TYPE_CHECKING:
    from rig.recorder import Recording


@dataclass(frozen=True)
class StandSummary:
    """``lines``: the console lines, each result with what it is relative to; ``values``: ``{key: (value, unit)}``,
    a dynamic stand's metrics as ``stand.<name>`` (:meth:`Metric.number`: counts, shutdown 1/0; e.g.
    ``stand.start_up_peak_torque``), a static rig's per cycle as ``static.cycle_<i>.<name>`` (e.g.
    ``static.cycle_1.loop_energy``), a lab sheet's result numbers as ``lab.<sheet>.<name>`` (units:
    :func:`~rig.analysis.lab_report.shown_value`, display units; e.g. ``lab.cardan_joint.ratio_max``); names in snake case."""

    lines: list[str]
    values: dict[str, tuple[float, str]]


#: how a summary line starts whose lab sheet could not be made (``rig analyse`` repeats it on the console)
NO_SHEET = "lab: no sheet"


def stand_summary(rec: "Recording") -> StandSummary | None:
    """The summary of a lab bench, clutch dynamic stand or static clutch rig run (in that order of trial); None
    for a recording with curves or of no stand."""
    if rec.curves:
        return None
    from rig.analysis import clutch_report, lab_report, static_clutch_report
    try:
        sheets = lab_report.lab_sheets(rec)
    except (SceneError, ValueError) as exc:     # and what may be behind it (a counter card that lost the shaft)
        return StandSummary([f"{NO_SHEET} ({exc})"] + [f"warning: {w}" for w in lab_report.lab_warnings(rec)], {})
    if sheets is not None:
        return StandSummary(lab_report.summary_lines(sheets, rec),
                            {f"lab.{sheet.key}.{_snake(name)}": lab_report.shown_value(name, float(v))
                             for sheet in sheets for name, v in sheet.values.items()})
    res = clutch_report.stand_results(rec)
    if res is not None:
        return StandSummary(clutch_report.summary_lines(rec, *res),
                            {"stand." + _snake(m.name): (number, m.unit) for m in res[1]
                             if (number := m.number()) is not None})
    static = static_clutch_report.summary(rec)
    return None if static is None else StandSummary(static[0], {f"static.{k}": v for k, v in static[1].items()})


def _snake(name: str) -> str:
    return re.sub(r"\W+", "_", name.lower()).strip("_")
