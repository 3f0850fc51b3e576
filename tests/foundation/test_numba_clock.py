"""The one-time numba compilations in a run phase are timed and left out of its real-time factor, and said."""
from __future__ import annotations

from pathlib import Path

from rig.numba_clock import compile_seconds, watch
from rig.runner.session import RunSummary


def test_a_compilation_is_timed_once_a_cached_call_is_not():
    from numba import njit
    watch()
    watch()                                      # idempotent: one listener

    @njit(cache=False)
    def outer(x):
        return inner(x) + 1.0

    @njit(cache=False)
    def inner(x):
        return x * 2.0

    before = compile_seconds()
    assert outer(1.0) == 3.0
    first = compile_seconds() - before
    assert first > 0.0
    again = compile_seconds()
    assert outer(2.0) == 5.0 and compile_seconds() == again


def test_the_real_time_factor_leaves_compilation_out_and_the_line_says_so():
    from rig.cli import _compiled
    cold = RunSummary(Path("x.mcap"), 5, 2.0, 40.0, 100, run_time=35.0, compile_time=34.5)
    warm = RunSummary(Path("x.mcap"), 5, 2.0, 5.0, 100, run_time=0.5)
    assert cold.realtime_factor == 4.0 and warm.realtime_factor == 4.0
    assert _compiled(cold) == " without the 34.5 s of one-time numba compilation that fell in the run phase"
    assert _compiled(warm) == ""
