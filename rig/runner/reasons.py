"""Why a curve is NOK, on the host: the received curve re-evaluated against the program.

The CAN ``Result`` frame says only *which* elements failed (``FailMask``). The host knows the program (it
set it and read it back over serial) and has the curve, so it runs the unit's own evaluation code
(:class:`firmware_sim.digiforce.evaluation.Reevaluation`) on the curve as received and takes each failed
element's reason from there, written in the display units (rig.analysis.units). The device's verdict stays
the verdict; the host's serves as the explanation and as a check: when the host's verdicts differ from
the ``FailMask`` (the curve crosses the bus quantised, 1 µm and 5 mN on the classic frames), the result
says so in the reason and :meth:`ResultExplainer.explain` returns a ``verdict_mismatch`` event (never
silent). Why this and not the serial ``RR`` command: docs/digiforce.md, "Why a curve is NOK".
"""
from __future__ import annotations

from typing import Any, Mapping

from firmware_sim.digiforce.evaluation import Reevaluation
from firmware_sim.digiforce.results import ElementResult
from rig.analysis.units import DisplayUnits

MASK_BITS = 32        # FailMask covers elements 0…31

NOT_REEVALUATED = {
    "incomplete": "failed on the device; the curve did not arrive complete, so the host could not re-evaluate it",
    "y2": "failed on the device; Y2 does not travel over CAN, so the host could not re-evaluate it",
    "passes": "failed on the device, but the curve as received passes this element on the host "
              "(see event verdict_mismatch)",
    "unknown": "failed on the device; the host's program has no element at this position",
}


class ResultExplainer:
    """Element verdicts with reasons for the results of one program (``program``: normalised, as the
    device returns it), reasons written in ``units``."""

    def __init__(self, program: Mapping[str, Any], units: DisplayUnits, digits: int = 4) -> None:
        self.units = units
        self.evaluation = Reevaluation(program, lambda ch, v: units.channel(ch).text(v, digits))

    def explain(self, result: Any, curve: Any | None) -> tuple[list[dict[str, Any]], dict[str, Any] | None]:
        """``elements`` for ``/device/result`` (name, kind, ok from the device's FailMask, reason) and the
        data of a ``verdict_mismatch`` event (None when the host agrees with the device). ``result``: the
        driver's CurveResult (``ok``, ``fail_mask``); ``curve``: the received curve (``t``, ``x``, ``y``) or
        None when it did not arrive complete."""
        host: list[ElementResult | None] | None = None
        if curve is not None and getattr(curve, "t", None) is not None:
            host = self.evaluation.verdicts(curve.t, curve.x, curve.y)
        names = ([(v.name, v.kind) if v is not None else (e.name, e.kind)
                  for v, e in zip(host, self._aligned(host))] if host is not None else self.evaluation.names)
        mask = int(result.fail_mask)
        count = max(len(names), mask.bit_length())
        elements = []
        for i in range(count):
            name, kind = names[i] if i < len(names) else (f"element {i}", "?")
            verdict = host[i] if host is not None and i < len(host) else None
            failed = bool(mask >> i & 1) if i < MASK_BITS else (verdict is not None and not verdict.ok)
            reason = ""
            if failed:
                if verdict is not None:
                    reason = verdict.reason or NOT_REEVALUATED["passes"]
                elif i >= len(names):
                    reason = NOT_REEVALUATED["unknown"]
                else:
                    reason = NOT_REEVALUATED["incomplete" if host is None else "y2"]
            elements.append({"name": name, "kind": kind, "ok": not failed, "reason": reason})
        return elements, self._mismatch(result, host)

    def _aligned(self, host: list[ElementResult | None]) -> list[Any]:
        """The program's elements aligned with the host verdicts (a leading reference verdict shifts them)."""
        shift = len(host) - len(self.evaluation.elements)
        return [None] * shift + list(self.evaluation.elements)

    def _mismatch(self, result: Any, host: list[ElementResult | None] | None) -> dict[str, Any] | None:
        if host is None:
            return None
        mask = int(result.fail_mask)
        host_mask = sum(1 << i for i, v in enumerate(host) if v is not None and not v.ok and i < MASK_BITS)
        checked = sum(1 << i for i, v in enumerate(host) if v is not None and i < MASK_BITS)
        host_ok = all(v.ok for v in host if v is not None)
        beyond = mask >> len(host)                  # failed elements the host's program does not have
        if host_mask == mask & checked and not beyond and (host_ok == bool(result.ok) or None in host):
            return None
        differ = [v.name for i, v in enumerate(host) if v is not None and i < MASK_BITS
                  and (not v.ok) != bool(mask >> i & 1)]
        differ += [f"element {i}" for i in range(len(host), mask.bit_length()) if mask >> i & 1]
        return {"number": int(result.number), "device_fail_mask": mask, "host_fail_mask": host_mask,
                "device_ok": bool(result.ok), "host_ok": host_ok, "elements": differ,
                "detail": "the host's re-evaluation of the received curve differs from the device's verdict "
                          f"for {', '.join(differ) or 'the overall result'}; the device's verdict is recorded"}
