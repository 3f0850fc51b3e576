"""Δt sampling stays exact far into a run: time stamps of ~10⁴ s carry rounding of ~10⁻¹² s, which must not
move a sample on an interval boundary into the previous interval (it was skipped from ~512 s on)."""
from __future__ import annotations

import numpy as np
import pytest

from firmware_sim.digiforce.memory import CurveMemory


@pytest.mark.parametrize("start_index", [0, 5_144_900, 10_344_900, 40_000_000])   # 0 s, 514 s, 1034 s, 4000 s
def test_every_sample_of_a_rate_equal_to_the_step_is_stored_at_any_run_time(start_index: int):
    dt = 1e-4
    t = (start_index + 1 + np.arange(2550)) * dt          # how the runner makes its sample times
    rows = np.column_stack([t, np.zeros((t.size, 3))])
    mem = CurveMemory(4000, "time", dt, "stop")
    mem.begin(float(t[0]))
    for part in np.array_split(rows, 13):                  # offered in chunks, as the device does
        mem.add(part)
    stored = mem.finish()
    assert len(stored) == t.size
    np.testing.assert_array_equal(stored[:, 0], t)


def test_half_rate_keeps_every_second_sample_late_in_a_run():
    dt = 1e-4
    t = (10_344_900 + 1 + np.arange(1000)) * dt
    mem = CurveMemory(4000, "time", 2 * dt, "stop")
    mem.begin(float(t[0]))
    mem.add(np.column_stack([t, np.zeros((t.size, 3))]))
    stored = mem.finish()
    np.testing.assert_array_equal(stored[:-1, 0], t[::2])    # plus the last sample, always kept
