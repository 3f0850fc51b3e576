"""Stochastic tolerance analysis (MODELS §3.5): sample machines, run the full chain, summarise Δs(φ).

Lengths are normal with σ = T/3. The groove clearance c is exponential, f(c) = λ·exp(−λc) (assumption: a
roller loose by c sits off its working flank towards the cam centre, so the pitch radius it follows is
r − c). Samples are drawn in tasks of fixed size, each with its own generator from ``SeedSequence(seed).spawn``,
evaluated by an executor (:mod:`rig.executors`) and summarised by streaming statistics
(:mod:`rig.analysis.streaming`: moments and exact percentiles, never all samples in memory; each task
regenerates its samples from its seed in every pass). The result depends on the seed and the task size only:
it is bit-identical for any executor and number of workers.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Iterator, Sequence

import numpy as np

from rig.analysis.streaming import ColumnStats, column_statistics
from rig.plants.cam_bar.chain import SingularPositionError
from rig.plants.cam_bar.tolerance import PARAMS, CamChain, ToleranceSet

if TYPE_CHECKING:
    from rig.executors import Executor

TASK_SAMPLES = 50_000  # machines per task (≈ 0.1–0.2 s a pass on one core at 360 angles); fixed, not per worker
BLOCK = 2000           # machines drawn and evaluated at once inside a task (≈ 6 MB at 360 angles)
PERCENTILES = (0.135, 99.865)  # the ±3σ points of a normal law


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


@dataclass(frozen=True)
class ChainSamples:
    """One task's machines: ``n`` deviated chains drawn from ``seed`` in blocks of ``block``; the same
    blocks every time they are asked for."""

    chain: CamChain
    tol: ToleranceSet
    seed: np.random.SeedSequence
    n: int
    block: int = BLOCK

    def blocks(self) -> Iterator[np.ndarray]:
        """Δs (m) of the machines, blocks of shape (≤ block, angles)."""
        rng = np.random.default_rng(self.seed)
        for start in range(0, self.n, self.block):
            dq = sample_deviations(rng, self.tol, min(self.block, self.n - start))
            yield self.chain.evaluate(self.chain.deviation_rows(dq), self.chain.s)


def fold_task(task: tuple[ChainSamples, Callable]) -> object:
    """Apply a fold of :mod:`rig.analysis.streaming` to one task's blocks (runs on a worker)."""
    source, fold = task
    return fold(source.blocks())


@dataclass(frozen=True)
class MonteCarloResult(ColumnStats):
    """Δs(φ) over ``n`` sampled machines (m) at cam angles ``phi`` (rad): the per-angle statistics of
    :class:`ColumnStats` (mean, σ with ddof 1, min/max, exact percentiles by numpy's linear interpolation)."""

    phi: np.ndarray


def tasks(chain: CamChain, tol: ToleranceSet, n: int, seed: "int | np.random.SeedSequence",
          task_samples: int = TASK_SAMPLES) -> list[ChainSamples]:
    """The run's tasks: ``task_samples`` machines each (the last one the rest), task i drawn from
    ``SeedSequence(seed).spawn(count)[i]`` (``seed`` an int, or a SeedSequence of its own stream)."""
    sizes = [min(task_samples, n - i) for i in range(0, n, task_samples)]
    root = (np.random.SeedSequence(seed.entropy, spawn_key=seed.spawn_key, pool_size=seed.pool_size)   # a copy:
            if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed))   # spawn counts its children
    return [ChainSamples(chain, tol, s, k) for s, k in zip(root.spawn(len(sizes)), sizes)]


def monte_carlo(chain: CamChain, tol: ToleranceSet, n: int, seed: "int | np.random.SeedSequence", executor: "Executor | None" = None,
                task_samples: int = TASK_SAMPLES, percents: Sequence[float] = PERCENTILES,
                progress: Callable[[int], object] | None = None, one_pass: bool = True) -> MonteCarloResult:
    """Run ``n`` sampled machines through the full chain on ``executor`` (default serial) in tasks of
    ``task_samples``; ``progress(k)`` is called as each task has passed k machines (about
    :func:`rig.analysis.streaming.passes` passes in all); ``one_pass=False`` takes the histogram passes even where the tails would
    do (the same numbers; for comparison)."""
    from rig.executors import make_executor
    if n < 2 or task_samples < 1:
        raise ValueError(f"Monte-Carlo run needs n ≥ 2 and task_samples ≥ 1 (got n={n}, task_samples={task_samples})")
    work = tasks(chain, tol, n, seed, task_samples)
    own = executor is None
    executor = make_executor("serial") if own else executor

    def run(fold: Callable) -> Iterator[object]:
        for source, part in zip(work, executor.map(fold_task, [(source, fold) for source in work])):
            if progress is not None:
                progress(source.n)
            yield part

    try:
        st = column_statistics(run, percents, n=n if one_pass else None)
    except SingularPositionError as exc:
        bad = int(np.count_nonzero(~buildable_probe(chain, tol, seed)))
        raise SingularPositionError(
            f"{exc}: {bad} of {PROBE} machines drawn from these tolerances ({100.0 * bad / PROBE:.3g} %) cannot be "
            "assembled, so the stroke deviation of the set is not defined; tighten the tolerances (or the nominal "
            "geometry's margin) until none fails") from None
    finally:
        if own:
            executor.close()
    return MonteCarloResult(**vars(st), phi=chain.phi)


PROBE = 10_000         # machines drawn to tell how many of a set cannot be assembled


def buildable_probe(chain: CamChain, tol: ToleranceSet, seed: "int | np.random.SeedSequence") -> np.ndarray:
    """Whether each of :data:`PROBE` machines drawn from ``tol`` (generator seeded with ``seed``) can be assembled."""
    dq = sample_deviations(np.random.default_rng(seed), tol, PROBE)
    return chain.buildable(chain.deviation_rows(dq))
