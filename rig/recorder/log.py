"""Events as Foxglove's well-known ``foxglove.Log`` messages (topic ``/log``, beside ``/events``)."""
from __future__ import annotations

from typing import Any, Mapping

INFO, WARNING, ERROR = 2, 3, 4          # foxglove.LogLevel values

#: event kinds that say something went wrong on the link, in the data or the machine (else INFO)
WARNING_KINDS = frozenset({"sequence_gap", "unknown_frame", "bad_length", "decode_error", "error_frame", "curve",
                           "result", "incomplete_curve", "result_missing", "live_dropped", "shutdown",
                           "run_short", "curve_clipped", "input_overrange", "encoder_illegal", "reading_at_limit",
                           "curves_in_one_cycle",
                           "not_recorded", "verdict_mismatch", "statistics_not_read",
                           "follower_lift", "cam_stalled", "motor_below_load", "tappet_lift_off"})
ERROR_KINDS = frozenset({"interrupted", "run_stopped"})


def level(kind: str) -> int:
    """foxglove.LogLevel of an event kind: ERROR, WARNING or INFO."""
    return ERROR if kind in ERROR_KINDS else WARNING if kind in WARNING_KINDS else INFO


def log_message(log_ns: int, t: float, kind: str, data: Mapping[str, Any]) -> dict[str, Any]:
    """The ``foxglove.Log`` of one event: timestamp = its log time (ns since 1970), name = its kind, message
    = simulation time and its data as ``key=value``."""
    text = ", ".join(f"{k}={v}" for k, v in data.items())
    return {"timestamp": {"sec": log_ns // 1_000_000_000, "nsec": log_ns % 1_000_000_000}, "level": level(kind),
            "message": f"t={t:.6f} s {kind}" + (f": {text}" if text else ""), "name": kind, "file": "", "line": 0}
