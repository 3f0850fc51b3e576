"""Physical quantities at the edges: parse ``"260 mm"`` or ``L3_mm = 260`` into SI floats.

SI is used everywhere inside the code (m, kg, s, N, rad). Scene and device files may use any unit
pint understands; the expected unit of a field is given as an SI unit string (``"m"``, ``"N/m"``,
``"rad"``, ``"N*m"``, ``"rad/s"``, ``"1"`` for pure numbers).
"""
from __future__ import annotations

import re
from functools import lru_cache

import pint


def _registry() -> pint.UnitRegistry:
    """pint's default registry, its parsed definitions cached in the user's cache folder (0.07 s instead of 0.3 s
    a start); without a usable cache folder, parsed afresh."""
    try:
        return pint.UnitRegistry(cache_folder=":auto:")
    except Exception:                  # noqa: BLE001  (no writable cache folder, a cache pint cannot read)
        return pint.UnitRegistry()


ureg = _registry()
ureg.define("rev = revolution")          # "2.5 rev/s": the abbreviation engineers write
_INTEGER = re.compile(r"(?<![\w.])(?<![eE][+-])(\d+)(?![\w.])")   # an integer literal, not in a name or float


class UnitError(ValueError):
    """A value has no unit, an unknown unit or a unit of the wrong dimension."""


#: an example quantity per SI unit, for the message on a value rig cannot read as a quantity
EXAMPLES = {"m": "260 mm", "rad": "60 deg", "rad/s": "150 rpm", "s": "100 ms", "N": "40 N", "N/m": "1.89 N/mm",
            "N*m": "25 N*m", "kg": "0.91 kg", "Hz": "10 kHz", "bit/s": "500 kbit/s", "m/s^2": "9.81 m/s^2", "kg*m^2": "0.02 kg*m^2",
            "s/m": "0.5 s/m", "1/m": "60 / mm", "1": "0.5"}


def example(si_unit: str) -> str:
    """``"150 rpm"``: a quantity of the kind ``si_unit`` measures, as a scene writes it."""
    return EXAMPLES.get(si_unit or "1", f"1 {si_unit}")


def split_quantity(text: str) -> tuple[float, str] | None:
    """(number, unit as written) of a text that starts with a number (``"1.68 N/mm"`` → (1.68, "N/mm"); the unit ""
    for a plain number); None otherwise. The unit is not checked (:func:`unit_of` does)."""
    m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*", text)
    if m is None:
        return None
    unit = m.group(2)
    return float(m.group(1)), "1" + unit if unit.startswith("/") else unit     # "60 / mm": the unit 1/mm (pint
    # reads "/ mm" alone as no unit: two equal scenes, "60 / mm" and "60000 1/m", were two machines; an audit)


def unit_of(text: str) -> str | None:
    """The unit of a quantity string as written (``"N/mm"`` of ``"1.68 N/mm"``); None for a plain number or a text
    that is no quantity."""
    split = split_quantity(text)
    if split is None or not split[1]:
        return None
    try:
        ureg.Unit(split[1])
    except Exception:                  # noqa: BLE001  (pint's parser raises many kinds)
        return None
    return split[1]


def _unknown(value: object, unit: str | None, si_unit: str, names: tuple[str, ...], what: str) -> UnitError:
    """The error for a value with a name pint does not know: no quantity at all ("fast"), or an unknown unit."""
    hint = f'(e.g. "{example(si_unit)}")'
    if unit is not None:
        return UnitError(f"{what}: the key's unit {unit!r} is not a unit rig knows {hint}")
    if isinstance(value, str) and not _NUMBER.search(value):
        kind = "a number" if si_unit in (None, "", "1") else "a quantity with a unit"
        return UnitError(f"{what}: {value!r} is not {kind} {hint}")
    unknown = ", ".join(repr(n) for n in names) or "its unit"
    return UnitError(f"{what}: {value!r}: {unknown} is not a unit rig knows {hint}")


def _unit_text(suffix: str) -> str:
    """Turn a key suffix like ``N_per_mm`` or ``N_m`` into a pint unit expression."""
    return suffix.replace("_per_", "/").replace("_", "*")


_NUMBER = re.compile(r"\d|\binf\b|\bnan\b", re.IGNORECASE)      # a quantity string holds a number
#: "1 500 rpm": pint multiplies the two (500 rpm; "1 000 mm" is 0); not a unit that starts with a number ("150 1/min")
_SIDE_BY_SIDE = re.compile(r"\d\.?\s+\.?\d+(?:\.\d*)?(?!\d|\s*/\s*[^\d\s.])")   # ("2 1/2 in" is refused)


def _one_number(value: str, what: str) -> None:
    """Refuse a quantity string whose number a person and pint read differently: a ± (pint's measurement, then a
    product: "1.5 ± 0.1 mm" read 0.15 mm), a comma (a decimal comma, "1,89
    N/mm", or a thousands separator, "1,500 rpm": 100× or 1000× off read as the other) and numbers side by side
    (a thousands space, "1 500 rpm", which pint reads as the product 1·500)."""
    if "±" in value or "+/-" in value:      # pint reads "1.5 ± 0.1 mm" as 0.15 mm (a measurement, then a product)
        raise UnitError(f"{what}: {value!r} has a ± (a tolerance): write the value alone (e.g. \"1.5 mm\"); a "
                        f"tolerance has its own key where the scene takes one")
    if "," in value:
        raise UnitError(f"{what}: {value!r} has a comma: a decimal comma or a thousands separator? Write the number "
                        f"with a decimal point and no separators (e.g. \"1.89 N/mm\", \"1500 rpm\")")
    if _SIDE_BY_SIDE.search(value):
        raise UnitError(f"{what}: {value!r} has two numbers side by side (pint would multiply them: \"1 500\" reads "
                        f"500): write one number without spaces (e.g. \"1500 rpm\")")


@lru_cache(maxsize=4096)
def _parsed(text: str) -> tuple[float, str]:
    """(magnitude, unit) of a quantity string, parsed by pint once per text (a scene is read several times per
    command, 1600 quantities in the demo's ``rig run``; pint's parser takes ~0.2 ms each). Integer literals read as
    floats: a power of numbers ("9**9**9") overflows at once instead of computing a huge integer for minutes."""
    q = ureg.Quantity(_INTEGER.sub(r"\1.0", text))
    if not isinstance(q, ureg.Quantity):
        q = ureg.Quantity(float(q), "")
    return float(q.magnitude), str(q.units)


@lru_cache(maxsize=None)
def _factor(unit: str, si_unit: str) -> float:
    q = ureg.Quantity(1.0, unit)
    return float(q.to(si_unit).magnitude)


def is_dimensionless(si_unit: str) -> bool:
    return si_unit in ("", "1")


@lru_cache(maxsize=None)
def _angle_power(unit: str) -> float:
    """The power of the angle in ``unit`` (1 for rad/s and rpm, 0 for Hz and N·m, −1 for N·m/rad). pint counts the
    radian as dimensionless, so "2.5 Hz" would convert to 2.5 rad/s without this."""
    return dict(ureg.get_root_units(unit or "dimensionless")[1]._units).get("radian", 0)


def _same_angle(unit: str, si_unit: str, value: object, what: str) -> None:
    """Refuse a unit whose angle content differs from the expected one: a frequency (Hz, 1/min) for an angular
    speed is revolutions to some and radians to others; an angle unit for a plain frequency or number is a slip."""
    have, want = _angle_power(unit), _angle_power(si_unit)
    if have == want:
        return
    if want == 1 and have == 0 and si_unit == "rad/s":
        raise UnitError(f"{what}: {value!r} is a frequency, not an angular speed: write revolutions (\"150 rpm\", "
                        f"\"2.5 rev/s\") or radians (\"15.7 rad/s\")")
    angle = {1: "an angle", -1: "a per-angle quantity", 0: "no angle"}
    raise UnitError(f"{what}: {value!r} has {angle.get(have, 'an angle power')} in its unit, expected something "
                    f"convertible to {si_unit or 'a plain number'} ({angle.get(want, 'another angle power')})")


def to_si(value: object, si_unit: str, unit: str | None = None, what: str = "value") -> float:
    """Convert ``value`` to a float in ``si_unit``.

    ``value`` is a number (its unit given by ``unit``, e.g. from a key suffix) or a string with its
    unit (``"260 mm"``). Pure numbers are accepted without a unit only when ``si_unit`` is
    dimensionless. Raises :class:`UnitError` naming ``what`` on any problem.
    """
    if isinstance(value, bool):
        raise UnitError(f"{what}: expected a quantity in {si_unit or 'no unit'}, got the boolean {value}")
    try:
        if isinstance(value, str):
            if unit is not None:
                raise UnitError(f"{what}: the key already names the unit {unit!r}; give a plain number, not {value!r}")
            if not _NUMBER.search(value):           # no number: not a quantity ("mm" was read as 1 mm; an audit)
                raise _unknown(value, None, si_unit, (), what)
            _one_number(value, what)
            magnitude, unit_text = _parsed(value)
            if unit_text in ("", "dimensionless") and not is_dimensionless(si_unit):
                raise UnitError(f"{what}: {value!r} has no unit; expected something convertible to {si_unit}")
            factor = _factor(unit_text or "dimensionless", si_unit or "dimensionless")
            _same_angle(unit_text, si_unit, value, what)
            return magnitude * factor
        if not isinstance(value, (int, float)):
            raise UnitError(f"{what}: expected a number or a quantity string, got {type(value).__name__} {value!r}")
        if unit is None:
            if not is_dimensionless(si_unit):
                raise UnitError(
                    f"{what}: {value!r} has no unit; write e.g. \"{value} <unit>\" or suffix the key with a unit "
                    f"(expected something convertible to {si_unit})")
            return float(value)
        factor = _factor(_unit_text(unit), si_unit or "dimensionless")
        _same_angle(_unit_text(unit), si_unit, f"{value} {unit}", what)
        return float(value) * factor
    except UnitError:
        raise
    except pint.UndefinedUnitError as exc:
        raise _unknown(value, unit, si_unit, tuple(getattr(exc, "unit_names", ())), what) from None
    except pint.DimensionalityError:
        raise UnitError(f"{what}: {value!r}{' ' + unit if unit else ''} has the wrong dimension; "
                        f"expected something convertible to {si_unit}") from None
    except Exception:  # pint's parser raises many kinds (TokenError, ZeroDivisionError, AssertionError ...)
        raise UnitError(f"{what}: cannot read {value!r}{' with unit ' + unit if unit else ''} as a quantity "
                        f"(a number and a unit, e.g. \"260 mm\" or \"1.89 N/mm\")") from None
