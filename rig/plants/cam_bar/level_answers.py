"""A cam-bar scene's fidelity questions answered at levels 0, 1 and 2, and how far the lower levels are from level 2.

One cam revolution of the scene's nominal machine (no per-cycle variation) on the scene's sample grid: L0 the
kinematics, L1 the kinetostatics at the nominal speed, L2 the groove dynamics with the level-2 solver setting the
scene gets. A cam drive that starts from rest runs :data:`SETTLE` revolutions of start-up before a revolution of steady
running, and level 2's answers cover them all: the start-phase jump the thesis saw is in its rod-force peak and flank
switches (the most in any one revolution), and the lower levels, which know only the constant speed, are judged
against it — they used to be compared with the steady revolution only, and a start-up that switched flanks went
unseen. The answers (SI; counts as floats): ``stroke`` (m, peak to peak, steady revolution), ``rod_force`` (N, the
signed peak), ``flank_switches`` (count per revolution), ``dwell_vibration`` (m, peak-to-peak deviation of the slider
from its law in the upper dwell; level 2 only).

:func:`compare` is what :func:`rig.fidelity.choose` asks before it trusts a lower level: a lower level's answer
further from level 2's than the scene's ``model_tolerance`` (relative to level 2's magnitude; a count must be equal)
means that, at this operating point, the question needs level 2. ``rig bench fidelity`` times the same runs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from rig.scene import Scene

SETTLE = 2          # revolutions a cam drive starting from rest runs before the one compared
#: display unit and scale of each answer (SI → display)
UNITS = {"stroke": ("mm", 1e3), "rod_force": ("N", 1.0), "flank_switches": ("count", 1.0),
         "dwell_vibration": ("µm", 1e6)}


def peak(values: np.ndarray) -> float:
    """The signed value of largest magnitude (the rod force's peak as the console prints it, − = compression)."""
    values = np.asarray(values, dtype=float)
    return float(values[np.argmax(np.abs(values))])


def dwell_vibration(mech: Any, phi: np.ndarray, s: np.ndarray) -> float:
    """Peak-to-peak deviation (m) of the slider ``s`` from its law at the cam angles ``phi`` it was at, in the upper
    dwell; NaN without an upper dwell on the grid."""
    law = mech.state(phi).s
    top = law >= mech.program.levels[1] - 1e-12
    return float(np.ptp(s[top] - law[top])) if top.any() else math.nan


class LevelRuns:
    """The three levels' computations of one revolution of a cam-bar scene's nominal machine, each callable on its
    own (:meth:`run`) so that it can be timed, and their answers (:meth:`answers`)."""

    def __init__(self, scene: Scene, method: str, options: Mapping[str, float]):
        from rig.plants.cam_bar.level2 import Level2
        from rig.plants.cam_bar.scene_io import mechanism_from_scene, read_level2_model, read_speed_profile
        from rig.runner.config import SCENE_SCHEMA
        self.mech = mech = mechanism_from_scene(scene)
        speed = read_speed_profile(scene)
        self.omega = speed.nominal_omega
        self.period = 2 * math.pi / self.omega
        settle = SETTLE if mech.cam_drive is not None and mech.cam_drive.start == "rest" else 0
        self.simulated = {0: self.period, 1: self.period, 2: (settle + 1) * self.period}   # s each level simulates
        t = settle * self.period + np.arange(0.0, self.period, 1.0 / scene.read("scene", SCENE_SCHEMA)["sample_rate"])
        self.t, self.phi = t, speed.drive(t).phi          # the compared (steady) revolution: all that L0, L1 know
        self.t_all = np.concatenate([np.arange(0.0, t[0], t[1] - t[0]) if settle else np.zeros(0), t])   # L2's
        self.revolutions = [(k * self.period, (k + 1) * self.period) for k in range(settle)] + [(t[0], t[-1])]
        self.model = Level2(mech, speed, model=read_level2_model(scene))
        self.method, self.options = method, dict(options)

    def run(self, level: int) -> Any:
        """Level 0's kinematic state, level 1's loads, or level 2's (run, signals) on the compared revolution."""
        if level == 0:
            return self.mech.state(self.phi)
        if level == 1:
            return self.mech.kinetostatics(self.phi, self.omega)
        run = self.model.simulate((0.0, float(self.t[-1])), self.model.initial_state(0.0), t_eval=self.t_all,
                                  method=self.method, **self.options)
        return run, self.model.signals(self.t_all, run.solution.y)

    def answers(self, level: int, result: Any = None) -> dict[str, float]:
        """The questions ``level`` answers (SI), from ``result`` (:meth:`run`'s, computed here when None)."""
        result = self.run(level) if result is None else result
        if level == 0:
            return {"stroke": float(np.ptp(result.s))}
        if level == 1:
            return {"stroke": float(np.ptp(self.mech.state(self.phi).s)), "rod_force": peak(result.F_rod),
                    "flank_switches": float(len(self.mech.flank_switch_angles(self.omega, n=self.t.size)))}
        run, sig = result
        counts = [sum(a <= sw.time < b for sw in run.switches) for a, b in self.revolutions[:-1]]
        a, b = self.revolutions[-1]
        switches = max(counts + [sum(a <= sw.time <= b for sw in run.switches)])      # the most in one revolution
        steady = self.t_all >= self.t[0]
        return {"stroke": float(np.ptp(sig["s"][steady])), "rod_force": peak(sig["F_rod"]),
                "flank_switches": float(switches), "dwell_vibration": dwell_vibration(self.mech, sig["phi"], sig["s"])}


@dataclass(frozen=True)
class Deviation:
    """A lower level's answer against level 2's at the scene's operating point."""

    question: str
    level: int
    value: float        # SI
    reference: float    # level 2's, SI

    @property
    def unit(self) -> str:
        return UNITS[self.question][0]

    def beyond(self, tolerance: float) -> bool:
        """Further than ``tolerance`` (relative to level 2's magnitude) from level 2's answer; a count: unequal."""
        if self.unit == "count":
            return self.value != self.reference
        return abs(self.value - self.reference) > tolerance * abs(self.reference)

    def shown(self, value: float, digits: int = 4) -> str:
        """An answer in display units, ``digits`` significant digits."""
        unit, scale = UNITS[self.question]
        return f"{value * scale:.{digits}g}" + ("" if unit == "count" else f" {unit}")

    def text(self) -> str:
        """How it differs: "+2" for a count; "-64 % in magnitude" (a signed peak of −89 N against −248 N is 64 %
        smaller, not "+64 %"), or "opposite sign" when the signs differ."""
        value, reference = self.value, self.reference
        if self.unit == "count":
            return f"{value - reference:+g}"
        scale = UNITS[self.question][1]
        if not reference:
            return f"{(value - reference) * scale:+.3g} {self.unit}"
        if value and math.copysign(1.0, value) != math.copysign(1.0, reference):
            return f"opposite sign ({(value - reference) * scale:+.3g} {self.unit})"
        return f"{100 * (abs(value) - abs(reference)) / abs(reference):+.3g} % in magnitude"

    def describe(self) -> str:
        """``"L1's rod_force -88.98 N against L2's -327.5 N (-72.8 % in magnitude)"`` (more digits where 4 show the
        two answers alike)."""
        for digits in (4, 6, 9):
            mine, theirs = self.shown(self.value, digits), self.shown(self.reference, digits)
            if mine != theirs:
                break
        return f"L{self.level}'s {self.question} {mine} against L2's {theirs} ({self.text()})"


def compare(scene: Scene, level: int, questions: list[str], method: str,
            options: Mapping[str, float]) -> list[Deviation]:
    """Each of ``questions`` that ``level`` (0 or 1) answers, its answer against level 2's on one revolution of the
    scene's nominal machine (level 2 with ``method`` and ``options``)."""
    runs = LevelRuns(scene, method, options)
    low, top = runs.answers(level), runs.answers(2)
    return [Deviation(q, level, low[q], top[q]) for q in questions if q in low]
