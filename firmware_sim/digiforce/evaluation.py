"""Evaluation of one curve against a program: the element verdicts and process values.

The unit evaluates each curve it records with :func:`evaluate_curve`. A host that received the curve
(over CAN) and knows the program can run the same code with :func:`reevaluate` to learn *why* a curve
failed: the CAN ``Result`` frame carries only which elements failed (docs/digiforce.md, "Why a curve
is NOK"). Verdicts come in the unit's order: ``reference`` first when the reference could not be
found, then the enabled elements in program order (bit *i* of ``FailMask`` is verdict *i*).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from .curve import Curve, base_process_values, reference_x, turning_index
from .elements import Element, Formatter, build_elements, plain_format
from .results import ElementResult


def evaluate_curve(elements: Sequence[Element], curve: Curve) -> tuple[list[ElementResult], dict[str, float]]:
    """Verdicts of ``elements`` (enabled ones, built with :func:`build_elements`) and all process values."""
    values = base_process_values(curve)
    verdicts = []
    for el in elements:
        part = curve.part(el.part)
        yv = curve.y if el.channel == "y" else curve.y2
        c = el.check(curve.x[part], yv[part])
        verdicts.append(ElementResult(el.name, el.kind, c.ok, c.reason, c.at))
        values.update({f"{el.name}.{k}": v for k, v in c.values.items()})
    return verdicts, values


def reference_verdict(problem: str | None) -> list[ElementResult]:
    """The ``reference`` pseudo-element that leads the verdicts when the reference was not found."""
    return [] if problem is None else [ElementResult("reference", "reference", False, problem)]


class Reevaluation:
    """The program's evaluation, for curves as a host receives them (X already referenced by the unit).

    ``fmt`` writes the numbers of the reasons (e.g. in the host's display units). Elements on a channel the
    curve does not carry (Y2 over CAN) cannot be re-evaluated: their verdict is ``None``.
    """

    def __init__(self, program: Mapping[str, Any], fmt: Formatter | None = None) -> None:
        self.program = program
        self.elements = build_elements(list(program.get("elements", [])), fmt)
        self.reference = program.get("reference", {"mode": "absolute"})
        self.fmt = fmt or plain_format

    @property
    def names(self) -> list[tuple[str, str]]:
        """(name, kind) of the verdicts when the reference is found, in FailMask order."""
        return [(e.name, e.kind) for e in self.elements]

    def verdicts(self, t: np.ndarray, x: np.ndarray, y: np.ndarray,
                 y2: np.ndarray | None = None) -> list[ElementResult | None]:
        """The verdicts of the received curve, in the unit's order (``None``: not re-evaluable)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        k = turning_index(x)
        # the unit subtracted the reference from X; whether it found one depends on Y alone
        problem = reference_x(x, y, k, self.reference, self.fmt)[1] if self.reference["mode"] == "y_threshold" else None
        curve = Curve(t=np.asarray(t, float), x=x, y=y, y2=None if y2 is None else np.asarray(y2, float),
                      turning_index=k)
        out: list[ElementResult | None] = list(reference_verdict(problem))
        for el in self.elements:
            if el.channel != "y" and curve.y2 is None:
                out.append(None)
            else:
                out.extend(evaluate_curve([el], curve)[0])
        return out
