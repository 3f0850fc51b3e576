"""End-to-end real-time factor of the demo scene (plant → transducers → DigiForce → CAN + serial → host →
MCAP), measured in one run: classic CAN (the demo) and CAN FD (fewer, larger frames), each against the
bare python-can ``virtual`` bus moving the same number of frames (send + receive, nothing else) and
against the 1 Mbit/s wire.

Run: ``python benchmarks/bench_rig.py [cycles]`` (default 20; the demo runs 50). Target: >= 10x real time
at 10 kHz acquisition.
"""
from __future__ import annotations

import sys
import tempfile
import time
import uuid
from pathlib import Path

import can

from rig.runner import run_scene

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "data" / "scenes" / "pin_insertion.toml"


def bare_bus_rate(frames: int, length: int) -> float:
    """Frames/s through python-can's ``virtual`` bus alone: ``bus.send`` of each frame, then draining the
    receiver frame by frame with ``recv``."""
    channel = f"bench-{uuid.uuid4().hex}"
    with can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as tx, \
            can.Bus(interface="virtual", channel=channel) as rx:
        start = time.perf_counter()
        for i in range(frames):
            tx.send(can.Message(arbitration_id=0x302, data=bytes(length), is_extended_id=False, is_fd=length > 8,
                                timestamp=i * 1e-4))
        while rx.recv(0.0) is not None:
            pass
        return frames / (time.perf_counter() - start)


def main() -> None:
    cycles = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    with tempfile.TemporaryDirectory() as tmp:
        fd_scene = Path(tmp) / "pin_insertion_fd.toml"
        fd_scene.write_text(SCENE.read_text().replace("bitrate = 1000000", "bitrate = 1000000\nfd = true\n"
                                                      "data_bitrate = 4000000", 1))
        print(f"demo scene, {cycles} cycles at 10 kHz acquisition (wall time includes serial configuration "
              f"and statistics read-back at 115200 baud)")
        for label, scene, length in (("classic CAN 1 Mbit/s", SCENE, 8), ("CAN FD 1/4 Mbit/s", fd_scene, 64)):
            cpu = time.process_time()
            s = run_scene(scene, Path(tmp) / f"{label[:5]}.mcap", cycles=cycles)
            cpu = time.process_time() - cpu
            rate = s.frames / s.wall_time
            bare = bare_bus_rate(s.frames, length)
            print(f"  {label:22s}: {s.simulated_time:6.2f} s simulated in {s.wall_time:6.2f} s wall ({cpu:5.2f} s CPU) "
                  f"= {s.realtime_factor:5.2f}x real time  [target >= 10x: {'met' if s.realtime_factor >= 10 else 'NOT met'}]")
            print(f"  {'':22s}  {s.frames} frames, {rate:,.0f} frames/s end to end = {rate / bare:.3f} x the bare "
                  f"virtual bus ({bare:,.0f} frames/s), {s.frames / s.simulated_time:,.0f} frames/s on the wire")


if __name__ == "__main__":
    main()
