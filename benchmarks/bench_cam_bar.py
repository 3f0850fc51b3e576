"""Benchmark: cam-bar L0 + L1 over one revolution of 3600 angles, vectorised vs a per-angle scalar loop.

Run: python benchmarks/bench_cam_bar.py   (target: vectorised ≤ 1 ms per revolution on one core)
"""
from __future__ import annotations

import time
from math import tau

import numpy as np

from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.plant import DEMO_SPEED


def best_of(fn, repeats: int) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    mech, omega = PinInsertionMechanism(), DEMO_SPEED.omega
    phi = np.linspace(0.0, tau, 3600, endpoint=False)
    vec = best_of(lambda: mech.kinetostatics(phi, omega), 50)
    loop = best_of(lambda: [mech.kinetostatics(float(p), omega) for p in phi], 3)
    ref = mech.kinetostatics(phi, omega).R23n
    check = np.array([float(mech.kinetostatics(float(p), omega).R23n) for p in phi[::90]])
    assert np.allclose(check, ref[::90], rtol=1e-12, atol=1e-12)
    print(f"cam-bar L0+L1, 3600 angles: vectorised {vec * 1e3:.3f} ms, scalar loop {loop * 1e3:.1f} ms, "
          f"speed-up x{loop / vec:.0f} (target <= 1 ms: {'met' if vec <= 1e-3 else 'NOT met'})")


if __name__ == "__main__":
    main()
