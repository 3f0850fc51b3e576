"""Shared helpers for the DigiForce tests: an ideal unit with simple scaling (1 V = 1 m, 1 V = 1 N)."""
import numpy as np
import pytest

from firmware_sim.digiforce import DigiForce
from firmware_sim.digiforce.elements import build_elements, normalize_elements

SIMPLE = {
    "channels": {
        "x": {"input": "voltage", "range": 10.0, "cutoff": "off", "unit": "m",
              "scaling": {"mode": "sensitivity", "electrical": 1.0, "engineering": 1.0}},
        "y": {"input": "process", "range": 5.0, "cutoff": "off", "unit": "N",
              "scaling": {"mode": "sensitivity", "electrical": 1.0, "engineering": 1.0}},
    },
}


def _make_element(cfg):
    norm = normalize_elements([cfg], {"x": "m", "y": "N"}, "test")
    return build_elements(norm)[0]


@pytest.fixture
def make_element():
    """Factory: one element object from its config (units m and N)."""
    return _make_element


@pytest.fixture
def unit():
    """An ideal unit (no rng) with program 0 set to SIMPLE scaling and filters off."""
    dev = DigiForce()
    dev.set_program(0, SIMPLE)
    return dev


@pytest.fixture
def press():
    """Factory of press cycles (see :func:`_press_curve`)."""
    return _press_curve


def _press_curve(n=2001, stroke=4.0, peak=3.0, duration=0.2):
    """t, x, y of a press cycle: X out and back (cosine), Y rising with X on the way out, lower on return."""
    t = np.linspace(0.0, duration, n)
    x = stroke / 2 * (1 - np.cos(2 * np.pi * t / duration))
    y = peak * (x / stroke) ** 2 * np.where(t <= duration / 2, 1.0, 0.5)
    return t, x, y
