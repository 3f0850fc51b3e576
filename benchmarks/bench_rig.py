"""End-to-end real-time factor of the demo scene (plant → transducers → DigiForce → CAN + serial → host →
MCAP), measured in one run, classic CAN (the demo) against CAN FD (fewer, larger frames).

Run: ``python benchmarks/bench_rig.py [cycles]``. Target: >= 10x real time at 10 kHz acquisition.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from rig.runner import run_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"


def main() -> None:
    cycles = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    with tempfile.TemporaryDirectory() as tmp:
        fd_scene = Path(tmp) / "pin_insertion_fd.toml"
        fd_scene.write_text(SCENE.read_text().replace("bitrate = 1000000", "bitrate = 1000000\nfd = true\n"
                                                      "data_bitrate = 4000000", 1))
        print(f"demo scene, {cycles} cycles at 10 kHz acquisition (wall time includes serial configuration "
              f"and statistics read-back at 115200 baud)")
        for label, scene in (("classic CAN 1 Mbit/s", SCENE), ("CAN FD 1/4 Mbit/s", fd_scene)):
            s = run_scene(scene, Path(tmp) / f"{label[:5]}.mcap", cycles=cycles)
            print(f"  {label:22s}: {s.simulated_time:6.2f} s simulated in {s.wall_time:6.2f} s wall = "
                  f"{s.realtime_factor:5.2f}x real time, {s.frames} frames ({s.frames / s.wall_time:,.0f} frames/s)"
                  f"  [target >= 10x: {'met' if s.realtime_factor >= 10 else 'NOT met'}]")


if __name__ == "__main__":
    main()
