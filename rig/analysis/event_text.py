"""An event's fields as the report words them (display units, the interruption's reason in words)."""
from __future__ import annotations

from rig.analysis.units import DisplayUnits
from rig.recorder.reader import interruption_text

#: SI unit of an event's numeric field (shown in the program's display units); other fields are shown as recorded
EVENT_FIELD_SI = {"phi": "rad", "left_phi": "rad", "phi_r": "rad", "flight": "s", "backlog": "s", "torque": "N*m",
                  "peak_torque": "N*m", "cam_angle": "rad", "min_cam_angle": "rad", "min_t": "s", "force": "N",
                  "omega": "rad/s", "omega3": "rad/s"}


def event_details(event: dict, units: DisplayUnits) -> str:
    """``"phi 248.7°, left_phi 233.3°, flight 0.008566 s, to other"``: an event's fields in display units."""
    parts = []
    for key, value in event.items():
        if key in ("t", "kind"):
            continue
        if key in EVENT_FIELD_SI and isinstance(value, (int, float)) and not isinstance(value, bool):
            value = units.of(EVENT_FIELD_SI[key]).text(value)
        elif event.get("kind") == "interrupted" and key == "reason":
            value = interruption_text(str(value))
        elif isinstance(value, float):
            value = f"{value:.4g}"
        parts.append(f"{key} {value}")
    return ", ".join(parts)
