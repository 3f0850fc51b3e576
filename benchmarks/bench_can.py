"""Host CAN decode throughput (frames/s) against what a 1 Mbit/s bus can carry; target >= 10x.

Frames are produced once by the device node (curves of 4000 pairs, live data, status) over the
``virtual`` bus and then fed to ``drivers.can.CanHost.receive`` in a timed loop.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path
from types import SimpleNamespace

import can
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from drivers.can import CanHost  # noqa: E402
from firmware_sim.can_budget import BusTiming  # noqa: E402
from firmware_sim.can_node import CanNode  # noqa: E402


class Device:
    """Minimal device for the producer side: idle, program 1, results set by the benchmark."""

    last_result = None

    def status(self) -> dict:
        return {"state": "idle", "program": 1}


def produce(fd: bool, curves: int, rng: np.random.Generator) -> list[can.Message]:
    dev_bus = can.Bus(interface="virtual", channel=f"bench-{fd}", preserve_timestamps=True)
    sink = can.Bus(interface="virtual", channel=f"bench-{fd}", preserve_timestamps=True)
    device = Device()
    node = CanNode(dev_bus, device, bitrate=1_000_000, fd=fd, data_bitrate=5_000_000 if fd else None)
    frames: list[can.Message] = []
    t = 0.0
    for k in range(curves):
        n = 4000
        x = np.linspace(0, 0.04, n)
        device.last_result = SimpleNamespace(number=k + 1, program=1, ok=True, elements=[],
                                             process_values={"y_max": 800.0},
                                             curve=SimpleNamespace(t=t + np.arange(n) * 1e-4, x=x,
                                                                   y=800 * x / 0.04 + rng.normal(0, 1, n)))
        for _ in range(20):                          # 2 s of live data at 10 kHz per curve
            ts = t + np.arange(1000) * 1e-4
            node.publish_live(ts, np.sin(ts) * 0.01, np.cos(ts) * 100)
            t += 0.1
            node.advance_to(t)
            while (m := sink.recv(0)) is not None:
                frames.append(m)
    dev_bus.shutdown()
    sink.shutdown()
    return frames


def decode_rate(frames: list[can.Message], repeats: int = 3) -> tuple[float, CanHost]:
    best = 0.0
    for _ in range(repeats):
        host = CanHost(can.Bus(interface="virtual", channel="bench-host"))
        t0 = time.perf_counter()
        for m in frames:
            host.receive(m)
        best = max(best, len(frames) / (time.perf_counter() - t0))
        host.bus.shutdown()
    return best, host


def main() -> None:
    rng = np.random.default_rng(1)
    for fd in (False, True):
        frames = produce(fd, 4, rng)
        rate, host = decode_rate(frames)
        assert len(host.curves()) == 4 and host.events == [], host.events[:3]
        timing = BusTiming(1_000_000, fd=fd, data_bitrate=5_000_000 if fd else None)
        if fd:
            limit = 1.0 / timing.frame_time(0x303, bytes(64), is_fd=True)
            label = "CAN FD 64-byte frames, 1 Mbit/s + 5 Mbit/s data phase"
        else:
            limit = 1_000_000 / 111          # 8-byte standard frames with no stuff bits: the most frames/s
            label = "classic 8-byte frames, 1 Mbit/s"
        print(f"{label}: host decodes {rate:,.0f} frames/s ({len(frames)} frames); bus limit {limit:,.0f} frames/s; "
              f"ratio {rate / limit:.1f}x (target >= 10x)")


if __name__ == "__main__":
    main()
