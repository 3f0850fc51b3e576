"""Static clutch rig (MODELS.md §4.4): one half clamped, torque by a weighted lever, quasi-static response.

The lever (arm L, default 1000 mm) carries a force program F(t) (piecewise linear, N), so the applied
torque is M = F·L (N·m). The clutch answers quasi-statically with Coulomb friction: the relative
angle sticks while T_unload(φ) ≤ M ≤ T_load(φ) and otherwise slides onto the loading branch (M
rising) or the unloading branch (M falling) — a play/stop operator, which yields the loading/unloading
hysteresis loop. Above the loading-branch peak the clutch disengages: an event is recorded, the angle
is held at the peak angle while overloaded and, once M falls back below the peak, the clutch has
snapped into the next lobe (angle offset by one lobe period). Truth signals (SI): ``lever_force``
(N), ``torque`` (N·m), ``relative_angle`` (rad, including slipped lobes) and, for leaf variants,
``leaf_strain`` at the strain-gauge position (m/m, read by the half-bridge + bridge amplifier).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from rig.plants.clutch.flat_tappet import CLUTCH_SCHEMA, FlatTappetClutch
from rig.plants.events import Event
from rig.plants.clutch.variants import (FlatTappetCharacteristic, LeafSpringClutch, RollerTappetClutch,
                                        RubberRollerClutch, RubberShoeClutch, StaticCharacteristic,
                                        measured_table)
from rig.scene import Field, Scene, SceneError, load_scene, read_table




#: scene [plant.clutch] schema and constructor of each variant the static rig can hold
VARIANTS: dict[str, tuple[Mapping[str, Field], Callable[[dict[str, Any]], StaticCharacteristic]]] = {
    "flat_tappet": (CLUTCH_SCHEMA, lambda p: FlatTappetCharacteristic(FlatTappetClutch(**p))),
    "leaf_spring": (LeafSpringClutch.SCHEMA, lambda p: LeafSpringClutch(**p)),
    "rubber_shoes": (RubberShoeClutch.SCHEMA, lambda p: RubberShoeClutch(**p)),
    "roller_tappet": (RollerTappetClutch.SCHEMA, lambda p: RollerTappetClutch(**p)),
    "rubber_rollers": (RubberRollerClutch.SCHEMA, lambda p: RubberRollerClutch(**p)),
    "table": ({"name": Field(None, doc="measured table in data/clutch/"),
               "through_origin": Field(None, True, "prepend the point (0, 0)")},
              lambda p: measured_table(p["name"], bool(p["through_origin"]))),
}

PLANT_SCHEMA: dict[str, Field] = {
    "variant": Field(None, doc=f"clutch variant: {', '.join(VARIANTS)}"),
    "lever_arm": Field("m", 1.0, "lever length (1000 mm on the real rig)"),
    "gauge_offset": Field("m", 0.0, "strain-gauge position on the leaf from mid-span"),
    "initial_force": Field("N", 0.0, "lever force at t = 0"),
}

STEP_SCHEMA: dict[str, Field] = {
    "duration": Field("s", doc="duration of the ramp"),
    "force": Field("N", doc="lever force at the end of the ramp"),
}


@dataclass(frozen=True)
class LeverProgram:
    """Piecewise-linear lever force: breakpoints ``times`` (s, from 0) and ``forces`` (N ≥ 0); held after."""

    times: np.ndarray
    forces: np.ndarray

    def __post_init__(self) -> None:
        if self.times.ndim != 1 or self.times.shape != self.forces.shape or self.times.size < 1:
            raise ValueError("lever program: times and forces must be matching 1-D arrays")
        if self.times[0] != 0 or np.any(np.diff(self.times) <= 0):
            raise ValueError("lever program: breakpoint times must start at 0 s and increase strictly")
        if np.any(self.forces < 0) or not np.all(np.isfinite(self.forces)):
            raise ValueError(f"lever program: forces must be finite and >= 0 N (the lever only loads one "
                             f"flank), got {self.forces[~(self.forces >= 0)][:1]} N")

    @classmethod
    def ramps(cls, initial_force: float, steps: list[tuple[float, float]]) -> "LeverProgram":
        """From a start force (N) and (duration s, end force N) ramps."""
        durations = np.array([d for d, _ in steps], dtype=float)
        if np.any(durations <= 0):
            raise ValueError("lever program: every ramp needs a duration > 0 s")
        return cls(np.concatenate(([0.0], np.cumsum(durations))),
                   np.array([initial_force] + [f for _, f in steps], dtype=float))

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def force(self, t: np.ndarray) -> np.ndarray:
        """Lever force (N) at times t (s)."""
        return np.interp(t, self.times, self.forces)


class StaticClutchRig:
    """The static rig as a plant: ``advance(t)`` → truth dict, ``events`` (see module docstring)."""

    def __init__(self, clutch: StaticCharacteristic, program: LeverProgram, lever_arm: float = 1.0,
                 gauge_offset: float = 0.0) -> None:
        if not lever_arm > 0:
            raise ValueError(f"static rig: lever arm {lever_arm!r} m must be > 0")
        self.clutch, self.program, self.lever_arm, self.gauge_offset = clutch, program, lever_arm, gauge_offset
        self.events: list[Event] = []
        self._phi = clutch.phi_min          # local angle inside the current lobe (rad)
        self._lobe = 0
        self._overloaded = False
        self._t_last = -math.inf
        self._leaf = isinstance(clutch, LeafSpringClutch)
        if self._leaf:
            clutch.leaf_strain(clutch.phi_min, gauge_offset)   # validates the gauge position

    @property
    def duration(self) -> float:
        """Length of the loading program (s)."""
        return self.program.duration

    def _limits(self, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Angle bounds of the stuck band for torques ``m`` below the loading peak (rad)."""
        c = self.clutch
        if not c.has_friction:
            phi = c.angle(m, 0.0, clip_low=True)
            return phi, phi
        lo = c.angle(m, 1.0, clip_low=True)
        t_peak_u = c.branch_peak(-1.0)[1]
        hi = np.where(m <= t_peak_u, c.angle(np.minimum(m, t_peak_u), -1.0, clip_low=True), np.inf)
        return lo, hi

    def advance(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """Truth at increasing times t (s), continuing from the previous call."""
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or (t.size and (t[0] <= self._t_last or np.any(np.diff(t) <= 0))):
            raise ValueError(f"static rig: times must be 1-D, strictly increasing and after t = {self._t_last} s")
        c = self.clutch
        force = self.program.force(t)
        torque = force * self.lever_arm
        phi_peak, t_peak = c.branch_peak(1.0)
        phi_peak_u = c.branch_peak(-1.0)[0] if c.has_friction else phi_peak
        engaged = torque <= t_peak
        lo = np.full(t.shape, phi_peak)
        hi = np.full(t.shape, phi_peak)
        if np.any(engaged):
            lo[engaged], hi[engaged] = self._limits(torque[engaged])
        local = np.empty(t.shape)
        lobes = np.empty(t.shape)
        phi, lobe, over = self._phi, self._lobe, self._overloaded
        for i in range(t.size):
            if not engaged[i]:
                if not over:
                    self.events.append(Event(float(t[i]), "disengagement",
                                             {"torque": float(torque[i]), "peak_torque": t_peak, "lobe": lobe}))
                    over = True
                phi = phi_peak
            else:
                if over:             # snapped over the apex into the next lobe
                    lobe, phi, over = lobe + 1, c.phi_min, False
                    self.events.append(Event(float(t[i]), "reengaged", {"torque": float(torque[i]), "lobe": lobe}))
                stuck_past_peak = (c.has_friction and phi > phi_peak_u
                                   and torque[i] >= float(c.torque(phi, -1.0)) and torque[i] <= float(c.torque(phi, 1.0)))
                if not stuck_past_peak:
                    phi = min(max(phi, lo[i]), hi[i])
            local[i], lobes[i] = phi, lobe
        self._phi, self._lobe, self._overloaded = phi, lobe, over
        if t.size:
            self._t_last = float(t[-1])
        out = {"lever_force": force, "torque": torque, "relative_angle": lobes * c.period + local}
        if self._leaf:
            out["leaf_strain"] = c.leaf_strain(local, self.gauge_offset)
        return out


def _where(scene: Scene, section: str) -> str:
    return f"{scene.path} [{section}]"


def rig_from_scene(scene: Scene) -> StaticClutchRig:
    """Build the static rig from a scene ([plant], [plant.clutch], [[program]]); errors name file and key."""
    plant = scene.read("plant", PLANT_SCHEMA, allow_tables=True)
    variant = plant["variant"]
    if variant not in VARIANTS:
        raise SceneError(f"{_where(scene, 'plant')}: key 'variant' = {variant!r} is not one of {', '.join(VARIANTS)}")
    extra = set(plant) - set(PLANT_SCHEMA) - {"clutch"}
    if extra:
        raise SceneError(f"{_where(scene, 'plant')}: unknown sub-table(s) {sorted(extra)} (only [plant.clutch])")
    schema, build = VARIANTS[variant]
    params = scene.read("plant.clutch", schema)
    try:
        clutch = build(params)
    except ValueError as exc:
        raise SceneError(f"{_where(scene, 'plant.clutch')}: {exc}") from None
    steps_raw = scene.data.get("program")
    if not isinstance(steps_raw, list) or not steps_raw or not all(isinstance(s, dict) for s in steps_raw):
        raise SceneError(f"{scene.path}: missing or malformed [[program]] (an array of tables with "
                         f"'duration' and 'force' keys giving the lever-force ramps)")
    steps = []
    for i, raw in enumerate(steps_raw, start=1):
        s = read_table(raw, STEP_SCHEMA, f"{scene.path} [[program]] #{i}")
        if not s["duration"] > 0 or not s["force"] >= 0:
            raise SceneError(f"{scene.path} [[program]] #{i}: need duration > 0 s and force >= 0 N, "
                             f"got {s['duration']} s, {s['force']} N")
        steps.append((s["duration"], s["force"]))
    if not plant["initial_force"] >= 0:
        raise SceneError(f"{_where(scene, 'plant')}: key 'initial_force' must be >= 0 N")
    try:
        return StaticClutchRig(clutch, LeverProgram.ramps(plant["initial_force"], steps), plant["lever_arm"],
                               plant["gauge_offset"])
    except ValueError as exc:
        raise SceneError(f"{_where(scene, 'plant')}: {exc}") from None


def load_static_rig(path: str | Path) -> StaticClutchRig:
    """Load a ``data/scenes/clutch_static*.toml`` scene and build its rig."""
    return rig_from_scene(load_scene(path))
