"""Where does the gripper jump? Level 2 over cam speed × spring rate × groove clearance (issue 14), on the sweep
machinery (:mod:`rig.sweep`: any executor, the same map everywhere).

Each point is the scene's machine (nominal: without its per-cycle variation) forced to level 2, with that speed,
spring rate and clearance, ``revolutions`` cam revolutions from the scene's start; recorded per point over the
last revolution: flank switches, the largest gap the roller opens off the working flank (m) and the gripper's
peak-to-peak deviation from its level-0 law (m). The sensor preload is not an axis: it offsets the reading only
(docs/cam-bar.md); pin clearances are (``rig sweep … --param plant.joints.follower=…`` on a scene with
``[plant.joints]``).

Run: python -m rig.plants.cam_bar.jump_map [SCENE] [-o out/jump_map.png] [--executor … --workers N]
"""
from __future__ import annotations

import argparse
import sys
from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from rig.motion.speed import RPM
from rig.sweep import Param
from rig.sweep.run import run_sweep

if TYPE_CHECKING:
    from rig.executors import Executor
    from rig.scene import Scene

SPEEDS_RPM = (100.0, 150.0, 200.0, 250.0, 280.0, 290.0, 300.0)
RATES = (1090.0, 1190.0, 1680.0, 1890.0)
CLEARANCES = (0.025e-3, 0.05e-3, 0.10e-3)
METRICS = ("flank_switches", "roller_gap", "gripper_deviation")


class JumpMap(NamedTuple):
    """Results on the grid (speed, rate, clearance): ``switches`` (count), ``gap`` and ``gripper`` (m), and why a
    point failed ('' where it ran; its values are then NaN / −1 switches)."""

    speeds: np.ndarray      # rad/s
    rates: np.ndarray       # N/m
    clearances: np.ndarray  # m
    switches: np.ndarray
    gap: np.ndarray
    gripper: np.ndarray
    errors: np.ndarray


def jump_map(scene: "Scene", speeds=SPEEDS_RPM, rates=RATES, clearances=CLEARANCES, revolutions: int = 2,
             executor: "Executor | None" = None) -> JumpMap:
    """The scene's machine at level 2 at each cam speed (rpm), spring rate (N/m) and clearance (m) on ``executor``
    (default serial): :func:`rig.sweep.run.run_sweep` with the metrics :data:`METRICS`."""
    from rig.executors import make_executor
    params = (Param("scene.fidelity", (2,)), Param("speed.speed", tuple(f"{v!r} rpm" for v in speeds)),
              Param("plant.k", tuple(f"{k!r} N/m" for k in rates)),
              Param("plant.clearance", tuple(f"{c!r} m" for c in clearances)))
    with make_executor("serial") if executor is None else nullcontext(executor) as chosen:
        result = run_sweep(scene, params, METRICS, chosen, revolutions)
    shape = (len(speeds), len(rates), len(clearances))
    column = {m: np.array([v[m] for v in result.values]).reshape(shape) for m in METRICS}
    switches = np.where(np.isnan(column["flank_switches"]), -1, column["flank_switches"]).astype(int)
    return JumpMap(np.asarray(speeds, float) * RPM, np.asarray(rates, float), np.asarray(clearances, float),
                   switches, column["roller_gap"], column["gripper_deviation"],
                   np.array(result.errors, dtype=object).reshape(shape))


def plot(result: JumpMap, path: Path) -> Path:
    """One panel per clearance: switches per revolution (colour) and gripper deviation (µm, text) over speed ×
    spring rate; written to ``path`` (PNG)."""
    from matplotlib.figure import Figure

    n = len(result.clearances)
    fig = Figure(figsize=(4.2 * n, 3.8), constrained_layout=True)
    axes = np.atleast_1d(fig.subplots(1, n, sharey=True))
    rpm = result.speeds / RPM
    vmax = max(int(result.switches.max()), 1)
    for m, ax in enumerate(axes):
        image = ax.imshow(result.switches[:, :, m].T, origin="lower", aspect="auto", cmap="Reds", vmin=0, vmax=vmax)
        for i in range(len(rpm)):
            for j in range(len(result.rates)):
                ax.text(i, j, f"{result.gripper[i, j, m] * 1e6:.0f}", ha="center", va="center", fontsize=8)
        ax.set_xticks(range(len(rpm)), [f"{v:g}" for v in rpm])
        ax.set_yticks(range(len(result.rates)), [f"{k / 1e3:.2f}" for k in result.rates])
        ax.set_xlabel("cam speed (rpm = pins/min)")
        ax.set_title(f"clearance {result.clearances[m] * 1e3:g} mm")
    axes[0].set_ylabel("spring rate (N/mm)")
    fig.colorbar(image, ax=list(axes), label="flank switches per revolution")
    fig.suptitle("Where does it jump? Level 2; numbers: gripper deviation from its law, µm peak to peak")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path


def main(argv: list[str] | None = None) -> None:
    from rig.executors.options import add_executor_arguments, run_on_executor
    from rig.scene import load_scene
    from rig.stops import stopped
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(Path(__file__).resolve().parents[3] / "data" / "scenes"
                                                       / "pin_insertion_as_drawn.toml"))
    parser.add_argument("-o", "--output", default="out/jump_map.png")
    add_executor_arguments(parser, local="dask-processes")
    args = parser.parse_args(argv)

    def kept(result: JumpMap, stop: KeyboardInterrupt) -> None:     # after the last point, while the workers closed
        show(result, Path(args.output))
        print(f"{stopped(stop)} while the workers closed, after the map's last point: the map above is whole",
              file=sys.stderr)
        raise SystemExit(130) from None

    show(run_on_executor(args, lambda executor: jump_map(load_scene(args.scene), executor=executor), kept,
                         local="dask-processes"), Path(args.output))


def show(result: JumpMap, output: Path) -> None:
    """Print the map's table and failures, and write its chart to ``output``."""
    for m, c in enumerate(result.clearances):
        print(f"clearance {c * 1e3:g} mm: switches per revolution (rows: spring rate N/mm; columns: rpm "
              f"{', '.join(f'{v / RPM:g}' for v in result.speeds)})")
        for j, k in enumerate(result.rates):
            cells = "  ".join(f"{result.switches[i, j, m]:d} ({result.gripper[i, j, m] * 1e6:4.0f} µm)"
                              for i in range(len(result.speeds)))
            print(f"  {k / 1e3:.2f}: {cells}")
    for index in zip(*np.nonzero(result.errors != "")):
        print(f"  failed at {result.speeds[index[0]] / RPM:g} rpm, {result.rates[index[1]] / 1e3:g} N/mm, "
              f"{result.clearances[index[2]] * 1e3:g} mm: {result.errors[index]}")
    print(f"map: {plot(result, output)}")


if __name__ == "__main__":
    main()
