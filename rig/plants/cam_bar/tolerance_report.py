"""Text table and chart of the cam-bar tolerance analysis (``rig tolerance``)."""
from __future__ import annotations

from dataclasses import dataclass
import math
from math import degrees
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rig.plants.cam_bar.fourbar import EXAMPLE_LENGTHS, EXAMPLE_TOLERANCES, influence_factors
from rig.plants.cam_bar.mechanism import PinInsertionMechanism
from rig.analysis.streaming import passes
from rig.plants.cam_bar.montecarlo import PERCENTILES, TASK_SAMPLES, MonteCarloResult, monte_carlo
from rig.plants.cam_bar.tolerance import PARAMS, CamChain, LinearResult, ToleranceSet, linear_analysis

if TYPE_CHECKING:
    from rig.executors import Executor

#: spawn key of the clearance run's stream under the seed ("clear"): its machines are not the first run's, nor those
#: of another seed (seed + 1 drew the next seed's lengths-only machines; an audit)
CLEARANCE_STREAM = 0x636C656172


def clearance_stream(seed: int) -> np.random.SeedSequence:
    """The clearance run's seed sequence under the scene's ``seed``."""
    return np.random.SeedSequence(seed, spawn_key=(CLEARANCE_STREAM,))


TABLE_ANGLES = (90.0, 120.0, 150.0, 180.0, 200.0, 260.0)  # deg: rise, top of the rise, return


@dataclass(frozen=True)
class ToleranceStudy:
    """Linear and Monte-Carlo results on one angle grid, the MC run without and with the clearance law, and the seed
    each run drew from (the clearance run from the seed's stream :data:`CLEARANCE_STREAM`)."""

    linear: LinearResult
    mc: MonteCarloResult
    mc_clearance: MonteCarloResult | None
    seed: int = 0

    @property
    def clearance_seed(self) -> np.random.SeedSequence:
        return clearance_stream(self.seed)


def run_study(mech: PinInsertionMechanism, tol: ToleranceSet, samples: int, seed: int,
              executor: "Executor | None" = None, step_deg: float = 1.0, progress: bool = False,
              task_samples: int = TASK_SAMPLES) -> ToleranceStudy:
    """Both methods over one revolution (grid ``step_deg``), the Monte-Carlo runs on ``executor`` (default
    serial); ``progress``: a bar on stderr counting machine evaluations (:func:`rig.analysis.streaming.passes` per run)."""
    from rig.console import progress as progress_bar
    phi = np.radians(np.arange(0.0, 360.0, step_deg))
    chain = CamChain.from_mechanism(mech, phi)
    lengths_only = ToleranceSet(tol.T)
    runs = 1 if tol.clearance_lambda is None else 2
    total = samples * runs * passes(samples, PERCENTILES)
    label = f"tolerance, {runs} runs of {samples} machines" if runs > 1 else "tolerance"
    with progress_bar(total, label, " machine evaluations", progress, unit_scale=True) as bar:
        def count(k: int) -> None:          # a rare extra refinement pass must not run the bar past 100 %
            bar.update(min(k, total - bar.n))
        mc_c = None if tol.clearance_lambda is None else monte_carlo(chain, tol, samples, clearance_stream(seed),
                                                                     executor, task_samples, progress=count)
        mc = monte_carlo(chain, lengths_only, samples, seed, executor, task_samples, progress=count)
    return ToleranceStudy(linear_analysis(chain, tol), mc, mc_c, seed)


def study_json(study: ToleranceStudy, run: dict | None = None) -> dict:
    """The study as JSON-ready data (m, per cam angle): each Monte-Carlo run's mean, σ, min, max and 0.135/99.865 %
    points beside the linear RSS, worst case and signed sum; ``run``: what the result depends on (scene, seed,
    machines, task size), written first."""
    lin = study.linear

    def mc_data(mc: MonteCarloResult, seed: np.random.SeedSequence | int) -> dict:
        drawn = ({"seed": seed.entropy, "spawn_key": list(seed.spawn_key)} if isinstance(seed, np.random.SeedSequence)
                 else {"seed": seed})
        return {"machines": mc.n, **drawn, "mean": mc.mean.tolist(), "std": mc.std.tolist(), "min": mc.minimum.tolist(),
                "max": mc.maximum.tolist(), **{f"p{p:g}": mc.percentiles[p].tolist() for p in PERCENTILES}}

    out = {"run": run or {}, "unit": "m", "phi_deg": np.round(np.degrees(lin.phi), 9).tolist(),
           "linear": {"rss": lin.rss.tolist(),
           "worst": lin.worst.tolist(), "signed": lin.signed.tolist()}, "monte_carlo": mc_data(study.mc, study.seed)}
    if study.mc_clearance is not None:
        out["monte_carlo_clearance"] = mc_data(study.mc_clearance, study.clearance_seed)
    return out


def _at(phi: np.ndarray, deg: float) -> int:
    return int(np.argmin(np.abs(np.degrees(phi) - deg)))


def study_table(study: ToleranceStudy) -> str:
    """Linear contributions, signed/worst/RSS and the MC comparison at a few angles and the stroke maxima (µm)."""
    lin, mc, mcc = study.linear, study.mc, study.mc_clearance
    um = 1e6
    head = f"  {'φ (°)':>6} " + " ".join(f"{k:>7}" for k in PARAMS) + f"  {'signed':>7} {'worst':>7} {'RSS':>7} " \
        f"{'MC 3σ':>7} {'MC mean':>7}" + (f" {'clr mean':>9} {'clr 3σ':>7}" if mcc else "")
    lines = ["linear tolerance analysis of the slider stroke (docs/tolerance.md), per angle φ: each tolerance's "
             "contribution ∂s/∂q·T, their signed sum, worst case and RSS; MC: Monte Carlo, normal σ = T/3"
             + ("; clr: Monte Carlo with the clearance law" if mcc else "") + "; all in µm:", head]
    idx = [_at(lin.phi, a) for a in TABLE_ANGLES]
    for i in idx:
        row = f"  {degrees(lin.phi[i]):6.1f} " + " ".join(f"{lin.contribution[k][i] * um:7.1f}" for k in PARAMS)
        row += (f"  {lin.signed[i] * um:7.1f} {lin.worst[i] * um:7.1f} {lin.rss[i] * um:7.1f} "
                f"{3 * mc.std[i] * um:7.1f} {mc.mean[i] * um:7.2f}")
        if mcc:
            row += f" {mcc.mean[i] * um:9.1f} {3 * mcc.std[i] * um:7.1f}"
        lines.append(row)
    i_w, i_r = int(np.argmax(lin.worst)), int(np.argmax(lin.rss))
    ratio = 3 * mc.std / lin.rss
    lines += [f"  max over the stroke: worst case {lin.worst[i_w] * um:.1f} µm at {degrees(lin.phi[i_w]):.0f}°, "
              f"RSS {lin.rss[i_r] * um:.1f} µm at {degrees(lin.phi[i_r]):.0f}°, "
              f"max |signed| {np.max(np.abs(lin.signed)) * um:.1f} µm",
              f"Monte Carlo ({mc.n} machines, normal σ = T/3): 3σ/RSS = {ratio.min():.3f} … {ratio.max():.3f}, "
              f"0.135–99.865 % band up to {np.max(mc.percentiles[99.865] - mc.percentiles[0.135]) * um:.1f} µm "
              f"(linear ±RSS: {2 * lin.rss.max() * um:.1f} µm)" + tail_note(mc.n)]
    if mcc:
        lines.append(f"  with the exponential clearance law: mean Δs {mcc.mean.min() * um:.1f} … {mcc.mean.max() * um:.1f} µm, "
                     f"99.865 % point up to {mcc.percentiles[99.865].max() * um:.1f} µm")
    fb = influence_factors(EXAMPLE_LENGTHS, EXAMPLE_TOLERANCES, np.radians(np.arange(0.0, 360.0, 1.0)))
    lines.append("four-bar example l = (100, 30, 120, 70) mm, Δl = (0.3, 0.2, 0.5, 0.3) mm: max |∂ψ/∂l| "
                 + ", ".join(f"{np.max(np.abs(f)) * 1e-3:.4f}" for f in fb.factors)
                 + f" rad/mm; Δψ worst {degrees(fb.worst.max()):.3f}°, RSS {degrees(fb.rss.max()):.3f}°")
    return "\n".join(lines)


TAIL = 0.00135          # share of the machines beyond each of the 0.135 / 99.865 % points
TAIL_MACHINES = 10      # machines beyond each point for an estimate of it (fewer: a warning beside the band)


def tail_note(n: int) -> str:
    """The warning beside the 0.135–99.865 % band of ``n`` machines when too few lie beyond its points ("" if
    enough): below 1/0.00135 ≈ 741 machines the band is the sample's range."""
    beyond = n * TAIL
    if beyond >= TAIL_MACHINES:
        return ""
    what = ("about the sample's range (each point between the two most extreme machines of its side)" if beyond < 1.0
            else "a rough estimate")
    return (f"\n  ** of {n} machines {beyond:.3g} are expected beyond each 0.135 % point: the band is {what}, not "
            f"those points (≥ {math.ceil(TAIL_MACHINES / TAIL)} samples for {TAIL_MACHINES} in each tail) **")


def plot_study(study: ToleranceStudy, path: str | Path) -> Path:
    """PNG of Δs(φ): linear ±worst/±RSS bands and signed sum, MC percentile bands (µm)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rig.analysis.plots import write_tight

    lin, mc, mcc = study.linear, study.mc, study.mc_clearance
    deg, um = np.degrees(lin.phi), 1e6
    fig, ax = plt.subplots(figsize=(12, 5))
    ax.fill_between(deg, -lin.worst * um, lin.worst * um, color="0.88", label="linear ± worst case")
    ax.plot(deg, lin.rss * um, "b-", lw=1.2, label="linear ± RSS")
    ax.plot(deg, -lin.rss * um, "b-", lw=1.2)
    ax.plot(deg, lin.signed * um, "k--", lw=1, label="linear signed (all +T)")
    few = "" if mc.n * TAIL >= TAIL_MACHINES else ": sample range" if mc.n * TAIL < 1.0 else ": rough, few in the tails"
    ax.plot(deg, mc.percentiles[99.865] * um, "r:", lw=1.8, label=f"MC 0.135 / 99.865 % ({mc.n} machines{few})")
    ax.plot(deg, mc.percentiles[0.135] * um, "r:", lw=1.8)
    ax.plot(deg, mc.mean * um, "r-", lw=0.8, label="MC mean")
    if mcc:
        ax.plot(deg, mcc.percentiles[99.865] * um, "g-.", lw=1.2, label="MC with clearance law: 0.135 / 99.865 %")
        ax.plot(deg, mcc.percentiles[0.135] * um, "g-.", lw=1.2)
        ax.plot(deg, mcc.mean * um, "g-", lw=0.8, label="MC with clearance law: mean")
    ax.set_xlabel("cam angle φ (°)")
    ax.set_ylabel("Δs (µm)")
    ax.set_title("slider-stroke deviation of the pin-insertion chain")
    ax.grid(True)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return write_tight(fig, path)
