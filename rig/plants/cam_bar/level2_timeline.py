"""Runner interface of the cam-bar plant at fidelity 2: truth from the groove dynamics (:mod:`.level2`).

Integrates the compiled kernel with the setting's ``method`` and ``method_options`` (default DP45 at rtol 1e-7,
≈ 5e-7 of max|e| over a revolution; :mod:`rig.fidelity` picks them from the work–precision data when the scene
states questions or a tolerance) chunk by chunk, continuing from the last state;
with ``[plant.variation]`` each cam revolution runs with its cycle's mechanism (load parameters) and gets its
chain stroke deviation Δs added, as at level 1. Events: ``flank_switch`` (data ``phi``, ``to``) from the
contact onsets of the integration, and ``accel_jump`` program crossings as at level 1. With a cam drive
(:mod:`.drive`) the cam angle is a state: a chunk runs with the mechanism of the cycle it starts in (the cycle's
load parameters take over at the first chunk boundary of a revolution).
"""
from __future__ import annotations

from math import tau
from typing import TYPE_CHECKING

import numpy as np

from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.timeline import Timeline

if TYPE_CHECKING:
    from rig.motion.speed import SpeedProfile
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism
    from rig.plants.cam_bar.variation import CyclePlant

class Level2Timeline(Timeline):
    """Keeps the integration state (t, y, flank in contact) between :meth:`advance` calls."""

    def __init__(self, mech: "PinInsertionMechanism", speed: "SpeedProfile", cycles: "CyclePlant | None" = None,
                 method: str = "DP45", options: dict[str, float] | None = None):
        super().__init__(mech, speed, cycles)
        self.method, self.options = method, dict(options or {})
        self._state: tuple[float, tuple, str | None] | None = None
        self._models: dict[int, Level2] = {}

    def _model(self, cycle: int) -> Level2:
        if cycle not in self._models:
            mech = self._mechanism(cycle)
            self._models = {cycle: Level2(mech, self.speed)}
        return self._models[cycle]

    def advance(self, t: np.ndarray) -> dict[str, np.ndarray]:
        self._check_times(t)
        mech = self.mech
        if mech.cam_drive is None:
            phi = self.speed.drive(t).phi
        else:        # the cam angle is a state: the chunk runs in the cycle it starts in
            phi = np.full(t.size, self._state[1][2] if self._state is not None else self.speed.phi0)
        cycle = np.floor(phi / tau).astype(int) if self.cycles is not None else np.zeros(t.size, int)
        parts = []
        for c in np.unique(cycle):
            tt = t[cycle == c]
            model = self._model(int(c))
            t0, y0, flank = self._state if self._state is not None else (tt[0], model.initial_state(tt[0]), None)
            run = model.simulate((t0, tt[-1]), y0, flank, t_eval=tt, method=self.method, **self.options)
            self._state = (run.solution.t_final, run.solution.y_final, run.flank)
            self.events.extend(run.switches)
            part = model.signals(tt, run.solution.y)
            parts.append(part if self.cycles is None else self._deviate(part, int(c)))
        if not t.size:
            return self._model(min(self._models, default=0)).signals(t, np.zeros((2, 0)))
        out = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
        phi = out["phi"]
        last_phi = np.array([self._last[1]]) if self._last is not None else phi[:0]
        last_t = np.array([self._last[0]]) if self._last is not None else t[:0]
        self.events.extend(self._program_crossings(np.concatenate([last_t, t]), np.concatenate([last_phi, phi])))
        self.events.sort(key=lambda e: e.time)
        self._last = (float(t[-1]), float(phi[-1]), float(out["R23"][-1]))
        return out
