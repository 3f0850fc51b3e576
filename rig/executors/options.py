"""Command-line options of the executors: ``--executor``, ``--workers``, ``--scheduler``."""
from __future__ import annotations

import argparse

from rig.executors import EXECUTORS, Executor, make_executor


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def add_executor_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the executor options to a command's parser."""
    parser.add_argument("--executor", choices=tuple(EXECUTORS),
                        help="where the tasks run (default: dask when --workers > 1 or --scheduler is given, else "
                             "serial); results do not depend on it")
    parser.add_argument("--workers", type=_workers, default=1,
                        help="workers of the local Dask cluster (127.0.0.1; results do not depend on it)")
    parser.add_argument("--scheduler", metavar="ADDR",
                        help="address of an existing Dask scheduler, e.g. tcp://10.0.0.5:8786 (its workers need "
                             "mechrig installed)")


def executor_from_args(args: argparse.Namespace) -> Executor:
    """The executor the options name (:func:`rig.executors.make_executor`)."""
    return make_executor(args.executor, args.workers, args.scheduler)
