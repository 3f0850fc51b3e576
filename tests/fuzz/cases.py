"""Case counts of the fuzz tests: examples run per target and outcomes counted per reason.

The fuzz tests record through the ``fuzz_cases`` fixture of ``tests/conftest.py``, whose hooks write
``fuzz-cases.json`` into pytest's base temporary directory at the end of the session and print the
table in pytest's terminal summary (with pytest-xdist: the workers' counts, summed by the
controller). Run as a script to summarize a written file::

    python tests/fuzz/cases.py [FILE]     # default: the newest fuzz-cases.json of pytest's sessions
"""
from __future__ import annotations

import getpass
import json
import sys
import tempfile
import threading
import time
from collections import Counter, defaultdict
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterator, TypeVar

T = TypeVar("T")
#: seconds after which one fuzzed call counts as a hang: a loop that never ends, not a slow machine — a bound of a few
#: seconds failed on a loaded machine (building a level-2 scene's plant loads its compiled kernels: 3.0 s, 2026-11-29)
HANG = 30.0

FILE_NAME = "fuzz-cases.json"


class Case:
    """One example of a target: counts its outcomes (a reason string each)."""

    HANG = HANG

    def __init__(self, outcomes: Counter[str]) -> None:
        self._outcomes = outcomes

    def outcome(self, reason: str, n: int = 1) -> None:
        """Count ``n`` outcomes of kind ``reason`` (a rejection reason, or an accepted kind)."""
        if n:
            self._outcomes[reason] += n

    @staticmethod
    def within(seconds: float, fn: Callable[..., T], *args: Any) -> T:
        """``fn(*args)`` run in a daemon thread; fails (a hang) when it has not returned after ``seconds``.
        Its exception, if any, is raised here."""
        box: dict[str, Any] = {}

        def run() -> None:
            try:
                box["value"] = fn(*args)
            except BaseException as exc:  # handed to the caller as is
                box["error"] = exc
        thread = threading.Thread(target=run, daemon=True, name="fuzz-bounded-call")
        thread.start()
        thread.join(seconds)
        assert not thread.is_alive(), f"{getattr(fn, '__name__', fn)}{args!r:.200} still running after {seconds} s"
        if "error" in box:
            raise box["error"]
        return box["value"]


class CaseLog:
    """Examples run and outcomes per fuzz target."""

    def __init__(self) -> None:
        self.examples: Counter[str] = Counter()
        self.outcomes: defaultdict[str, Counter[str]] = defaultdict(Counter)

    @contextmanager
    def example(self, target: str, limit: float) -> Iterator[Case]:
        """Count one example of ``target``; fails it when it takes longer than ``limit`` seconds (a hang). Limits
        are wall time on a possibly loaded machine, so they are generous (60 s against milliseconds): a hang
        is infinite, and a tight limit would be a timing race."""
        self.examples[target] += 1
        start = time.monotonic()
        yield Case(self.outcomes[target])
        elapsed = time.monotonic() - start
        assert elapsed <= limit, f"{target}: one example took {elapsed:.2f} s (limit {limit} s)"

    def as_dict(self) -> dict[str, dict]:
        """``{target: {"examples": n, "outcomes": {reason: count}}}``, sorted."""
        return {t: {"examples": n, "outcomes": dict(sorted(self.outcomes[t].items()))}
                for t, n in sorted(self.examples.items())}

    def merge(self, counts: dict[str, dict]) -> None:
        """Add counts in the form of :meth:`as_dict` (another process's)."""
        for target, entry in counts.items():
            self.examples[target] += entry["examples"]
            self.outcomes[target].update(entry["outcomes"])

    def write(self, path: Path) -> None:
        """Write :meth:`as_dict` to ``path`` as JSON."""
        path.write_text(json.dumps(self.as_dict(), indent=1) + "\n", encoding="utf-8")


def table(counts: dict[str, dict]) -> list[str]:
    """Lines of a plain-text table: per target its examples, then each outcome with its count."""
    lines = [f"{'target / outcome':<70} {'count':>8}"]
    for target, entry in counts.items():
        lines.append(f"{target:<70} {entry['examples']:>8} examples")
        lines.extend(f"    {reason[:66]:<66} {n:>8}" for reason, n in entry["outcomes"].items())
    return lines


def latest_file() -> Path:
    """The newest ``fuzz-cases.json`` among pytest's base directories (``pytest-current`` may belong to
    another session running meanwhile)."""
    root = Path(tempfile.gettempdir()) / f"pytest-of-{getpass.getuser()}"
    files = sorted(root.glob(f"pytest-*/{FILE_NAME}"), key=lambda p: p.stat().st_mtime)
    return files[-1] if files else root / "pytest-current" / FILE_NAME


def main(argv: list[str]) -> int:
    """Print the table of ``argv[0]`` (default: :func:`latest_file`); 1 when there is none."""
    path = Path(argv[0]) if argv else latest_file()
    if not path.is_file():
        print(f"no fuzz case counts at {path} (run: python -m pytest tests/fuzz)", file=sys.stderr)
        return 1
    print("\n".join(table(json.loads(path.read_text(encoding="utf-8")))))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
