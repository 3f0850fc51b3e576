"""Run-phase real-time factor of every shipped scene end to end, as a user runs it: ``rig run SCENE -o OUT --no-report``
in a fresh process (plant → transducers → unit → CAN + serial → host → MCAP), numba's cache warm (one untimed run of
each scene first, unless ``--cold``). The factor is the one ``rig run`` prints (simulated time / wall time of the run
phase, without the serial set-up and read-back); the data path's target is >= 10x. Also printed: the whole command's
wall time.

Run: ``python benchmarks/bench_scenes.py [--repeats 2] [--cold] [SCENE ...]`` (default: every data/scenes/*.toml).
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RIG = Path(sys.executable).with_name("rig")
LINE = re.compile(r"([\d.]+) s simulated(?: \([^)]*\))? in ([\d.]+) s \(([\d.]+)x real time")
TARGET = 10.0


def run(scene: Path, out: Path) -> tuple[float, float, float, float]:
    """(simulated s, run phase s, printed factor, command wall s) of one ``rig run``."""
    cmd = [str(RIG), "run", str(scene), "-o", str(out), "--no-report"]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    m = LINE.search(p.stdout)
    if p.returncode or m is None:
        raise SystemExit(f"{scene.name}: rig run failed ({p.returncode}):\n{p.stdout[-1500:]}\n{p.stderr[-1500:]}")
    return float(m[1]), float(m[2]), float(m[3]), wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="*", type=Path)
    ap.add_argument("--repeats", type=int, default=2, help="timed runs per scene, the best kept (default 2)")
    ap.add_argument("--cold", action="store_true", help="no untimed first run")
    args = ap.parse_args()
    scenes = args.scenes or sorted((ROOT / "data" / "scenes").glob("*.toml"))
    print(f"{'scene':34s} {'simulated':>9s} {'run phase':>9s} {'factor':>7s} {'command':>8s}  >= {TARGET:g}x")
    below = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes:
            out = Path(tmp) / f"{scene.stem}.mcap"
            if not args.cold:
                run(scene, out)
            best = max((run(scene, out) for _ in range(args.repeats)), key=lambda r: r[2])
            sim, phase, factor, wall = best
            ok = factor >= TARGET
            below += [] if ok else [scene.stem]
            print(f"{scene.stem:34s} {sim:8.2f}s {phase:8.2f}s {factor:6.1f}x {wall:7.2f}s  {'yes' if ok else 'NO'}",
                  flush=True)
    print(f"{len(scenes) - len(below)} of {len(scenes)} scenes at >= {TARGET:g}x real time"
          + (f"; below: {', '.join(below)}" if below else ""))


if __name__ == "__main__":
    main()
