"""What rig says on stderr besides its results: log records, warnings, progress bars, one-time notices.

The ``rig`` command calls :func:`configure` once: one handler on the root logger writes each record as
one line (``rig: ...`` for rig's own, ``rig: <logger>: ...`` for a library's), through tqdm so that a
progress bar on the terminal stays intact; rig's notices (logger ``rig``, INFO) are shown unless ``-q``;
libraries speak from WARNING up, except for messages known to be harmless (:data:`HARMLESS`: python-can's
socketcand client logs a warning every time a TCP read ends inside a frame line — thousands per run — and
one per failed connection attempt, hundreds of thousands in its 10 s retry loop). Python warnings
(e.g. a solver's ``StiffnessWarning``) become one line each. The first numba compilation of a group of
rig's kernels is announced with its expected duration (:func:`announce_compilation`); loading them from
numba's cache is not.
"""
from __future__ import annotations

import atexit
import logging
import sys
import threading
import warnings
from typing import Any

from tqdm import tqdm

log = logging.getLogger("rig")

#: logger name -> message starts that are never worth a line (rig handles what they mean itself)
HARMLESS: dict[str, tuple[str, ...]] = {
    # a TCP read ended inside a "< frame ... >" line; python-can waits for the rest, as it should
    "can.interfaces.socketcand.socketcand": ("Got incomplete message", "Failed to connect to server"),
}
_PLANT = ("the plant model and its solver", "30-60 s")
#: numba compilations announced: module prefix -> (what is compiled, how long a first compilation takes)
COMPILED: dict[str, tuple[str, str]] = {
    "rig.plants.": _PLANT,
    "rig.solvers.": _PLANT,
    "mechrig_": _PLANT,     # solver modules generated per kernel
    "firmware_sim.can_arbitration": ("the CAN arbitration", "1 s"),
    "firmware_sim.transducers": ("the transducer models", "1 s"),
    "rig.analysis.streaming": ("the Monte-Carlo statistics", "5-10 s"),
}


class _DropHarmless(logging.Filter):
    def __init__(self, starts: tuple[str, ...]) -> None:
        super().__init__()
        self.starts = starts

    def filter(self, record: logging.LogRecord) -> bool:
        try:
            return not str(record.msg).startswith(self.starts)
        except Exception:          # noqa: BLE001  (a filter must never break logging)
            return True


def quiet_libraries() -> None:
    """Drop the :data:`HARMLESS` messages at their loggers (idempotent; also for rig used as a library)."""
    for name, starts in HARMLESS.items():
        logger = logging.getLogger(name)
        if not any(isinstance(f, _DropHarmless) for f in logger.filters):
            logger.addFilter(_DropHarmless(starts))


class _Formatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        text = record.getMessage()
        if record.exc_info and record.levelno >= logging.ERROR:
            text += f" ({record.exc_info[1]})"
        if record.name == "rig" or record.name.startswith("rig."):
            level = "" if record.levelno < logging.WARNING else f"{record.levelname.lower()}: "
            return f"rig: {level}{text}"
        first = text.split("\n", 1)[0]             # a library's traceback stays out: one line per record
        return f"rig: {record.name}: {record.levelname.lower()}: {first}"


class _Handler(logging.Handler):
    """Writes through ``tqdm.write`` to the current ``sys.stderr`` (progress bars are redrawn below)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            tqdm.write(self.format(record), file=sys.stderr)
        except Exception:          # noqa: BLE001
            self.handleError(record)


SHOWN_PER_KIND = 3            # warnings of one category shown before the rest are only counted
_warned: dict[str, int] = {}


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as one log line; after :data:`SHOWN_PER_KIND` of a category the rest are counted and their
    number is reported when the process ends (a solver stepping at its stability limit warns every few
    steps: no floods)."""
    name = category.__name__
    _warned[name] = _warned.get(name, 0) + 1
    log_ = logging.getLogger("rig.warnings")
    if _warned[name] <= SHOWN_PER_KIND:
        log_.warning("%s: %s", name, " ".join(str(message).split()))
    if _warned[name] == SHOWN_PER_KIND:
        log_.warning("%s: further ones are counted, not shown", name)


@atexit.register
def _report_suppressed() -> None:
    for name, count in _warned.items():
        if count > SHOWN_PER_KIND:
            logging.getLogger("rig.warnings").warning("%s: %d more not shown", name, count - SHOWN_PER_KIND)


def configure(quiet: bool = False) -> None:
    """Set up rig's stderr output (see the module docstring); ``quiet``: notices and progress off,
    warnings and errors stay. Calling it again replaces the previous set-up."""
    root = logging.getLogger()
    for handler in [h for h in root.handlers if isinstance(h, _Handler)]:
        root.removeHandler(handler)
    handler = _Handler()
    handler.setFormatter(_Formatter())
    root.addHandler(handler)
    log.setLevel(logging.WARNING if quiet else logging.INFO)
    quiet_libraries()
    warnings.showwarning = _show_warning
    _warned.clear()
    announce_compilation()


LOGGED_INTERVAL = 10.0     # s between two progress lines when stderr is a file or a pipe (not a terminal)


def progress(total: float | None, desc: str, unit: str, enabled: bool = True, **kwargs: Any) -> tqdm:
    """A progress bar on stderr that stays as a final line (``leave``); ``enabled=False``: nothing shown. Into a file
    or a pipe (a CI log) each redraw is a line of its own: it redraws every :data:`LOGGED_INTERVAL` s there, not ten
    times a second."""
    if not getattr(sys.stderr, "isatty", lambda: False)():
        kwargs.setdefault("mininterval", LOGGED_INTERVAL)
    return tqdm(total=total, desc=desc, unit=unit, disable=not enabled, leave=True, file=sys.stderr,
                dynamic_ncols=True, **kwargs)


# -- numba ---------------------------------------------------------------------------------------------
_announced: set[str] = set()
_listening = False
_lock = threading.Lock()


def _group(module: str) -> tuple[str, str] | None:
    return next((v for prefix, v in COMPILED.items() if module.startswith(prefix)), None)


def announce_compilation() -> None:
    """Log, once per group of :data:`COMPILED`, that numba compiles it now and how long that takes.
    Numba raises ``numba:compile`` events only for real compilations, not for cache loads."""
    global _listening
    with _lock:
        if _listening:
            return
        try:
            from numba.core import event
        except Exception:          # noqa: BLE001  (numba missing or changed: no notice, nothing else)
            return

        class Listener(event.Listener):
            def on_start(self, ev: Any) -> None:
                try:
                    module = ev.data["dispatcher"].py_func.__module__ or ""
                except Exception:  # noqa: BLE001
                    return
                group = _group(module)
                if group is None or group[0] in _announced:
                    return
                _announced.add(group[0])
                log.info("compiling %s with numba: once, about %s (later runs load it from the cache)",
                         group[0], group[1])

            def on_end(self, ev: Any) -> None:
                pass

        event.register("numba:compile", Listener())
        _listening = True
