"""Benchmark: level 2 of the pin-insertion plant — our solvers against scipy and CVODE at equal error.

A thin wrapper of the work–precision harness (``rig bench work-precision``, :mod:`rig.bench`): one cam
revolution of the scene's mechanism (variation off) from the quasi-static start, error in the follower's
dynamic deviation e on the scene's 10 kHz grid against a DP45 rtol 1e-13 reference confirmed by scipy DOP853
and our Rodas4 at 1e-12; ours (euler, semi-implicit euler, rk4: step sweeps; dp45, rodas4: tolerance sweeps,
compiled) and the peers (scipy solve_ivp RK45/DOP853/Radau/BDF/LSODA, odeint, CVODE) on the same compiled
kernel. Prints one line per method (cheapest run with error <= 1e-6, its real-time factor) and ours against the
best peer; writes out/bench_level2/<scene>.csv and .png.

Run: python benchmarks/bench_level2.py [--scene data/scenes/pin_insertion_l2.toml] [--quick]
"""
from __future__ import annotations

import argparse
from pathlib import Path

from rig.bench.workprecision import SCENES, run_scenes

ROOT = Path(__file__).resolve().parents[1]

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", type=Path, default=SCENES[0])
    ap.add_argument("--quick", action="store_true", help="fewer settings")
    args = ap.parse_args()
    run_scenes([args.scene], ROOT / "out" / "bench_level2", args.quick)
