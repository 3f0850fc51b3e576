"""CSV export of curves and results for spreadsheets (comma-separated, UTF-8).

Values are in the display units (rig.analysis.units), and every column that holds a quantity names its
unit in brackets (``x [mm]``, ``y_min [N]``, ``t [s]``, ``angle [deg]``; ASCII unit names). Without
display units the values are SI and the brackets say so.
"""
from __future__ import annotations

import csv
import functools
import math
from itertools import chain, repeat
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from rig.analysis.numbers import decimals
from rig.analysis.sets import cut_reason, memory_note, missing_values, process_values
from rig.analysis.units import DisplayUnits, Unit, unit
from rig.recorder import CurveRecord


NO_REASON = "NOK: the device named no failing element"


def cells(values: np.ndarray, digits: int = 9, decimals: int | None = None) -> list[str]:
    """Each value to ``digits`` significant digits (more than the float32 / 20-bit resolution the curves
    cross the bus with), or to ``decimals`` fixed decimals; empty for NaN."""
    form = f"%.{digits}g" if decimals is None else f"%.{decimals}f"
    return [form % v if v == v else "" for v in values.tolist()]


def column(name: str, u: Unit) -> str:
    """``name [unit]``; a pure number keeps its bare name."""
    return f"{name} [{u.ascii}]" if u.ascii else name


def _units_of(units: DisplayUnits | Mapping[int, DisplayUnits] | None, program: int) -> DisplayUnits:
    if isinstance(units, DisplayUnits):
        return units
    if units and program in units:
        return units[program]
    if units:
        return next(iter(units.values()))
    return DisplayUnits({"x": unit("m", "m"), "y": unit("N", "N")})


def export_curves(curves: Sequence[CurveRecord], path: Path,
                  units: DisplayUnits | Mapping[int, DisplayUnits] | None = None) -> Path:
    """One row per sample: curve, program, i, t, x, y, cam angle (empty when not measured), in the display
    units of the first curve's program (``units``: one DisplayUnits or one per program)."""
    du = _units_of(units, curves[0].program if curves else 0)
    ux, uy, ua, ut = du.channel("x"), du.channel("y"), du.of("rad"), du.of("s")
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["curve", "program", "i", column("t", ut), column("x", ux), column("y", uy), column("angle", ua)])
        for c in curves:
            columns = [ut(c.t), ux(c.x), uy(c.y)] + ([] if c.angle is None else [ua(c.angle)])
            if all(np.isfinite(v).all() for v in columns):   # every cell a number: one formatting pass per curve
                f.write(_rows(c.number, c.program, columns))
                continue
            angle = cells(columns[3]) if c.angle is not None else [""] * c.t.size
            w.writerows(zip(repeat(c.number), repeat(c.program), range(c.t.size), cells(columns[0], 12),
                            cells(columns[1]), cells(columns[2]), angle))
    return path


def _rows(number: int, program: int, columns: list[np.ndarray]) -> str:
    """CSV rows ``number, program, i, t, x, y[, angle]`` of finite columns, formatted as :func:`_cells` does
    (t to 12, the others to 9 significant digits; an empty angle cell when there is no angle column)."""
    n = columns[0].size
    row = f"{int(number)},{int(program)},%d,%.12g,%.9g,%.9g" + (",%.9g\r\n" if len(columns) == 4 else ",\r\n")
    flat = np.empty((n, 1 + len(columns)), dtype=object)
    flat[:, 0] = range(n)
    for j, v in enumerate(columns):
        flat[:, j + 1] = v.tolist()
    return (row * n) % tuple(flat.ravel().tolist())


def reason_text(result: Mapping) -> str:
    """Why a result is NOK: ``element: reason`` of each failed element, ``; ``-separated; never empty for a
    NOK result (a failed element without a reason, or a NOK without a failed element, says so)."""
    failed = [e for e in result.get("elements", []) if not e.get("ok", True)]
    text = "; ".join(f"{e.get('name')}: {e.get('reason') or 'no reason recorded'}" for e in failed)
    if not text and not result.get("ok", True):
        text = NO_REASON
    return cut_reason(memory_note(result), text)


def _shortest(value: float) -> float:
    """A value that is exactly a float32 (what the unit sends) as the shortest decimal reading back as that float32
    (0.2547000051 → 0.2547), so that unit conversion does not print its binary tail; other values unchanged."""
    single = np.float32(value)
    return float(str(single)) if float(single) == value else value


def export_results(results: Sequence[Mapping], path: Path,
                   units: DisplayUnits | Mapping[int, DisplayUnits] | None = None) -> Path:
    """One row per curve: number, program, ok (1/0) and verdict (OK/NOK), failed elements, the reason (non-empty for
    every NOK row), complete (1/0) and the process values that did not arrive, ``memory`` ("cut": the curve filled
    the unit's curve memory and stops there; "thinned": decimated to fit), then every process value in its display
    unit (``units``: one DisplayUnits or one per program); a value the unit sent as float32 at that precision
    (:func:`_shortest`: 0.2547 s, not 0.2547000051)."""
    table = process_values(results)
    du = _units_of(units, int(results[0].get("program", 0)) if results else 0)
    shown = {name: du.value(name) for name in table}
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["curve", "program", "ok", "verdict", "failed_elements", "reason", "complete", "missing", "memory",
                    *(column(name, shown[name]) for name in table)])
        for i, r in enumerate(results):
            failed = ";".join(str(e.get("name")) for e in r.get("elements", []) if not e.get("ok", True))
            missing = missing_values(r)
            w.writerow([r.get("number"), r.get("program"), int(bool(r["ok"])), "OK" if r["ok"] else "NOK", failed,
                        reason_text(r),
                        int(r.get("complete", True) is not False), ";".join(missing), memory_note(r),
                        *("" if np.isnan(v[i]) else "%.10g" % shown[name](_shortest(float(v[i])))
                          for name, v in table.items())])
    return path


#: SI units of the stand topics' columns beyond the plants' truth signals (rig.analysis.units.SIGNAL_SI)
STAND_SI = {"t": "s", "edge_time": "s", "speed_time": "s", "speed": "rad/s", "displacement": "m", "count": "1",
            "speed_method": "1"}


@functools.lru_cache(maxsize=1)
def _device_signals() -> dict[str, dict[str, tuple[str, float]]]:
    """The DBC's device signals by message and signal, both in snake case (the ``/stand/`` topic name and its column:
    ``encoder1``, ``edge_time``): (SI unit, "1" for a count; the step the signal is carried in, its scale)."""
    from rig.dbc import load_dbc
    from rig.recorder.schemas import snake
    return {snake(m.name): {snake(s.name): (s.unit or "1", abs(float(s.scale or 0.0))) for s in m.signals}
            for m in load_dbc().messages if "DEVICE" in m.senders}


def dbc_units() -> dict[str, str]:
    """SI unit of every device signal of the DBC by its column name (snake case; "1" for a count): the unit of a
    reading message's column on its ``/stand/`` topic."""
    return {name: unit for signals in _device_signals().values() for name, (unit, _) in signals.items()}


def stand_units() -> dict[str, dict[str, str]]:
    """SI units of the ``/stand/`` topics' columns by topic and column ("1" for a count or code): the DBC's units of
    each reading message's signals, and the host's derived columns (:data:`STAND_SI`)."""
    return {f"/stand/{message}": {**STAND_SI, **{name: unit for name, (unit, _) in signals.items()}}
            for message, signals in _device_signals().items()}


def export_events(events: Sequence[Mapping], details: Sequence[str], path: Path) -> Path:
    """The recording's events as CSV, one row each: simulation time (s), kind, its ``details`` as the report words
    them (:func:`rig.analysis.event_text.event_details`)."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["t [s]", "kind", "details"])
        w.writerows([f"{e.get('t', math.nan):.9g}", e.get("kind", ""), d] for e, d in zip(events, details))
    return path


def export_table(headers: Sequence[str], rows: Iterable[Sequence[Any]], path: Path) -> Path:
    """A report table (a lab sheet's) as CSV: its cells (as the report shows them, or numbers; units in the headers),
    a dash or None (no value) as an empty cell."""
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(headers)
        w.writerows(["" if cell in ("—", None) else cell for cell in row] for row in rows)
    return path


def dbc_steps() -> dict[str, dict[str, float]]:
    """The step (SI, the signal's scale) in which the DBC carries each device signal: by the ``/stand/`` topic name of
    its message (``encoder1``), then by its column name (``edge_time``)."""
    return {message: {name: step for name, (_, step) in signals.items() if step}
            for message, signals in _device_signals().items()}


def export_series(series: Mapping[str, np.ndarray] | Iterable[Mapping[str, np.ndarray]], path: Path,
                  units: DisplayUnits | None = None, topic: str = "") -> Path:
    """One recorded stand topic (``t`` and its columns, SI; or its blocks one after the other, e.g.
    ``Recording.series_blocks``, written as they come) as CSV, one row per reading, each quantity in its
    display unit (``units``: the report's; default :data:`~rig.analysis.units.DEFAULTS`), named in brackets (units
    from the stand columns, the DBC's signals, the plants' truth signals). With its ``topic``, a reading its message
    carries in a DBC step has the decimals that step resolves in its display unit (a tachometer's 0.01 rad/s:
    0.0955 rpm, two decimals — 1180.01 rpm, not 1180.00658); the host's own columns (angles and speeds from the
    counts and edge times) keep 9 significant digits."""
    from rig.analysis.units import SIGNAL_SI
    du = units or DisplayUnits()
    blocks = iter([series] if isinstance(series, Mapping) else series)
    first = next(blocks, {})
    names = list(first)
    shown = [unit("s", "s") if n in ("t", "edge_time", "speed_time") else
             du.of(STAND_SI.get(n) or dbc_units().get(n) or SIGNAL_SI.get(n, "1")) for n in names]
    steps = dbc_steps().get(topic.removeprefix("/stand/"), {}) if topic else {}     # the columns its message carries
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow([column(n, u) for n, u in zip(names, shown)])
        for block in chain([first], blocks):
            w.writerows(zip(*(cells(u(np.asarray(block[n], dtype=float)),
                                     decimals=decimals(steps[n] * u(1.0), 1) if n in steps and n != "t" else None)
                              for n, u in zip(names, shown))))
    return path
