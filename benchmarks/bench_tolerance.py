"""Benchmark: Monte-Carlo tolerance analysis of the cam-bar chain (machines × 360 angles, full chain,
streaming statistics) on the executors: serial, local Dask with 1 and 2 workers; and, as the baseline in the
same run, 2 workers with the percentiles found by histogram passes (moments, histogram, collect: three
evaluations of every machine) instead of the one-pass tails.

Prints wall time, machines per second, the speed-up of 2 workers over 1 and the peak resident memory of
this process and its children (sampled every 20 ms); asserts the results are bit-identical.
Run: python benchmarks/bench_tolerance.py [MACHINES]   (default 1 000 000)
"""
from __future__ import annotations

import os
import sys
import threading
import time

import numpy as np
import psutil

from rig.executors import make_executor
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.montecarlo import monte_carlo
from rig.plants.cam_bar.tolerance import CamChain, load_tolerances


class PeakRss:
    """Peak summed RSS (bytes) of this process and its children while the block runs."""

    def __enter__(self) -> "PeakRss":
        self.peak, self._stop = 0, threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def _sample(self) -> None:
        me = psutil.Process()
        while not self._stop.is_set():
            total = 0
            for p in [me] + me.children(recursive=True):
                try:
                    total += p.memory_info().rss
                except psutil.Error:
                    pass
            self.peak = max(self.peak, total)
            time.sleep(0.02)

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def run(chain: CamChain, name: str, workers: int, n: int, one_pass: bool = True) -> tuple[float, float, object]:
    with PeakRss() as mem, make_executor(name, workers) as ex:
        t0 = time.perf_counter()
        result = monte_carlo(chain, load_tolerances(), n, seed=1, executor=ex, one_pass=one_pass)
        wall = time.perf_counter() - t0
    return wall, mem.peak, result


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    chain = CamChain.from_mechanism(PinInsertionMechanism(), np.radians(np.arange(0.0, 360.0, 1.0)))
    monte_carlo(chain, load_tolerances(), 4000, seed=1)  # warm-up (numba cache)
    rows = [(label, *run(chain, name, w, n, one)) for label, name, w, one in
            (("serial", "serial", 1, True), ("dask, 1 worker", "dask", 1, True), ("dask, 2 workers", "dask", 2, True),
             ("dask, 2 workers, histogram passes", "dask", 2, False))]
    ref = rows[0][3]
    for _, _, _, r in rows[1:]:
        assert all(np.array_equal(getattr(ref, f), getattr(r, f)) for f in ("mean", "std", "minimum", "maximum"))
        assert all(np.array_equal(ref.percentiles[p], r.percentiles[p]) for p in ref.percentiles), "results differ"
    print(f"MC tolerance analysis with the clearance law, {n} machines x {chain.phi.size} angles (full chain, "
          f"streaming mean/sigma/min/max and exact 0.135/99.865 % points; {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.1f} at the end):")
    for label, wall, peak, _ in rows:
        print(f"  {label:34}: {wall:6.2f} s = {n / wall:9.0f} machines/s, peak RSS {peak / 2 ** 20:5.0f} MiB")
    print(f"  speed-up 2 workers / 1 worker: x{rows[1][1] / rows[2][1]:.2f}; one pass / histogram passes on 2 workers: "
          f"x{rows[3][1] / rows[2][1]:.2f} (identical results on all four)")


if __name__ == "__main__":
    main()
