"""Parameter sweeps: a grid over scene parameters, each point a scene with overrides, built and run like
``rig run`` builds its plant, reduced to metrics (``rig sweep``).

A parameter is a dotted key into the scene's TOML tree (``plant.k``, ``speed.speed``) and its values are
scene values (``"1.09 N/mm"``; numbers and booleans as TOML literals). Every point is a task for an executor
(:mod:`rig.executors`): the rows come back in grid order, the same on every executor.
"""
from __future__ import annotations

import copy
import itertools
import tomllib
from dataclasses import dataclass
from typing import Any, Sequence

from rig.outputs import UsageError
from rig.scene import Scene, SceneError
from rig.units import UnitError, to_si, unit_of


@dataclass(frozen=True)
class Param:
    """A swept scene key (dotted) and its values, as written in a scene."""

    key: str
    values: tuple[Any, ...]


def _literal(text: str) -> Any:
    """A TOML literal (number, boolean, quoted string) or else the text itself (e.g. ``"150 rpm"``)."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def parse_param(text: str) -> Param:
    """``KEY=V1,V2,...`` → :class:`Param`; values split at commas and stripped."""
    key, sep, values = text.partition("=")
    key = key.strip()
    parts = [v.strip() for v in values.split(",")]
    if not sep or not key or not all(parts) or any(not p for p in key.split(".")):
        raise ValueError(f"--param {text!r}: expected KEY=VALUE[,VALUE...] with a dotted scene key, e.g. "
                         f"'plant.k=1.09 N/mm,1.89 N/mm'")
    if len(key.split(".")) < 2:
        raise ValueError(f"--param {text!r}: {key!r} names a section, not a key (e.g. plant.k)")
    for sep_ in (";", "|"):
        if any(sep_ in p for p in parts):
            raise ValueError(f"--param {text!r}: values are separated by commas, not {sep_!r} (e.g. "
                             f"'{key}={values.replace(sep_, ',')}')")
    values = tuple(_literal(p) for p in parts)
    same = [float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v for v in values]   # 1 = 1.0
    twice = [parts[i] for i, v in enumerate(same) if v in same[:i]]
    if twice:
        raise ValueError(f"--param {key}: the value {twice[0]!r} is given twice (each point once)")
    return Param(key, values)


def check_units(scene: Scene, params: Sequence[Param]) -> None:
    """A :class:`UsageError` naming the ``--param`` whose value has no unit, or one of another dimension, where the
    scene writes that key with a unit (``plant.k = "1.68 N/mm"``): the value given, not the scene, is wrong; where the
    scene leaves the key to its default (does not write it), the values are compared in the unit of the first that has
    one. A value given twice (as written or in another unit) is refused: each point runs once."""
    for param in params:
        node: Any = scene.data
        for part in param.key.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        unit = unit_of(node) if isinstance(node, str) else None
        where = f'the scene writes {param.key} = "{node}"'
        if node is None:                          # the key left to its default: the values' own units
            unit = next((u for u in (unit_of(v) for v in param.values if isinstance(v, str)) if u), None)
            where = f"{param.key}'s other values have units"
        if unit is None:                          # plain numbers: parse_param refused repeats as written
            continue
        seen: dict[float, Any] = {}
        for value in param.values:
            what = f"--param {param.key}={value}"
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                raise UsageError(f'{what}: {value} has no unit; {where}: give the '
                                 f'unit, e.g. "{param.key}={value} {unit}"')
            try:
                si = to_si(value, unit, what=what)
            except UnitError as exc:
                raise UsageError(str(exc)) from None
            si = float(f"{si:.12g}")              # "0.07 cm" and "0.7 mm" differ in the last bits of their SI value
            if si in seen:
                raise UsageError(f"--param {param.key}: {value!r} is the same value as {seen[si]!r} (each point once)")
            seen[si] = value


def grid(params: Sequence[Param]) -> list[tuple[Any, ...]]:
    """Every combination of the values, the last parameter varying fastest."""
    keys = [p.key for p in params]
    if len(set(keys)) != len(keys):
        raise ValueError(f"a parameter is given twice: {', '.join(sorted({k for k in keys if keys.count(k) > 1}))}")
    return list(itertools.product(*(p.values for p in params)))


def with_overrides(scene: Scene, overrides: dict[str, Any]) -> Scene:
    """A copy of ``scene`` with the dotted keys set to the given values; the table a key is in must exist."""
    data = copy.deepcopy(scene.data)
    for key, value in overrides.items():
        *tables, name = key.split(".")
        node: Any = data
        for i, part in enumerate(tables):
            if isinstance(node, dict) and isinstance(node.get(part), list):
                raise SceneError(f"{scene.path}: cannot set {key!r}: [[{'.'.join(tables[:i + 1])}]] is an array of "
                                 "tables, whose entries a sweep cannot address (sweep a copy of the scene per entry "
                                 "value, or a key of a plain table)")
            if not isinstance(node, dict) or not isinstance(node.get(part), dict):
                raise SceneError(f"{scene.path}: cannot set {key!r}: the scene has no table "
                                 f"[{'.'.join(tables[:i + 1])}]")
            node = node[part]
        node[name] = value
    return Scene(scene.path, data, scene.text)
