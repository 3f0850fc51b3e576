"""Benchmark: Monte-Carlo tolerance analysis of the cam-bar chain (samples × 360 angles, full chain).

Prints MC machines per second with 1 and 2 worker processes (same chunks, bit-identical results) and the
vectorised-vs-per-sample-loop ratio, all measured in this run.
Run: python benchmarks/bench_tolerance.py
"""
from __future__ import annotations

import os
import time

import numpy as np

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.montecarlo import monte_carlo, sample_deviations
from rig.plants.cam_bar.tolerance import CamChain, load_tolerances

SAMPLES = 100_000
LOOP_SAMPLES = 1000


def timed(fn) -> tuple[float, object]:
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def main() -> None:
    chain = CamChain.from_mechanism(PinInsertionMechanism(), np.radians(np.arange(0.0, 360.0, 1.0)))
    tol = load_tolerances()
    monte_carlo(chain, tol, 4000, seed=1)  # warm-up
    t1, r1 = timed(lambda: monte_carlo(chain, tol, SAMPLES, seed=1, workers=1))
    t2, r2 = timed(lambda: monte_carlo(chain, tol, SAMPLES, seed=1, workers=2))
    assert np.array_equal(r1.samples, r2.samples), "worker count changed the result"
    dq = sample_deviations(np.random.default_rng(2), tol, LOOP_SAMPLES)
    tv, vec = timed(lambda: chain.deviation(dq))
    tl, loop = timed(lambda: np.concatenate([chain.deviation({k: v[i] for k, v in dq.items()})
                                             for i in range(LOOP_SAMPLES)]))
    assert np.allclose(vec, loop, rtol=0, atol=1e-15)
    n_ang = chain.phi.size
    print(f"MC tolerance analysis, {SAMPLES} machines x {n_ang} angles (full chain, incl. sampling and statistics; "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the end):")
    print(f"  1 worker : {t1:6.2f} s = {SAMPLES / t1:9.0f} machines/s ({SAMPLES * n_ang / t1 / 1e6:.1f} M chain evals/s)")
    print(f"  2 workers: {t2:6.2f} s = {SAMPLES / t2:9.0f} machines/s, speed-up x{t1 / t2:.2f} (identical results)")
    print(f"  vectorised vs per-sample loop ({LOOP_SAMPLES} machines): {tv * 1e3:.1f} ms vs {tl * 1e3:.0f} ms, "
          f"ratio x{tl / tv:.0f}")


if __name__ == "__main__":
    main()
