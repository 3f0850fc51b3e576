"""Clutch stand solver benchmark: real-time factor at 1e-6 relative error in φ_r and speed vs scipy.

For the start-up and short-shock scenes: reference = our DP45 at rtol 1e-12 (cross-checked against
scipy DOP853 at 1e-12); error = max|φ_r − φ_r,ref| / max|φ_r,ref| on the scene's sample grid.
Each solver runs a tolerance sweep; the cheapest run reaching 1e-6 is compared. scipy solve_ivp gets
the same tuple RHS and is restarted at the load's time breaks. Writes out/bench_clutch_<scene>.png.
Run: python benchmarks/bench_clutch.py
"""
from __future__ import annotations

import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from rig.plants.clutch.stand import ClutchStand  # noqa: E402
from rig.scene import load_scene  # noqa: E402
from rig.solvers import integrate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TARGET = 1e-6


def ours(dyn, y0, t, method, **opt):
    sol = integrate(dyn.problem(y0), (t[0], t[-1]), method=method, t_eval=t, **opt)
    return sol.y[0] - sol.y[2]


def scipy_run(dyn, y0, t, method, rtol, atol):
    breaks = [b for b in dyn.problem(y0).time_breaks if t[0] < b < t[-1]]
    edges, y, out = [t[0], *breaks, t[-1]], np.array(y0), []
    fun = lambda tt, yy: dyn.rhs(tt, tuple(yy))  # noqa: E731
    for a, b in zip(edges, edges[1:]):
        sel = t[(t >= a) & (t <= b)] if a == t[0] else t[(t > a) & (t <= b)]
        s = solve_ivp(fun, (a, b), y, method=method, t_eval=sel, rtol=rtol, atol=atol)
        out.append(s.y[0] - s.y[2])
        y = s.y[:, -1] if sel.size and sel[-1] == b else solve_ivp(fun, (a, b), y, method=method, rtol=rtol,
                                                                     atol=atol).y[:, -1]
    return np.concatenate(out)


def timed(f, *a, **k):
    best, res = np.inf, None
    for _ in range(2):
        t0 = time.perf_counter()
        res = f(*a, **k)
        best = min(best, time.perf_counter() - t0)
    return best, res


def bench(scene_name: str) -> None:
    scene = load_scene(ROOT / "data" / "scenes" / f"{scene_name}.toml")
    stand = ClutchStand.from_scene(scene)
    dyn, y0 = stand.dynamics, stand.y
    from rig.units import to_si
    T = to_si(scene.data["scene"]["duration"], "s")
    t = np.linspace(0.0, T, 2001)
    ref = ours(dyn, y0, t, "DP45", rtol=1e-12, atol=1e-14)
    ref_sp = scipy_run(dyn, y0, t, "DOP853", 1e-12, 1e-14)
    scale = np.max(np.abs(ref))
    print(f"\n== {scene_name}: duration {T:.3g} s, max|phi_r| {np.degrees(scale):.3g} deg, "
          f"reference check vs scipy DOP853: {np.max(np.abs(ref_sp - ref)) / scale:.1e}")
    runs = {}
    for label, f, params in (
            ("ours DP45", lambda p: ours(dyn, y0, t, "DP45", rtol=p, atol=p * 1e-3), [1e-4, 1e-5, 1e-6, 1e-7, 1e-8]),
            ("ours RK4", lambda p: ours(dyn, y0, t, "RK4", h=p), [1e-3, 5e-4, 2.5e-4, 1.25e-4]),
            ("scipy RK45", lambda p: scipy_run(dyn, y0, t, "RK45", p, p * 1e-3), [1e-4, 1e-5, 1e-6, 1e-7, 1e-8]),
            ("scipy DOP853", lambda p: scipy_run(dyn, y0, t, "DOP853", p, p * 1e-3), [1e-5, 1e-6, 1e-7, 1e-8])):
        runs[label] = []
        for p in params:
            cpu, phi = timed(f, p)
            err = np.abs(phi - ref) / scale
            runs[label].append((p, cpu, float(err.max()), err))
            print(f"  {label:13s} param {p:8.1e}: cpu {cpu * 1e3:8.1f} ms  rel.err {err.max():.2e}  "
                  f"real-time x{T / cpu:7.1f}")
    best = {}
    for label, rs in runs.items():
        ok = [r for r in rs if r[2] <= TARGET]
        best[label] = min(ok, key=lambda r: r[1]) if ok else None
    b = best["ours DP45"]
    if b:
        print(f"  -> ours DP45 at <= {TARGET:g}: real-time factor {T / b[1]:.1f}x (param {b[0]:g})")
        for other in ("scipy RK45", "scipy DOP853", "ours RK4"):
            if best[other]:
                print(f"  -> speed-up of ours DP45 over {other} at equal error: {best[other][1] / b[1]:.1f}x")
    fig, ax = plt.subplots(figsize=(8, 5))
    for label, rs in runs.items():
        for p, cpu, e, err in rs:
            ax.semilogy(t, np.maximum(err, 1e-16), lw=0.8, label=f"{label} {p:g} ({cpu * 1e3:.0f} ms)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("relative error in phi_r")
    ax.set_title(scene_name)
    ax.legend(fontsize=6, ncol=2)
    (ROOT / "out").mkdir(exist_ok=True)
    fig.savefig(ROOT / "out" / f"bench_clutch_{scene_name}.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    for name in ("clutch_startup", "clutch_shock_short"):
        bench(name)
