"""Runner interface of the cam-bar plant at fidelity 2: truth from the groove dynamics (:mod:`.level2`).

Integrates the compiled kernel with the setting's ``method`` and ``method_options`` (default DP45 at rtol 1e-7,
≈ 5e-7 of max|e| over a revolution; :mod:`rig.fidelity` picks them from the work–precision data when the scene
states questions or a tolerance) chunk by chunk, continuing from the last state;
with ``[plant.variation]`` each cam revolution runs with its cycle's mechanism (load parameters) and gets its
chain stroke deviation Δs added, as at level 1. Events: ``flank_switch`` (data ``phi``, ``to``) and
``flank_bounce`` (data ``phi``, ``flank``: the roller struck again the flank it had left) from the contact onsets of
the integration, and ``accel_jump`` program crossings as at level 1. With a cam drive
(:mod:`.drive`) the cam angle is a state, known only once integrated: a chunk is integrated with its cycle's
mechanism, and where the cam angle passes into the next revolution the samples from there on are integrated
again with the next cycle's, from the last sample before it — the switch falls on the same sample as without a
drive, whatever the chunk length.
"""
from __future__ import annotations

from math import tau
from typing import TYPE_CHECKING

import numpy as np

from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.level2_model import Level2Model
from rig.plants.cam_bar.timeline import Timeline
from rig.solvers import SolverDivergence

if TYPE_CHECKING:
    from rig.motion.speed import SpeedProfile
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism
    from rig.plants.cam_bar.variation import CyclePlant

class Level2Timeline(Timeline):
    """Keeps the integration state (t, y, flank in contact) between :meth:`advance` calls."""

    def __init__(self, mech: "PinInsertionMechanism", speed: "SpeedProfile", cycles: "CyclePlant | None" = None,
                 method: str = "DP45", options: dict[str, float] | None = None, model: Level2Model = Level2Model()):
        super().__init__(mech, speed, cycles)
        self.method, self.options, self.model = method, dict(options or {}), model
        self._state: tuple[float, tuple, str | None] | None = None
        self._models: dict[int, Level2] = {}
        self._cycle = 0                     # with a cam drive: the revolution the integration state is in

    def _model(self, cycle: int) -> Level2:
        if cycle not in self._models:
            mech = self._mechanism(cycle)
            self._models = {cycle: Level2(mech, self.speed, model=self.model)}
        return self._models[cycle]

    def advance(self, t: np.ndarray) -> dict[str, np.ndarray]:
        self._check_times(t)
        if self.mech.cam_drive is None:
            phi = self.speed.drive(t).phi
            cycle = np.floor(phi / tau).astype(int) if self.cycles is not None else np.zeros(t.size, int)
            if self.cycles is not None and t.size:
                self.cycles.forget_before(int(cycle[0]) - 1)
            parts = [self._integrate(t[cycle == c], int(c))[0] for c in np.unique(cycle)]
        else:
            if self.cycles is not None:
                self.cycles.forget_before(self._cycle - 1)
            parts = self._driven(t)                     # (a stalled cam: the runs' cam_stalled events)
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

    def _integrate(self, tt: np.ndarray, cycle: int, within: bool = False) -> tuple[dict[str, np.ndarray], int]:
        """Samples ``tt`` (s) integrated with the mechanism of ``cycle``, continuing the state: their signals and
        how many were kept — all, or with ``within`` (a driven cam, whose angle is a state known only once
        integrated) those before the first sample in the next revolution, the state then set back to the last of
        them with the flank in contact there."""
        model = self._model(cycle)
        t0, y0, flank = self._state if self._state is not None else (tt[0], model.initial_state(tt[0]), None)
        if tt[-1] <= t0:                        # the very first sample alone: the initial state, nothing to integrate
            self._state = (t0, y0, flank)
            return model.signals(tt, np.repeat(np.asarray(y0, dtype=float).reshape(-1, 1), tt.size, axis=1)), tt.size
        try:
            run = model.simulate((t0, tt[-1]), y0, flank, t_eval=tt, method=self.method, **self.options)
        except SolverDivergence as exc:         # which integration stopped: the message has the time, state and cause
            settings = ", ".join(f"{k} = {v:g}" if isinstance(v, float) else f"{k} = {v}" for k, v in self.options.items())
            exc.add_note(f"level 2 of machine cycle {cycle} integrated with {self.method}"
                         + (f" ({settings})" if settings else ""))
            raise
        part = model.signals(tt, run.solution.y)
        beyond = np.flatnonzero(part["phi"] >= tau * (cycle + 1)) if within else ()
        k = int(beyond[0]) if len(beyond) else tt.size
        if k == 0:                              # passed before the first sample: nothing of it in this revolution
            return {}, 0
        if k == tt.size:
            kept = run.events
            self._state = (run.solution.t_final, run.solution.y_final, run.flank)
        else:
            kept = [e for e in run.events if e.time <= tt[k - 1]]
            switched = [e for e in kept if e.kind == "flank_switch"]
            self._state = (float(tt[k - 1]), tuple(run.solution.y[:, k - 1]), switched[-1].data["to"] if switched
                           else (flank if flank is not None else model.flank_of(t0, y0)))
            part = {key: v[:k] for key, v in part.items()}
        self.events.extend(kept)
        return (part if self.cycles is None else self._deviate(part, cycle)), k

    def _driven(self, t: np.ndarray) -> list[dict[str, np.ndarray]]:
        """The samples ``t`` with a cam drive: each revolution's samples with that cycle's mechanism (where the cam
        angle passes into the next revolution, the rest is integrated again from the last sample before it)."""
        parts, i = [], 0
        while i < t.size:
            part, k = self._integrate(t[i:], self._cycle, within=self.cycles is not None)
            if k:
                parts.append(part)
                i += k
            if i < t.size:
                self._cycle += 1
        return parts
