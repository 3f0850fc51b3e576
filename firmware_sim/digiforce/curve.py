"""A recorded curve: stored pairs, X turning point (forward/return split), reference, process values."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from .elements import ELEMENT_KINDS, Formatter, plain_format

BASE_VALUES = ("x_max", "x_min", "y_max", "y_min", "x_at_y_max", "y_at_x_max", "x_end", "y_end",
               "duration", "pairs")
Y2_VALUES = ("y2_max", "y2_min")


@dataclass
class Curve:
    """Stored pairs in engineering units (t in s). ``turning_index`` is the last pair of the forward part
    and the first of the return part. ``x_reference`` was subtracted from X (reference mode)."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    y2: np.ndarray | None
    turning_index: int
    x_reference: float = 0.0
    overflow: bool = False
    decimations: int = 0
    dropped: int = 0
    sampling: dict[str, Any] = field(default_factory=dict)

    def part(self, name: str) -> slice:
        """Index range of the ``forward``, ``return`` or ``complete`` curve."""
        k = self.turning_index
        return {"forward": slice(0, k + 1), "return": slice(k, None), "complete": slice(None)}[name]

    @property
    def flags(self) -> dict[str, Any]:
        return {"overflow": self.overflow, "decimated": self.decimations > 0, "decimations": self.decimations,
                "dropped": self.dropped}

    def to_dict(self) -> dict[str, Any]:
        return {"pairs": int(self.t.size), "t": self.t.tolist(), "x": self.x.tolist(), "y": self.y.tolist(),
                "y2": None if self.y2 is None else self.y2.tolist(), "turning_index": self.turning_index,
                "x_reference": self.x_reference, "sampling": dict(self.sampling), **self.flags}


def turning_index(x: np.ndarray) -> int:
    """Index of the X turning point: the extreme of X farther from the start (the forward stroke's end)."""
    i_max, i_min = int(np.argmax(x)), int(np.argmin(x))
    return i_max if x[i_max] - x[0] >= x[0] - x[i_min] else i_min


def reference_x(x: np.ndarray, y: np.ndarray, k: int, reference: Mapping[str, Any],
                fmt: Formatter = plain_format) -> tuple[float, str | None]:
    """X to subtract for the reference mode, and why it cannot be found (or None; its threshold written by ``fmt``,
    e.g. with the Y channel's unit).

    ``y_threshold``: X where Y first reaches the threshold from below on the forward part (interpolated);
    ``end``: X at the end of the forward part (where the final force is reached).
    """
    mode = reference["mode"]
    if mode == "absolute":
        return 0.0, None
    if mode == "end":
        return float(x[k]), None
    level = reference["y_threshold"]
    yf = y[:k + 1]
    hit = np.nonzero((yf[:-1] < level) & (yf[1:] >= level))[0]
    if hit.size == 0:
        return 0.0, f"Y never reaches the reference threshold {fmt('y', level)} from below on the forward part"
    i = int(hit[0])
    return float(x[i] + (level - y[i]) / (y[i + 1] - y[i]) * (x[i + 1] - x[i])), None


def base_process_values(c: Curve) -> dict[str, float]:
    """Process values of the complete curve (after reference)."""
    iy, ix = int(np.argmax(c.y)), int(np.argmax(c.x))
    out = {"x_max": float(c.x[ix]), "x_min": float(c.x.min()), "y_max": float(c.y[iy]), "y_min": float(c.y.min()),
           "x_at_y_max": float(c.x[iy]), "y_at_x_max": float(c.y[ix]), "x_end": float(c.x[-1]),
           "y_end": float(c.y[-1]), "duration": float(c.t[-1] - c.t[0]), "pairs": float(c.t.size)}
    if c.y2 is not None:
        out |= {"y2_max": float(c.y2.max()), "y2_min": float(c.y2.min())}
    return out


def process_value_axes(elements: list[Mapping[str, Any]], has_y2: bool) -> dict[str, str]:
    """Where every process value of a program lies: ``"x"``, ``"y"``, ``"y2"`` (the channel), ``"t"``
    (``duration``) or ``""`` (``pairs``, a count). Element values lie on the axis their name starts with (Y
    meaning the element's channel); a threshold's ``at`` on the axis other than the threshold's."""
    out = {name: "t" if name == "duration" else "" if name == "pairs" else name.split("_")[0]
           for name in BASE_VALUES + (Y2_VALUES if has_y2 else ())}
    for e in elements:
        channel = e.get("channel", "y")
        for v in ELEMENT_KINDS[e["kind"]].values:
            if v == "at":
                out[f"{e['name']}.at"] = "x" if e.get("axis", "y") == "y" else channel
            else:
                out[f"{e['name']}.{v}"] = "x" if v.startswith("x") else channel
    return out


def process_value_units(elements: list[Mapping[str, Any]], units: Mapping[str, str]) -> dict[str, str]:
    """SI unit of every process value a program produces (``units``: the enabled channels' units; see
    :func:`process_value_axes`): ``duration`` in s, ``pairs`` a pure number."""
    return {name: "s" if axis == "t" else "1" if axis == "" else units[axis]
            for name, axis in process_value_axes(elements, "y2" in units).items()}


def nan_to_none(value: float) -> float | None:
    """JSON has no NaN: undefined values travel as null."""
    return None if math.isnan(value) else value
