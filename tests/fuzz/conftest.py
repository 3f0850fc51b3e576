"""Fixtures of the fuzz tests: byte-stream mutations and a 1-cycle demo recording made once per session (the
case counter ``fuzz_cases`` is in ``tests/conftest.py``: its counts are summed over pytest-xdist's workers
there)."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest
from hypothesis import strategies as st

from rig.runner import run_scene

ROOT = Path(__file__).resolve().parents[2]


# -- byte-stream mutations -------------------------------------------------------------------------
def _offsets(size: int) -> st.SearchStrategy[int]:
    """Anywhere, and more often near the start and the end (headers, check characters, summaries)."""
    return st.one_of(st.integers(0, size), st.integers(0, min(size, 64)), st.integers(max(0, size - 4096), size))


def mutations(size: int, max_ops: int = 3) -> st.SearchStrategy[list[tuple]]:
    """1 to ``max_ops`` edits of a byte string of ``size`` bytes: ``("flip", at, mask)``, ``("truncate", at)``,
    ``("insert", at, bytes)``, ``("delete", at, n)``; offsets beyond the (edited) length wrap around."""
    at = _offsets(size)
    op = st.one_of(st.tuples(st.just("flip"), at, st.integers(1, 255)),
                   st.tuples(st.just("truncate"), at),
                   st.tuples(st.just("insert"), at, st.binary(min_size=1, max_size=16)),
                   st.tuples(st.just("delete"), at, st.integers(1, 64)))
    return st.lists(op, min_size=1, max_size=max_ops)


def apply(raw: bytes, ops: list[tuple]) -> bytes:
    """``raw`` edited by ``ops`` (see :func:`mutations`), in order."""
    out = bytearray(raw)
    for kind, at, *arg in ops:
        at = at % (len(out) + 1)
        if kind == "flip" and at < len(out):
            out[at] ^= arg[0]
        elif kind == "truncate":
            del out[at:]
        elif kind == "insert":
            out[at:at] = arg[0]
        elif kind == "delete":
            del out[at:at + arg[0]]
    return bytes(out)


@pytest.fixture(scope="session")
def mutate() -> SimpleNamespace:
    """``mutate.mutations(size)`` (a strategy) and ``mutate.apply(raw, ops)`` (conftest is not importable)."""
    return SimpleNamespace(mutations=mutations, apply=apply)


@pytest.fixture(scope="session")
def demo_recording(tmp_path_factory) -> Path:
    """A 1-cycle recording of the pin insertion demo scene, made once per session."""
    out = tmp_path_factory.mktemp("fuzz-demo") / "demo.mcap"
    run_scene(ROOT / "data" / "scenes" / "pin_insertion.toml", out, cycles=1)
    return out
