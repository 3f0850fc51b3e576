"""Measurement programs: validation of a program's settings and the factory default program.

A program is a JSON-serialisable dict (see docs/digiforce.md). Quantities are SI numbers or strings
with units (``"2 mm"``); X values are in the X channel's engineering unit, Y values in the Y one's.
:func:`validate_program` returns the complete, normalised program (all numbers in SI).
:func:`check_units` is the stricter check of a program a person wrote (a scene's ``[device.config]``):
there every quantity carries its unit.
"""
from __future__ import annotations

import copy
from typing import Any, Mapping

from rig.units import ureg

from . import checks
from .description import Description
from .curve import process_value_units
from .elements import normalize_elements
from .errors import DigiForceError

START_MODES = ("command", "external", "x", "y")
STOP_MODES = ("command", "external", "x", "y", "time")
SAMPLING_MODES = {"time": "s", "dx": "x", "dy": "y"}
OVERFLOW_POLICIES = ("stop", "decimate")
REFERENCE_MODES = ("absolute", "y_threshold", "end")
DIRECTIONS = ("rising", "falling")


def default_program(number: int, desc: Description) -> dict[str, Any]:
    """Factory setting: X LVDT 0...5 V = 0...100 mm, Y bridge 1.5 mV/V = 1000 N, control by command."""
    return validate_program({
        "name": f"program {number}",
        "channels": {
            "x": {"input": "voltage", "range": 10.0, "excitation": 5.0, "sensor_resistance": 1000.0,
                  "cutoff": 1000.0, "unit": "m",
                  "scaling": {"mode": "sensitivity", "electrical": 5.0, "engineering": 0.1}},
            "y": {"input": "bridge", "range": 2e-3, "excitation": 5.0, "sensor_resistance": 350.0,
                  "cutoff": 1000.0, "unit": "N",
                  "scaling": {"mode": "sensitivity", "electrical": 1.5e-3, "engineering": 1000.0}},
        },
    }, desc)


def _engineering_unit(value: Any, where: str) -> str:
    if not isinstance(value, str):
        raise DigiForceError(f"{where}: expected a unit string such as 'N' or 'm', got {value!r}")
    try:
        factor = ureg.Quantity(1.0, value).to_base_units().magnitude
    except Exception:  # pint raises several unrelated types for bad unit text
        raise DigiForceError(f"{where}: unknown unit {value!r}") from None
    if abs(factor - 1.0) > 1e-12:
        raise DigiForceError(f"{where}: engineering unit must be coherent SI (N, m, rad, N*m, ...), got {value!r}")
    return value


def _scaling(cfg: Any, electrical_unit: str, unit: str, where: str) -> dict[str, Any]:
    checks.known_keys(cfg, ("mode", "electrical", "engineering", "zero", "points"), where)
    mode = checks.choice(cfg, "mode", ("sensitivity", "teach"), where, "sensitivity")
    if mode == "sensitivity":
        checks.known_keys(cfg, ("mode", "electrical", "engineering", "zero"), where)
        out = {"mode": mode,
               "electrical": checks.number(cfg, "electrical", electrical_unit, where),
               "engineering": checks.number(cfg, "engineering", unit, where),
               "zero": checks.number(cfg, "zero", electrical_unit, where, 0.0)}
        if out["electrical"] == 0 or out["engineering"] == 0:
            raise DigiForceError(f"{where}: electrical and engineering full-scale values must be non-zero")
        return out
    checks.known_keys(cfg, ("mode", "points"), where)
    points = cfg.get("points")
    if not isinstance(points, (list, tuple)) or len(points) != 2 or any(
            not isinstance(p, (list, tuple)) or len(p) != 2 for p in points):
        raise DigiForceError(f"{where}.points: expected two [electrical, engineering] pairs, got {points!r}")
    pts = [[checks.quantity(p[0], electrical_unit, f"{where}.points[{i}][0]"),
            checks.quantity(p[1], unit, f"{where}.points[{i}][1]")] for i, p in enumerate(points)]
    if pts[0][0] == pts[1][0] or pts[0][1] == pts[1][1]:
        raise DigiForceError(f"{where}.points: the two teach points must differ in both coordinates, got {pts}")
    return {"mode": mode, "points": pts}


def scaling_line(sc: Mapping[str, Any]) -> tuple[float, float]:
    """(scale, zero) of a validated scaling: engineering = (electrical − zero)·scale."""
    if sc["mode"] == "sensitivity":
        return sc["engineering"] / sc["electrical"], sc["zero"]
    (e1, v1), (e2, v2) = sc["points"]
    scale = (v2 - v1) / (e2 - e1)
    return scale, e1 - v1 / scale


def span(channel: Mapping[str, Any]) -> float:
    """Width of a validated channel's measuring range in its engineering unit: the electrical range ±range through
    its scaling (tare shifts it, never widens it)."""
    return abs(2.0 * channel["range"] * scaling_line(channel["scaling"])[0])


def _channel(name: str, cfg: Any, desc: Description, where: str) -> dict[str, Any]:
    keys = ("enabled", "input", "range", "excitation", "sensor_resistance", "cutoff", "unit", "scaling",
            "tare_at_start")
    checks.known_keys(cfg, keys, where)
    enabled = checks.flag(cfg, "enabled", where, True)
    inp = desc.inputs[checks.choice(cfg, "input", desc.inputs_for(name), where)]
    unit = _engineering_unit(cfg.get("unit"), f"{where}.unit")
    rng = checks.pick_step(checks.number(cfg, "range", inp.electrical_unit, where), inp.ranges, f"{where}.range")
    exc = checks.pick_step(checks.number(cfg, "excitation", "V", where, inp.excitations[-1]), inp.excitations,
                           f"{where}.excitation")
    res = checks.number(cfg, "sensor_resistance", "ohm", where, inp.resistance_max, minimum=0.0)
    if exc > 0:
        if not inp.resistance_min <= res <= inp.resistance_max:
            raise DigiForceError(f"{where}.sensor_resistance: {res:g} ohm outside the input's "
                                 f"{inp.resistance_min:g}...{inp.resistance_max:g} ohm")
        if exc / res > inp.max_current * (1 + 1e-12):
            raise DigiForceError(f"{where}: excitation {exc:g} V into {res:g} ohm draws {exc / res * 1e3:.3g} mA, "
                                 f"more than the input's {inp.max_current * 1e3:g} mA")
    cutoff_raw = cfg.get("cutoff", 0.0)
    cutoff = 0.0 if cutoff_raw in (0, "off", None) else checks.pick_step(
        checks.quantity(cutoff_raw, "Hz", f"{where}.cutoff"), desc.cutoff_steps, f"{where}.cutoff")
    return {"enabled": enabled, "input": inp.name, "range": rng, "excitation": exc, "sensor_resistance": res,
            "cutoff": cutoff, "unit": unit,
            "scaling": _scaling(cfg.get("scaling", {}), inp.electrical_unit, unit, f"{where}.scaling"),
            "tare_at_start": checks.flag(cfg, "tare_at_start", where, False)}


def _trigger(cfg: Any, modes: tuple[str, ...], units: Mapping[str, str], where: str) -> dict[str, Any]:
    checks.known_keys(cfg, ("mode", "value", "direction", "hysteresis", "duration"), where)
    mode = checks.choice(cfg, "mode", modes, where, "command")
    out: dict[str, Any] = {"mode": mode}
    if mode in ("x", "y"):
        out["value"] = checks.number(cfg, "value", units[mode], where)
        out["direction"] = checks.choice(cfg, "direction", DIRECTIONS, where, "rising")
        out["hysteresis"] = checks.number(cfg, "hysteresis", units[mode], where, default=0.0, minimum=0.0)
    elif mode == "time":
        out["duration"] = checks.number(cfg, "duration", "s", where, positive=True)
    extra = set(cfg) - set(out)
    if extra:
        raise DigiForceError(f"{where}: key {sorted(extra)[0]!r} does not apply to mode {mode!r}")
    return out


def _limits(cfg: Any, units: Mapping[str, str], where: str) -> dict[str, list[float | None]]:
    """``{process value: [lower, upper]}``, each bound a quantity in the value's unit (``units``; X values in
    the X channel's unit, Y values in the Y one's, ``duration`` in s, ``pairs`` a pure number)."""
    if not isinstance(cfg, Mapping):
        raise DigiForceError(f"{where}: expected a table/dict of [lower, upper] pairs, got {cfg!r}")
    out = {}
    for key, pair in cfg.items():
        if key not in units:
            raise DigiForceError(f"{where}: {key!r} is not a process value of this program "
                                 f"(known: {', '.join(sorted(units))})")
        if not isinstance(pair, (list, tuple)) or len(pair) != 2 or list(pair) == [None, None]:
            raise DigiForceError(f"{where}.{key}: expected [lower, upper] (one may be null), got {pair!r}")
        lo, hi = (None if v is None else checks.quantity(v, units[key], f"{where}.{key} ({side})")
                  for v, side in zip(pair, ("lower", "upper")))
        if lo is not None and hi is not None and not lo < hi:
            raise DigiForceError(f"{where}.{key}: lower limit {checks.written(pair[0], units[key])} must be below "
                                 f"upper limit {checks.written(pair[1], units[key])}")
        out[key] = [lo, hi]
    return out


SWITCH_KEYS = ("input", "mode")


def merge(base: Mapping[str, Any], update: Mapping[str, Any]) -> dict[str, Any]:
    """``update`` over ``base``: dicts merge key by key, anything else (lists too) replaces, null removes the key (as
    a JSON merge patch, RFC 7386: ``"limits": {"x_max": null}`` removes that limit; a removed setting takes its
    default). A dict that switches ``input`` or ``mode`` to another value replaces the old one (its settings do not
    carry over)."""
    out = copy.deepcopy(dict(base))
    for key, value in update.items():
        if value is None:
            out.pop(key, None)
            continue
        old = out.get(key)
        switched = isinstance(value, Mapping) and isinstance(old, Mapping) and any(
            k in value and value[k] != old.get(k) for k in SWITCH_KEYS)
        if isinstance(value, Mapping) and isinstance(old, Mapping) and not switched:
            out[key] = merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def validate_program(cfg: Any, desc: Description, where: str = "program") -> dict[str, Any]:
    """Check a complete program and return it normalised (SI numbers, defaults filled in)."""
    checks.known_keys(cfg, ("name", "channels", "control", "sampling", "reference", "elements", "limits"), where)
    name = checks.text(cfg, "name", where, "program")
    chans_cfg = cfg.get("channels", {})
    checks.known_keys(chans_cfg, desc.channels(), f"{where}.channels")
    channels = {}
    for ch in desc.channels():
        if ch not in chans_cfg and ch == "y2":
            channels[ch] = {"enabled": False}
            continue
        if ch not in chans_cfg:
            raise DigiForceError(f"{where}.channels: missing channel {ch!r}")
        if ch == "y2" and isinstance(chans_cfg[ch], Mapping) and chans_cfg[ch].get("enabled", True) is False:
            checks.known_keys(chans_cfg[ch], ("enabled",), f"{where}.channels.y2 (disabled)")
            channels[ch] = {"enabled": False}
            continue
        channels[ch] = _channel(ch, chans_cfg[ch], desc, f"{where}.channels.{ch}")
        if not channels[ch]["enabled"]:
            raise DigiForceError(f"{where}.channels.{ch}: channel {ch!r} cannot be disabled")
    units = {ch: c["unit"] for ch, c in channels.items() if c["enabled"]}

    control_cfg = cfg.get("control", {})
    checks.known_keys(control_cfg, ("start", "stop"), f"{where}.control")
    control = {"start": _trigger(control_cfg.get("start", {}), START_MODES, units, f"{where}.control.start"),
               "stop": _trigger(control_cfg.get("stop", {}), STOP_MODES, units, f"{where}.control.stop")}
    for which, t in control.items():
        if t["mode"] in ("x", "y") and t["hysteresis"] >= span(channels[t["mode"]]):
            raise DigiForceError(f"{where}.control.{which}.hysteresis: {t['hysteresis']:g} {units[t['mode']]} is not "
                                 f"below the whole measuring span of channel {t['mode']!r} "
                                 f"({span(channels[t['mode']]):g} {units[t['mode']]}: its range scaled): the trigger "
                                 f"could never arm")
    trig = control["start"]["mode"]
    if trig in ("x", "y") and channels[trig]["tare_at_start"]:
        raise DigiForceError(f"{where}.channels.{trig}.tare_at_start: cannot tare the channel that triggers the "
                             f"start (control.start.mode = {trig!r}); tare it by command instead")

    s_cfg = cfg.get("sampling", {})
    w = f"{where}.sampling"
    checks.known_keys(s_cfg, ("mode", "delta", "overflow"), w)
    s_mode = checks.choice(s_cfg, "mode", SAMPLING_MODES, w, "time")
    s_unit = SAMPLING_MODES[s_mode] if s_mode == "time" else units[SAMPLING_MODES[s_mode]]
    delta = checks.number(s_cfg, "delta", s_unit, w, 1.0 / desc.max_rate if s_mode == "time" else None,
                          positive=True)
    if s_mode == "time" and delta < 1.0 / desc.max_rate * (1 - 1e-9):
        raise DigiForceError(f"{w}.delta: {delta:g} s is faster than the unit's {desc.max_rate:g} pairs/s")
    sampling = {"mode": s_mode, "delta": delta, "overflow": checks.choice(s_cfg, "overflow", OVERFLOW_POLICIES, w,
                                                                          "stop")}

    r_cfg = cfg.get("reference", {})
    w = f"{where}.reference"
    checks.known_keys(r_cfg, ("mode", "y_threshold"), w)
    r_mode = checks.choice(r_cfg, "mode", REFERENCE_MODES, w, "absolute")
    reference: dict[str, Any] = {"mode": r_mode}
    if r_mode == "y_threshold":
        reference["y_threshold"] = checks.number(r_cfg, "y_threshold", units["y"], w)
    elif "y_threshold" in r_cfg:
        raise DigiForceError(f"{w}.y_threshold: only used with mode 'y_threshold', not {r_mode!r}")

    elements = normalize_elements(cfg.get("elements", []), units, f"{where}.elements")
    limits = _limits(cfg.get("limits", {}), process_value_units(elements, units), f"{where}.limits")
    return {"name": name, "channels": channels, "control": control, "sampling": sampling, "reference": reference,
            "elements": elements, "limits": limits}


def _mark_si(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {k: _mark_si(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_mark_si(v) for v in value]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return checks.NormalisedSI(value)
    return value


def check_units(base: Mapping[str, Any], config: Mapping[str, Any], desc: Description, where: str = "program") -> None:
    """Refuse a bare number where ``config`` (written by a person, e.g. a scene's ``[device.config]``) needs a
    quantity: ``limits.x_max = [0.0415, 0.0425]`` is an error naming ``limits.x_max``, ``["41.5 mm", "42.5 mm"]``
    is right. ``base``: the normalised program ``config`` is merged over (its SI numbers are the unit's own).
    Other problems are left to :func:`validate_program` (the full check that follows)."""
    with checks.units_required():
        try:
            validate_program(merge(_mark_si(base), config), desc, where)
        except checks.MissingUnitError:
            raise
        except DigiForceError:
            pass
