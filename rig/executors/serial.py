"""The serial executor: tasks one after the other in this process."""
from __future__ import annotations

from typing import Any, Callable, Iterable, Iterator

from rig.executors import Executor


class SerialExecutor(Executor):
    """``map`` is the built-in map: no workers, no pickling, the reference for every other executor."""

    name = "serial"

    def __init__(self, workers: int = 1):
        self.workers = 1

    def map(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Any]:
        return map(fn, tasks)
