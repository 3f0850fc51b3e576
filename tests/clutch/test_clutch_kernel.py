"""The compiled clutch kernel's load programs and motor line against the Python load objects."""
import math

import numpy as np
import pytest

from rig.plants.clutch import FlatTappetClutch, kernel
from rig.plants.clutch.loads import (LinearInSpeed, LinearMotor, Load, LoadSum, ShoeBrake, Steps, Zone, constant,
                                     shock, step)

CLUTCH = FlatTappetClutch(r0=0.055, r1=0.130, r2=0.030, k_a=3000.0, F_a1=1284.0)
LOADS = LoadSum([constant(5.0), step(0.2, 3.0), shock(0.1, 0.05, 40.0), Zone(7.0, 1.0, 2.5),
                 ShoeBrake(0.01, 0.005, 900.0, (0.15, 0.3), (2000.0, 100.0), omega_s=0.3),
                 LinearInSpeed(1.5, 0.02), Steps(-1.0, (0.05, 0.1, 0.12), (2.0, 0.5, 4.0)),
                 ShoeBrake(0.02, 0.01, 50.0)])


def test_load_program_matches_python_loads():
    motor = LinearMotor(437.7, 3.87, ratio=1.3, t_off=0.25)
    p = kernel.pack(CLUTCH, motor, LOADS.program(), 0.01, False, False)
    rng = np.random.default_rng(7)
    times = np.concatenate([rng.uniform(0, 0.4, 300), [0.05, 0.1, 0.12, 0.15, 0.2, 0.25, 0.3]])  # and on the breaks
    for t in times:
        phi3, w3 = rng.uniform(-20, 20), rng.uniform(-3, 3)
        z = tuple(rng.uniform(0, 3000, 2))
        y = np.array([0.1, 2.0, phi3, w3, *z])
        assert kernel.load_torque(t, phi3, w3, y, p) == pytest.approx(LOADS.torque(t, phi3, w3, z), rel=1e-14, abs=1e-12)
        out = np.zeros(6)
        kernel.load_rates(t, y, p, out)
        np.testing.assert_allclose(out[4:], LOADS.rates(t, phi3, w3, z), rtol=1e-14)
        w1 = rng.uniform(0, 150)
        assert kernel.motor_torque(t, w1, p) == pytest.approx(motor.torque(t, w1), rel=1e-14, abs=1e-12)


def test_a_load_without_compiled_form_is_named():
    class Custom(Load):
        def torque(self, t, phi3, omega3, z):
            return math.sin(t)

    with pytest.raises(NotImplementedError, match="Custom has no compiled form"):
        LoadSum([constant(1.0), Custom()]).program()
