"""Streaming per-column statistics (rig.analysis.streaming) against numpy on all samples at once."""
from __future__ import annotations

import numpy as np
import pytest

from rig.analysis.streaming import column_statistics, passes

PERCENTS = (0.0, 0.135, 2.5, 50.0, 97.5, 99.865, 100.0)


def _runner(data: np.ndarray, task: int, block: int):
    """``run(fold)`` over tasks of ``task`` rows handing their rows over in blocks of ``block``."""
    tasks = [data[i:i + task] for i in range(0, len(data), task)]

    def run(fold):
        for rows in tasks:
            yield fold(rows[k:k + block] for k in range(0, len(rows), block))
    return run


@pytest.mark.parametrize("n, bins, cap, announced", [(5000, 1024, 4096, False), (3001, 16, 10, False),
                                                    (777, 2, 2, False), (5000, 1024, 4096, True),
                                                    (3001, 16, 10, True)])
def test_percentiles_equal_numpys_bit_for_bit_and_moments_to_rounding(n, bins, cap, announced):
    rng = np.random.default_rng(n)
    data = rng.standard_normal((n, 5)) * [1.0, 1e-4, 1e3, 5.0, 1.0] + [0.0, 3e-4, -2e3, 0.0, 7.0]
    data[:, 0] = np.round(data[:, 0], 1)        # many ties
    data[:, 3] = rng.exponential(1.0, n)        # skewed
    data[:, 4] = 7.0                            # constant column
    st = column_statistics(_runner(data, 97, 40), PERCENTS, bins=bins, cap=cap, n=n if announced else None)
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


def _counting(run):
    """``run`` that counts the passes made over the samples."""
    calls = []

    def counted(fold):
        calls.append(type(fold).__name__)
        return run(fold)
    return counted, calls


def test_tails_of_a_known_count_give_the_same_numbers_in_one_pass():
    rng = np.random.default_rng(3)
    data = rng.standard_normal((20000, 4)) * [1.0, 1e-5, 3.0, 1.0]
    data[:, 3] = np.round(rng.exponential(1.0, 20000), 2)       # skewed, with ties
    tails = (0.0, 0.135, 99.865, 100.0)
    run, calls = _counting(_runner(data, 3000, 700))
    one = column_statistics(run, tails, n=len(data))
    assert calls == ["TailsFold"] and passes(len(data), tails) == 1
    three = column_statistics(_runner(data, 3000, 700), tails)
    for p in tails:
        np.testing.assert_array_equal(one.percentiles[p], np.percentile(data, p, axis=0))
        np.testing.assert_array_equal(one.percentiles[p], three.percentiles[p])
    for a, b in ((one.mean, three.mean), (one.std, three.std), (one.minimum, three.minimum)):
        np.testing.assert_array_equal(a, b)                     # same blocks, same merge order: same bits


def test_tails_larger_than_the_cap_fall_back_to_the_histogram_passes():
    data = np.random.default_rng(4).standard_normal((3000, 2))
    run, calls = _counting(_runner(data, 1000, 500))
    st = column_statistics(run, (50.0,), cap=1000, n=len(data))  # the median needs 1500 values a column
    assert calls[0] == "MomentsFold" and len(calls) >= 3 and passes(len(data), (50.0,), cap=1000) == 3
    np.testing.assert_array_equal(st.percentiles[50.0], np.percentile(data, 50.0, axis=0))


def test_a_wrong_announced_count_is_an_error():
    data = np.zeros((100, 1))
    with pytest.raises(RuntimeError, match="produced 100 samples, 120 were announced"):
        column_statistics(_runner(data, 30, 10), (0.135,), n=120)
    with pytest.raises(RuntimeError, match="produced 100 samples, 120 were announced"):
        column_statistics(_runner(data, 30, 10), (50.0,), cap=4, n=120)


@pytest.mark.filterwarnings("ignore:invalid value:RuntimeWarning")     # inf − inf in the moments, then the error
@pytest.mark.parametrize("announced", [False, True])
def test_non_finite_samples_are_an_error_naming_the_columns(announced):
    data = np.random.default_rng(5).standard_normal((500, 4))
    data[17, 2], data[3, 3] = np.nan, np.inf
    with pytest.raises(ValueError, match=r"not all finite .* in 2 column\(s\), the first \[2, 3\]"):
        column_statistics(_runner(data, 100, 50), (0.135, 99.865), n=len(data) if announced else None)
    short = np.random.default_rng(6).standard_normal((10, 2))    # a task smaller than the tails, NaN in it
    short[9, 1] = np.nan
    with pytest.raises(ValueError, match=r"not all finite .* in 1 column\(s\), the first \[1\]"):
        column_statistics(_runner(short, 9, 9), (0.135, 99.865), n=10 if announced else None)
