"""The unit's description as data (``data/devices/digiforce_9310.toml``): ranges, steps, figures."""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.scene import Field, SceneError, read_table
from rig.units import UnitError, to_si

from .errors import DigiForceError

DEFAULT_PATH = Path(__file__).resolve().parents[2] / "data" / "devices" / "digiforce_9310.toml"
CHANNELS = ("x", "y", "y2")
QUANTITY_UNITS = {"ratio": "1", "voltage": "V"}

UNIT_SCHEMA = {
    "model": Field(None), "serial_number": Field(None), "firmware": Field(None),
    "programs": Field("1"), "max_rate": Field("Hz"), "curve_memory": Field("1"),
    "evaluation_time": Field("s"), "cutoff_steps": Field(None), "filter_order": Field("1"),
    "adc_bits": Field("1"), "noise_lsb": Field("1"), "has_y2": Field(None, False),
}
INPUT_SCHEMA = {
    "channels": Field(None), "quantity": Field(None), "ranges": Field(None), "excitations": Field(None),
    "resistance_min": Field("ohm"), "resistance_max": Field("ohm"), "max_current": Field("A"),
    "accuracy": Field("1"),
}


@dataclass(frozen=True)
class InputType:
    """One input type: allowed ranges (V/V or V), excitations (V), sensor resistance (ohm), accuracy."""

    name: str
    channels: tuple[str, ...]
    quantity: str
    ranges: tuple[float, ...]
    excitations: tuple[float, ...]
    resistance_min: float
    resistance_max: float
    max_current: float
    accuracy: float

    @property
    def electrical_unit(self) -> str:
        return QUANTITY_UNITS[self.quantity]


@dataclass(frozen=True)
class Description:
    """The whole unit: identity, capacities (rates in 1/s, times in s) and its input types."""

    model: str
    serial_number: str
    firmware: str
    programs: int
    max_rate: float
    curve_memory: int
    evaluation_time: float
    cutoff_steps: tuple[float, ...]
    filter_order: int
    adc_bits: int
    noise_lsb: float
    has_y2: bool
    inputs: dict[str, InputType]

    def channels(self) -> tuple[str, ...]:
        return CHANNELS if self.has_y2 else CHANNELS[:2]

    def inputs_for(self, channel: str) -> list[str]:
        return [name for name, inp in self.inputs.items() if channel in inp.channels]


def _quantities(values: Any, unit: str, where: str) -> tuple[float, ...]:
    if not isinstance(values, list) or not values:
        raise DigiForceError(f"{where}: expected a non-empty list of quantities in {unit}")
    try:
        return tuple(sorted(to_si(v, unit, what=where) for v in values))
    except UnitError as exc:
        raise DigiForceError(str(exc)) from None


def _integer(value: float, where: str, minimum: int) -> int:
    if value != int(value) or value < minimum:
        raise DigiForceError(f"{where}: expected an integer >= {minimum}, got {value}")
    return int(value)


def parse_description(data: dict[str, Any], where: str = "device description") -> Description:
    """Validate a description tree (as read from TOML) and return it in SI."""
    try:
        unit = read_table(data.get("unit", {}), UNIT_SCHEMA, f"{where} [unit]")
        raw_inputs = data.get("inputs")
        if not isinstance(raw_inputs, dict) or not raw_inputs:
            raise DigiForceError(f"{where}: missing [inputs.*] tables")
        inputs = {}
        for name, table in raw_inputs.items():
            w = f"{where} [inputs.{name}]"
            t = read_table(table, INPUT_SCHEMA, w)
            if t["quantity"] not in QUANTITY_UNITS:
                raise DigiForceError(f"{w}: quantity must be one of {sorted(QUANTITY_UNITS)}, got {t['quantity']!r}")
            channels = t["channels"]
            if not isinstance(channels, list) or not set(channels) <= set(CHANNELS) or not channels:
                raise DigiForceError(f"{w}: channels must be a list drawn from {CHANNELS}, got {channels!r}")
            inputs[name] = InputType(
                name=name, channels=tuple(channels), quantity=t["quantity"],
                ranges=_quantities(t["ranges"], QUANTITY_UNITS[t["quantity"]], f"{w} ranges"),
                excitations=_quantities(t["excitations"], "V", f"{w} excitations"),
                resistance_min=t["resistance_min"], resistance_max=t["resistance_max"],
                max_current=t["max_current"], accuracy=t["accuracy"])
    except SceneError as exc:
        raise DigiForceError(str(exc)) from None
    steps = _quantities(unit["cutoff_steps"], "Hz", f"{where} [unit] cutoff_steps")
    desc = Description(
        model=str(unit["model"]), serial_number=str(unit["serial_number"]), firmware=str(unit["firmware"]),
        programs=_integer(unit["programs"], f"{where} [unit] programs", 1), max_rate=unit["max_rate"],
        curve_memory=_integer(unit["curve_memory"], f"{where} [unit] curve_memory", 2),
        evaluation_time=unit["evaluation_time"], cutoff_steps=steps,
        filter_order=_integer(unit["filter_order"], f"{where} [unit] filter_order", 1),
        adc_bits=_integer(unit["adc_bits"], f"{where} [unit] adc_bits", 2), noise_lsb=unit["noise_lsb"],
        has_y2=bool(unit["has_y2"]), inputs=inputs)
    for ch in desc.channels():
        if not desc.inputs_for(ch):
            raise DigiForceError(f"{where}: no input type serves channel {ch!r}")
    return desc


def load_description(description: dict | str | Path | None = None) -> Description:
    """A description from a dict, a TOML file path, or the default ``digiforce_9310.toml``."""
    if isinstance(description, dict):
        return parse_description(description)
    path = DEFAULT_PATH if description is None else Path(description)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise DigiForceError(f"cannot read device description {path}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise DigiForceError(f"{path}: not valid TOML: {exc}") from None
    return parse_description(data, str(path))
