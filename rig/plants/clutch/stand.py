"""Dynamic clutch stand for scenes (plant = "clutch_dynamic", MODELS.md §4.4).

Motor → V-belt (ratio) → coupling under test → gear coupling → torque meter → flywheel → shoe brake.
Inertias are lumped: J1 = driving side (motor rotor·ratio² + pulleys + driving half), J3 = driven side
(driven half + gear coupling + meter + flywheel + brake drum), of which ``J_down`` lies downstream of the
torque meter (meter reading M_t = M3 + J_down·ω̇3). Apex crossings of the relative angle are
disengagements; ``shutdown_count`` of them within ``shutdown_window`` raise the shutdown flag (and,
with ``trip_on_shutdown``, switch the motor off).
"""
from __future__ import annotations

import copy
import dataclasses
import math
import warnings
from typing import Any

import numpy as np

from rig.plants.clutch.dynamics import ClutchDynamics
from rig.plants.clutch.flat_tappet import CLUTCH_SCHEMA, FlatTappetClutch
from rig.plants.clutch.leaf_dynamics import LeafDynamics
from rig.plants.clutch.loads import (LinearInSpeed, LinearMotor, Load, LoadSum, ShoeBrake, Zone, constant, shock,
                                     step)
from rig.plants.events import Event
from rig.plants.clutch.variants import LeafSpringClutch
from rig.scene import Field, Scene, SceneError, read_table
from rig.solvers import METHODS, EventRecord, StiffnessWarning, integrate
from rig.solvers.stepper import FixedStepper

STIFF = "Rodas4"      # the implicit method a run switches to when an explicit one meets stiffness

_COMMON = {
    "variant": Field(None, "flat_tappet", "coupling: flat_tappet (MODELS §4.1-4.3) or leaf_spring (§4.5)"),
    "J_down": Field("kg*m^2", 0.0, "inertia downstream of the torque meter (part of J3)"),
    "omega0": Field("rad/s", 0.0, "initial speed of both halves"),
    "phi_r0": Field("rad", None, "initial relative angle (default: the frictionless static deflection "
                                 "that carries the load torque at t = 0 and omega0)"),
    "shutdown_count": Field("1", 2, "disengagements within the window that flag a shutdown", minimum=1, integer=True),
    "shutdown_window": Field("s", 0.5, "window for counting disengagements", positive=True),
    "trip_on_shutdown": Field(None, False, "switch the motor off when the shutdown flag rises"),
    "method": Field(None, "DP45", "integration method, a name of rig.solvers.METHODS (Rodas4 for a stiff stand, e.g. "
                                  "a steep geared motor line: b0/J1 of thousands per second)"),
    "rtol": Field("1", 1e-7, "solver relative tolerance"),
    "atol": Field("1", 1e-9, "solver absolute tolerance"),
}
STAND_SCHEMA = {
    **CLUTCH_SCHEMA, **_COMMON,
    "friction": Field(None, "stick_slip", "friction model: stick_slip (switched, default) or tanh"),
    "v_s": Field("m/s", 0.01, "velocity scale of the tanh friction regularisation (friction = tanh)"),
    "blocked": Field(None, False, "driven half clamped"),
}
LEAF_STAND_SCHEMA = {
    **_COMMON,
    "leaf": Field(None, doc="the leaf-spring coupling, table [plant.leaf] (LeafSpringClutch.SCHEMA)"),
    "J1": Field("kg*m^2", doc="driving-side inertia (motor rotor through the belt, pulleys, driving half)"),
    "J3": Field("kg*m^2", doc="driven-side inertia (driven half, gear coupling, meter, flywheel, drum)"),
    "omega_s": Field("rad/s", 1.0, "relative speed regularising the lobe/leaf friction sign (tanh)"),
}


def plant_schema(scene: Scene) -> dict[str, Field]:
    """The [plant] schema of the scene's coupling variant."""
    variant = scene.section("plant").get("variant", "flat_tappet")
    if variant not in ("flat_tappet", "leaf_spring"):
        raise SceneError(f"{scene.path} [plant]: variant {variant!r} is not flat_tappet or leaf_spring")
    return LEAF_STAND_SCHEMA if variant == "leaf_spring" else STAND_SCHEMA
MOTOR_SCHEMA = {
    "a0": Field("N*m", 437.708, "motor line M = a0 - b0*omega (stall torque, + = driving direction)", minimum=0.0),
    "b0": Field("N*m*s/rad", 3.870, "motor line slope", minimum=0.0),
    "ratio": Field("1", 1.0, "belt ratio omega_motor/omega1", positive=True),
    "t_off": Field("s", math.inf, "motor switched off at this time"),
}
_LOAD_SCHEMAS = {
    "constant": ({"torque": Field("N*m")}, lambda p: constant(p["torque"])),
    "step": ({"time": Field("s"), "torque": Field("N*m")}, lambda p: step(p["time"], p["torque"])),
    "shock": ({"start": Field("s"), "duration": Field("s"), "torque": Field("N*m")},
              lambda p: shock(p["start"], p["duration"], p["torque"])),
    "zone": ({"torque": Field("N*m"), "start": Field("rad"), "end": Field("rad"), "period": Field("rad", 2 * math.pi)},
             lambda p: Zone(p["torque"], p["start"], p["end"], p["period"])),
    "linear": ({"alpha0": Field("N*m"), "beta0": Field("N*m*s/rad")}, lambda p: LinearInSpeed(p["alpha0"], p["beta0"])),
    "brake": ({"gain": Field("N*m/N"), "tau": Field("s"), "force": Field("N"), "step_time": Field("s", None),
               "step_force": Field("N", None), "pulse_start": Field("s", None), "pulse_duration": Field("s", None),
               "pulse_force": Field("N", None), "omega_s": Field("rad/s", 0.5),
               "friction": Field(None, "stick_slip", "brake friction: tanh (regularised by omega_s) or stick_slip")},
              lambda p: ShoeBrake(p["gain"], p["tau"], p["force"], *_brake_command(p), p["omega_s"], p["friction"])),
}


def _brake_command(p: dict[str, Any]) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Switch times and force levels of a brake command: ``force``, optionally a ``step_time`` to
    ``step_force``, plus an optional pulse adding ``pulse_force`` for ``pulse_duration`` from ``pulse_start``."""
    pulse = (p["pulse_start"], p["pulse_duration"], p["pulse_force"])
    if (p["step_time"] is None) != (p["step_force"] is None):
        raise ValueError("a brake step needs both step_time and step_force")
    if any(v is None for v in pulse) and any(v is not None for v in pulse):
        raise ValueError("a brake pulse needs pulse_start, pulse_duration and pulse_force")
    if pulse[1] is not None and not pulse[1] > 0:
        raise ValueError(f"brake pulse_duration must be > 0 s, got {pulse[1]} s")

    def command(t: float) -> float:
        f = p["force"] if p["step_time"] is None or t < p["step_time"] else p["step_force"]
        return f + (pulse[2] if pulse[0] is not None and pulse[0] <= t < pulse[0] + pulse[1] else 0.0)

    times = sorted({x for x in (p["step_time"], pulse[0], None if pulse[0] is None else pulse[0] + pulse[1])
                    if x is not None})
    return tuple(times), tuple(command(x) for x in times)


def load_from_tables(tables: dict[str, Any], where: str) -> LoadSum:
    """Build the load from ``[load.NAME]`` sub-tables, each with ``type`` = constant | step | shock |
    zone | linear | brake."""
    parts: list[Load] = []
    for name, table in tables.items():
        if not isinstance(table, dict):
            named = ", ".join(f"[load.{k}]" for k, v in tables.items() if isinstance(v, dict)) or "none"
            raise SceneError(f"{where}: [load] holds only load tables [load.NAME] (with type = ...); 'load.{name}' = "
                             f"{table!r} is not one (the scene's loads: {named}; set a load's key as load.NAME.KEY)")
        if "type" not in table:
            raise SceneError(f"{where}: [load.{name}] must be a table with a 'type' key")
        kind = table["type"]
        if not isinstance(kind, str) or kind not in _LOAD_SCHEMAS:
            raise SceneError(f"{where}: [load.{name}] unknown type {kind!r} (known: {', '.join(_LOAD_SCHEMAS)})")
        schema, build = _LOAD_SCHEMAS[kind]
        params = read_table({k: v for k, v in table.items() if k != "type"}, schema, f"{where} [load.{name}]")
        try:
            parts.append(build(params))
        except (TypeError, ValueError) as exc:
            raise SceneError(f"{where} [load.{name}]: {exc}") from None
    return LoadSum(parts)


def _leaf(p: dict[str, Any], motor: LinearMotor, load: LoadSum, where: str) -> LeafDynamics:
    """The leaf-spring coupling's dynamics from the stand's [plant] values and its [plant.leaf] table."""
    if not isinstance(p["leaf"], dict):
        raise SceneError(f"{where}: the leaf_spring variant needs a table [plant.leaf]")
    leaf = LeafSpringClutch(**read_table(p["leaf"], LeafSpringClutch.SCHEMA, where))
    return LeafDynamics(leaf, motor, load, p["J1"], p["J3"], p["J_down"], p["omega_s"])


def _method_problem(method: str) -> str | None:
    """Why ``method`` cannot run a stand (which integrates at rtol/atol: an adaptive method of rig.solvers), or None."""
    adaptive = [name for name, cls in METHODS.items() if not issubclass(cls, FixedStepper)]
    if method in adaptive:
        return None
    return (f"method {method!r} is not one of the adaptive methods {', '.join(adaptive)}"
            + (" (a fixed-step method has no rtol/atol; rig bench work-precision charts them on the stand)"
               if method in METHODS else ""))


class ClutchStand:
    """Runner-facing plant: ``advance(t)`` returns truth signals, ``events`` lists what happened."""

    def __init__(self, dynamics: "ClutchDynamics | LeafDynamics", omega0: float = 0.0, shutdown_count: int = 2,
                 shutdown_window: float = 0.5, trip_on_shutdown: bool = False, rtol: float = 1e-7,
                 atol: float = 1e-9, phi_r0: float | None = None, method: str = "DP45"):
        why = _method_problem(method)
        if why:
            raise ValueError(why)
        self.method = method
        self.dynamics = dynamics
        if phi_r0 is None:
            phi_r0 = 0.0 if dynamics.blocked or omega0 == 0.0 else dynamics.equilibrium_angle(omega0)
        self.y = dynamics.initial_state(omega0, phi_r0)
        self.t = 0.0
        self.events: list[Event] = []
        self.disengagement_times: list[float] = []
        self._lifted = False                 # whether the last sample had the tappets off the cam (N_B ≤ 0)
        self.shutdown = False
        self.shutdown_count, self.shutdown_window = int(shutdown_count), shutdown_window
        self.trip_on_shutdown = trip_on_shutdown
        self.rtol, self.atol = rtol, atol
        self._h: float | None = None
        if omega0 == 0.0:
            self._check_start()

    def _check_start(self) -> None:
        """A ``motor_below_load`` event at t = 0 when the motor's stall torque at the coupling is below what the shoe
        brakes hold at rest: the stand cannot start. A stick–slip brake then holds it (as the stand would); a
        regularised (tanh) one lets it creep at ω_s·atanh(M_motor/M_brake), which is the model's, not the stand's."""
        motor, loads = self.dynamics.motor, getattr(self.dynamics.load, "loads", [self.dynamics.load])
        brakes = [ld for ld in loads if isinstance(ld, ShoeBrake)]
        held = sum(ld.gain * ld.force for ld in brakes)
        stall = motor.ratio * motor.a0
        if brakes and stall < held:
            tanh = [ld for ld in brakes if ld.friction == "tanh"]
            creep = tanh[0].omega_s * math.atanh(stall / held) if tanh and len(brakes) == 1 else None
            data = {"motor_stall_torque": stall, "brake_torque": held}
            if creep is not None:
                data["creep_speed"] = creep
            self.events.append(Event(0.0, "motor_below_load", data))

    @classmethod
    def from_scene(cls, scene: Scene) -> "ClutchStand":
        """Build from a scene with [scene] (plant = "clutch_dynamic"), [plant], [motor], [load.*]."""
        plant = scene.section("scene").get("plant")      # the rest of [scene] is the runner's (rig.runner.config)
        if plant != "clutch_dynamic":
            raise SceneError(f"{scene.path} [scene]: plant = {plant!r}, expected 'clutch_dynamic'")
        p = scene.read("plant", plant_schema(scene))
        m = scene.read("motor", MOTOR_SCHEMA)
        load = load_from_tables(scene.section("load"), str(scene.path))
        motor = LinearMotor(m["a0"], m["b0"], m["ratio"], m["t_off"])
        try:
            if p["variant"] == "leaf_spring":
                dyn: ClutchDynamics | LeafDynamics = _leaf(p, motor, load, f"{scene.path} [plant.leaf]")
            else:
                clutch = FlatTappetClutch(**{k: p[k] for k in CLUTCH_SCHEMA})
                dyn = ClutchDynamics(clutch, motor, load, v_s=p["v_s"], blocked=bool(p["blocked"]),
                                     J_down=p["J_down"], friction=p["friction"])
        except ValueError as exc:
            raise SceneError(f"{scene.path} [plant]: {exc}") from None
        why = _method_problem(p["method"])
        if why:
            raise SceneError(f"{scene.path} [plant]: key 'method': {why}")
        try:
            return cls(dyn, p["omega0"], p["shutdown_count"], p["shutdown_window"], bool(p["trip_on_shutdown"]),
                       p["rtol"], p["atol"], p["phi_r0"], p["method"])
        except ValueError as exc:      # no initial state: the load at t = 0 with omega0 / phi_r0
            raise SceneError(f"{scene.path} [plant] (initial state, omega0 and phi_r0 with [motor] and [load]): "
                             f"{exc}") from None

    def _on_apex(self, rec: EventRecord) -> bool:
        omega_r = rec.y[1]
        self.disengagement_times.append(rec.t)
        self.events.append(Event(rec.t, "disengagement", {
            "phi_r": rec.y[0], "direction": 1 if omega_r >= 0 else -1,
            "count": len(self.disengagement_times)}))
        recent = [x for x in self.disengagement_times if x > rec.t - self.shutdown_window]
        if not self.shutdown and len(recent) >= self.shutdown_count:
            self.shutdown = True
            self.events.append(Event(rec.t, "shutdown", {"disengagements_in_window": len(recent)}))
            if self.trip_on_shutdown:
                self.dynamics.motor.trip_at = rec.t
                return True
        return False

    def _switch_if_stiff(self, stiff_at: float | None, caught: list[warnings.WarningMessage]) -> None:
        """An explicit method's stiffness test fired (the stand settled into a stiff state the method was not chosen
        for — :mod:`rig.fidelity` picks the method from the scene's work–precision span): the chunk it finished is
        accurate (its steps were cut by stability, not accuracy), the next ones run on the implicit :data:`STIFF`
        method, as LSODA switches; a ``method_switch`` event records when and why instead of a warning. Other
        warnings pass on."""
        for w in caught:
            if not (issubclass(w.category, StiffnessWarning) and self.method != STIFF):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        if stiff_at is not None and self.method != STIFF:
            why = next((str(w.message) for w in caught if issubclass(w.category, StiffnessWarning)), "stiff")
            self.events.append(Event(stiff_at, "method_switch", {"from": self.method, "to": STIFF, "why": why}))
            self.method = STIFF

    def prepare(self) -> None:
        """Load the compiled kernels of this stand's method (numba's cache, 30–50 ms) before a run phase: a copy
        integrates 1 ms numerically, its closed-form stuck flow off (a start from rest is stuck for its first chunks,
        so the kernels would first load mid-run). Nothing of this stand changes."""
        stand = copy.deepcopy(self)
        problem = dataclasses.replace(stand.dynamics.problem(stand.y, lambda rec: False), flow=None)
        end = stand.t + 1e-3
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StiffnessWarning)
            integrate(problem, (stand.t, end), stand.method, t_eval=[end], rtol=stand.rtol, atol=stand.atol)

    def advance(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """Integrate on to the increasing sample times ``t`` (s, ≥ current time); return truth (SI)."""
        t = np.asarray(t, dtype=float)
        if t.size == 0:
            return {}
        if t[0] < self.t or np.any(np.diff(t) <= 0):
            raise ValueError(f"ClutchStand.advance: times must increase from the current time {self.t} s")
        if t[-1] > self.t:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", StiffnessWarning)
                sol = integrate(self.dynamics.problem(self.y, self._on_apex), (self.t, float(t[-1])), self.method,
                                t_eval=t, rtol=self.rtol, atol=self.atol, first_step=self._h)
            self._switch_if_stiff(sol.stiff_at, caught)
            for r in sol.events:
                if r.name in ("phase_boundary", "lobe_wrap", "load_zone"):
                    self.events.append(Event(r.t, r.name, {"phi_r": r.y[0]}))
            self.y, self.t, self._h = sol.y_final, sol.t_final, sol.h_last
            self.events.sort(key=lambda e: e.time)
            Y = sol.y
        else:
            Y = np.asarray(self.y)[:, None]
        out = self.dynamics.outputs(t, Y)
        if isinstance(self.dynamics, ClutchDynamics):
            self._lift_offs(t, out)
        return out

    def _lift_offs(self, t: np.ndarray, out: dict[str, np.ndarray]) -> None:
        """A ``tappet_lift_off`` event (data ``omega3`` rad/s, ``phi_r`` rad) at the first sample of each stretch where
        the cam–tappet normal force N_B would be negative — the tappets' inertia and their centrifugal force beat the
        spring: they lift off the cam. The model (tappets following the cam, N_B held at 0 there) no longer describes
        the coupling — it still transmits the spring's torque through a contact without force —, so what follows is
        not the machine's (an audit: a 400 rad/s stand 'disengaged' and swung ±65 N·m with N_B = 0 throughout)."""
        off = out["N_B"] <= 0.0                      # NaN (the tappet self-locked in its guide) is not a lift-off
        starts = np.flatnonzero(off & ~np.r_[self._lifted, off[:-1]])
        self._lifted = bool(off[-1])
        for k in starts:
            self.events.append(Event(float(t[k]), "tappet_lift_off", {"omega3": float(out["omega3"][k]),
                                                                     "phi_r": float(out["phi_r"][k])}))
        if starts.size:
            self.events.sort(key=lambda e: e.time)
