"""The stop by SIGTERM, told apart from Ctrl-C (both stop a command the same way; the recording and the console name
which); a spawned worker process's part in a stop."""
from __future__ import annotations

import logging
import signal


class Terminated(KeyboardInterrupt):
    """SIGTERM (sent by ``timeout``, ``docker stop``, systemd, CI runners) where the console script takes it
    (:func:`rig.launch.entry`): stops the command as Ctrl-C does; a recording names it ``Terminated: SIGTERM``."""

    def __init__(self, *args: object) -> None:          # (pickle and copy pass the message again)
        super().__init__(*(args or ("SIGTERM",)))


def terminated(exc: BaseException | None) -> bool:
    """Whether a stop is SIGTERM's: a :class:`Terminated`, or an exception raised from one."""
    while exc is not None:
        if isinstance(exc, Terminated):
            return True
        exc = exc.__cause__
    return False


def stopped(exc: BaseException | None) -> str:
    """The console's word for a stop: "terminated (SIGTERM)" or "interrupted" (Ctrl-C)."""
    return "terminated (SIGTERM)" if terminated(exc) else "interrupted"


def stop_on_signals() -> None:
    """Ctrl-C back to Python's KeyboardInterrupt and SIGTERM a :class:`Terminated`: both stop a command with its one
    line, the recording closed and marked interrupted (the console script's, and ``python -m rig.cli``'s)."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _raise_terminated)


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated


def spawned_worker() -> None:
    """In a worker process that multiprocessing spawned (Dask's, re-running the command's main module as
    ``__mp_main__``): ignore Ctrl-C — it reaches every process of the terminal's group, and the parent says it once and
    closes its workers — and the "task cancelled" notices of the tasks the parent cancels then (its doing, no news)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed.worker.state_machine").setLevel(logging.ERROR)
