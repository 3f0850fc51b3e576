"""What plants report to the runner besides their truth signals."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Event:
    """Something a plant did at ``time`` (s): ``kind`` (e.g. "flank_switch", "disengagement") and details."""

    time: float
    kind: str
    data: dict[str, Any] = field(default_factory=dict)
