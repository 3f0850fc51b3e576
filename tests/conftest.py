"""Shared fixtures: a small Dask cluster for the executor, sweep and batch tests (2 worker threads in this
process, in-process transport, HTTP status servers on 127.0.0.1 only), started once when first asked for; a
served machine (``rig serve`` in its own process) for the cross-process tests; and the fuzz tests' case counter,
its counts summed over pytest-xdist's workers (the suite runs on every core: ``-n auto`` in pyproject.toml)."""
from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Iterator

import pytest

# tests replace the fidelity checks and data: no choice is read from, or kept in, the user's cache (rig.fidelity_cache;
# its own tests turn it on in a folder of their own); the commands the tests start inherit this
os.environ["MECHRIG_FIDELITY_CACHE"] = "0"

_spec = importlib.util.spec_from_file_location("fuzz_cases", Path(__file__).parent / "fuzz" / "cases.py")
cases = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cases)
_FUZZ_LOG = pytest.StashKey[object]()


@contextlib.contextmanager
def served(scene: Path, endpoints: Path, *args: str, timeout: float = 120.0) -> Iterator[dict]:
    """``rig serve SCENE`` in its own process: yields its endpoints once announced; on leaving, waits for it
    to exit by itself (it does once its host released it: exit status 0 asserted), else kills it."""
    serve = subprocess.Popen([sys.executable, "-m", "rig.cli", "-q", "serve", str(scene), *args,
                              "--endpoints", str(endpoints), "--wait", str(int(timeout))],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + timeout
        while not endpoints.exists() or not endpoints.read_text():
            assert serve.poll() is None, serve.stderr.read()
            assert time.monotonic() < deadline, "rig serve did not announce its endpoints"
            time.sleep(0.05)
        yield json.loads(endpoints.read_text())
        assert serve.wait(timeout=timeout) == 0, serve.stderr.read()        # it exits once released
    finally:
        serve.kill()
        serve.wait()


@pytest.fixture(scope="session")
def dask_scheduler():
    """Address of a running LocalCluster (2 single-threaded workers, processes=False)."""
    from distributed import LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address="127.0.0.1:0",
                      worker_dashboard_address="127.0.0.1:0") as cluster:
        yield cluster.scheduler_address


@pytest.fixture
def serve_scene():
    """:func:`served`, for the cross-process tests."""
    return served


@pytest.fixture(scope="session")
def fuzz_cases(request) -> "cases.CaseLog":
    """The session's :class:`cases.CaseLog` of the fuzz tests (``tests/fuzz/cases.py``)."""
    return request.config.stash.setdefault(_FUZZ_LOG, cases.CaseLog())


def pytest_sessionfinish(session) -> None:
    """A pytest-xdist worker hands its fuzz case counts to the controller; the controller (or a session without
    workers) writes the sum to ``<basetemp>/fuzz-cases.json``."""
    log = session.config.stash.get(_FUZZ_LOG, None)
    if log is None or not log.examples:
        return
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:
        workeroutput["fuzz_cases"] = log.as_dict()
    elif (factory := getattr(session.config, "_tmp_path_factory", None)) is not None:   # pytest's, not public
        log.write(factory.getbasetemp() / cases.FILE_NAME)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error) -> None:
    """On pytest-xdist's controller: add a finished worker's fuzz case counts to the session's."""
    counts = getattr(node, "workeroutput", {}).get("fuzz_cases")
    if counts:
        node.config.stash.setdefault(_FUZZ_LOG, cases.CaseLog()).merge(counts)


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    """The fuzz case counts of the session, as a table in pytest's summary."""
    log = config.stash.get(_FUZZ_LOG, None)
    if log is None or not log.examples or hasattr(config, "workeroutput"):
        return
    terminalreporter.section("fuzz case counts")
    for line in cases.table(log.as_dict()):
        terminalreporter.write_line(line)
