"""``rig bench``: one subcommand per benchmark module.

Each module named in :data:`BENCH_MODULES` has ``register(sub, parents)`` adding its subparser under
``rig bench`` with ``set_defaults(func=...)``; heavy imports stay inside the command functions.
"""
from __future__ import annotations

import argparse
import importlib

BENCH_MODULES: tuple[str, ...] = ("rig.bench.workprecision", "rig.bench.fidelity", "rig.bench.stability")


def register(sub: argparse._SubParsersAction, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``rig bench`` and its subcommands to the ``rig`` parser."""
    bench = sub.add_parser("bench", parents=parents, help="solver work-precision charts and stability maps")
    bench_sub = bench.add_subparsers(dest="bench_command", required=True, parser_class=type(bench))
    for module in BENCH_MODULES:
        importlib.import_module(module).register(bench_sub, parents)
