"""A small stand-in with the DigiForce API used by the CAN node (the real unit is tested elsewhere)."""
from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest


@dataclass
class ElementResult:
    name: str
    kind: str
    ok: bool
    reason: str = ""


@dataclass
class FakeDevice:
    """Records the commands it receives; :meth:`finish` makes a result like the unit's ``last_result``."""

    calls: list = field(default_factory=list)
    program: int = 0
    state: str = "idle"
    last_result: object = None
    number: int = 0

    def select_program(self, n: int) -> None:
        if not 0 <= n < 16:
            raise ValueError(f"program {n} out of 0..15")
        self.program = n
        self.calls.append(("select_program", n))

    def start(self, t: float) -> None:
        self.state = "measuring"
        self.calls.append(("start", t))

    def stop(self, t: float) -> None:
        self.state = "idle"
        self.calls.append(("stop", t))

    def tare(self, channel: str) -> None:
        if channel not in ("x", "y", None):
            raise ValueError(f"no channel {channel}")
        self.calls.append(("tare", channel))

    def reset_statistics(self) -> None:
        self.calls.append(("reset_statistics",))

    def identify(self) -> str:
        self.calls.append(("identify",))
        return "FAKE DIGIFORCE"

    def status(self) -> dict:
        return {"state": self.state, "program": self.program}

    def state_at(self, t: float) -> tuple[str, object]:
        return self.state, self.last_result

    def finish(self, t: np.ndarray, x: np.ndarray, y: np.ndarray, elements: list[ElementResult],
               process_values: dict[str, float]) -> SimpleNamespace:
        self.number += 1
        self.last_result = SimpleNamespace(number=self.number, program=self.program,
                                           ok=all(e.ok for e in elements), elements=elements,
                                           process_values=process_values, curve=SimpleNamespace(t=t, x=x, y=y))
        return self.last_result


def make_curve(rng: np.random.Generator, n: int = 4000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A press-fit-like curve: stroke 0..40 mm, force rising to ~800 N, with noise (SI)."""
    t = np.arange(n) * 1e-4
    x = 0.04 * np.sin(np.pi * np.arange(n) / (n - 1)) ** 2
    y = 800 * (x / 0.04) ** 2 - 25 + rng.normal(0, 2.0, n)
    return t, x, y


@pytest.fixture
def fakes() -> SimpleNamespace:
    """The helpers of this file for test modules (conftest is not importable under importlib mode)."""
    return SimpleNamespace(ElementResult=ElementResult, make_curve=make_curve, FakeDevice=FakeDevice)


@pytest.fixture
def device() -> FakeDevice:
    return FakeDevice()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20240611)
