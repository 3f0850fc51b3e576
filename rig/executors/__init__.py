"""Executors: where independent tasks run, chosen by name like python-can's interfaces.

``make_executor("serial")`` runs tasks one after the other in this process; ``make_executor("dask", workers=N)``
on a local Dask cluster (``LocalCluster``, worker threads), ``"dask-processes"`` on one of worker processes
listening on 127.0.0.1, ``make_executor("dask", scheduler="tcp://host:8786")`` on an existing Dask cluster. Every executor has the same :class:`Executor` interface, so the calling code
never changes. Other packages add executors as entry points in the group ``rig.executor`` (``name =
"package.module:Class"``, a subclass of :class:`Executor` built as ``Class(workers)`` or ``Class(workers,
scheduler=...)``), as python-can finds interfaces in ``can.interface``. Results come back in task order; a task's result must depend only on the task (its own
``SeedSequence`` child, fixed task boundaries), never on the executor or the number of workers.
"""
from __future__ import annotations

import importlib
import math
from abc import ABC, abstractmethod
from typing import Any, Callable, Iterable, Iterator, Sequence

#: the built-in executors: name -> "module:Class", imported on use (Dask only when asked for)
EXECUTORS: dict[str, str] = {
    "serial": "rig.executors.serial:SerialExecutor",
    "dask": "rig.executors.dask_cluster:DaskExecutor",
    "dask-processes": "rig.executors.dask_cluster:DaskProcessesExecutor",
}
ENTRY_POINT_GROUP = "rig.executor"


def available() -> dict[str, str]:
    """Every executor by name: the built-ins and those installed packages register in the entry-point group
    ``rig.executor`` (a plugin cannot replace a built-in)."""
    from importlib.metadata import entry_points
    plugins = {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}
    return {**{k: v for k, v in plugins.items() if k not in EXECUTORS}, **EXECUTORS}


class Executor(ABC):
    """Runs ``fn(task)`` for each task; ``workers`` is how many run at once (1 for serial)."""

    name: str = ""
    workers: int = 1

    @abstractmethod
    def map(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Any]:
        """``fn(task)`` of every task, yielded in task order; at most a few tasks per worker are in flight
        (their results are held until their turn), so memory stays bounded for any number of tasks."""

    def close(self) -> None:
        """Release workers and connections (nothing for serial)."""

    def describe(self) -> str:
        return f"{self.name}, {self.workers} worker{'s' if self.workers != 1 else ''}"

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def batches(items: Sequence[Any], workers: int, per_worker: int = 8) -> list[list[Any]]:
    """``items`` in consecutive groups, about ``per_worker`` groups per worker: one task per group when single
    items are too small for a task (use only where an item's result does not depend on its group)."""
    size = max(1, math.ceil(len(items) / (per_worker * workers)))
    return [list(items[i:i + size]) for i in range(0, len(items), size)]


def default_name(workers: int, scheduler: str | None) -> str:
    """``dask`` when a scheduler address or more than one worker is asked for, else ``serial``."""
    return "dask" if scheduler or workers > 1 else "serial"


def make_executor(name: str | None = None, workers: int = 1, scheduler: str | None = None) -> Executor:
    """The executor ``name`` (one of :func:`available`; None: :func:`default_name`) with ``workers``
    workers; ``scheduler``: address of a scheduler (Dask, or a plugin that takes one)."""
    name = default_name(workers, scheduler) if name is None else name
    known = available()
    if name not in known:
        raise ValueError(f"unknown executor {name!r} (known: {', '.join(known)})")
    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"an executor needs at least 1 worker, got {workers!r}")
    if scheduler and name in EXECUTORS and name != "dask":
        raise ValueError(f"a scheduler address ({scheduler}) needs the dask executor, not {name}")
    if name == "serial" and workers != 1:
        raise ValueError(f"the serial executor runs 1 worker, got {workers}; use the dask executor for more")
    module, _, cls = known[name].partition(":")
    try:
        kind = getattr(importlib.import_module(module), cls)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"executor {name!r}: cannot load {known[name]!r} ({exc})") from None
    if not (isinstance(kind, type) and issubclass(kind, Executor)):
        raise ValueError(f"executor {name!r}: {known[name]!r} is not an rig.executors.Executor")
    return kind(workers) if scheduler is None else kind(workers, scheduler=scheduler)
