"""Throughput of the simulated transducers at the acquisition unit's full rate (100 kS/s).

Feeds 1 s of signal in 10 000-sample chunks (as the device would) and prints, per transducer,
the real-time factor (simulated time / wall time) and the cost relative to a baseline: a bare
2nd-order ``scipy.signal.lfilter`` over the same samples (the cheapest possible "transducer").
Also compares the exact FOH low pass with ``scipy.signal.lsim`` (same input interpolation).
"""
from __future__ import annotations

import math
import time
from pathlib import Path
import sys

import numpy as np
from scipy import signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from firmware_sim.transducers import LowPass, load_transducer  # noqa: E402

RATE, CHUNK = 100_000, 10_000


def best_of(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    t = np.arange(RATE) / RATE
    b, a = signal.butter(2, 2 * 1000 / RATE)
    baseline = best_of(lambda: [signal.lfilter(b, a, t[i:i + CHUNK]) for i in range(0, t.size, CHUNK)])
    signals = {
        "burster_8411": 800.0 * np.sin(2 * math.pi * 2.5 * t),
        "brake_force_2kN": 1000.0 + 800.0 * np.sin(2 * math.pi * 2.5 * t),
        "burster_8740": 0.05 + 0.04 * np.sin(2 * math.pi * 2.5 * t),
        "torque_meter_50Nm": 40.0 * np.sin(2 * math.pi * 2.5 * t),
        "potentiometer_dmm": 3.0 + 2.0 * np.sin(2 * math.pi * 0.5 * t),
        "encoder_1024": 2 * math.pi * 15.0 * t,  # 15 rev/s = 61 k edges/s
    }
    print(f"baseline (lfilter, 1 s at {RATE} S/s): {baseline * 1e3:.2f} ms")
    print(f"{'transducer':20s} {'wall ms':>9s} {'× real time':>12s} {'× baseline':>11s}")
    for name, q in signals.items():
        def run() -> None:
            s = load_transducer(name, np.random.default_rng(0))
            for i in range(0, t.size, CHUNK):
                s.measure(t[i:i + CHUNK], q[i:i + CHUNK])
        wall = best_of(run)
        print(f"{name:20s} {wall * 1e3:9.2f} {1.0 / wall:12.1f} {wall / baseline:11.1f}")
    u = signals["burster_8740"]
    lp = best_of(lambda: LowPass(100.0, 2)(t, u))
    ls = best_of(lambda: signal.lsim(([(2 * math.pi * 100) ** 2], [1, 2 * math.sqrt(0.5) * 2 * math.pi * 100,
                                                                   (2 * math.pi * 100) ** 2]), u, t), repeat=1)
    print(f"LowPass (FOH, exact) vs scipy.signal.lsim over {t.size} samples: {lp * 1e3:.2f} ms vs "
          f"{ls * 1e3:.2f} ms, speed-up ×{ls / lp:.1f}")


if __name__ == "__main__":
    main()
