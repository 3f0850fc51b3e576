"""Streaming per-column statistics (rig.analysis.streaming) against numpy on all samples at once."""
from __future__ import annotations

import numpy as np
import pytest

from rig.analysis.streaming import column_statistics

PERCENTS = (0.0, 0.135, 2.5, 50.0, 97.5, 99.865, 100.0)


def _runner(data: np.ndarray, task: int, block: int):
    """``run(fold)`` over tasks of ``task`` rows handing their rows over in blocks of ``block``."""
    tasks = [data[i:i + task] for i in range(0, len(data), task)]

    def run(fold):
        for rows in tasks:
            yield fold(rows[k:k + block] for k in range(0, len(rows), block))
    return run


@pytest.mark.parametrize("n, bins, cap", [(5000, 1024, 4096), (3001, 16, 10), (777, 2, 2)])
def test_percentiles_equal_numpys_bit_for_bit_and_moments_to_rounding(n, bins, cap):
    rng = np.random.default_rng(n)
    data = rng.standard_normal((n, 5)) * [1.0, 1e-4, 1e3, 5.0, 1.0] + [0.0, 3e-4, -2e3, 0.0, 7.0]
    data[:, 0] = np.round(data[:, 0], 1)        # many ties
    data[:, 3] = rng.exponential(1.0, n)        # skewed
    data[:, 4] = 7.0                            # constant column
    st = column_statistics(_runner(data, 97, 40), PERCENTS, bins=bins, cap=cap)
    for p in PERCENTS:
        np.testing.assert_array_equal(st.percentiles[p], np.percentile(data, p, axis=0))
    assert st.n == n
    np.testing.assert_allclose(st.mean, data.mean(axis=0), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(st.std, data.std(axis=0, ddof=1), rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(st.minimum, data.min(axis=0))
    np.testing.assert_array_equal(st.maximum, data.max(axis=0))


def test_tasks_that_do_not_reproduce_their_samples_are_caught():
    rng = np.random.default_rng(1)

    def run(fold):                                # fresh random samples on every pass
        for _ in range(3):
            yield fold([rng.standard_normal((100, 2))])
    with pytest.raises(RuntimeError, match="not reproducible"):
        column_statistics(run, (50.0,))


def test_bad_arguments_raise_clear_errors():
    with pytest.raises(ValueError, match="bins >= 2"):
        column_statistics(_runner(np.zeros((10, 1)), 5, 5), (50.0,), bins=1)
    with pytest.raises(ValueError, match="at least 2 samples"):
        column_statistics(_runner(np.zeros((1, 1)), 5, 5), (50.0,))
