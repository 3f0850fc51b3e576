"""Small validators for program settings (dicts from the host): clear errors naming key and value."""
from __future__ import annotations

import contextlib
import contextvars
import math
from typing import Any, Iterable, Iterator, Mapping

import numpy as np

from rig.scene import as_written
from rig.units import UnitError, to_si

from .errors import DigiForceError

# Set while a program written by a person (a scene's [device.config]) is checked: a bare number where a
# quantity is expected is then an error instead of an SI value (the device's own API takes SI numbers).
_UNITS_REQUIRED: contextvars.ContextVar[bool] = contextvars.ContextVar("units_required", default=False)


class NormalisedSI(float):
    """A number the unit normalised itself (SI by construction): accepted without a unit even within
    :func:`units_required`."""


class MissingUnitError(DigiForceError):
    """A bare number where a quantity with a unit is required (see :func:`units_required`)."""


@contextlib.contextmanager
def units_required() -> Iterator[None]:
    """Within this block, :func:`quantity` refuses bare numbers for dimensioned quantities."""
    token = _UNITS_REQUIRED.set(True)
    try:
        yield
    finally:
        _UNITS_REQUIRED.reset(token)


def known_keys(cfg: Mapping[str, Any], keys: Iterable[str], where: str) -> None:
    """Reject keys that are not in ``keys``."""
    if not isinstance(cfg, Mapping):
        raise DigiForceError(f"{where}: expected a table/dict, got {type(cfg).__name__} {cfg!r}")
    unknown = sorted(set(cfg) - set(keys))
    if unknown:
        raise DigiForceError(f"{where}: unknown key {unknown[0]!r} (known keys: {', '.join(sorted(keys))})")


def choice(cfg: Mapping[str, Any], key: str, options: Iterable[str], where: str, default: Any = None) -> Any:
    value = cfg.get(key, default)
    options = tuple(options)
    if value not in options:
        raise DigiForceError(f"{where}.{key}: {value!r} is not one of {', '.join(map(repr, options))}")
    return value


def flag(cfg: Mapping[str, Any], key: str, where: str, default: bool) -> bool:
    value = cfg.get(key, default)
    if not isinstance(value, bool):
        raise DigiForceError(f"{where}.{key}: expected true or false, got {value!r}")
    return value


def text(cfg: Mapping[str, Any], key: str, where: str, default: str | None = None) -> str:
    value = cfg.get(key, default)
    if not isinstance(value, str) or not value:
        raise DigiForceError(f"{where}.{key}: expected a non-empty string, got {value!r}")
    return value


#: units a bare number of a quantity in SI ``unit`` was likely meant in (the hint of a missing unit): the one a
#: scene usually writes first (a bare 41.5 for an X limit is far likelier 41.5 mm than 41.5 m), then another scale
_EXAMPLE_UNITS = {"m": ("mm", "m"), "N": ("N", "kN"), "s": ("ms", "s"), "rad": ("deg", "rad"), "N*m": ("N*m",)}


def quantity(value: Any, unit: str, what: str) -> float:
    """A number (already in SI ``unit``) or a string with a unit (``"2 mm"``) as a finite SI float.
    Inside :func:`units_required` a bare number for a dimensioned ``unit`` is a :class:`MissingUnitError`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise DigiForceError(f"{what}: expected a number or a quantity string, got {value!r}")
    if isinstance(value, (int, float)) and not isinstance(value, NormalisedSI) and unit not in ("", "1") \
            and _UNITS_REQUIRED.get():
        examples = " or ".join(f'"{value} {u}"' for u in _EXAMPLE_UNITS.get(unit, (unit,)))
        raise MissingUnitError(f"{what}: {value!r} has no unit (a bare number is not read as SI here: it would be "
                               f"{value!r} {unit}); write it with the unit you mean, e.g. {examples}")
    try:
        out = to_si(value, unit, unit if isinstance(value, (int, float)) and unit not in ("", "1") else None, what)
    except UnitError as exc:
        raise DigiForceError(str(exc)) from None
    if not math.isfinite(out):
        raise DigiForceError(f"{what}: must be finite, got {value!r}")
    return out


def written(value: Any, unit: str) -> str:
    """A value as the program wrote it, for a message: ``"42.5 mm"`` (a quantity string) or a plain number with
    the SI ``unit`` it is read in (``0.0425 m``)."""
    return as_written(value, None if unit in ("", "1") else unit)


def number(cfg: Mapping[str, Any], key: str, unit: str, where: str, default: Any = None,
           minimum: float | None = None, positive: bool = False) -> float:
    """``cfg[key]`` as an SI quantity; ``default`` when absent; range checks with clear messages."""
    if key not in cfg and default is None:
        raise DigiForceError(f"{where}: missing key {key!r}")
    if key not in cfg:                      # the unit's own default (SI) is not written by anyone
        token = _UNITS_REQUIRED.set(False)
        try:
            value = quantity(default, unit, f"{where}.{key}")
        finally:
            _UNITS_REQUIRED.reset(token)
    else:
        value = quantity(cfg[key], unit, f"{where}.{key}")
    if positive and not value > 0:
        raise DigiForceError(f"{where}.{key}: must be > 0, got {cfg.get(key, default)!r}")
    if minimum is not None and value < minimum:
        raise DigiForceError(f"{where}.{key}: must be >= {minimum}, got {cfg.get(key, default)!r}")
    return value


def quantities(cfg: Mapping[str, Any], key: str, unit: str, where: str) -> np.ndarray:
    """``cfg[key]``, a list of values, as an SI array. The list's unit is ``cfg[key + "_unit"]`` when given
    (then its items are plain numbers); otherwise each item is a quantity string or (outside
    :func:`units_required`) an SI number."""
    values, unit_key = cfg.get(key), f"{key}_unit"
    what = f"{where}.{key}"
    if not isinstance(values, (list, tuple)) or not values:
        raise DigiForceError(f"{what}: expected a non-empty list of values, got {values!r}")
    if unit_key in cfg:
        given = text(cfg, unit_key, where)
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            raise DigiForceError(f"{what}: {where}.{unit_key} names the unit ({given!r}); give plain numbers")
        try:
            factor = to_si(1.0, unit, given, f"{where}.{unit_key}")
        except UnitError as exc:
            raise DigiForceError(str(exc)) from None
        out = np.asarray(values, dtype=float) * factor
    else:
        try:
            out = np.array([quantity(v, unit, f"{what}[{j}]") for j, v in enumerate(values)])
        except MissingUnitError:
            raise MissingUnitError(f"{what}: numbers without a unit; add {unit_key} = \"{unit}\" (or the unit the "
                                   f"numbers are in), or write each value with its unit") from None
    if not np.all(np.isfinite(out)):
        raise DigiForceError(f"{what}: values must be finite")
    return out


def pick_step(value: float, steps: Iterable[float], what: str) -> float:
    """The step equal to ``value`` (relative tolerance 1e-9) or an error listing the steps."""
    steps = tuple(steps)
    for s in steps:
        if math.isclose(value, s, rel_tol=1e-9, abs_tol=1e-15):
            return s
    raise DigiForceError(f"{what}: {value:g} is not one of the unit's steps ({', '.join(f'{s:g}' for s in steps)})")
