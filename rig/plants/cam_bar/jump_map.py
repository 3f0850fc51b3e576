"""Where does the gripper jump? Level 2 over cam speed × spring rate × groove clearance (issue 14).

For each point one machine (the scene's, with that speed, spring rate and clearance) runs ``revolutions`` cam
revolutions at level 2 from the quasi-static start; recorded per point: flank switches in the last revolution,
the largest gap the roller opens off the working flank (m) and the gripper's peak-to-peak deviation from its
level-0 law (m). A serial loop (the sweep machinery of the scale-out issue does not exist yet). The sensor
preload is not an axis: it offsets the reading only (docs/cam-bar.md).

Run: python -m rig.plants.cam_bar.jump_map [SCENE] [-o out/jump_map.png]
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from math import tau
from pathlib import Path
from typing import NamedTuple

import numpy as np

from rig.motion.speed import RPM, ConstantSpeed
from rig.plants.cam_bar.level2 import Level2
from rig.plants.cam_bar.level2_model import Level2Model
from rig.plants.cam_bar.mechanism import PinInsertionMechanism

SPEEDS_RPM = (100.0, 150.0, 200.0, 250.0, 280.0, 290.0, 300.0)
RATES = (1090.0, 1190.0, 1680.0, 1890.0)
CLEARANCES = (0.025e-3, 0.05e-3, 0.10e-3)


class JumpMap(NamedTuple):
    """Results on the grid (speed, rate, clearance): ``switches`` (count), ``gap`` and ``gripper`` (m)."""

    speeds: np.ndarray      # rad/s
    rates: np.ndarray       # N/m
    clearances: np.ndarray  # m
    switches: np.ndarray
    gap: np.ndarray
    gripper: np.ndarray


def jump_map(mech: PinInsertionMechanism, speeds=SPEEDS_RPM, rates=RATES, clearances=CLEARANCES,
             revolutions: int = 2, samples: int = 1441, model: Level2Model = Level2Model()) -> JumpMap:
    """Level 2 of ``mech`` under the assumptions ``model`` (variation and cam drive off) at each cam speed (rpm),
    spring rate (N/m) and clearance (m); statistics of the last of ``revolutions`` revolutions on ``samples``
    points."""
    shape = (len(speeds), len(rates), len(clearances))
    switches, gap, grip = np.zeros(shape, int), np.zeros(shape), np.zeros(shape)
    for i, rpm in enumerate(speeds):
        period = tau / (rpm * RPM)
        t = np.linspace((revolutions - 1) * period, revolutions * period, samples)
        for j, k in enumerate(rates):
            for m, c in enumerate(clearances):
                machine = replace(mech, k=k, clearance=c, cam_drive=None)
                level2 = Level2(machine, ConstantSpeed(rpm * RPM), model=model)
                run = level2.simulate((0.0, t[-1]), t_eval=t, rtol=1e-7, atol=1e-12)
                sig = level2.signals(t, run.solution.y)
                switches[i, j, m] = sum(1 for e in run.switches if e.time >= t[0])
                gap[i, j, m] = max(float(np.max(-sig["delta_w"])), 0.0)
                grip[i, j, m] = float(np.ptp(sig["s"] - machine.state(sig["phi"]).s))
    return JumpMap(np.asarray(speeds) * RPM, np.asarray(rates, float), np.asarray(clearances, float), switches,
                   gap, grip)


def plot(result: JumpMap, path: Path) -> Path:
    """One panel per clearance: switches per revolution (colour) and gripper deviation (µm, text) over speed ×
    spring rate; written to ``path`` (PNG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(result.clearances)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 3.8), sharey=True, constrained_layout=True)
    axes = np.atleast_1d(axes)
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
    fig.colorbar(image, ax=axes, label="flank switches per revolution")
    fig.suptitle("Where does it jump? Level 2; numbers: gripper deviation from its law, µm peak to peak")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> None:
    from rig.plants.cam_bar.scene_io import read_level2_model
    from rig.scene import load_scene
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(Path(__file__).resolve().parents[3] / "data" / "scenes"
                                                       / "pin_insertion_as_drawn.toml"))
    parser.add_argument("-o", "--output", default="out/jump_map.png")
    args = parser.parse_args(argv)
    scene = load_scene(args.scene)
    result = jump_map(PinInsertionMechanism.from_scene(scene), model=read_level2_model(scene))
    for m, c in enumerate(result.clearances):
        print(f"clearance {c * 1e3:g} mm: switches per revolution (rows: spring rate N/mm; columns: rpm "
              f"{', '.join(f'{v / RPM:g}' for v in result.speeds)})")
        for j, k in enumerate(result.rates):
            cells = "  ".join(f"{result.switches[i, j, m]:d} ({result.gripper[i, j, m] * 1e6:4.0f} µm)"
                              for i in range(len(result.speeds)))
            print(f"  {k / 1e3:.2f}: {cells}")
    print(f"map: {plot(result, Path(args.output))}")


if __name__ == "__main__":
    main()
