"""Host statistics against the device's own: counts and n, mean, σ per process value of one program.

The unit keeps statistics of every result it evaluated; the host reads its final snapshot over serial
(``/device/statistics``: ``program``, ``total``, ``ok``, ``nok`` and per process value ``n``, ``mean``,
``std`` (ddof = 1), ``min``, ``max``, ``cp``, ``cpk``). Process values reach the host as float32 over
CAN, so each one may differ from the device's by half a float32 ulp (≤ u·|v|, u = 2⁻²⁴): the mean by at
most u·max|v|, σ by at most u·max|v|·√(n/(n−1)). Host and device agree when the counts are equal and
every mean and σ lies within that bound plus a relative ``RTOL`` (summation order).
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from rig.analysis.sets import process_values

F32_ROUNDOFF = 2.0 ** -24   # unit roundoff of float32 (round to nearest)
RTOL = 1e-6                 # relative tolerance for differences in summation order
ABSENT = {"n": 0, "mean": None, "std": None}   # a value the device has no entry for


def final_snapshot(snapshots: Sequence[Mapping], program: int) -> Mapping | None:
    """The last statistics snapshot the device sent for ``program`` (None if there is none)."""
    return next((s for s in reversed(snapshots) if s.get("program") is not None and int(s["program"]) == program),
                None)


def moments(values: np.ndarray) -> dict:
    """n, mean and sample σ (ddof = 1) of the finite values (their unit); None where undefined."""
    v = values[np.isfinite(values)]
    return {"n": int(v.size), "mean": float(v.mean()) if v.size else None,
            "std": float(v.std(ddof=1)) if v.size > 1 else None}


def _close(host: float | None, device: float | None, slack: float) -> bool:
    """Equal within ``RTOL`` relative plus ``slack`` absolute (both None also counts as equal)."""
    if host is None or device is None:
        return host is None and device is None
    return abs(host - device) <= RTOL * max(abs(host), abs(device)) + slack


def compare_value(values: np.ndarray, device: Mapping) -> dict:
    """Host n/mean/σ of one process value (array over the results, NaN = absent) against the device's
    entry; ``differs`` lists which of n, mean, std disagree beyond float32 rounding."""
    host = moments(values)
    dev = {k: device.get(k, ABSENT[k]) for k in ABSENT}
    n = host["n"]
    slack_mean = F32_ROUNDOFF * float(np.max(np.abs(values[np.isfinite(values)]))) if n else 0.0
    slack_std = slack_mean * math.sqrt(n / (n - 1)) if n > 1 else 0.0
    checks = (("n", host["n"] == dev["n"]), ("mean", _close(host["mean"], dev["mean"], slack_mean)),
              ("std", _close(host["std"], dev["std"], slack_std)))
    return {"host": host, "device": dev, "differs": [k for k, ok in checks if not ok]}


def device_agreement(results: Sequence[Mapping], snapshot: Mapping | None) -> dict:
    """Compare one program's recorded results with the device's final statistics ``snapshot``.

    Only meaningful when the device counted exactly the recorded results; otherwise ``comparable`` is
    False and ``reason`` says why. ``equal``: the OK count and every value's n, mean and σ agree;
    ``differs`` names the values that do not (a value only the host has differs too); ``device_only``
    names values the device keeps but does not send (not compared).
    """
    if snapshot is None:
        return {"comparable": False, "equal": None, "reason": "the device sent no statistics for this program"}
    if snapshot.get("total") != len(results):
        return {"comparable": False, "equal": None,
                "reason": f"the device counted {snapshot.get('total')} results, the recording holds {len(results)}"}
    device_values = snapshot.get("values", {}) or {}
    values = {name: compare_value(v, device_values.get(name, ABSENT)) for name, v in process_values(results).items()}
    ok = {"host": sum(bool(r["ok"]) for r in results), "device": snapshot.get("ok")}
    differs = [name for name, v in values.items() if v["differs"]]
    return {"comparable": True, "equal": not differs and ok["host"] == ok["device"], "reason": None,
            "total": len(results), "ok": ok, "values": values, "differs": differs,
            "device_only": sorted(set(device_values) - set(values))}


def _difference(name: str, v: Mapping) -> str:
    """``name (mean host vs device, …)`` for the quantities of one value that differ."""
    label = {"n": "n", "mean": "mean", "std": "σ"}
    return f"{name} (" + ", ".join(f"{label[k]} {_num(v['host'][k])} vs {_num(v['device'][k])}"
                                   for k in v["differs"]) + ")"


def _num(v: float | int | None) -> str:
    return "—" if v is None else str(v) if isinstance(v, int) else f"{v:.7g}"


def agreement_text(a: Mapping) -> str:
    """One sentence: whether the host's statistics equal the device's, and which values differ."""
    if not a["comparable"]:
        return f"not compared: {a['reason']}"
    if a["equal"]:
        return (f"host statistics equal the device's ({a['total']} results, OK count, n/mean/σ of "
                f"{len(a['values'])} process values within float32 rounding)")
    parts = [_difference(name, a["values"][name]) for name in a["differs"]]
    if a["ok"]["host"] != a["ok"]["device"]:
        parts.insert(0, f"OK count {a['ok']['host']} vs {a['ok']['device']}")
    return "host statistics DIFFER from the device's (host vs device): " + "; ".join(parts)
