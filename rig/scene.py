"""Scene files: TOML documents in ``data/scenes/`` with explicit units, validated against schemas.

A *schema* is a mapping ``name -> Field``. :func:`read_table` checks a TOML table against it:
every key must be a field name (``L3 = "260 mm"``) or a field name with a unit suffix
(``L3_mm = 260``); unknown keys, missing required keys, wrong units, non-finite values (``inf``,
``nan``) and values outside a field's range (``Field(minimum=…, maximum=…, positive=…)``) raise :class:`SceneError`
naming the key and the file, and the value as the scene wrote it (``got "-0.05 mm"``). Values come back in SI.
"""
from __future__ import annotations

import difflib
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, TypeVar

from rig.limits import HUGE
from rig.units import UnitError, to_si

REQUIRED = object()


class SceneError(ValueError):
    """A scene file is unreadable, incomplete or inconsistent; the message names file and key."""


class ImpossibleGeometry(SceneError):
    """Every value of the scene is valid, but together they describe a mechanism that cannot be assembled (a sweep
    over geometry records such a point as failed instead of refusing the sweep)."""


@dataclass(frozen=True)
class Field:
    """One scene parameter: its SI unit (``"1"`` = pure number, ``None`` = not a quantity) and default; the range
    of a quantity (SI): ``minimum``/``maximum`` inclusive, ``below`` exclusive, ``positive`` excludes 0
    (:func:`read_table` checks it and names the value as the scene wrote it); ``says``: the range in the scene's
    words ("must be at least 0° and below 90°") instead of one in SI. ``integer``: a whole number (returned as an
    int); ``plain``: a plain number is in ``unit`` (``bitrate = 500000`` bit/s, or ``"500 kbit/s"``); ``one_of``: the
    values it may take (SI; ``says`` words them)."""

    unit: str | None = "1"
    default: Any = REQUIRED
    doc: str = ""
    minimum: float | None = None
    maximum: float | None = None
    positive: bool = False
    below: float | None = None
    says: str = ""
    integer: bool = False
    plain: bool = False
    one_of: tuple[float, ...] = ()

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def out_of_range(self, value: float) -> str | None:
        """What ``value`` (SI) must be when it is outside the range ("must not be negative"), else None."""
        if not ((self.minimum is not None and value < self.minimum) or (self.maximum is not None and value > self.maximum)
                or (self.positive and not value > 0.0) or (self.below is not None and not value < self.below)
                or (self.integer and not float(value).is_integer()) or (self.one_of and value not in self.one_of)):
            return None
        if self.says:
            return self.says
        unit = "" if self.unit in (None, "1") else f" {self.unit}"          # a bound other than 0 is in SI
        if self.integer:
            return self.whole()
        low = self.minimum if self.minimum is not None else 0.0 if self.positive else None
        if self.maximum is not None:
            return (f"must be at most {self.maximum:g}{unit}" if low is None else
                    f"must be {'above' if self.positive else 'between'} {low:g}{unit} "
                    f"{'and at most' if self.positive else 'and'} {self.maximum:g}{unit}")
        if self.positive and low == 0.0:
            return "must be positive"
        return "must not be negative" if low == 0.0 else f"must be at least {low:g}{unit}"

    def whole(self) -> str:
        """What an integer field's value must be: "must be an integer >= 0 and <= 65535"."""
        unit = "" if self.unit in (None, "1") else f" {self.unit}"
        return ("must be an integer" + (f" >= {self.minimum:.0f}{unit}" if self.minimum is not None else "")
                + (f" and <= {self.maximum:.0f}{unit}" if self.maximum is not None else ""))


def as_written(value: Any, unit: str | None = None) -> str:
    """A scene value as the file wrote it: ``"-0.05 mm"`` (a quantity string, quoted), ``-0.05 mm`` (a number
    whose key names the unit, ``clearance_mm = -0.05``), ``5.0`` / ``0`` (a number)."""
    if isinstance(value, str):
        return f'"{value}"'
    return f"{value!r}" + (f" {unit}" if unit else "")


@dataclass
class Scene:
    """A loaded scene: its raw TOML tree and where it came from; ``folder``: where the relative paths it names lie
    (None: the scene file's folder)."""

    path: Path
    data: dict[str, Any]
    text: str
    folder: Path | None = None

    @property
    def content(self) -> str:
        """The scene's file and values as one string, a cache key: equal for equal values whatever the text (a sweep's
        variants share their text, not their values) or the keys' order."""
        return f"{self.path}\n{json.dumps(self.data, sort_keys=True, default=str)}"

    def file(self, written: str | Path) -> Path:
        """A file the scene names, as written: a relative path is relative to the scene file's folder (not to the
        current directory), made whole (a worker in another directory finds it too)."""
        path = Path(written)
        return path if path.is_absolute() else ((self.folder if self.folder is not None else self.path.parent)
                                                / path).absolute()

    def section(self, name: str, required: bool = True) -> dict[str, Any]:
        """The sub-table ``name`` (dotted for nesting); a missing required one is a :class:`SceneError`."""
        node: Any = self.data
        for part in name.split("."):
            if not isinstance(node, dict) or part not in node:
                if required:
                    raise SceneError(f"{self.path}: missing section [{name}]")
                return {}
            node = node[part]
        if not isinstance(node, dict):
            raise SceneError(f"{self.path}: [{name}] must be a table, got {type(node).__name__}")
        return node

    def read(self, name: str, schema: Mapping[str, Field], required: bool = True,
             allow_tables: bool = False) -> dict[str, Any]:
        """Validate section ``name`` against ``schema`` (see :func:`read_table`)."""
        return read_table(self.section(name, required), schema, f"{self.path} [{name}]", allow_tables)


def load_scene(path: str | Path) -> Scene:
    """Parse a scene file; syntax errors are reported with the file name."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")         # (a byte-order mark, as some editors write, is fine)
    except OSError as exc:
        raise SceneError(f"cannot read scene file {path}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start}): a scene "
                         f"is a TOML file in UTF-8") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None
    return Scene(path=path, data=data, text=text)


def _match(key: str, schema: Mapping[str, Field]) -> tuple[str, str | None] | None:
    """Find the field a key names, and the unit its suffix gives (longest field name wins)."""
    if key in schema:
        return key, None
    best = None
    for name in schema:
        if key.startswith(name + "_") and len(key) > len(name) + 1 and (best is None or len(name) > len(best)):
            best = name
    if best is None or schema[best].unit is None:
        return None
    return best, key[len(best) + 1:]


T = TypeVar("T")


def read_subtable(table: Any, schema: Mapping[str, Field], where: str, name: str, build: Callable[[dict], T],
                  default: T) -> T:
    """An optional sub-table ``[<section>.<name>]``: ``default`` when absent, else ``build`` of its checked values
    (SI); a ValueError of ``build`` becomes a :class:`SceneError` naming ``where``."""
    if table is None:
        return default
    if not isinstance(table, dict):
        raise SceneError(f"{where}: '{name}' must be a table ([...{name}])")
    values = read_table(table, schema, where)
    try:
        return build(values)
    except ValueError as exc:
        raise SceneError(f"{where}: {exc}") from None


def read_table(table: Mapping[str, Any], schema: Mapping[str, Field], where: str,
               allow_tables: bool = False) -> dict[str, Any]:
    """Check ``table`` against ``schema`` and return ``{field: value}`` with quantities in SI.

    Fields with ``unit=None`` are passed through unchanged (strings, lists, tables). Sub-tables not in
    the schema are an error unless ``allow_tables`` (then they are returned as they are).
    """
    out: dict[str, Any] = {}
    spelled: dict[str, str] = {}            # each name's key as written
    for key, value in table.items():
        if allow_tables and isinstance(value, dict) and key not in schema:
            out[key] = value
            continue
        found = _match(key, schema)
        if found is None:
            known = ", ".join(sorted(schema)) or "(none)"
            close = difflib.get_close_matches(key, list(schema), n=1, cutoff=0.8)
            raise SceneError(f"{where}: unknown key {key!r}" + (f" (did you mean {close[0]!r}?)" if close else "")
                             + f" (known keys: {known})")
        name, unit = found
        if name in out:
            raise SceneError(f"{where}: {name!r} is given twice (as {spelled[name]!r} and {key!r})")
        spelled[name] = key
        field = schema[name]
        if field.unit is None:
            if isinstance(field.default, bool) and not isinstance(value, bool):      # a switch: TOML's true / false
                raise SceneError(f"{where}: key {key!r} must be true or false (no quotes)"
                                 + (f" ({field.doc})" if field.doc else "") + f", got {as_written(value)}")
            out[name] = value
            continue
        if unit is None and field.plain and isinstance(value, (int, float)) and not isinstance(value, bool):
            unit = field.unit
        try:
            out[name] = to_si(value, field.unit, unit, what=f"{where}: key {key!r}")
        except UnitError as exc:
            if field.integer and field.unit == "1":         # not a number at all: say what it must be
                raise SceneError(f"{where}: key {key!r} {field.whole()}" + (f" ({field.doc})" if field.doc else "")
                                 + f", got {as_written(value)}") from None
            raise SceneError(str(exc)) from None
        if not math.isfinite(out[name]):
            raise SceneError(f"{where}: key {key!r} must be a finite quantity, got {value!r}"
                             + (f" {unit}" if unit else ""))
        if abs(out[name]) > HUGE and not field.integer:     # finite, but its square overflows (L3 = "1e308 mm": a
            #                                                   traceback); a whole number (a seed) is no magnitude
            raise SceneError(f"{where}: key {key!r} is beyond any machine (more than {HUGE:g} in SI units), got "
                             f"{as_written(value, unit)}")
        wrong = field.out_of_range(out[name])
        if wrong is not None:
            raise SceneError(f"{where}: key {key!r} {wrong}" + (f" ({field.doc})" if field.doc else "")
                             + f", got {as_written(value, unit)}")
        if field.integer:
            out[name] = int(out[name])
    for name, field in schema.items():
        if name not in out:
            if field.required:
                raise SceneError(f"{where}: missing key {name!r}" + (f" ({field.doc})" if field.doc else ""))
            out[name] = field.default
    return out
