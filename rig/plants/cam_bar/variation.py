"""Cycle-to-cycle variation of the pin-insertion plant (scene table ``[plant.variation]``).

Each machine cycle (cam revolution n: 2πn ≤ φ < 2π(n + 1)) draws its own deviations, in cycle order, from
the generator the plant carries (seeded from the scene):

* load parameters ``F_c``, ``F_c_travel``, ``sensor_preload``, ``mu`` — normal, σ given with units; the cycle
  is evaluated by a copy of the mechanism with the drawn values (pin-to-pin scatter of the piercing force
  and of where the pin pierces, sensor zero drift, guide friction);
* chain parameters ``x_A0 … e_sk``, ``r`` — normal, σ in m; and the groove clearance take-up c from the
  exponential law f(c) = λ·exp(−λc) truncated to [0, clearance] (``clearance_lambda``): the roller runs c off
  its working flank, i.e. on pitch radius r − c. These change the slider stroke by Δs(φ) from the full
  deviated chain (:class:`rig.plants.cam_bar.tolerance.CamChain`); Δs is added to ``s`` and ``x_gripper``.
  Velocities, accelerations and forces keep the nominal motion (first order: |Δs| ≲ 0.3 mm ≪ 42 mm stroke).
  At fidelity 2 the roller's place in the groove is simulated, so the clearance draw is the cycle's groove
  clearance instead (the cycle's mechanism gets ``clearance`` = the drawn value; no take-up in Δs).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from rig.plants.cam_bar.montecarlo import sample_clearance
from rig.plants.cam_bar.tolerance import PARAMS, CamChain
from rig.scene import Field, SceneError, read_table

if TYPE_CHECKING:
    from rig.plants.cam_bar.mechanism import PinInsertionMechanism

LOAD_UNITS = {"F_c": "N", "F_c_travel": "m", "sensor_preload": "N", "mu": "1"}
PLANT_STREAM = 0x706C616E74  # spawn key of the plant's generator under the scene seed ("plant")
VARIATION_SCHEMA = {
    **{k: Field(u, 0.0, f"per-cycle standard deviation of {k}") for k, u in LOAD_UNITS.items()},
    **{k: Field("m", 0.0, f"per-cycle standard deviation of {k}") for k in PARAMS},
    "clearance_lambda": Field("1/m", None, "rate λ of the exponential groove-clearance take-up (≤ clearance)"),
}


@dataclass(frozen=True)
class CycleVariation:
    """Per-cycle standard deviations (SI) and the clearance-take-up rate λ (1/m, ``None``: no take-up)."""

    sigma: Mapping[str, float] = field(default_factory=dict)
    clearance_lambda: float | None = None
    where: str = "[plant.variation]"        # the scene file and section it came from (its errors name them)

    def __post_init__(self) -> None:
        for k, v in self.sigma.items():
            if k not in VARIATION_SCHEMA or k == "clearance_lambda":
                raise ValueError(f"variation: unknown parameter {k!r} (known: {', '.join(VARIATION_SCHEMA)})")
            if not v >= 0.0:
                raise ValueError(f"variation: standard deviation of {k} must not be negative, got {v!r}")
        if self.clearance_lambda is not None and not self.clearance_lambda > 0.0:
            raise ValueError(f"variation: clearance_lambda must be positive, got {self.clearance_lambda!r} 1/m")

    @classmethod
    def from_table(cls, table: Any, where: str) -> "CycleVariation":
        """From a ``[plant.variation]`` table (quantities with units)."""
        if not isinstance(table, dict):
            raise SceneError(f"{where}: 'variation' must be a table ([plant.variation])")
        v = read_table(table, VARIATION_SCHEMA, where)
        lam = v.pop("clearance_lambda")
        try:
            return cls({k: s for k, s in v.items() if s != 0.0}, lam, where)
        except ValueError as exc:
            raise SceneError(f"{where}: {exc}") from None

    def draw(self, rng: np.random.Generator, clearance: float) -> "CycleDeviation":
        """One cycle's deviations; the order of draws is fixed (load, chain, clearance)."""
        load = {k: float(rng.normal(0.0, self.sigma[k])) for k in LOAD_UNITS if k in self.sigma}
        chain = {k: float(rng.normal(0.0, self.sigma[k])) for k in PARAMS if k in self.sigma}
        take_up = None
        if self.clearance_lambda is not None:
            take_up = float(sample_clearance(rng, self.clearance_lambda, 1, clearance)[0])
            chain["r"] = chain.get("r", 0.0) - take_up
        return CycleDeviation(load, chain, take_up)


def check_draws(variation: CycleVariation, nominal: "PinInsertionMechanism", where: str) -> None:
    """SceneError naming the key of a load parameter whose draws 3σ from the nominal are not a valid machine (a
    negative piercing force, a friction coefficient below 0): at least 0.13 % of the cycles would draw one and stop
    the run there, after cycles already simulated (an audit: F_c σ = 100 N on 40 N failed at cycle 2). A draw beyond
    3σ still can, and is then named (:meth:`CyclePlant.mechanism`)."""
    for key in LOAD_UNITS:
        sigma = variation.sigma.get(key, 0.0)
        if not sigma:
            continue
        for side in (-3.0, 3.0):
            try:
                replace(nominal, **{key: getattr(nominal, key) + side * sigma})
            except ValueError as exc:
                unit = "" if LOAD_UNITS[key] == "1" else f" {LOAD_UNITS[key]}"
                raise SceneError(f"{where}: key {key!r} σ = {sigma:g}{unit} is too wide for the nominal "
                                 f"{getattr(nominal, key):g}{unit}: a draw {side:+g}σ from it is no valid machine "
                                 f"({exc}); at least 0.13 % of the cycles would draw one and stop the run there — "
                                 f"lower σ to keep ±3σ a valid machine") from None


@dataclass(frozen=True)
class CycleDeviation:
    """Deviations of one cycle (SI): load parameters and chain parameters (m; ``r`` includes the clearance
    take-up), and the drawn clearance (m, ``None`` without ``clearance_lambda``)."""

    load: Mapping[str, float]
    chain: Mapping[str, float]
    take_up: float | None = None


class CyclePlant:
    """Hands out, per cycle number, the mechanism to evaluate and the stroke deviation Δs(φ) (m); at ``fidelity``
    2 the drawn clearance is the cycle's groove clearance (simulated), else it is taken up in the chain."""

    def __init__(self, nominal: "PinInsertionMechanism", variation: CycleVariation, rng: np.random.Generator,
                 fidelity: int = 1):
        self.nominal, self.variation, self.rng, self.fidelity = nominal, variation, rng, fidelity
        self._first: int | None = None
        self._drawn: dict[int, CycleDeviation] = {}      # the latest cycles' draws (cycle index from the first)
        self._draws = 0                                  # cycles drawn so far
        self._mechs: dict[int, "PinInsertionMechanism"] = {}
        # load the compiled chain now (numba's first cache load in a process, ≈ 0.4 s) rather than in the run's
        # first chunk, where it would be counted in the run phase
        CamChain.from_mechanism(nominal, np.zeros(1)).deviation({})

    def deviation(self, cycle: int) -> CycleDeviation:
        """The deviations of ``cycle``, drawing every earlier cycle first (so chunking does not matter)."""
        if self._first is None:
            self._first = cycle
        i = cycle - self._first
        if i < 0:
            raise ValueError(f"variation: cycle {cycle} precedes the first simulated cycle {self._first}")
        if i not in self._drawn and i < self._draws:
            raise ValueError(f"variation: cycle {cycle} was drawn and forgotten (cycles advance; the previous one "
                             "is kept)")
        while self._draws <= i:
            self._drawn[self._draws] = self.variation.draw(self.rng, self.nominal.clearance)
            self._draws += 1
        return self._drawn[i]

    def forget_before(self, cycle: int) -> None:
        """Drop the draws and mechanisms of the cycles before ``cycle`` (the timeline calls it with the cycle
        before each chunk's first: a chunk's events are refined in any of the cycles it spans, and in the one its
        previous sample fell in, so that memory stays bounded whatever the speed and the chunk)."""
        if self._first is not None:
            self._drawn = {k: d for k, d in self._drawn.items() if k >= cycle - self._first}
        self._mechs = {c: m for c, m in self._mechs.items() if c >= cycle}

    def mechanism(self, cycle: int) -> "PinInsertionMechanism":
        """A copy of the nominal mechanism with the cycle's load parameters (the nominal one if none vary); at
        fidelity 2 also with the cycle's drawn groove clearance."""
        if cycle not in self._mechs:
            dev = self.deviation(cycle)
            values = {k: getattr(self.nominal, k) + d for k, d in dev.load.items()}
            if self.fidelity == 2 and dev.take_up is not None:
                values["clearance"] = dev.take_up
            try:
                mech = replace(self.nominal, **values) if values else self.nominal
            except ValueError as exc:           # a draw beyond ±3σ (check_draws): rare, and named
                raise SceneError(f"{self.variation.where}: cycle {cycle} drew no valid machine ({exc}): a σ that "
                                 f"wide reaches it now and then — lower it") from None
            self._mechs[cycle] = mech
        return self._mechs[cycle]

    def stroke_deviation(self, cycle: int, phi: np.ndarray,
                         known: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Δs (m) of the cycle's deviated chain at cam angles ``phi`` (zeros if no chain parameter varies);
        ``known``: the nominal level-0 (s, ψ, r) at ``phi`` if the caller has them."""
        dev = self.deviation(cycle)
        dq = dict(dev.chain)
        if self.fidelity == 2 and dev.take_up is not None:     # simulated in the groove, not taken up
            dq["r"] += dev.take_up
        if not any(dq.values()):
            return np.zeros_like(phi)
        return CamChain.from_mechanism(self.nominal, phi, known).deviation(dq)[0]


def plant_generator(seed: int) -> np.random.Generator:
    """The plant's generator under a scene seed (an independent stream from the runner's spawned ones)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(PLANT_STREAM,)))
