"""Ctrl-C taken between the steps of a run loop, not inside one.

Python raises KeyboardInterrupt wherever the main thread happens to be: inside the MCAP writer compressing a chunk
(its buffer already emptied: seconds of every topic lost from the middle of a file marked valid, its index pointing at
them), between recording a curve and marking it recorded (written twice, and a false ``curves_in_one_cycle``), or
inside a compiled numba function (``SystemError: … returned a result with an exception set`` and a traceback instead
of the one-line stop). Inside :func:`deferred_interrupt` the first Ctrl-C (or SIGTERM, where the console script made
it one: :func:`rig.launch.entry`) is only noted and raised at the loop's next ``check()``, where the host's and the
writer's state is whole; another one raises at once only when the first has waited :data:`STUCK` s for a check (a
loop that no longer checks still stops) — a double tap a few ms apart once raised inside the writer all the same.
"""
from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rig.stops import Terminated

STUCK = 1.0       # s a stop may wait for the loop's check before another Ctrl-C raises at once


def _stops() -> list[int]:
    """The signals that stop a run: SIGINT, and SIGTERM where a Python handler takes it (the console script's)."""
    return [signal.SIGINT] + ([signal.SIGTERM] if callable(signal.getsignal(signal.SIGTERM)) else [])


@contextmanager
def shielded() -> Iterator[None]:
    """Ctrl-C (and the console script's SIGTERM) ignored while the block runs: the closing of a recording after a stop
    was asked for — a second Ctrl-C a few ms after the first once landed in the MCAP writer's finish and left the file
    without its summary. Outside the main thread: nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, lambda signum, frame: None) for s in _stops()}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, signal.default_int_handler if handler is None else handler)


@contextmanager
def deferred_interrupt() -> Iterator[Callable[[], None]]:
    """The loop's ``check()``: raises KeyboardInterrupt if Ctrl-C came since the block began,
    :class:`~rig.stops.Terminated` if SIGTERM did (and so does the block's end, for one after the last check).
    Outside the main thread (no signal handlers there) ``check()`` does nothing and Ctrl-C keeps Python's own
    behaviour."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    pending: list[tuple[float, int]] = []       # when the stop was asked for (monotonic s), and by which signal

    def stop(signum: int) -> KeyboardInterrupt:
        return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()

    def note(signum: int, frame: object) -> None:
        if pending and time.monotonic() - pending[0][0] > STUCK:
            raise stop(signum)
        if not pending:
            pending.append((time.monotonic(), signum))

    def check() -> None:
        if pending:
            signum = pending.pop()[1]
            raise stop(signum)

    previous = {s: signal.signal(s, note) for s in _stops()}
    try:
        yield check
    finally:
        for s, handler in previous.items():
            signal.signal(s, signal.default_int_handler if handler is None else handler)
    check()                          # a Ctrl-C after the loop's last check is not lost
