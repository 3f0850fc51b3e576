"""Clutch stand solver benchmark: real-time factor at 1e-6 relative error in φ_r and speed vs scipy.

What is compared (per scene, stick–slip friction as in the scene files, whatever values they hold now):
* the same hybrid problem (``ClutchDynamics.problem``: RHS, phase/apex/wrap/stick–slip events, mode
  switches with momentum projection, mode re-selection at load steps) integrated over the scene's
  duration and sampled on 2001 points; error = max|φ_r − φ_r,ref| / max|φ_r,ref|, reference = ours at
  rtol 1e-12, cross-checked against scipy DOP853 at rtol 1e-12 (printed);
* ours: ``rig.solvers.integrate`` with DP45 — stuck segments in closed form (``Problem.flow``), slip
  segments by DP45 — and, to show what the closed form buys, the same with the closed form disabled;
* scipy: ``solve_ivp`` (RK45, DOP853, LSODA) with the same tuple RHS and event functions (terminal where
  ours restart), the same actions/resets, restarted at the load's time breaks; it integrates stuck
  segments numerically (``solve_ivp`` has no closed-form hook);
* each solver runs a tolerance sweep in half decades (atol = 1e-3·rtol); the cheapest run reaching 1e-6
  is compared with the cheapest run of the best scipy method. CPU = best of several runs (2 shared
  cores: noisy). Our right-hand side is compiled (numba, ``rig.plants.clutch.kernel``) and so is our
  DP45 step; scipy calls the same compiled RHS through its Python wrapper (``JitRhs.__call__``).
Writes out/bench_clutch_<scene>.png (error against time). Run: python benchmarks/bench_clutch.py
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from rig.plants.clutch.stand import ClutchStand  # noqa: E402
from rig.scene import load_scene  # noqa: E402
from rig.solvers import EventRecord, integrate  # noqa: E402
from rig.solvers.integrate import _past_root  # noqa: E402  (same switching rule as ours)
from rig.units import to_si  # noqa: E402

TARGET = 1e-6
SCENES = ("clutch_startup", "clutch_shock_short", "clutch_overload_hold", "clutch_shock_drop")
SCIPY = ("RK45", "DOP853", "LSODA")


def ours(dyn, y0, t, closed_form=True, **opt):
    prob = dyn.problem(y0)
    if not closed_form:
        prob.flow = None
    sol = integrate(prob, (t[0], t[-1]), t_eval=t, **opt)
    return sol.y[0]


def scipy_run(dyn, y0, t, method, rtol, atol):
    """solve_ivp on the same hybrid problem: terminal events where ours restart, same actions/resets."""
    prob = dyn.problem(y0)
    fun = lambda tt, yy: dyn.rhs(tt, tuple(yy))  # noqa: E731
    edges = [b for b in prob.time_breaks if t[0] < b < t[-1]] + [t[-1]]
    out = np.empty((len(y0), t.size))
    tc, y = float(t[0]), tuple(y0)
    prob.reset(tc, y)
    stalls = 0
    i = 0
    for b in edges:
        while True:
            evs, idx = [], []
            for k, e in enumerate(prob.events):
                if e.fun(tc, y) == 0.0 and not e.mode_dependent:
                    continue                         # just fired here: scipy would re-trigger at t0
                g = (lambda tt, yy, f=e.fun: f(tt, tuple(yy)))
                g.terminal, g.direction = bool(e.restart or e.action or e.terminal), e.direction
                evs.append(g)
                idx.append(k)
            s = solve_ivp(fun, (tc, b), y, method=method, rtol=rtol, atol=atol, events=evs, dense_output=True)
            t_end = float(s.t[-1])
            j = int(np.searchsorted(t, t_end, side="right"))
            if j > i:
                out[:, i:j] = s.sol(t[i:j])
                i = j
            y = tuple(s.y[:, -1])
            if s.status != 1:
                tc = math.nextafter(t_end, math.inf)
                prob.reset(tc, y)
                break
            k = next(idx[m] for m, te in enumerate(s.t_events) if te.size and te[-1] == t_end)
            e = prob.events[k]
            # restart just past the root (where g has its new sign), as ours acts on mode switches;
            # otherwise solve_ivp re-detects the same root at its start time for ever
            rising = e.direction > 0 if e.direction else e.fun(float(s.t[-2]), tuple(s.y[:, -2])) < 0.0
            t_end = _past_root(e.fun, lambda tt: tuple(s.sol(tt)), t_end, float(b), rising)
            y = tuple(s.sol(t_end))
            stalls = stalls + 1 if t_end <= tc else 0
            if stalls > 50:
                raise RuntimeError(f"scipy {method}: event chattering at t = {t_end} s")
            changed = e.action(EventRecord(t_end, e.name, y, 0.0)) if e.action else False
            if isinstance(changed, tuple):
                y = changed
            tc = t_end
            prob.reset(tc, y)
    return out[0]


def timed(f, *a, **k):
    """Best CPU time of up to 25 runs (at least 5, stopping after ~0.5 s) and the last result."""
    best, res, spent, n = np.inf, None, 0.0, 0
    while n < 5 or (n < 25 and spent < 0.5):
        t0 = time.perf_counter()
        res = f(*a, **k)
        dt = time.perf_counter() - t0
        best, spent, n = min(best, dt), spent + dt, n + 1
    return best, res


def sweep(runs, label, f, params, ref, scale, T):
    runs[label] = []
    for p in params:
        cpu, phi = timed(f, p)
        err = np.abs(phi - ref) / scale
        runs[label].append((p, cpu, float(err.max()), err))
        print(f"  {label:22s} rtol {p:8.1e}: cpu {cpu * 1e3:8.2f} ms  rel.err {err.max():.2e}  "
              f"real-time x{T / cpu:7.1f}")


def bench(scene_name: str) -> dict:
    scene = load_scene(ROOT / "data" / "scenes" / f"{scene_name}.toml")
    T = to_si(scene.data["scene"]["duration"], "s")
    t = np.linspace(0.0, T, 2001)
    stand = ClutchStand.from_scene(scene)         # the mode is re-selected at the start of every run
    dyn, y0 = stand.dynamics, stand.y
    ref = ours(dyn, y0, t, rtol=1e-12, atol=1e-14)
    ref_sp = scipy_run(dyn, y0, t, "DOP853", 1e-12, 1e-14)
    scale = np.max(np.abs(ref))
    sol = integrate(dyn.problem(y0), (0.0, T), rtol=1e-8, atol=1e-11)
    print(f"\n== {scene_name}: duration {T:.3g} s, max|phi_r| {np.degrees(scale):.4g} deg, "
          f"mode switches {len(dyn._log_t) - 1}, disengagements {len(sol.t_events.get('apex', []))}, "
          f"reference vs scipy DOP853: {np.max(np.abs(ref_sp - ref)) / scale:.1e}")
    runs: dict[str, list] = {}
    tols = [10.0 ** -(k / 2) for k in range(10, 19)]         # 1e-5 ... 1e-9 in half decades
    sweep(runs, "ours DP45+closed form", lambda p: ours(dyn, y0, t, rtol=p, atol=p * 1e-3), tols, ref, scale, T)
    sweep(runs, "ours DP45 numeric only", lambda p: ours(dyn, y0, t, False, rtol=p, atol=p * 1e-3), tols, ref, scale, T)
    for m in SCIPY:
        sweep(runs, f"scipy {m}", lambda p, m=m: scipy_run(dyn, y0, t, m, p, p * 1e-3),
              tols + [10 ** -9.5, 1e-10] if m != "RK45" else tols, ref, scale, T)
    best = {label: min((r for r in rs if r[2] <= TARGET), key=lambda r: r[1], default=None)
            for label, rs in runs.items()}
    b = best["ours DP45+closed form"]
    result = {"scene": scene_name, "T": T}
    if b:
        result["realtime"] = T / b[1]
        print(f"  -> ours at <= {TARGET:g}: real-time factor {T / b[1]:.0f}x (rtol {b[0]:g}, {b[1] * 1e3:.2f} ms)")
        for other, r in best.items():
            if other != "ours DP45+closed form":
                print(f"  -> speed-up over {other} at equal error: "
                      + (f"{r[1] / b[1]:.1f}x (rtol {r[0]:g})" if r else f"no run reached {TARGET:g}"))
        sp = [(r[1], label) for label, r in best.items() if label.startswith("scipy") and r]
        if sp:
            result["vs_best_scipy"] = (min(sp)[0] / b[1], min(sp)[1])
            print(f"  => vs best scipy method ({min(sp)[1]}): {min(sp)[0] / b[1]:.1f}x")
    else:
        print(f"  -> ours never reached {TARGET:g}")
    fig, ax = plt.subplots(figsize=(9, 5.5))
    for label, rs in runs.items():
        for p, cpu, e, err in rs:
            ax.semilogy(t, np.maximum(err, 1e-16), lw=0.8, label=f"{label} {p:g} ({cpu * 1e3:.1f} ms)")
    ax.axhline(TARGET, color="k", ls="--", lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("relative error in phi_r")
    ax.set_title(f"{scene_name}: error against time")
    ax.legend(fontsize=5, ncol=3)
    (ROOT / "out").mkdir(exist_ok=True)
    fig.savefig(ROOT / "out" / f"bench_clutch_{scene_name}.png", dpi=110)
    plt.close(fig)
    return result


if __name__ == "__main__":
    results = [bench(name) for name in (sys.argv[1:] or SCENES)]
    print("\nsummary (at <= 1e-6 relative error in phi_r):")
    for r in results:
        vs = r.get("vs_best_scipy")
        print(f"  {r['scene']:22s} real-time x{r.get('realtime', float('nan')):7.0f}   vs best scipy: "
              + (f"{vs[0]:.1f}x ({vs[1]})" if vs else "n/a"))
