"""Stochastic tolerance analysis (MODELS §3.5): sample machines, run the full chain, summarise Δs(φ).

Lengths are normal with σ = T/3. The groove clearance c is exponential, f(c) = λ·exp(−λc) (assumption: a
roller loose by c sits off its working flank towards the cam centre, so the pitch radius it follows is
r − c). Samples are drawn and evaluated in fixed-size chunks, each with its own generator from
``SeedSequence(seed).spawn`` — the result is bit-identical for any number of worker processes.
"""
from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Callable

import numpy as np

from rig.plants.cam_bar.tolerance import PARAMS, CamChain, ToleranceSet

CHUNK = 2000  # samples per chunk (the unit of parallel work; fixed so results do not depend on workers)
PERCENTILES = (0.135, 2.5, 50.0, 97.5, 99.865)  # ±3σ and 95 % bands of a normal law


def sample_clearance(rng: np.random.Generator, lam: float, size: int, limit: float | None = None) -> np.ndarray:
    """Clearances (m) from f(c) = λ·exp(−λc), optionally truncated to [0, limit] (inverse CDF)."""
    u = rng.random(size)
    tail = 1.0 if limit is None else -np.expm1(-lam * limit)
    return -np.log1p(-u * tail) / lam


def sample_deviations(rng: np.random.Generator, tol: ToleranceSet, n: int) -> dict[str, np.ndarray]:
    """Parameter deviations (m) of ``n`` machines: normal σ = T/3; the clearance lowers r by c ~ Exp(λ)."""
    dq = {k: rng.normal(0.0, tol.T[k] / 3.0, n) for k in PARAMS}
    if tol.clearance_lambda is not None:
        dq["r"] = dq["r"] - sample_clearance(rng, tol.clearance_lambda, n)
    return dq


def _run_chunk(chain: CamChain, tol: ToleranceSet, seed: np.random.SeedSequence, n: int) -> np.ndarray:
    return chain.deviation(sample_deviations(np.random.default_rng(seed), tol, n))


@dataclass(frozen=True)
class MonteCarloResult:
    """Δs(φ) over ``n`` sampled machines (m): per-angle mean, standard deviation, min/max and the
    ``PERCENTILES``; ``samples`` holds every Δs (n × angles)."""

    phi: np.ndarray
    samples: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    minimum: np.ndarray
    maximum: np.ndarray
    percentiles: dict[float, np.ndarray]

    @property
    def n(self) -> int:
        return self.samples.shape[0]


def monte_carlo(chain: CamChain, tol: ToleranceSet, n: int, seed: int, workers: int = 1,
                chunk: int = CHUNK, progress: Callable[[int], object] | None = None) -> MonteCarloResult:
    """Run ``n`` sampled machines through the full chain in chunks of ``chunk``, on ``workers`` processes;
    ``progress(k)`` is called as each chunk of k machines is done."""
    if n < 2 or chunk < 1 or workers < 1:
        raise ValueError(f"Monte-Carlo run needs n ≥ 2, chunk ≥ 1, workers ≥ 1 (got n={n}, chunk={chunk}, "
                         f"workers={workers})")
    sizes = [min(chunk, n - i) for i in range(0, n, chunk)]
    seeds = np.random.SeedSequence(seed).spawn(len(sizes))
    args = ([chain] * len(sizes), [tol] * len(sizes), seeds, sizes)
    by_angle = np.empty((chain.phi.size, n))  # angle-major: the per-angle statistics read contiguous rows
    pool = ProcessPoolExecutor(max_workers=workers) if workers > 1 else None
    try:
        parts = pool.map(_run_chunk, *args) if pool else map(_run_chunk, *args)
        start = 0
        for part in parts:
            by_angle[:, start:start + part.shape[0]] = part.T
            start += part.shape[0]
            if progress is not None:
                progress(part.shape[0])
    finally:
        if pool:
            pool.shutdown()
    pct = np.percentile(by_angle, PERCENTILES, axis=1)
    return MonteCarloResult(chain.phi, by_angle.T, by_angle.mean(axis=1), by_angle.std(axis=1, ddof=1),
                            by_angle.min(axis=1), by_angle.max(axis=1), dict(zip(PERCENTILES, pct)))
