"""Curve evaluation speed: all element types on a 4000-pair curve, against the real unit's 90 ms.

Run: python benchmarks/bench_digiforce.py  (prints times measured in this run and ratios to the baseline)
"""
from __future__ import annotations

import time

import numpy as np

from firmware_sim.digiforce import DigiForce

REAL_UNIT_EVALUATION = 0.090   # s, data sheet (data/devices/digiforce_9310.toml: evaluation_time)


def press(n: int, peak: float = 3.0, stroke: float = 4.0):
    t = np.linspace(0.0, 0.4, n)
    x = stroke / 2 * (1 - np.cos(2 * np.pi * t / 0.4))
    y = peak * (x / stroke) ** 2 * np.where(t <= 0.2, 1.0, 0.5)
    return t, x, y


def program() -> dict:
    _, rx, ry = press(4000)
    fwd = slice(0, 2000)
    refs = [{"x": rx[fwd][1:].tolist(), "y": (ry[fwd][1:] * s).tolist()} for s in (0.97, 1.0, 1.03)]
    simple = {"input": "voltage", "range": 10.0, "cutoff": "off", "unit": "m",
              "scaling": {"electrical": 1.0, "engineering": 1.0}}
    return {
        "channels": {"x": simple, "y": {**simple, "input": "process", "range": 5.0, "unit": "N"}},
        "sampling": {"mode": "time", "delta": 1e-4},
        "elements": [
            {"kind": "window", "name": "W_in", "part": "forward", "x_min": 1.5, "x_max": 2.5, "y_min": 0.2,
             "y_max": 1.5, "entry": "left", "exit": "right"},
            {"kind": "window", "name": "W_peak", "x_min": 3.5, "x_max": 4.5, "y_min": 2.5, "y_max": 3.5,
             "entry": "ignore", "exit": "ignore", "check": "y_max"},
            {"kind": "threshold", "name": "S_y", "part": "forward", "axis": "y", "value": 1.0},
            {"kind": "threshold", "name": "S_x", "part": "return", "axis": "x", "value": 2.0, "direction": "falling"},
            {"kind": "trapezoid", "name": "T_y", "part": "forward", "axis": "y", "start": 2.8, "end": 3.6,
             "lower": [1.0, 1.8], "upper": [2.0, 3.0]},
            {"kind": "trapezoid", "name": "T_x", "part": "return", "axis": "x", "start": 0.4, "end": 1.0,
             "lower": [1.2, 1.8], "upper": [2.8, 3.6], "entry": "top", "exit": "bottom"},
            {"kind": "envelope", "name": "E", "part": "forward", "references": refs, "dx": 0.02, "dy": 0.05},
        ],
    }


def main() -> None:
    dev = DigiForce()
    dev.set_program(0, program())
    t, x, y = press(4000)
    dev.start()
    dev.feed(t, x, y)                  # 4000 samples at ~10 kHz, one pair each
    result = dev.stop()
    curve = result.curve
    assert curve.t.size == 4000 and result.ok, [e.reason for e in result.elements if not e.ok]
    n_el = len(result.elements)
    runs = []
    for _ in range(300):
        t0 = time.perf_counter()
        dev.evaluate(curve)
        runs.append(time.perf_counter() - t0)
    med = float(np.median(runs))
    print(f"curve: {curve.t.size} pairs, {n_el} elements "
          f"({', '.join(sorted({e.kind for e in result.elements}))})")
    print(f"evaluation (elements + process values): median {med * 1e3:.3f} ms, min {min(runs) * 1e3:.3f} ms "
          f"over {len(runs)} runs")
    print(f"ratio to the real unit's {REAL_UNIT_EVALUATION * 1e3:.0f} ms: {med / REAL_UNIT_EVALUATION:.4f} "
          f"({REAL_UNIT_EVALUATION / med:.0f}x faster); target <= 1 ms: {'met' if med <= 1e-3 else 'NOT met'}")

    # acquisition throughput: one second of input at the unit's full 100 kHz, Δt sampling with decimation
    dev.set_program(0, {"sampling": {"delta": 1e-5, "overflow": "decimate"}})
    n = 100_000
    ta = dev.status()["time"] + 1e-5 + np.arange(n) * 1e-5
    xa, ya = np.sin(ta) + 1, np.cos(ta)
    t0 = time.perf_counter()
    dev.start()
    dev.feed(ta, xa, ya)
    dev.stop()
    took = time.perf_counter() - t0
    print(f"acquisition: 1 s of input at 100 kHz processed in {took * 1e3:.1f} ms "
          f"(ratio to real time {took:.4f})")


if __name__ == "__main__":
    main()
