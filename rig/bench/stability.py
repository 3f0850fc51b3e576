"""``rig bench stability``: where the fixed-step methods fail on the cam-bar level 2, and whether it is seen.

Cells: method (euler, semi-implicit euler, rk4) × step size h × contact-stiffness factor (the roller/flank
contact length ``roller_width`` scaled, so the contact stiffness and its mode frequency rise with it) × cam speed
(the scene's constant speed scaled: the faster cam loads the contact harder and switches flanks), over ``t_sim``
of the scene's machine from the quasi-static start. Each cell is compared with a reference
(DP45 at rtol 1e-11) on the scene's sample grid (error = max|e − e_ref| / max|e_ref|) and classed
``converged`` (error ≤ 1e-3), ``inaccurate`` (error above 1e-3, but at most :data:`SILENT` or with the method's
:class:`~rig.solvers.ResolutionWarning`, in ``message``), ``detected`` (the method stopped with its divergence
report) or ``silent`` (error above :data:`SILENT`, or non-finite, without a report or warning: a wrong answer nobody
was told about; until 2026-11-28 only an error above 1 counted). The adaptive methods (dp45, tsit5, rodas4) run once per stiffness at rtol 1e-6 with their RHS calls.
Writes ``DIR/stability.csv`` and ``DIR/stability.png`` (one panel per fixed-step method and cam speed).
"""
from __future__ import annotations

import argparse
import csv
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

FIXED = {"euler": "Euler", "semi-implicit euler": "SymplecticEuler", "rk4": "RK4"}
ADAPTIVE = {"dp45": "DP45", "tsit5": "Tsit5", "rodas4": "Rodas4"}
STEPS = [4e-4, 2e-4, 1e-4, 5e-5, 2.5e-5, 1.25e-5]
FACTORS = [0.5, 1.0, 2.0, 4.0]
SPEEDS = [1.0, 2.0]            # × the scene's cam speed (the demo machine: 150 and 300 rpm)
CLASSES = ("converged", "inaccurate", "detected", "silent")
SILENT = 0.1                   # relative error beyond which an unreported answer is a silent failure
COLUMNS = ("method", "h", "stiffness_factor", "cam_speed_rpm", "class", "error", "nfev", "message")


def _model(scene: Any, factor: float, speed: float = 1.0) -> tuple[Any, tuple, float]:
    """Level 2 with the contact stiffness scaled by ``factor`` and the cam speed by ``speed``; its initial state
    and cam speed (rpm)."""
    from rig.motion.speed import ConstantSpeed
    from rig.plants.cam_bar.level2 import Level2
    from rig.plants.cam_bar.scene_io import mechanism_from_scene, read_level2_model, read_speed_profile
    base, profile = mechanism_from_scene(scene), read_speed_profile(scene)
    omega = profile.nominal_omega * speed
    mech = mechanism_from_scene(scene, roller_width=base.roller_width * factor)
    model = Level2(mech, ConstantSpeed(omega, phi0=profile.phi0), model=read_level2_model(scene))
    return model, model.initial_state(0.0), omega * 60.0 / (2.0 * math.pi)


def _run(model: Any, y0: tuple, grid: np.ndarray, method: str, **options: float) -> tuple[np.ndarray, int, str]:
    """e on the grid, RHS calls and the run's ResolutionWarning ("" without one)."""
    from rig.solvers import ResolutionWarning, SolverDivergence, StiffnessWarning, integrate
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("ignore", StiffnessWarning)
        warnings.simplefilter("always", ResolutionWarning)
        sol = integrate(model.problem(y0), (0.0, float(grid[-1])), method=method, t_eval=grid, **options)
    if sol.status == "terminated":       # the model's own stop (a terminal event): reported, not silent
        step = f", h = {options['h'] * 1e3:g} ms" if "h" in options else f", rtol = {options.get('rtol', '')}"
        raise SolverDivergence(f"{method}{step}: stopped at t = {sol.t_final:.6g} s by the terminal event "
                               f"{sol.events[-1].name!r}: {model.overload(sol.t_final, sol.y_final)}",
                               sol.t_final, sol.y_final)
    coarse = [str(w.message) for w in said if issubclass(w.category, ResolutionWarning)]
    return sol.y[0], sol.nfev, coarse[0] if coarse else ""


def stability_map(scene_path: str | Path, t_sim: float = 0.2, steps: list[float] = STEPS,
                  factors: list[float] = FACTORS, speeds: list[float] = (1.0,)) -> list[dict[str, Any]]:
    """Rows of the map (module docstring)."""
    from rig.plants.cam_bar.scene_io import require_level2
    from rig.runner.config import read_config
    from rig.scene import load_scene
    from rig.solvers import SolverDivergence
    scene = load_scene(scene_path)
    require_level2(scene, "rig bench stability")
    rate = read_config(scene, choose_level=False).sample_rate
    grid = np.linspace(0.0, t_sim, int(round(t_sim * rate)) + 1)
    rows: list[dict[str, Any]] = []
    for speed, f in [(v, f) for v in speeds for f in factors]:
        model, y0, rpm = _model(scene, f, speed)
        ref, _, _ = _run(model, y0, grid, "DP45", rtol=1e-11, atol=1e-16, stiffness="ignore")
        scale = float(np.max(np.abs(ref)))
        cells = [(name, method, {"h": h}) for name, method in FIXED.items() for h in steps]
        cells += [(name, method, {"rtol": 1e-6, "atol": 1e-11, "stiffness": "ignore"})
                  for name, method in ADAPTIVE.items()]
        for name, method, options in cells:
            try:
                e, nfev, coarse = _run(model, y0, grid, method, **options)
            except SolverDivergence as exc:
                rows.append({"method": name, "h": options.get("h", ""), "stiffness_factor": f,
                             "cam_speed_rpm": f"{rpm:.4g}", "class": "detected",
                             "error": "", "nfev": "", "message": " ".join(str(exc).split())})
                continue
            err = float(np.max(np.abs(e - ref)) / scale)
            err = err if math.isfinite(err) else math.inf
            cls = "converged" if err <= 1e-3 else "inaccurate" if err <= SILENT or (coarse and math.isfinite(err)) \
                else "silent"
            rows.append({"method": name, "h": options.get("h", ""), "stiffness_factor": f,
                         "cam_speed_rpm": f"{rpm:.4g}", "class": cls,
                         "error": f"{err:.3e}", "nfev": nfev, "message": " ".join(coarse.split())})
    return rows


def write(rows: list[dict[str, Any]], out: Path) -> tuple[Path, Path]:
    """``stability.csv`` and ``stability.png`` in ``out``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    from rig.analysis.plots import write_tight
    out.mkdir(parents=True, exist_ok=True)
    path = out / "stability.csv"
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    fixed = [r for r in rows if r["method"] in FIXED]
    steps = sorted({float(r["h"]) for r in fixed}, reverse=True)
    factors = sorted({float(r["stiffness_factor"]) for r in fixed})
    rpms = sorted({r["cam_speed_rpm"] for r in fixed}, key=float)
    fig, axes = plt.subplots(len(rpms), len(FIXED), figsize=(4.2 * len(FIXED), 3.2 * len(rpms) + 0.6),
                             sharey=True, squeeze=False)
    cmap = ListedColormap(["#2e8b57", "#f0c040", "#4a7fd0", "#d03030"])
    for row, rpm in zip(axes, rpms):
        for ax, name in zip(row, FIXED):
            grid = np.full((len(factors), len(steps)), np.nan)
            for r in fixed:
                if r["method"] == name and r["cam_speed_rpm"] == rpm:
                    grid[factors.index(float(r["stiffness_factor"])), steps.index(float(r["h"]))] = \
                        CLASSES.index(r["class"])
            ax.imshow(grid, cmap=cmap, vmin=-0.5, vmax=3.5, aspect="auto", origin="lower")
            ax.set_xticks(range(len(steps)), [f"{h * 1e6:g}" for h in steps], rotation=45)
            ax.set_yticks(range(len(factors)), [f"{f:g}" for f in factors])
            ax.set_xlabel("step h (µs)")
            ax.set_title(f"{name}, cam {float(rpm):g} rpm")
        row[0].set_ylabel("contact stiffness factor")
    fig.suptitle("cam-bar level 2 — green: converged, yellow: inaccurate (within 10 % or warned), blue: divergence "
                 "detected, red: silent (wrong, unreported)", fontsize=10)
    return path, write_tight(fig, out / "stability.png")


def cmd_stability(args: argparse.Namespace) -> int:
    from rig.outputs import claim_dir, writable_dir
    out = Path(args.output)
    writable_dir(out, "output")
    rows = stability_map(args.scene, t_sim=0.1 if args.quick else 0.2,
                         steps=STEPS[::2] if args.quick else STEPS, factors=[1.0, 4.0] if args.quick else FACTORS,
                         speeds=[1.0] if args.quick else SPEEDS)
    csv_path, png = write(rows, claim_dir(out))
    counts = {c: sum(r["class"] == c for r in rows) for c in CLASSES}
    print(", ".join(f"{c} {n}" for c, n in counts.items()) + f" of {len(rows)} cells")
    for r in rows:
        if r["class"] == "silent":
            print(f"silent: {r['method']} h = {r['h']} s, stiffness x{r['stiffness_factor']}, cam "
                  f"{r['cam_speed_rpm']} rpm: error {r['error']} "
                  f"without a divergence report or an accuracy warning")
    print(f"wrote {csv_path} and {png}")
    return 0


def register(sub: argparse._SubParsersAction, parents: list[argparse.ArgumentParser]) -> None:
    """``rig bench stability [--scene SCENE] [--quick] -o DIR``."""
    from rig.cli import DATA
    p = sub.add_parser("stability", parents=parents,
                       help="fixed-step methods x step x contact stiffness x cam speed on the cam-bar level 2: converged, "
                            "inaccurate, detected or silent (CSV + PNG)")
    p.add_argument("--scene", default=str(DATA / "scenes" / "pin_insertion_l2.toml"),
                   help="level-2 cam-bar scene (default data/scenes/pin_insertion_l2.toml)")
    p.add_argument("--quick", action="store_true", help="fewer cells, shorter span")
    p.add_argument("-o", "--output", required=True, help="output directory")
    p.set_defaults(func=cmd_stability)
