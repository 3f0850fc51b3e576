"""Wall time numba spends compiling in this process (not loading from its cache): a run subtracts the compilations
that fell in its run phase from the time its real-time factor is measured over, and says so."""
from __future__ import annotations

import threading
import time
from typing import Any

_state = threading.local()
_lock = threading.Lock()
_total = 0.0
_watching = False


def watch() -> None:
    """Start counting (idempotent; nothing happens without numba)."""
    global _watching
    with _lock:
        if _watching:
            return
        try:
            from numba.core import event
        except Exception:          # noqa: BLE001  (numba missing or changed: nothing is counted)
            return

        class Clock(event.Listener):
            """Times the outermost compilation of each thread (a kernel's callees compile inside it)."""

            def on_start(self, ev: Any) -> None:
                depth = getattr(_state, "depth", 0)
                if depth == 0:
                    _state.start = time.perf_counter()
                _state.depth = depth + 1

            def on_end(self, ev: Any) -> None:
                global _total
                _state.depth = getattr(_state, "depth", 1) - 1
                if _state.depth == 0:
                    with _lock:
                        _total += time.perf_counter() - _state.start

        event.register("numba:compile", Clock())
        _watching = True


def compile_seconds() -> float:
    """Seconds spent in numba compilations since :func:`watch` was first called."""
    return _total
