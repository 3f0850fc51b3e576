"""Clutch stand solver benchmark: real-time factor at 1e-6 relative error in φ_r and speed against the peers.

The comparison is the work–precision harness (``rig bench work-precision``, :mod:`rig.bench`) on each scene's
hybrid problem (``ClutchDynamics.problem``: stick–slip modes, events, load steps; stuck segments in closed
form for ours): error in φ_r on the scene's sample grid against a DP45 rtol 1e-13 reference confirmed by scipy
DOP853 and our Rodas4 at 1e-12; ours and the peers (scipy solve_ivp, odeint, CVODE) on the same compiled
kernel, restarted at the same events. On top, what the closed form buys: our DP45 with ``Problem.flow``
switched off at the tolerance of its cheapest run at 1e-6. Writes out/bench_clutch/<scene>.csv and .png.

Run: python benchmarks/bench_clutch.py [--quick] [scene ...]   (scene names from data/scenes)
"""
from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from rig.bench.harness import best_runs, measure
from rig.bench.workprecision import SCENE_DIR, run_scenes

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("clutch_startup", "clutch_shock_short", "clutch_overload_hold", "clutch_shock_drop")


def without_closed_form(result) -> None:
    """Print our DP45 at its cheapest 1e-6 setting with the stuck segments integrated numerically."""
    problem, best = result.problem, best_runs(result.rows).get("dp45")
    if best is None:
        return
    numeric = dataclasses.replace(problem, make=lambda: dataclasses.replace(problem.make(), flow=None))
    row = measure(numeric, "dp45", float(best.setting.split("=")[1]), result.reference)
    print(f"  dp45 {best.setting} without the closed form: " + (
        f"{row.wall_s * 1e3:.2f} ms (error {row.error:.1e}) against {best.wall_s * 1e3:.2f} ms with it: "
        f"(numeric / closed form {row.wall_s / best.wall_s:.2f})" if row.status == "ok" else row.status))


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*", default=list(SCENES))
    ap.add_argument("--quick", action="store_true", help="fewer settings")
    args = ap.parse_args()
    for result in run_scenes([SCENE_DIR / f"{name}.toml" for name in args.scenes], ROOT / "out" / "bench_clutch",
                             args.quick):
        without_closed_form(result)
