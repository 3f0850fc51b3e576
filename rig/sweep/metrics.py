"""Sweep metrics: what one scene's plant does, as numbers, and the one adapter that builds and runs it.

The plant is built as ``rig run`` builds it (:func:`rig.runner.plants.make_plant`, nominal: without the
scene's per-cycle variation, so a point is one deterministic machine) and driven through its runner interface
(``advance(t)`` at the scene's sample rate, ``events``). Cam bar: ``revolutions`` cam revolutions from the
scene's start, metrics over the last one; clutch stand: the scene's duration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from math import tau
from typing import Any, Callable

import numpy as np

from rig.scene import Scene

CHUNK = 0.1  # s of simulated time per advance() call before the analysed window
OK_CYCLES = 20  # curves of ok_share when the scene states no [scene] cycles


@dataclass
class PlantRun:
    """A plant after its run: truth signals over the analysed window (SI; cam bar: the last revolution),
    the window (s), the plant (its events, state) and the scene it was built from."""

    plant: Any
    signals: dict[str, np.ndarray]
    window: tuple[float, float]
    scene: Scene | None = None

    @cached_property
    def law(self) -> np.ndarray:
        """The slider's level-0 stroke (m) at the analysed samples' cam angles (cam bar)."""
        return self.plant.mech.state(self.signals["phi"]).s

    def events(self, kind: str) -> list:
        a, b = self.window
        return [e for e in self.plant.events if e.kind == kind and a <= e.time <= b]


def run_plant(scene: Scene, revolutions: int = 2) -> PlantRun:
    """Build the scene's plant and run it (module docstring): the sweep's one adapter to the plants."""
    from rig.runner.config import read_config
    from rig.runner.plants import make_plant
    cfg = read_config(scene)
    plant = make_plant(cfg.plant, scene, nominal=True)
    if cfg.plant == "cam_bar":
        omega = float(plant.speed.drive(np.array([0.0])).omega[0])
        if not omega > 0.0:
            raise ValueError(f"{scene.path}: the cam does not turn at t = 0 (ω = {omega} rad/s)")
        end = revolutions * tau / omega
        start = end - tau / omega
    elif cfg.duration is not None:
        start = end = cfg.duration
    else:
        raise ValueError(f"{scene.path}: a {cfg.plant!r} scene needs [scene] duration for a sweep")
    t = np.arange(0.0, end + 0.5 / cfg.sample_rate, 1.0 / cfg.sample_rate)
    before = t[t < start]
    for i in range(0, before.size, max(1, int(CHUNK * cfg.sample_rate))):
        plant.advance(before[i:i + int(CHUNK * cfg.sample_rate)])
    window = t[t >= start]
    signals = plant.advance(window) if window.size else {}
    return PlantRun(plant, signals, (float(start), float(end)), scene)


def _upper_dwell_vibration(run: PlantRun) -> float:
    """Peak-to-peak deviation of the slider from its level-0 law in the upper dwell (m; 0 below level 2, which
    :func:`check_levels` refuses)."""
    sig, mech, law = run.signals, run.plant.mech, run.law
    top = law >= mech.program.levels[1] - 1e-12
    return float(np.ptp(sig["s"][top] - law[top])) if top.any() else float("nan")


def _gripper_deviation(run: PlantRun) -> float:
    """Peak-to-peak deviation of the slider from its level-0 law over the analysed revolution (m)."""
    return float(np.ptp(run.signals["s"] - run.law))


def _roller_gap(run: PlantRun) -> float:
    """Largest gap the roller opens off the working flank (m, ≥ 0); NaN below level 2 (no groove modelled;
    :func:`check_levels` refuses it there)."""
    gap = run.signals.get("delta_w")
    return max(float(np.max(-gap)), 0.0) if gap is not None else float("nan")


def ok_share(scene: Scene, cycles: int = OK_CYCLES) -> float:
    """Share of machine cycles the acquisition unit judges OK (0…1): the scene's plant *with* its per-cycle
    variation (the scene's seed) through its X and Y transducers into its DigiForce program, ``cycles`` curves
    (the scene's [scene] cycles when it states them) — the device side of ``rig run`` without the bus."""
    from rig.runner.config import read_config
    from rig.runner.machine import instruments
    from rig.runner.plants import make_plant
    cfg = read_config(scene)
    cycles = cfg.cycles or cycles
    plant = make_plant(cfg.plant, scene)
    transducers, device = instruments(cfg)
    x, y = cfg.wired("device.x"), cfg.wired("device.y")
    if x is None or y is None:
        raise ValueError(f"{scene.path}: ok_share needs transducers wired to device.x and device.y")
    n = max(2, round(CHUNK * cfg.sample_rate))
    ok = done = step = 0
    limit = cfg.duration if cfg.duration is not None else math.inf
    while done < cycles:
        t = (step * n + 1 + np.arange(n)) / cfg.sample_rate
        if t[0] > limit + 60.0:
            raise ValueError(f"{scene.path}: only {done} of {cycles} curves by t = {t[0]:.3g} s (ok_share)")
        step += 1
        truth = plant.advance(t)
        for result in device.feed(t, transducers[x.name].measure(t, truth[x.signal]),
                                  transducers[y.name].measure(t, truth[y.signal])):
            ok += bool(result.ok)
            done += 1
    return ok / done


@dataclass(frozen=True)
class Metric:
    """A sweep metric: the plants it applies to, its unit, what it is, and how it is computed; ``integer``: a count
    or a flag (the table writes it as a whole number, the maps tick and label it in whole numbers); ``level``: the
    lowest model level (:mod:`rig.fidelity`) whose plant answers it — below it a sweep refuses the metric."""

    plants: tuple[str, ...]
    unit: str
    doc: str
    compute: Callable[[PlantRun], float]
    integer: bool = False
    level: int = 1
    shown: str | None = None       # the unit the table and maps show it in (default: rig.analysis.units' for it)

    @property
    def display(self) -> Any:
        """The :class:`rig.analysis.units.Unit` the table and the maps show this metric in."""
        from rig.analysis.units import unit
        return unit(self.unit, self.shown)


METRICS: dict[str, Metric] = {
    "flank_switches": Metric(("cam_bar",), "1", "flank switches of the roller in the last revolution",
                             lambda r: float(len(r.events("flank_switch"))), integer=True),
    "flank_bounces": Metric(("cam_bar",), "1", "bounces of the roller on a flank (it strikes again the flank it "
                            "left: a jump without a switch) in the last revolution",
                            lambda r: float(len(r.events("flank_bounce"))), integer=True, level=2),
    "upper_dwell_vibration": Metric(("cam_bar",), "m", "gripper deviation from its law in the upper dwell, peak to "
                                    "peak, last revolution", _upper_dwell_vibration, level=2, shown="um"),
    "gripper_deviation": Metric(("cam_bar",), "m", "gripper deviation from its law, peak to peak, last revolution "
                                "(contact deflection, flight across the groove and pins)",
                                _gripper_deviation, level=2, shown="um"),
    "roller_gap": Metric(("cam_bar",), "m", "largest gap the roller opens off the working flank, last revolution",
                         _roller_gap, level=2, shown="um"),
    "rod_force_peak": Metric(("cam_bar",), "N", "largest |F_rod| of the last revolution: the rod's load cell reading "
                             "(rod tension + the sensor's mounting preload)",
                             lambda r: float(np.max(np.abs(r.signals["F_rod"])))),
    "rod_tension_peak": Metric(("cam_bar",), "N", "largest |rod tension| of the last revolution: the force in the rod "
                               "itself, the load cell's preload left out (a preload sweep does not move it)",
                               lambda r: float(np.max(np.abs(r.signals["rod_tension"])))),
    "ok_share": Metric(("cam_bar",), "1", f"share of cycles the DigiForce program judges OK, with the scene's "
                       f"per-cycle variation ([scene] cycles, else {OK_CYCLES}); the seed also draws the transducers' "
                       f"static errors once: one seed is one set of sensors (sweep scene.seed for their spread)",
                       lambda r: ok_share(r.scene)),
    "disengagements": Metric(("clutch_dynamic",), "1", "disengagements (apex passes) over the scene's duration",
                             lambda r: float(len(r.plant.disengagement_times)), integer=True, level=2),
    "shutdown": Metric(("clutch_dynamic",), "1", "1 if the stand's shutdown rule fired, else 0",
                       lambda r: float(r.plant.shutdown), integer=True, level=2),
}


def check_metrics(names: list[str], plant: str) -> None:
    """A ValueError naming what is wrong unless every metric exists, is asked for once and applies to ``plant``."""
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"--metric {', '.join(twice)} is given twice: each metric is one column and one map")
    for name in names:
        if name not in METRICS:
            raise ValueError(f"unknown metric {name!r} (known: {', '.join(METRICS)})")
        if plant not in METRICS[name].plants:
            raise ValueError(f"metric {name!r} applies to {', '.join(METRICS[name].plants)} scenes, not {plant!r}")


def check_levels(names: list[str], levels: list[int], where: str) -> None:
    """A ValueError unless every point's model level (``levels``, one per grid point of the scene ``where``)
    answers every metric: it names the metrics, the level they need, the points' level and how to get it."""
    from rig.fidelity import LEVEL_NAMES
    short = {m: METRICS[m].level for m in names if min(levels) < METRICS[m].level}
    if not short:
        return
    need = max(short.values())
    low = sorted({lv for lv in levels if lv < need})
    runs = (f"runs at level {low[0]} ({LEVEL_NAMES[low[0]]})" if len(set(levels)) == 1 else
            f"runs {sum(lv < need for lv in levels)} of its {len(levels)} points at level {', '.join(map(str, low))}")
    what = "; ".join(f"{m!r} needs level {lv} ({LEVEL_NAMES[lv]})" for m, lv in short.items())
    example = CAM_BAR_EXAMPLES.get(need) if all(METRICS[m].plants == ("cam_bar",) for m in short) else None
    raise ValueError(f"{where} {runs}; {what}: below that the sweep would write 0 or NaN. Give --fidelity {need} "
                     f"(or a scene at level {need}: [scene] fidelity = {need}, or questions that need it"
                     + (f", e.g. {example}" if example else "") +
                     "), or leave the metric out")


#: a shipped cam-bar scene at each model level (the example of check_levels' message)
CAM_BAR_EXAMPLES = {1: "data/scenes/pin_insertion.toml", 2: "data/scenes/pin_insertion_l2.toml"}
