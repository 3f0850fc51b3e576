"""Runner interface of the cam-bar plant: truth signals at increasing times and the events crossed.

Events (kind, data):
* ``"flank_switch"`` — the contact force with the mounted spring changes sign; data: ``phi`` (rad, wrapped),
  ``to`` (``"working"`` or ``"other"`` flank);
* ``"accel_jump"`` — the cam angle crosses a program angle where s'' jumps; data: ``phi``, ``jump``
  (m/rad²), ``segment`` (0-based).
Event times are refined with Brent's method to 1e-12 s.
"""
from __future__ import annotations

from math import tau
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import brentq

from rig.plants.cam_bar.kinetostatics import solve
from rig.plants.cam_bar.switches import sign_changes
from rig.plants.events import Event

if TYPE_CHECKING:
    from rig.motion.speed import SpeedProfile
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism
    from rig.plants.cam_bar.variation import CyclePlant


class Timeline:
    """Evaluates the mechanism (each cycle's, with ``cycles``) along the speed profile ``speed`` and keeps the
    last sample to continue across calls."""

    def __init__(self, mech: "PinInsertionMechanism", speed: "SpeedProfile", cycles: "CyclePlant | None" = None):
        self.mech, self.speed, self.cycles = mech, speed, cycles
        self.events: list[Event] = []
        self._last: tuple[float, float, float] | None = None  # (t, unwrapped φ, R23n)
        self._program_events = mech.program.events()

    def _contact(self, t: float) -> float:
        dr = self.speed.drive(np.array([t]))
        mech = self._mechanism(int(np.floor(dr.phi[0] / tau)))
        return float(mech.kinetostatics(dr.phi, dr.omega, dr.alpha).R23n[0])

    def _mechanism(self, cycle: int) -> "PinInsertionMechanism":
        return self.mech if self.cycles is None else self.cycles.mechanism(cycle)

    def _truth(self, mech: "PinInsertionMechanism", t: np.ndarray, phi: np.ndarray, omega: np.ndarray,
               alpha: np.ndarray) -> dict[str, np.ndarray]:
        st = mech.state(phi, omega, alpha)
        ks = solve(mech, st, mech.k)
        return {"t": t, "phi": phi, "cam_angle": np.mod(phi, tau), "omega": omega, "alpha": alpha,
                "s": st.s, "v": st.s_d, "a": st.s_dd, "x_gripper": mech.s0 - st.s, "psi": st.psi,
                "theta": st.theta, "r": st.r, "F_rod": ks.F_rod, "rod_tension": ks.rod_tension,
                "R23": ks.R23n, "M23": ks.M23, "M_e": ks.M_e, "M_sigma": ks.M_sigma,
                "drive_torque": ks.drive_torque, "F_c": ks.F_c, "pressure_angle": ks.pressure_angle}

    def _check_times(self, t: np.ndarray) -> None:
        if t.ndim != 1 or (t.size > 1 and np.any(np.diff(t) <= 0.0)):
            raise ValueError("advance(t): t must be a 1-D array of strictly increasing times")
        if self._last is not None and t.size and t[0] <= self._last[0]:
            raise ValueError(f"advance(t): t starts at {t[0]:g} s, not after the previous call's end "
                             f"{self._last[0]:g} s")

    def advance(self, t: np.ndarray) -> dict[str, np.ndarray]:
        self._check_times(t)
        mech = self.mech
        dr = self.speed.drive(t)
        if self.cycles is None or not t.size:
            out = self._truth(mech, t, dr.phi, dr.omega, dr.alpha)
        else:  # one cycle (cam revolution) at a time, each with its own deviations
            cycle = np.floor(dr.phi / tau).astype(int)
            self.cycles.forget_before(int(cycle[0]) - 1)
            parts = []
            for c in np.unique(cycle):
                i = cycle == c
                part = self._truth(self.cycles.mechanism(int(c)), t[i], dr.phi[i], dr.omega[i], dr.alpha[i])
                parts.append(self._deviate(part, int(c), (part["s"], part["psi"], part["r"])))
            out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        if t.size:
            self._find_events(t, dr.phi, out["R23"])
            self._last = (float(t[-1]), float(dr.phi[-1]), float(out["R23"][-1]))
        return out

    def _deviate(self, part: dict[str, np.ndarray], cycle: int,
                 known: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """Add the cycle's chain stroke deviation Δs(φ) to ``s`` and ``x_gripper`` of a truth chunk (``known``: its
        level-0 (s, ψ, r), the nominal chain's at level 1)."""
        ds = self.cycles.stroke_deviation(cycle, part["phi"], known)
        part["s"], part["x_gripper"] = part["s"] + ds, part["x_gripper"] - ds
        return part

    def _find_events(self, t: np.ndarray, phi: np.ndarray, contact: np.ndarray) -> None:
        if self._last is not None:
            t = np.concatenate(([self._last[0]], t))
            phi = np.concatenate(([self._last[1]], phi))
            contact = np.concatenate(([self._last[2]], contact))
        found: list[Event] = []
        for i in sign_changes(contact):
            tc = brentq(self._contact, t[i], t[i + 1], xtol=1e-12)
            phic = float(self.speed.drive(np.array([tc])).phi[0])
            found.append(Event(tc, "flank_switch", {"phi": phic % tau,
                                                    "to": "working" if contact[i + 1] >= 0.0 else "other"}))
        self.events.extend(sorted(found + self._program_crossings(t, phi), key=lambda e: e.time))

    def _program_crossings(self, t: np.ndarray, phi: np.ndarray) -> list[Event]:
        """``accel_jump`` events for program angles crossed between consecutive samples (t, φ)."""
        found: list[Event] = []
        for ev in self._program_events:
            laps = np.floor((phi - ev.angle) / tau)
            for i in np.flatnonzero(laps[1:] > laps[:-1]):
                target = ev.angle + tau * laps[i + 1]
                f = lambda x: float(self.speed.drive(np.array([x])).phi[0]) - target  # noqa: E731
                tc = t[i + 1] if f(t[i + 1]) == 0.0 else brentq(f, t[i], t[i + 1], xtol=1e-12)
                found.append(Event(tc, "accel_jump", {"phi": ev.angle, "jump": float(ev.jump),
                                                      "segment": ev.segment}))
        return found
