"""Fixtures of the serial-link tests: a fake DigiForce with the real unit's method set, device + client."""
from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from drivers.digiforce_serial import DigiForceClient
from firmware_sim.digiforce import Curve
from firmware_sim.serial_device import SerialDevice


class FakeResult:
    def __init__(self, data: dict[str, Any]) -> None:
        self._data = data

    def to_dict(self, include_curve: bool = True) -> dict[str, Any]:
        return copy.deepcopy(self._data) | ({"curve": "not for the serial RR"} if include_curve else {})


class FakeDigiForce:
    """Same methods as firmware_sim.digiforce.DigiForce; records every call in ``calls``."""

    PROGRAM_KEYS = {"name", "channels", "control", "sampling", "reference", "elements", "limits"}

    def __init__(self, rng: np.random.Generator, n_pairs: int = 4000) -> None:
        self.n_programs, self.active_program = 16, 1        # programs 0 ... 15, as the real unit
        self.programs = {n: {"name": f"program {n}", "channels": {"x": {"cutoff": 1000.0}, "y": {"cutoff": 1000.0}},
                             "sampling": {"mode": "time", "delta": 1e-5, "overflow": "stop"}, "elements": []}
                         for n in range(16)}
        t = np.sort(rng.uniform(0.0, 0.04, n_pairs))
        self.last_curve: Curve | None = Curve(t, rng.normal(0.01, 0.003, n_pairs), rng.normal(500.0, 120.0, n_pairs),
                                              None, turning_index=n_pairs // 2, x_reference=0.001,
                                              sampling={"mode": "time", "delta": 1e-5})
        self.last_result: FakeResult | None = FakeResult({"ok": False, "elements": [{"kind": "window", "ok": False}],
                                                          "values": {"y_max": 812.25, "x_at_y_max": 0.0123}})
        self.stats = {"count": 3, "ok": 2, "nok": 1, "y_max": {"mean": 800.5, "std": math.nan, "cpk": math.inf}}
        self.running = False
        self.calls: list[tuple] = []

    def identify(self) -> str:
        return "FAKE DigiForce 9310-sim SN 0001 FW 1.0"

    def _check(self, n: int) -> None:
        if not 0 <= n < self.n_programs:
            raise ValueError(f"program {n} outside 0..{self.n_programs - 1}")

    def select_program(self, n: int) -> None:
        self._check(n)
        self.active_program = n

    def get_program(self, n: int) -> dict[str, Any]:
        self._check(n)
        return copy.deepcopy(self.programs[n])

    def set_program(self, n: int, cfg: dict[str, Any], fits: Any = None) -> None:
        self._check(n)
        bad = sorted(set(cfg) - self.PROGRAM_KEYS)
        if bad:
            raise ValueError(f"program {n}: unknown keys {bad}")
        why = fits(cfg) if fits is not None else None
        if why:
            raise ValueError(f"program {n}: {why}")
        self.programs[n] = copy.deepcopy(cfg)

    def tare(self, channel: str | None) -> None:
        if channel not in ("x", "y", None):
            raise ValueError(f"tare: no channel {channel!r}")
        self.calls.append(("tare", channel))

    def start(self, t: float | None) -> None:
        if self.running:
            raise ValueError("start: a measurement is already running")
        self.running = True
        self.calls.append(("start", t))

    def stop(self, t: float | None) -> None:
        self.running = False
        self.calls.append(("stop", t))

    def statistics(self, program: int) -> dict[str, Any]:
        self._check(program)
        return copy.deepcopy(self.stats) | {"program": program}

    def reset_statistics(self, program: int) -> None:
        self._check(program)
        self.calls.append(("reset_statistics", program))

    def status(self) -> dict[str, Any]:
        return {"running": self.running, "program": self.active_program, "curves": 7}


@pytest.fixture
def fake() -> FakeDigiForce:
    return FakeDigiForce(np.random.default_rng(20240611))


@pytest.fixture
def link(fake):
    """(device, client, fake) over a pty at 1 Mbaud, short timeout."""
    with SerialDevice(fake, "pty", baudrate=1_000_000, address=5) as device:
        client = DigiForceClient(device.port, baudrate=1_000_000, address=5, timeout=0.2, retries=3)
        try:
            yield device, client, fake
        finally:
            client.close()
