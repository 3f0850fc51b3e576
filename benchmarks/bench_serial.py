"""Serial link benchmark: read a 4000-pair curve at 115200 baud over a pty and compare the time with
the byte time of everything that crossed the wire (10 bits per byte). Target: ratio within 5 %.

Run: python benchmarks/bench_serial.py
"""
from __future__ import annotations

import time

import numpy as np

from drivers.digiforce_serial import DigiForceClient
from firmware_sim.digiforce import Curve
from firmware_sim.serial_device import SerialDevice

BAUD, PAIRS = 115200, 4000


class CurveSource:
    """The part of the DigiForce API the curve transfer uses."""

    def __init__(self, rng: np.random.Generator) -> None:
        t = np.arange(PAIRS) * 1e-5
        self.last_curve = Curve(t, rng.normal(0.01, 0.003, PAIRS), rng.normal(500.0, 120.0, PAIRS), None,
                                turning_index=PAIRS // 2)

    def identify(self) -> str:
        return "benchmark curve source"


def main() -> None:
    source = CurveSource(np.random.default_rng(1))
    with SerialDevice(source, "pty", baudrate=BAUD) as device, DigiForceClient(device.port, baudrate=BAUD) as client:
        client.identify()
        sent, received = client.bytes_sent, client.bytes_received
        t0 = time.perf_counter()
        curve = client.read_curve()
        elapsed = time.perf_counter() - t0
        n_bytes = client.bytes_sent - sent - 3 + client.bytes_received - received   # final ACK not awaited
    exact = np.array_equal(curve.x, source.last_curve.x) and np.array_equal(curve.y, source.last_curve.y)
    byte_time = n_bytes * 10 / BAUD
    ratio = elapsed / byte_time
    print(f"serial curve read, {PAIRS} pairs at {BAUD} baud over {device.port}: {n_bytes} bytes on the wire")
    print(f"  byte time {byte_time:.3f} s, measured {elapsed:.3f} s, ratio {ratio:.4f} "
          f"({'within' if abs(ratio - 1) <= 0.05 else 'OUTSIDE'} 5 %), data exact: {exact}")


if __name__ == "__main__":
    main()
