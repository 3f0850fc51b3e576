"""Work–precision problems from scenes: the hybrid ODE a scene's plant integrates, the span, the output grid and
the compared quantity.

* a cam-bar scene at fidelity 2: level 2 of the pin-insertion mechanism (per-cycle variation off) over one cam
  revolution from the quasi-static start; compared: the follower's dynamic deviation e (rad);
* a ``clutch_dynamic`` scene: the stand's hybrid problem (stick–slip modes, events, load steps) over the scene's
  duration; compared: the relative angle φ_r (rad).

Output on the scene's sample grid; error = max |x − x_ref| / max |x_ref| over it.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.fidelity import ATOL_SCALE
from rig.scene import Scene, SceneError, load_scene
from rig.solvers import Problem
from rig.units import to_si


@dataclass
class Sweeps:
    """Settings swept per method: step sizes h (s) of the fixed-step methods, tolerances rtol of the adaptive
    ones (atol = rtol · ``atol_scale``)."""

    steps: dict[str, list[float]]
    tols: list[float]


@dataclass
class WorkProblem:
    """A problem to chart: ``make()`` returns a fresh :class:`Problem` at the initial state (a plant's
    discrete modes are re-selected by its ``reset``); ``component`` the state index compared on ``grid`` (s);
    atol = rtol · ``atol_scale``; sweeps ``full`` and ``quick``."""

    name: str
    title: str
    quantity: str
    make: Callable[[], Problem]
    t_sim: float
    grid: np.ndarray
    component: int
    atol_scale: float
    full: Sweeps
    quick: Sweeps

    def error(self, y: np.ndarray, ref: np.ndarray) -> float:
        """max |x − x_ref| / max |x_ref| of the compared component on the grid (NaN anywhere → inf)."""
        x, r = y[self.component], ref[self.component]
        err = float(np.max(np.abs(x - r)) / np.max(np.abs(r)))
        return err if math.isfinite(err) else math.inf


TOLS = [10.0 ** (-k / 2) for k in range(8, 21)]            # 1e-4 ... 1e-10 in half decades
QUICK_TOLS = [1e-5, 1e-6, 10.0 ** -6.5, 1e-7, 1e-8]


def _key(scene: Scene, key: str, path: Path) -> Any:
    """``[scene] key``; a :class:`SceneError` naming it when the scene lacks it."""
    value = scene.section("scene").get(key)
    if value is None:
        raise SceneError(f"{path} [scene]: missing key {key!r} (the work-precision problem needs it)")
    return value


def _grid(t_sim: float, rate: float) -> np.ndarray:
    return np.linspace(0.0, t_sim, int(round(t_sim * rate)) + 1)


def _halving(h0: float, n: int) -> list[float]:
    return [h0 / 2 ** k for k in range(n)]


def _level2(scene, path: Path, checked: bool = True) -> WorkProblem:
    from rig.plants.cam_bar.level2 import Level2
    from rig.plants.cam_bar.scene_io import mechanism_from_scene, read_level2_model, read_speed_profile, require_level2
    if checked:
        require_level2(scene, "rig bench work-precision")
    mech = mechanism_from_scene(scene)
    speed = read_speed_profile(scene)
    model = Level2(mech, speed, model=read_level2_model(scene))
    t_sim = 2 * math.pi / speed.nominal_omega
    y0 = model.initial_state(0.0)
    rate = to_si(_key(scene, "sample_rate", path), "Hz", what=f"{path} [scene] sample_rate")
    # explicit Euler is stable on the contact only below h ~ 60 us (h*omega_n < 2*zeta), RK4 below ~ 0.2 ms
    full = Sweeps({"euler": _halving(4e-5, 6), "semi-implicit euler": _halving(4e-5, 6), "rk4": _halving(2e-4, 6)},
                  TOLS)
    quick = Sweeps({"euler": [1e-5, 2.5e-6], "semi-implicit euler": [1e-5, 2.5e-6], "rk4": [5e-5, 2.5e-5, 1.25e-5]},
                   QUICK_TOLS)
    return WorkProblem(path.stem, f"{path.stem}: cam-bar level 2, one revolution ({t_sim:g} s)",
                       "follower deviation e", lambda: model.problem(y0), t_sim, _grid(t_sim, rate), 0,
                       ATOL_SCALE["cam_bar"],
                       full, quick)


def _clutch(scene, path: Path) -> WorkProblem:
    from rig.plants.clutch.stand import ClutchStand
    t_sim = to_si(_key(scene, "duration", path), "s", what=f"{path} [scene] duration")
    rate = to_si(_key(scene, "sample_rate", path), "Hz", what=f"{path} [scene] sample_rate")
    stand = ClutchStand.from_scene(scene)
    dyn, y0 = stand.dynamics, stand.y
    full = Sweeps({"euler": _halving(1e-4, 6), "semi-implicit euler": _halving(1e-4, 6), "rk4": _halving(1e-3, 6)},
                  TOLS)
    quick = Sweeps({"euler": [1e-4, 1e-5], "semi-implicit euler": [1e-4, 1e-5], "rk4": [2e-4, 5e-5]},
                   QUICK_TOLS)
    return WorkProblem(path.stem, f"{path.stem}: clutch stand, {t_sim:g} s", "relative angle phi_r",
                       lambda: dyn.problem(y0), t_sim, _grid(t_sim, rate), 0, ATOL_SCALE["clutch_dynamic"], full, quick)


def load_problem(path: str | Path, t_sim: float | None = None) -> WorkProblem:
    """The work–precision problem of a scene file (``t_sim`` (s) shortens its span, e.g. for tests)."""
    return problem_of(load_scene(Path(path)), t_sim)


def problem_of(scene: Scene, t_sim: float | None = None, checked: bool = True) -> WorkProblem:
    """The work–precision problem of a scene (``checked`` False: a cam-bar scene is taken at level 2 without asking
    which level it runs at — for :mod:`rig.fidelity`, which is deciding that)."""
    path = Path(scene.path)
    plant = scene.section("scene").get("plant")
    if plant == "cam_bar":
        problem = _level2(scene, path, checked)
    elif plant == "clutch_dynamic":
        problem = _clutch(scene, path)
    else:
        raise SceneError(f"{path} [scene]: plant = {plant!r} has no work-precision problem (cam_bar at fidelity 2 "
                         f"or clutch_dynamic)")
    if t_sim is not None:
        if not 0.0 < t_sim <= problem.t_sim:
            raise ValueError(f"t_sim = {t_sim!r} s must lie in (0, {problem.t_sim:g}] for {path}")
        problem.t_sim = t_sim
        problem.grid = problem.grid[problem.grid <= t_sim]
    return problem
