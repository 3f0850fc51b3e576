"""Benchmark: cam-bar fidelity levels 0/1/2 and the level-2 solvers, error against time over one revolution.

Scene: the pin-insertion mechanism at 300 rpm with the softest spring (1.09 N/mm), where level 1 predicts a
flank switch during the return. Reference: level 2 integrated by DP45 at rtol 1e-9. Compared:
level 0 (prescribed stroke) and level 1 (kinetostatic contact force) — modelling error against the level-2
reference — and level 2 by DP45 and by the implicit Rosenbrock23 at several tolerances — numerical error.
Writes out/bench_cam_bar_levels.png; prints steps, RHS calls, wall time, max errors and ratios.
Run: python benchmarks/bench_cam_bar_levels.py
"""
from __future__ import annotations

import time
import warnings
from math import pi
from pathlib import Path

import matplotlib
import numpy as np

from rig.motion import ConstantSpeed
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.level2 import Level2
from rig.solvers import Rosenbrock23, StiffnessWarning

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OMEGA = 300 * pi / 30
T = 2 * pi / OMEGA
GRID = np.linspace(0.0, T, 4001)
RUNS = [("DP45", 1e-3), ("DP45", 1e-5), (Rosenbrock23, 1e-2), (Rosenbrock23, 1e-3),
        (Rosenbrock23, 1e-4)]


def run(model: Level2, method, rtol: float) -> tuple[dict, dict]:
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StiffnessWarning)
        res = model.simulate((0.0, T), method=method, t_eval=GRID, rtol=rtol, atol=rtol * 1e-6)
    wall = time.perf_counter() - t0
    sol = res.solution
    info = {"steps": sol.nsteps, "nfev": sol.nfev, "wall": wall, "stiff_at": sol.stiff_at,
            "warned": any(issubclass(w.category, StiffnessWarning) for w in caught), "switches": len(res.switches)}
    return model.signals(GRID, sol.y), info


def main() -> None:
    mech = PinInsertionMechanism(k=1090.0)
    model = Level2(mech, ConstantSpeed(OMEGA))
    print("reference: level 2, DP45 rtol 1e-9 ...", flush=True)
    ref, ref_info = run(model, "DP45", 1e-9)
    print(f"  {ref_info['steps']} steps, {ref_info['wall']:.1f} s, {ref_info['switches']} flank switches")
    curves, table = {}, []
    level0 = mech.state(ref["phi"], OMEGA)
    curves["level 0 (s)"] = (np.abs(level0.s - ref["s"]), None)
    level1 = mech.kinetostatics(ref["phi"], OMEGA)
    curves["level 1 (R23; s as level 0)"] = (None, np.abs(level1.R23n - ref["R23"]))
    for method, rtol in RUNS:
        name = f"L2 {method if isinstance(method, str) else method.__name__} rtol {rtol:g}"
        sig, info = run(model, method, rtol)
        curves[name] = (np.abs(sig["s"] - ref["s"]), np.abs(sig["R23"] - ref["R23"]))
        table.append((name, info, np.max(curves[name][0]), np.max(curves[name][1])))
    print(f"{'run':34s} {'steps':>6s} {'RHS':>7s} {'wall s':>7s} {'max|ds| m':>10s} {'max|dR23| N':>11s}  stiffness")
    for name, info, es, ef in table:
        flag = f"warned at t = {info['stiff_at']:.4f} s" if info["warned"] else "-"
        print(f"{name:34s} {info['steps']:6d} {info['nfev']:7d} {info['wall']:7.2f} {es:10.2e} {ef:11.2e}  {flag}")
    ds0 = np.max(curves["level 0 (s)"][0])
    print(f"level 0/1 modelling error against level 2: max |ds| = {ds0:.2e} m ({ds0 / mech.clearance:.2f} × "
          f"clearance), max |dR23| = {np.max(curves['level 1 (R23; s as level 0)'][1]):.0f} N")
    for name, info, es, _ in table:       # each DP45 run against the cheapest implicit run at least as accurate
        if "DP45" not in name:
            continue
        rivals = [(i["wall"], n, i) for n, i, e, _ in table if "DP45" not in n and e <= es]
        if rivals:
            wall, rname, rinfo = min(rivals)
            print(f"{name} vs {rname} (max|ds| no worse): steps x{info['steps'] / rinfo['steps']:.2f}, "
                  f"RHS calls x{info['nfev'] / rinfo['nfev']:.2f}, wall x{info['wall'] / wall:.2f}")
        else:
            print(f"{name}: no implicit run is as accurate")
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    for name, (es, ef) in curves.items():
        style = "k-" if name.startswith("level") else ("--" if "DP45" in name else "-")
        if es is not None:
            axes[0].semilogy(GRID * 1e3, np.maximum(es, 1e-13), style, lw=1, label=name)
        if ef is not None:
            axes[1].semilogy(GRID * 1e3, np.maximum(ef, 1e-9), style, lw=1, label=name)
    axes[0].set_ylabel("|s − s_ref| (m)")
    axes[1].set_ylabel("|R23 − R23_ref| (N)")
    axes[1].set_xlabel("time (ms), one revolution at 300 rpm, k = 1.09 N/mm")
    axes[0].legend(fontsize=7, ncol=2)
    axes[0].set_title("cam-bar levels 0/1/2 and level-2 solvers against level 2 (DP45, rtol 1e-9)")
    out = ROOT / "out" / "bench_cam_bar_levels.png"
    out.parent.mkdir(exist_ok=True)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"chart: {out}")


if __name__ == "__main__":
    main()
