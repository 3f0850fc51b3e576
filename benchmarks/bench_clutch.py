"""Clutch stand solver benchmark: real-time factor at 1e-6 relative error in φ_r and speed vs scipy.

For the start-up and short-shock scenes (stick–slip friction, the scene default): reference = our DP45
at rtol 1e-12, cross-checked against scipy DOP853 at 1e-12; error = max|φ_r − φ_r,ref| / max|φ_r,ref|
on the scene's sample grid. Each solver runs a tolerance sweep; the cheapest run reaching 1e-6 is
compared. scipy ``solve_ivp`` gets the same tuple RHS, the same event functions (terminal where ours
restart) and the same mode switches/resets, restarted at the load's time breaks. The regularised
(tanh) model is run too, to show the stiffness that motivated the switch. Writes
out/bench_clutch_<scene>.png (error against time per solver/tolerance).
Run: python benchmarks/bench_clutch.py
"""
from __future__ import annotations

import math
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from rig.plants.clutch.dynamics import ClutchDynamics  # noqa: E402
from rig.plants.clutch.stand import ClutchStand  # noqa: E402
from rig.scene import load_scene  # noqa: E402
from rig.solvers import StiffnessWarning, integrate  # noqa: E402
from rig.units import to_si  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TARGET = 1e-6


def ours(dyn, y0, t, method, **opt):
    sol = integrate(dyn.problem(y0), (t[0], t[-1]), method=method, t_eval=t, **opt)
    return sol.y[0] - sol.y[2]


def scipy_run(dyn, y0, t, method, rtol, atol):
    """solve_ivp on the same hybrid problem: terminal events where ours restart, same actions/resets."""
    prob = dyn.problem(y0)
    fun = lambda tt, yy: dyn.rhs(tt, tuple(yy))  # noqa: E731
    edges = [b for b in prob.time_breaks if t[0] < b < t[-1]] + [t[-1]]
    out = np.empty((len(y0), t.size))
    tc, y = float(t[0]), tuple(y0)
    prob.reset(tc, y)
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
                if prob.reset(tc, y):
                    pass
                break
            k = next(idx[m] for m, te in enumerate(s.t_events) if te.size and te[-1] == t_end)
            e = prob.events[k]
            from rig.solvers import EventRecord
            changed = e.action(EventRecord(t_end, e.name, y, 0.0)) if e.action else False
            if isinstance(changed, tuple):
                y = changed
            tc = t_end
            prob.reset(tc, y)
    return out[0] - out[2]


def timed(f, *a, **k):
    best, res = np.inf, None
    for _ in range(3):
        t0 = time.perf_counter()
        res = f(*a, **k)
        best = min(best, time.perf_counter() - t0)
    return best, res


def sweep(runs, label, f, params, ref, scale, T):
    runs[label] = []
    for p in params:
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always", StiffnessWarning)
            cpu, phi = timed(f, p)
        err = np.abs(phi - ref) / scale
        runs[label].append((p, cpu, float(err.max()), err))
        stiff = " [StiffnessWarning]" if any(issubclass(x.category, StiffnessWarning) for x in w) else ""
        print(f"  {label:16s} param {p:8.1e}: cpu {cpu * 1e3:8.2f} ms  rel.err {err.max():.2e}  "
              f"real-time x{T / cpu:7.1f}{stiff}")


def bench(scene_name: str) -> None:
    scene = load_scene(ROOT / "data" / "scenes" / f"{scene_name}.toml")
    stand = ClutchStand.from_scene(scene)
    dyn, y0 = stand.dynamics, stand.y
    T = to_si(scene.data["scene"]["duration"], "s")
    t = np.linspace(0.0, T, 2001)
    ref = ours(dyn, y0, t, "DP45", rtol=1e-12, atol=1e-14)
    ref_sp = scipy_run(dyn, y0, t, "DOP853", 1e-12, 1e-14)
    scale = np.max(np.abs(ref))
    print(f"\n== {scene_name} (stick-slip): duration {T:.3g} s, max|phi_r| {np.degrees(scale):.3g} deg, "
          f"mode switches {len(dyn._log_t) - 1}, reference vs scipy DOP853: {np.max(np.abs(ref_sp - ref)) / scale:.1e}")
    runs: dict[str, list] = {}
    tols = [1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
    sweep(runs, "ours DP45", lambda p: ours(dyn, y0, t, "DP45", rtol=p, atol=p * 1e-3), tols, ref, scale, T)
    sweep(runs, "ours RK4", lambda p: ours(dyn, y0, t, "RK4", h=p), [2e-3, 1e-3, 5e-4, 2.5e-4], ref, scale, T)
    sweep(runs, "scipy RK45", lambda p: scipy_run(dyn, y0, t, "RK45", p, p * 1e-3), tols, ref, scale, T)
    sweep(runs, "scipy DOP853", lambda p: scipy_run(dyn, y0, t, "DOP853", p, p * 1e-3), tols[:4], ref, scale, T)
    c = dyn.clutch
    smooth = ClutchDynamics(c, dyn.motor, dyn.load, v_s=0.01, blocked=dyn.blocked, J_down=dyn.J_down,
                            friction="tanh")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StiffnessWarning)
        ref_tanh = ours(smooth, y0, t, "DP45", rtol=1e-12, atol=1e-14)
    sweep(runs, "ours DP45 tanh", lambda p: ours(smooth, y0, t, "DP45", rtol=p, atol=p * 1e-3), [1e-5, 1e-7],
          ref_tanh, np.max(np.abs(ref_tanh)), T)
    best = {}
    for label, rs in runs.items():
        ok = [r for r in rs if r[2] <= TARGET]
        best[label] = min(ok, key=lambda r: r[1]) if ok else None
    b = best["ours DP45"]
    if b:
        print(f"  -> ours DP45 at <= {TARGET:g}: real-time factor {T / b[1]:.0f}x (rtol {b[0]:g}, {b[1] * 1e3:.2f} ms)")
        for other in ("scipy RK45", "scipy DOP853", "ours RK4", "ours DP45 tanh"):
            if best[other]:
                print(f"  -> speed-up of ours DP45 over {other} at equal error: {best[other][1] / b[1]:.1f}x")
            else:
                print(f"  -> {other}: no run reached {TARGET:g}")
    else:
        print(f"  -> ours DP45 never reached {TARGET:g}")
    fig, ax = plt.subplots(figsize=(9, 5.5))
    for label, rs in runs.items():
        for p, cpu, e, err in rs:
            ax.semilogy(t, np.maximum(err, 1e-16), lw=0.8, label=f"{label} {p:g} ({cpu * 1e3:.1f} ms)")
    ax.axhline(TARGET, color="k", ls="--", lw=0.8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("relative error in phi_r")
    ax.set_title(f"{scene_name}: error against time")
    ax.legend(fontsize=5.5, ncol=3)
    (ROOT / "out").mkdir(exist_ok=True)
    fig.savefig(ROOT / "out" / f"bench_clutch_{scene_name}.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    for name in ("clutch_startup", "clutch_shock_short"):
        bench(name)
