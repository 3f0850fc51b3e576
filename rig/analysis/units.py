"""Display units: the unit a person reads a quantity in (report, CSV files, console, NOK reasons).

Everything is recorded and computed in SI (m, N, rad, N·m, s). What is *shown* follows the scene:

1. a device channel (X, Y, Y2) is shown in the unit the scene writes that channel's values in: the most
   frequent unit among the quantities of its ``[device.config]`` (control values, elements, limits) that
   convert to the channel's engineering unit (``x_max = "43 mm"`` → X in mm; ties: the first written);
2. every other quantity is shown in the unit of a channel of its kind if there is one (lengths as the length
   channel), else in the unit the whole scene writes quantities of its kind in most often (a clutch scene
   writing ``omega0 = "110.5 rad/s"`` shows speeds in rad/s; times always in s), else in :data:`DEFAULTS` by
   dimension — mm,
   N, °, N·m, rpm, s — and in its SI unit when the dimension is not listed.

:class:`Unit` converts (``unit(si_values)``) and labels (``label`` for people, ``ascii`` for CSV headers).
"""
from __future__ import annotations

import tomllib
from collections import Counter
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Iterable, Mapping

import numpy as np

from rig.units import ureg

# display unit by SI unit (the fallback of rule 2)
DEFAULTS = {"m": "mm", "N": "N", "rad": "deg", "N*m": "N*m", "J": "J", "s": "s", "rad/s": "rpm", "m/s": "mm/s",
            "m/s^2": "mm/s^2", "m/m": "um/m", "1": ""}
_LABELS = {"degree": ("°", "deg"), "meter * newton": ("N·m", "N*m"), "revolutions_per_minute": ("rpm", "rpm"),
           "micrometer / meter": ("µm/m", "um/m"), "millimeter / second ** 2": ("mm/s²", "mm/s^2"),
           "micrometer": ("µm", "um"),
           "dimensionless": ("", "")}
_ASCII = {label: ascii_ for label, ascii_ in _LABELS.values() if label}     # display label → pint text
_ANGLES = ("radian", "degree", "turn", "revolution", "arcminute", "arcsecond", "grad")

# SI units of the plants' truth signals (rig.plants: cam bar level 1/2, clutch stand and static rig, lab bench)
SIGNAL_SI = {
    "phi_in": "rad", "phi_out": "rad", "omega_in": "rad/s", "omega_out": "rad/s", "alpha_in": "rad/s^2", "alpha_out": "rad/s^2",
    "phi": "rad", "cam_angle": "rad", "psi": "rad", "theta": "rad", "psi_kin": "rad", "pressure_angle": "rad",
    "phi1": "rad", "phi3": "rad", "phi_r": "rad", "angle": "rad",
    "omega": "rad/s", "omega1": "rad/s", "omega3": "rad/s", "omega_r": "rad/s", "alpha": "rad/s^2",
    "s": "m", "x_gripper": "m", "r": "m", "delta_w": "m", "delta_o": "m", "v": "m/s", "a": "m/s^2",
    "F_rod": "N", "rod_tension": "N", "R23": "N", "F_c": "N", "F_a": "N", "N_B": "N", "force": "N",
    "M23": "N*m", "M_e": "N*m", "M_sigma": "N*m", "drive_torque": "N*m", "M1": "N*m", "M3": "N*m",
    "M_t": "N*m", "T_c": "N*m", "T_in": "N*m", "T_out": "N*m", "torque": "N*m", "shaft_torque": "N*m",
    "motor_speed": "rad/s", "relative_angle": "rad", "lever_force": "N", "leaf_strain": "m/m", "contact_force": "N",
}
#: what each plant truth signal is, for chart legends (the recorded name stays the key)
SIGNAL_LABEL = {
    "cam_angle": "cam angle φ (wrapped)", "phi": "cam angle φ", "psi": "follower angle ψ",
    "psi_kin": "ψ of level 0", "omega": "cam speed", "s": "stroke s",
    "delta_w": "penetration, working flank", "delta_o": "penetration, other flank", "R23": "contact force R23",
    "F_rod": "rod force", "M_sigma": "cam moment on the follower, with spring M_Σ", "drive_torque": "drive torque needed",
    "motor_speed": "motor speed (at the cam)", "shaft_torque": "torque in the shaft",
    "phi1": "driving half φ1", "phi3": "driven half φ3", "phi_r": "relative angle φ1 − φ3",
    "omega1": "driving half ω1", "omega3": "driven half ω3", "omega_r": "relative speed", "M1": "motor torque",
    "M3": "load torque", "M_t": "torque-meter shaft", "T_c": "coupling torque", "F_a": "spring force",
    "N_B": "cam normal force N_B", "phi_in": "input angle", "phi_out": "output angle", "omega_in": "input speed",
    "omega_out": "output speed", "alpha_in": "input acceleration", "alpha_out": "output acceleration", "v": "speed v",
    "a": "acceleration a", "torque": "input torque", "relative_angle": "relative angle",
    "contact_force": "cam–follower contact force the law needs (< 0: it would lift off)",
    "lever_force": "loading-lever force", "leaf_strain": "leaf-spring strain",
}
#: a plant's own meaning of a signal name several plants record (the ``plant`` of the recording's metadata)
PLANT_SIGNAL_LABEL = {
    "cam_bar": {"s": "stroke s of the slider (gripper)", "v": "slider speed", "a": "slider acceleration"},
    "lab_bench": {"s": "follower stroke s", "v": "follower speed", "a": "follower acceleration"},
}


def signal_label(name: str, plant: str | None = None) -> str | None:
    """What the truth signal ``name`` is, for a chart legend: the plant's own meaning
    (:data:`PLANT_SIGNAL_LABEL`), else :data:`SIGNAL_LABEL`; None for a signal without one."""
    return PLANT_SIGNAL_LABEL.get(plant or "", {}).get(name, SIGNAL_LABEL.get(name))
QUANTITY = {"m": "length", "N": "force", "rad": "angle", "N*m": "torque", "s": "time", "rad/s": "angular speed",
            "rad/s^2": "angular acceleration", "m/s": "speed", "m/s^2": "acceleration", "m/m": "strain",
            "1": "number"}


def _is_angle(unit: str) -> bool:
    return any(w in str(ureg.Unit(unit)) for w in _ANGLES)


@lru_cache(maxsize=None)
def _kind(unit: str) -> tuple[str, bool]:
    """What a unit measures: its dimensionality and whether it is (or contains) an angle."""
    u = ureg.Unit(unit)
    return str(u.dimensionality), _is_angle(unit)


def same_kind(a: str, b: str) -> bool:
    """Whether units ``a`` and ``b`` measure the same quantity (mm and m yes; ° and a pure number no)."""
    try:
        return _kind(a) == _kind(b)
    except Exception:  # pint raises several unrelated types for unit text it cannot read
        return False


NOISE_FLOOR = 1e-9    # display units: smaller values are rounding noise (no instrument or model resolves them)


@dataclass(frozen=True)
class Unit:
    """A display unit: ``label`` (``"mm"``, ``"°"``, ``"N·m"``), ``ascii`` (``"deg"``, ``"N*m"``) and
    ``factor`` (display value = SI value × factor) of the SI unit ``si``."""

    label: str
    ascii: str
    factor: float
    si: str

    def __call__(self, value: Any) -> Any:
        """SI value(s) in this unit (floats stay floats, None stays None, arrays become arrays)."""
        if value is None:
            return None
        if isinstance(value, (int, float)):
            return float(value) * self.factor if self.factor != 1.0 else float(value)
        return np.asarray(value, dtype=float) * self.factor

    def text(self, value: float | None, digits: int = 4) -> str:
        """``"41.2 mm"`` (``digits`` significant digits) of an SI value; a dash for None; a value below
        :data:`NOISE_FLOOR` in this unit is 0 (a root found at 0° reads "0°", not "-2.172e-14°")."""
        if value is None or not np.isfinite(value):
            return "—"
        shown = self(value)
        number = f"{shown if abs(shown) >= NOISE_FLOOR else 0.0:.{digits}g}"
        return f"{number} {self.label}".rstrip() if self.label not in ("°",) else f"{number}°"

    def axis(self, quantity: str) -> str:
        """Axis label ``"quantity (unit)"``."""
        return f"{quantity} ({self.label})" if self.label else quantity


@lru_cache(maxsize=None)
def unit(si: str, display: str | None = None) -> Unit:
    """The :class:`Unit` showing SI unit ``si`` in ``display`` (default :data:`DEFAULTS`, else SI)."""
    if display is None:
        display = next((d for s, d in DEFAULTS.items() if s == si), None)
        if display is None:
            display = next((d for s, d in DEFAULTS.items() if same_kind(s, si) and s != "1"), si)
    if si in ("", "1") or display in ("", "1"):
        return Unit("", "", 1.0, si or "1")
    pu = ureg.Unit(display)
    label, text = _LABELS.get(str(pu), (f"{pu:~P}", f"{pu:~C}".replace("**", "^")))   # m/s^2 as mm/s^2, not m/s**2
    factor = float(ureg.Quantity(1.0, si).to(pu).magnitude)
    return Unit(label, text, 1.0 if abs(factor - 1.0) < 1e-15 else factor, si)


SI_TIME = unit("s")


def _strings(node: Any) -> Iterable[str]:
    """Every string in a nested TOML table (depth first, in writing order)."""
    if isinstance(node, str):
        yield node
    elif isinstance(node, Mapping):
        for v in node.values():
            yield from _strings(v)
    elif isinstance(node, (list, tuple)):
        for v in node:
            yield from _strings(v)


@lru_cache(maxsize=256)
def _quantity_unit(text: str) -> str | None:
    """The unit a quantity string is written in (``"43 mm"`` → ``"millimeter"``); None if it is not one, nor is a
    unit alone (a channel's ``unit = "rad"``: its coherent SI unit, not how the scene writes its values)."""
    if not any(c.isdigit() for c in text):
        return None
    try:
        q = ureg.Quantity(text)
    except Exception:  # not a quantity (names, modes): pint raises many kinds
        return None
    if not isinstance(q, ureg.Quantity) or str(q.units) == "dimensionless":
        return None
    return str(q.units)


def written_units(config: Mapping | None, si: str) -> str | None:
    """The unit ``config`` writes quantities of SI unit ``si`` in most often (ties: the first); None if none."""
    if not config or si in ("", "1"):
        return None
    counts: Counter[str] = Counter(u for u in (_quantity_unit(s) for s in _strings(config))
                                   if u is not None and same_kind(u, si))
    return max(counts, key=lambda u: counts[u]) if counts else None   # Counter keeps first-seen order on ties


@dataclass
class DisplayUnits:
    """Display units of one program's channels (``channels``: ``{"x": Unit, "y": Unit, …}``) and of
    everything else (:meth:`of`); ``axes``: which channel each process value lies on (``t`` for time,
    ``""`` for pure numbers)."""

    channels: dict[str, Unit] = field(default_factory=dict)
    axes: dict[str, str] = field(default_factory=dict)
    scene: Mapping | None = None          # the scene's whole table: the units it writes (rule 2)

    def of(self, si: str) -> Unit:
        """Display unit of any SI unit: that of a channel of the same kind, else the scene's, else the default."""
        for u in self.channels.values():
            if u.si == si or same_kind(u.si, si):
                return u if u.si == si else unit(si, pint_label(u.label))
        written = written_units(self.scene, si) if si != "s" else None     # times stay in s (durations in ms)
        if written is not None:
            try:
                return unit(si, written)
            except Exception:  # a unit pint reads but cannot convert to (offset units…): the default
                pass
        return unit(si)

    def channel(self, ch: str) -> Unit:
        return self.channels.get(ch) or unit("1")

    def value(self, name: str) -> Unit:
        """Display unit of a process value (``x_max``, ``duration``, ``insertion.x_entry`` …)."""
        axis = self.axes.get(name) or _axis_of_name(name)
        if axis == "t":
            return SI_TIME
        return self.channels.get(axis) or unit("1")

    def signal(self, name: str) -> Unit:
        """Display unit of a plant truth signal (:data:`SIGNAL_SI`; unknown names stay unconverted)."""
        si = SIGNAL_SI.get(name)
        return self.of(si) if si is not None else Unit("SI", "SI", 1.0, "?")


def pint_label(label: str) -> str:
    """A display unit's label as pint reads it ("°" → "deg", "N·m" → "N*m", "µm" → "um")."""
    return _ASCII.get(label, label.replace("·", "*"))


def _axis_of_name(name: str) -> str:
    """Channel of a process value by its name alone (element values without a program: by their first letter)."""
    if name == "duration":
        return "t"
    if name == "pairs":
        return ""
    base = name.split(".", 1)[-1]
    return "y2" if base.startswith("y2") else base[:1]


def configured_units(config: Mapping | None) -> dict[str, str]:
    """Channel units a scene's raw ``[device.config]`` sets, over the unit's factory X (m) and Y (N), a channel it
    disables left out: the units of a program the host did not read back (the serial link off; the schemas say
    "rad" where the report said mm)."""
    written = (config or {}).get("channels")
    out = {"x": "m", "y": "N"}
    for ch, c in (written.items() if isinstance(written, Mapping) else ()):
        if isinstance(c, Mapping) and c.get("enabled", True) is False:
            out.pop(ch, None)
        elif isinstance(c, Mapping) and isinstance(c.get("unit"), str):
            out[ch] = c["unit"]
    return out


def display_units(program: Mapping | None, scene_config: Mapping | None = None,
                  scene: Mapping | None = None) -> DisplayUnits:
    """Display units of a program (normalised, as the device returns it: ``channels.<ch>.unit`` and
    ``elements``) written by ``scene_config`` (the scene's raw ``[device.config]``, for rule 1) in ``scene``
    (the whole raw scene, for rule 2)."""
    program = program or {}
    channels = {ch: c.get("unit") for ch, c in (program.get("channels") or {}).items()
                if isinstance(c, Mapping) and c.get("enabled", True) and c.get("unit")}
    channels = channels or configured_units(scene_config)
    shown = {}
    for ch, si in channels.items():
        try:
            shown[ch] = unit(si, written_units(scene_config, si))
        except Exception:  # an engineering unit pint cannot read: show it as it is
            shown[ch] = Unit(si, si, 1.0, si)
    return DisplayUnits(shown, _axes(program, set(channels)), scene)


def _axes(program: Mapping, channels: set[str]) -> dict[str, str]:
    """Channel of every process value of the program (see firmware_sim.digiforce.curve.process_value_axes)."""
    try:
        from firmware_sim.digiforce.curve import process_value_axes
        return process_value_axes(list(program.get("elements") or []), "y2" in channels)
    except Exception:  # a program from elsewhere (hand-made recordings): names decide (_axis_of_name)
        return {}


def scene_device_config(scene_text: str | None) -> tuple[int | None, Mapping | None, Mapping | None]:
    """(program number, raw ``[device.config]``, the whole raw scene) of a scene's text; Nones where it has
    none."""
    if not scene_text:
        return None, None, None
    try:
        scene = tomllib.loads(scene_text)
    except tomllib.TOMLDecodeError:
        return None, None, None
    device = scene.get("device") if isinstance(scene.get("device"), Mapping) else {}
    config = device.get("config")
    return device.get("program"), config if isinstance(config, Mapping) else None, scene


def recording_units(rec: Any, program: int) -> DisplayUnits:
    """Display units of ``program`` in a recording (its program attachment and the scene that wrote it; the scene's
    ``[device] program`` defaults to 0, as the run's)."""
    number, config, scene = scene_device_config(getattr(rec, "scene_text", None))
    return display_units(rec.programs.get(program), config if (number or 0) == program else None, scene)
