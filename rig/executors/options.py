"""Command-line options of the executors: ``--executor``, ``--workers``, ``--scheduler``."""
from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from typing import TypeVar

from rig.executors import Executor, available, make_executor

T = TypeVar("T")


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


#: a Dask scheduler address: [scheme://]host:port (tcp, tls, ws, wss, ucx, ucxx or a backend's own; IPv6 in brackets),
#: or any inproc://…
ADDRESS = re.compile(r"(?:[a-z][a-z0-9+.-]*://)?(?:\[[0-9a-f:.]+\]|[^\s:/\[\]]+):(\d{1,5})|inproc://\S+",
                     re.IGNORECASE)


def _address(text: str) -> str:
    """argparse type of ``--scheduler``: a malformed address is a usage error (exit 2), not a failed run."""
    found = ADDRESS.fullmatch(text.strip())
    if not found or (found[1] is not None and not 0 < int(found[1]) < 65536):
        raise argparse.ArgumentTypeError(f"expected a scheduler address such as tcp://10.0.0.5:8786 or "
                                         f"10.0.0.5:8786, got {text!r}")
    return text.strip()


def add_executor_arguments(parser: argparse.ArgumentParser, local: str = "dask") -> None:
    """Add the executor options to a command's parser; ``local``: the local Dask kind the command uses when
    more than one worker is asked for without ``--executor`` (pass the same to :func:`executor_from_args`)."""
    parser.add_argument("--executor", choices=tuple(available()),
                        help=f"where the tasks run (default: {local} when --workers > 1, dask with --scheduler, "
                             "else serial); results do not depend on it")
    parser.add_argument("--workers", type=_workers, default=1,
                        help="workers of the local Dask cluster (results do not depend on it)")
    parser.add_argument("--scheduler", metavar="ADDR", type=_address,
                        help="address of an existing Dask scheduler, e.g. tcp://10.0.0.5:8786 (its workers need "
                             "mechrig installed)")


def executor_from_args(args: argparse.Namespace, local: str = "dask") -> Executor:
    """The executor the options name (:func:`rig.executors.make_executor`); without ``--executor``, more than
    one worker and no scheduler, the local Dask kind ``local`` (``dask-processes`` for tasks that hold the
    GIL, e.g. Python-level simulation or analysis)."""
    name = args.executor
    if name is None and args.scheduler is None and args.workers > 1:
        name = local
    return make_executor(name, args.workers, args.scheduler)


def run_on_executor(args: argparse.Namespace, work: Callable[[Executor], T], kept: Callable[[T, KeyboardInterrupt], None],
                    local: str = "dask") -> T:
    """``work(executor)`` on the executor the options name, its result returned once the executor has closed.
    A Ctrl-C while the workers close, after ``work`` returned, does not lose the result: ``kept(result, stop)``
    writes it and says so, then the stop goes on (marked said: the command line adds no second line). A stop
    inside ``work`` goes on as it came."""
    done: list[T] = []
    try:
        with executor_from_args(args, local=local) as executor:
            done.append(work(executor))
    except KeyboardInterrupt as stop:
        if not done:
            raise
        kept(done[0], stop)
        stop.said = ""          # type: ignore[attr-defined]
        raise
    return done[0]
