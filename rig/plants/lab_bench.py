"""Course lab benches (MODELS §5; DEVICES §1 "lab instruments"): a motor shaft turning at the scene's
[speed] profile drives one mechanism of the library, chosen by ``[plant] kind``:

* ``disc`` — the shaft alone (speed-measurement lab: slotted disc, tachometer, tachogenerator, stroboscope);
* ``cardan`` — a Cardan joint at ``shaft_angle`` (output shaft angle and speed, rig.mechanisms.Cardan);
* ``geneva`` — a Geneva drive with ``slots`` and ``centre_distance`` (wheel angle and speed; the crank angle
  is measured from the centre line, so ``[speed] phi0 = "180 deg"`` starts in the dwell);
* ``cam`` — a disc cam with a translating roller follower on its ``[[plant.cam_program]]``, held by a return
  spring (``spring_rate``, ``spring_preload``) and loaded by the follower's mass and, rising against ``gravity``,
  its weight: follower position, velocity, acceleration and the cam-shaft torque M = F·ds/dφ + J_cam·ω̇ with
  F = m·(a + g) + k·s + F0 (virtual power: M·ω = F·v + J·ω̇·ω).

Prescribed input motion (closed form, rig.motion.speed): kinematics and quasi-static torque, level 1. Truth
signals (SI): ``phi_in`` (rad, continuous), ``omega_in`` (rad/s), ``alpha_in`` (rad/s²) and, per kind,
``phi_out``/``omega_out``/``alpha_out`` (rad/s²) or ``s``/``v``/``a``/``torque``.
"""
from __future__ import annotations

from math import pi
from typing import Any

import numpy as np

from rig.mechanisms import Cardan, Geneva
from rig.motion.program import CamProgram
from rig.motion.speed import SpeedProfile
from rig.plants.events import Event
from rig.scene import Field, Scene, SceneError

KINDS = ("disc", "cardan", "geneva", "cam")
SCHEMAS: dict[str, dict[str, Field]] = {
    "disc": {"kind": Field(None)},
    "cardan": {"kind": Field(None), "shaft_angle": Field(
        "rad", doc="angle between input and output shaft; at 90° the output shaft cannot turn", minimum=0.0,
        below=pi / 2, says="must be at least 0° and below 90°")},
    "geneva": {"kind": Field(None), "slots": Field("1"), "centre_distance": Field("m")},
    "cam": {"kind": Field(None), "cam_program": Field(None, doc="array of tables [[plant.cam_program]]"),
            "follower_mass": Field("kg", 0.0, minimum=0.0), "spring_rate": Field("N/m", 0.0, minimum=0.0),
            "spring_preload": Field("N", 0.0, "spring force at s = 0"),
            "gravity": Field("m/s^2", 0.0, "gravity against the follower's rise (its weight m·g adds to the contact "
                             "force G): 9.81 m/s^2 for a follower rising vertically, 0 for a horizontal "
                             "one", minimum=0.0),
            "cam_inertia": Field("kg*m^2", 0.0, "inertia of the cam shaft beyond the torque transducer",
                                 minimum=0.0),
            "base_radius": Field("m", None, "the cam's base radius (for `rig cam-design` only; the run follows the "
                                 "law)", positive=True),
            "roller_radius": Field("m", None, "the follower roller's radius (for `rig cam-design` only)",
                                   positive=True)},
}


SPAN_GRID = 3600          # points per cam turn a lift span's least contact force is sought on (then refined)
LIFT_STEP = 2 * pi / 360   # rad: the largest cam turn between the points a lift is looked for on (finer than the
#                           samples where they are coarser: at 6000 rpm and 600 Hz every sample fell where the law's
#                           acceleration is 0 and a lift of −4600 N went unsaid; an audit)
LIFT_POINTS = 2_000_000   # at most this many points per call (beyond: coarser than LIFT_STEP)


class LabBench:
    """One lab bench: ``speed`` (the motor shaft), ``kind`` and its mechanism; ``advance(t)`` gives the truth."""

    def __init__(self, kind: str, speed: SpeedProfile, mechanism: Any = None, follower_mass: float = 0.0,
                 spring_rate: float = 0.0, spring_preload: float = 0.0, cam_inertia: float = 0.0,
                 gravity: float = 0.0) -> None:
        if kind not in KINDS:
            raise ValueError(f"lab bench kind must be one of {', '.join(KINDS)}, got {kind!r}")
        self.kind, self.speed, self.mechanism = kind, speed, mechanism
        self.follower_mass, self.spring_rate = follower_mass, spring_rate
        self.spring_preload, self.cam_inertia, self.gravity = spring_preload, cam_inertia, gravity
        self.events: list[Event] = []
        self._t_last = -np.inf
        self._lifting = False               # the cam follower's contact force was below zero at the last sample
        self._t_prev: float | None = None   # the previous call's last sample time (s)

    def advance(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """Truth at increasing times ``t`` (s), continuing from the previous call."""
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or (t.size and (t[0] <= self._t_last or np.any(np.diff(t) <= 0))):
            raise ValueError("LabBench.advance needs strictly increasing times after the previous call")
        if t.size:
            self._t_last = float(t[-1])
        out = self.truth(t)
        if "contact_force" in out and t.size:
            self._lifts(*self._lift_points(t, out))
        return out

    def _lift_points(self, t: np.ndarray, out: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t s, cam angle rad, contact force N) to look for lifts on: the samples, or, where the cam turns more than
        :data:`LIFT_STEP` between them (from the previous call's last sample on), the closed form on a grid that fine."""
        phi = out["phi_in"]
        start = self._t_prev if self._t_prev is not None else float(t[0])
        turned = float(np.max(np.abs(np.diff(np.r_[self.speed.drive(np.array([start])).phi, phi]))))
        self._t_prev = float(t[-1])
        if turned <= LIFT_STEP:
            return t, phi, out["contact_force"]
        n = min(int(np.ceil(turned / LIFT_STEP * (t.size + 1))), LIFT_POINTS)
        fine = np.linspace(start, float(t[-1]), n + 1)[1:] if start < t[0] else np.linspace(t[0], t[-1], n)
        closed = self.truth(fine)
        return fine, closed["phi_in"], closed["contact_force"]

    def _lifts(self, t: np.ndarray, phi: np.ndarray, force: np.ndarray) -> None:
        """A ``follower_lift`` event where the contact force the cam law needs goes below zero: the spring and the
        weight no longer hold the follower on the cam (force closure lost: it would jump, MODELS §2), and the bench's
        law-following model stops being the bench's motion there."""
        below = force < 0.0
        starts = np.flatnonzero(below & ~np.concatenate(([self._lifting], below[:-1])))
        for k in starts:
            t_min, f_min = self._lift_minimum(float(t[k]))
            self.events.append(Event(float(t[k]), "follower_lift", {
                "cam_angle": float(np.mod(phi[k], 2 * pi)), "force": f_min, "min_t": t_min,
                "min_cam_angle": float(np.mod(self.speed.drive(np.array([t_min])).phi[0], 2 * pi)),
                "detail": "the contact force the cam law needs is below zero: spring and weight no longer hold the "
                          "follower on the cam, which would lift off (jump) here; the law-following model and the "
                          "sheets' theory do not hold beyond it"}))
        self._lifting = bool(below[-1])

    def _lift_minimum(self, t0: float) -> tuple[float, float]:
        """(time s, force N) of the least contact force over the lift span that starts at ``t0``: the closed-form
        force on :data:`SPAN_GRID` points of the next cam turn up to where it is back at ≥ 0, its least sample refined
        by a bounded scalar minimisation — the whole span, wherever the run's chunks cut it (a minimum taken from the
        chunk's samples was the chunk's, and its angle the span's start). The window is one turn at the speed at
        ``t0`` (1 s at rest): a span longer than that (a negative preload on an accelerating cam) reports the least
        force within its first turn."""
        from scipy.optimize import minimize_scalar
        omega = abs(float(self.speed.drive(np.array([t0])).omega[0]))
        dt = (2 * pi / omega if omega > 0.0 else 1.0) / SPAN_GRID
        t = t0 + dt * np.arange(SPAN_GRID + 1)
        force = self.truth(t)["contact_force"]
        back = np.flatnonzero(force >= 0.0)
        i = int(np.argmin(force[:back[0] if back.size else force.size]))
        res = minimize_scalar(lambda x: float(self.truth(np.array([x]))["contact_force"][0]), method="bounded",
                              bounds=(t[max(i - 1, 0)], t[min(i + 1, t.size - 1)]), options={"xatol": 1e-12})
        return (float(res.x), float(res.fun)) if res.fun < force[i] else (float(t[i]), float(force[i]))

    def truth(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """The bench's signals at times ``t`` (s) (module docstring)."""
        d = self.speed.drive(t)
        out = {"t": t, "phi_in": d.phi, "omega_in": d.omega, "alpha_in": d.alpha}
        if self.kind == "cardan":
            out["phi_out"] = self.mechanism.output_angle(d.phi)
            ratio = self.mechanism.speed_ratio(d.phi)
            out["omega_out"] = ratio * d.omega
            out["alpha_out"] = self.mechanism.acceleration(d.phi, d.omega) + ratio * d.alpha   # ω1²·dr/dφ1 + r·α1
        elif self.kind == "geneva":
            motion = self.mechanism.kinematics(d.phi, 1.0)
            out["phi_out"] = self.mechanism.wheel_angle(d.phi)      # 0 in the dwell before the engagement about
                                                                    # φ1 = 0 (a start at φ1 = 180° is one index on)
            out["omega_out"] = motion.velocity * d.omega
            out["alpha_out"] = motion.acceleration * d.omega ** 2 + motion.velocity * d.alpha
        elif self.kind == "cam":
            m = self.mechanism.evaluate(d.phi)
            v, a = d.omega * m.s_p, d.omega ** 2 * m.s_pp + d.alpha * m.s_p
            force = self.contact_force(m.s, a)
            out.update(s=m.s, v=v, a=a, torque=force * m.s_p + self.cam_inertia * d.alpha, contact_force=force)
        return out

    def contact_force(self, s: np.ndarray, a: np.ndarray) -> np.ndarray:
        """The cam follower's contact force (N) at its position ``s`` (m) and acceleration ``a`` (m/s²): inertia and
        weight m·(a + g), spring k·s + preload (< 0: spring and weight no longer hold it on the cam)."""
        return self.follower_mass * (a + self.gravity) + self.spring_rate * s + self.spring_preload

    def cam_contact_force(self, phi: np.ndarray, omega: float) -> np.ndarray:
        """The contact force (N) at cam angles ``phi`` (rad) turning steadily at ``omega`` (rad/s)."""
        m = self.mechanism.evaluate(phi)
        return self.contact_force(m.s, omega * omega * m.s_pp)

    @classmethod
    def from_scene(cls, scene: Scene) -> "LabBench":
        """The bench of a scene's [plant] and [speed]; errors name the file, section and key."""
        from rig.plants.cam_bar.scene_io import read_program, read_speed_profile
        where = f"{scene.path} [plant]"
        kind = scene.section("plant").get("kind")
        if kind not in KINDS:
            raise SceneError(f"{where}: key 'kind' must be one of {', '.join(map(repr, KINDS))}, got {kind!r}")
        p = scene.read("plant", SCHEMAS[kind])
        speed = read_speed_profile(scene)
        try:
            if kind == "cardan":
                return cls(kind, speed, Cardan(p["shaft_angle"]))
            if kind == "geneva":
                slots = p["slots"]
                return cls(kind, speed, Geneva(int(slots) if float(slots).is_integer() else slots,
                                               p["centre_distance"]))
            if kind == "cam":
                program: CamProgram = read_program(p["cam_program"], 0.0, where)
                return cls(kind, speed, program, p["follower_mass"], p["spring_rate"], p["spring_preload"],
                           p["cam_inertia"], p["gravity"])
        except SceneError:                  # names the file and section itself
            raise
        except ValueError as exc:
            raise SceneError(f"{where}: {exc}") from None
        return cls(kind, speed)
