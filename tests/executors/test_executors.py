"""Executors by name (rig.executors): same results in task order on serial and Dask, clear errors."""
from __future__ import annotations

import hashlib
import json
import math
import time

import numpy as np
import pytest

from rig.executors import EXECUTORS, Executor, available, default_name, make_executor
from rig.plants.cam_bar import PinInsertionMechanism
from rig.plants.cam_bar.montecarlo import monte_carlo
from rig.plants.cam_bar.tolerance import CamChain, load_tolerances


def _slow_square(x: int) -> int:
    time.sleep(0.002 * (5 - x % 5))      # later tasks finish first: the order must come from the executor
    return x * x


def test_executors_are_chosen_by_name():
    assert set(EXECUTORS) == {"serial", "dask", "dask-processes"} <= set(available())
    assert default_name(1, None) == "serial" and default_name(2, None) == "dask"
    assert default_name(1, "tcp://127.0.0.1:8786") == "dask"
    with make_executor() as ex:
        assert ex.name == "serial" and ex.workers == 1
        assert list(ex.map(_slow_square, range(4))) == [0, 1, 4, 9]


@pytest.mark.parametrize("name, workers, scheduler, match", [
    ("threads", 1, None, "unknown executor 'threads'"),
    ("serial", 2, None, "serial executor runs 1 worker"),
    ("serial", 1, "tcp://127.0.0.1:8786", "needs the dask executor"),
    ("dask", 0, None, "at least 1 worker"),
])
def test_bad_executor_requests_say_what_is_wrong(name, workers, scheduler, match):
    with pytest.raises(ValueError, match=match):
        make_executor(name, workers, scheduler)


def test_a_scheduler_without_workers_is_an_error_not_a_silent_wait(monkeypatch):
    """A cluster whose scheduler has no worker would take the tasks and never run them: the executor says so (was
    "1 worker" and a run that waited forever)."""
    from distributed import LocalCluster
    from rig.executors import dask_cluster
    monkeypatch.setattr(dask_cluster, "WORKER_TIMEOUT", 0.5)
    with LocalCluster(n_workers=0, processes=False, dashboard_address="127.0.0.1:0") as cluster:
        with pytest.raises(ConnectionError, match=r"the Dask scheduler at .* has no workers \(none joined within "
                                                  r"0.5 s\): start some with 'dask worker "):
            make_executor("dask", scheduler=cluster.scheduler_address)


def test_dask_returns_results_in_task_order(dask_scheduler):
    with make_executor("dask", scheduler=dask_scheduler) as ex:
        assert ex.workers == 2 and "scheduler" in ex.describe()
        assert list(ex.map(_slow_square, range(23))) == [x * x for x in range(23)]


def test_local_dask_cluster_listens_on_loopback_only():
    import os

    import psutil
    with make_executor("dask", workers=2) as ex:
        assert ex.workers == 2 and ex.cluster.scheduler_address.startswith("inproc://")
        listening = [c.laddr.ip for c in psutil.net_connections("inet") if c.status == "LISTEN" and c.pid == os.getpid()]
        assert listening and set(listening) == {"127.0.0.1"}
        assert list(ex.map(_slow_square, range(6))) == [x * x for x in range(6)]
    assert ex.client.status == "closed"


def test_monte_carlo_is_bit_identical_on_serial_and_dask(dask_scheduler):
    chain = CamChain.from_mechanism(PinInsertionMechanism(), np.radians(np.arange(0.0, 360.0, 4.0)))
    tol = load_tolerances()
    serial = monte_carlo(chain, tol, 4000, seed=9, task_samples=600)
    with make_executor("dask", scheduler=dask_scheduler) as ex:
        dask = monte_carlo(chain, tol, 4000, seed=9, executor=ex, task_samples=600)
    for field in ("mean", "std", "minimum", "maximum"):
        np.testing.assert_array_equal(getattr(serial, field), getattr(dask, field))
    for p in serial.percentiles:
        np.testing.assert_array_equal(serial.percentiles[p], dask.percentiles[p])
    other_split = monte_carlo(chain, tol, 4000, seed=9, task_samples=1000)   # other tasks: other draws
    assert not np.array_equal(serial.mean, other_split.mean)


def test_rig_tolerance_json_is_the_same_on_serial_and_dask(tmp_path, dask_scheduler, monkeypatch):
    from rig.cli import main
    common = ["-q", "tolerance", "--samples", "3000", "--task-samples", "700", "-o", str(tmp_path)]
    assert main(common + ["--executor", "serial", "--json", str(tmp_path / "a.json")]) == 0
    assert main(common + ["--scheduler", dask_scheduler, "--json", str(tmp_path / "b.json")]) == 0
    a, b = (tmp_path / "a.json").read_text(), (tmp_path / "b.json").read_text()
    assert a == b
    data = json.loads(a)
    n = len(data["phi_deg"])
    assert n == 360 and data["monte_carlo"]["machines"] == 3000 and len(data["linear"]["rss"]) == n
    assert {"mean", "std", "min", "max", "p0.135", "p99.865"} <= set(data["monte_carlo_clearance"])
    mc = data["monte_carlo"]
    assert all(a <= lo <= hi <= b for a, lo, hi, b in zip(mc["min"], mc["p0.135"], mc["p99.865"], mc["max"]))
    from rig.cli import DEFAULT_SCENE
    assert data["run"] == {"scene": "pin_insertion", "scene_sha256": hashlib.sha256(DEFAULT_SCENE.read_bytes()).hexdigest(),
                           "seed": 20240611, "machines": 3000, "task_samples": 700}
    # the scene's content, not its path's spelling: the same file named relative to another directory, same JSON
    monkeypatch.chdir(DEFAULT_SCENE.parent)
    assert main(common + ["--executor", "serial", "--json", str(tmp_path / "c.json"), DEFAULT_SCENE.name]) == 0
    assert (tmp_path / "c.json").read_text() == a
    # each run names its seed, and that seed gives its numbers again through the API
    from rig.plants.cam_bar.tolerance_report import CLEARANCE_STREAM
    assert (mc["seed"], data["monte_carlo_clearance"]["seed"], data["monte_carlo_clearance"]["spawn_key"]) == (
        20240611, 20240611, [CLEARANCE_STREAM])
    from rig.plants.cam_bar.montecarlo import monte_carlo
    from rig.plants.cam_bar.tolerance import CamChain, load_tolerances
    from rig.plants.cam_bar.scene_io import mechanism_from_scene
    from rig.scene import load_scene
    chain = CamChain.from_mechanism(mechanism_from_scene(load_scene(DEFAULT_SCENE)), np.radians(np.arange(0.0, 360.0)))
    clear = data["monte_carlo_clearance"]
    again = monte_carlo(chain, load_tolerances(), 3000, np.random.SeedSequence(clear["seed"], spawn_key=clear["spawn_key"]),
                        task_samples=700)
    assert again.mean.tolist() == data["monte_carlo_clearance"]["mean"]


def test_commands_choose_their_local_dask_kind(monkeypatch):
    import argparse

    from rig.executors import options
    parser = argparse.ArgumentParser()
    options.add_executor_arguments(parser, local="dask-processes")
    monkeypatch.setattr(options, "make_executor", lambda name, workers, scheduler: (name, workers, scheduler))
    pick = lambda argv: options.executor_from_args(parser.parse_args(argv), local="dask-processes")  # noqa: E731
    assert pick([]) == (None, 1, None)                               # serial by make_executor's default
    assert pick(["--workers", "2"]) == ("dask-processes", 2, None)
    assert pick(["--workers", "2", "--executor", "dask"]) == ("dask", 2, None)
    assert pick(["--scheduler", "tcp://127.0.0.1:8786"]) == (None, 1, "tcp://127.0.0.1:8786")


def test_local_worker_processes_listen_on_loopback_only():
    import psutil
    with make_executor("dask-processes", workers=1) as ex:
        tree = [psutil.Process()] + psutil.Process().children(recursive=True)
        pids = {p.pid for p in tree}
        listening = {c.laddr.ip for c in psutil.net_connections("inet") if c.status == "LISTEN" and c.pid in pids}
        assert listening == {"127.0.0.1"} and len(tree) >= 2          # a nanny/worker process beside this one
        # a function worker processes can import (a test module's own is not importable there: importlib mode)
        assert list(ex.map(math.factorial, range(4))) == [1, 1, 2, 6]


def test_batches_keep_every_item_in_order():
    from rig.executors import batches
    items = list(range(101))
    for workers in (1, 2, 7):
        groups = batches(items, workers)
        assert [x for g in groups for x in g] == items and len(groups) <= 8 * workers
    assert batches([1, 2, 3], 2) == [[1], [2], [3]] and batches([], 2) == []


class _Reversed(Executor):
    """A plugin executor for the test: runs tasks serially (in task order, as every executor must)."""

    name = "reversed-plugin"

    def __init__(self, workers: int, scheduler: str | None = None) -> None:
        self.workers, self.scheduler = workers, scheduler

    def map(self, fn, tasks):
        return iter([fn(t) for t in tasks])


def test_executors_from_installed_packages_are_found_by_entry_point(monkeypatch):
    """A package registering ``[project.entry-points."rig.executor"]`` is usable by name, like python-can's
    interfaces; it cannot replace a built-in, and a broken registration is a clear error."""
    import importlib.metadata as md
    import rig.executors as executors
    fake = [md.EntryPoint("mine", f"{__name__}:_Reversed", executors.ENTRY_POINT_GROUP),
            md.EntryPoint("serial", f"{__name__}:_Reversed", executors.ENTRY_POINT_GROUP),
            md.EntryPoint("broken", f"{__name__}:_Nothing", executors.ENTRY_POINT_GROUP)]
    monkeypatch.setattr(md, "entry_points", lambda group=None: [e for e in fake if e.group == group])
    assert {"mine", "broken", "serial", "dask"} <= set(executors.available())
    with make_executor("mine", workers=3, scheduler="tcp://elsewhere:1") as ex:
        assert isinstance(ex, _Reversed) and ex.workers == 3 and ex.scheduler == "tcp://elsewhere:1"
        assert list(ex.map(_slow_square, range(3))) == [0, 1, 4]
    with make_executor("serial") as ex:
        assert type(ex).__name__ == "SerialExecutor"
    with pytest.raises(ValueError, match="executor 'broken': cannot load"):
        make_executor("broken")


def test_an_unreachable_scheduler_is_a_failed_run_naming_it(monkeypatch, capsys):
    """Exit status 1 (a run that failed: nothing listens there), not 2 (a usage error), with the address named."""
    import rig.executors.dask_cluster as cluster
    from rig.cli import main
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 1)
    assert main(["-q", "tolerance", "--samples", "1000", "--scheduler", "tcp://127.0.0.1:1"]) == 1
    assert ("cannot reach the Dask scheduler at tcp://127.0.0.1:1: connection refused (nothing listens on port 1 of "
            "127.0.0.1") in capsys.readouterr().err         # the cause, not Dask's "timed out" for every cause
    assert main(["-q", "tolerance", "--samples", "1000", "--scheduler", "127.0.0.1:1"]) == 1     # Dask's tcp too
    assert "127.0.0.1:1: connection refused" in capsys.readouterr().err
    assert main(["-q", "tolerance", "--samples", "1000", "--scheduler", "tcp://no-such-host.invalid:8786"]) == 1
    assert "at tcp://no-such-host.invalid:8786: host name 'no-such-host.invalid' does not resolve" in \
        capsys.readouterr().err


@pytest.mark.parametrize("address", ["bogus", "tcp://host", "10.0.0.5:port", "10.0.0.5:70000"])
def test_a_malformed_scheduler_address_is_a_usage_error(address, capsys):
    """Exit 2 naming the option (it was exit 1, "the peer did not answer as one (ValueError: missing port number)")."""
    from rig.cli import main
    with pytest.raises(SystemExit) as stop:
        main(["-q", "tolerance", "--samples", "1000", "--scheduler", address])
    assert stop.value.code == 2
    assert "argument --scheduler: expected a scheduler address such as tcp://10.0.0.5:8786" in capsys.readouterr().err


def _peer(answer: bytes | None):
    """A loopback server that takes connections and either never says a word (``answer`` None) or answers with
    ``answer`` and hangs up; (port, stop)."""
    import socket
    import threading
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0.1)
    held, stop = [], threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            if answer is None:
                held.append(conn)
            else:
                conn.sendall(answer)
                conn.close()
        for conn in held:
            conn.close()
        server.close()

    threading.Thread(target=serve, daemon=True).start()
    return server.getsockname()[1], stop.set


@pytest.mark.parametrize("answer, match", [
    (None, r"no Dask scheduler answered at tcp://127\.0\.0\.1:\d+ within 1 s: something takes connections there"),
    (b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n", r"no Dask scheduler at tcp://127\.0\.0\.1:\d+: the peer "
                                                               r"did not answer as one"),
])
def test_an_address_that_is_not_a_dask_scheduler_is_one_error_in_bounded_time(monkeypatch, answer, match):
    """A port that takes connections and stays silent waited forever; one that answers in another protocol ended in a
    63-line traceback (a 3 EiB allocation): both are one ConnectionError, within the connect timeout and its grace."""
    import time
    from rig.executors import dask_cluster
    monkeypatch.setattr(dask_cluster, "CONNECT_TIMEOUT", 0.5)
    monkeypatch.setattr(dask_cluster, "HANDSHAKE_GRACE", 0.5)
    port, stop = _peer(answer)
    began = time.monotonic()
    try:
        with pytest.raises(ConnectionError, match=match):
            make_executor("dask", scheduler=f"tcp://127.0.0.1:{port}")
    finally:
        stop()
    assert time.monotonic() - began < 30.0


def test_a_run_whose_workers_all_left_stops_with_a_clear_error(monkeypatch, caplog):
    """Every worker of an external scheduler killed mid-run: the run waited for ever without a word. Now a warning at
    once, and after NO_WORKERS s without one a ConnectionError naming the scheduler (times shortened here)."""
    import time as clock
    from distributed import LocalCluster
    import rig.executors.dask_cluster as cluster_module
    monkeypatch.setattr(cluster_module, "WATCH", 0.2)
    monkeypatch.setattr(cluster_module, "NO_WORKERS", 1.0)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address="127.0.0.1:0",
                      worker_dashboard_address="127.0.0.1:0") as cluster:
        ex = make_executor("dask", scheduler=cluster.scheduler_address)
        try:
            cluster.scale(0)
            deadline = clock.monotonic() + 30
            while ex.client.nthreads() and clock.monotonic() < deadline:
                clock.sleep(0.05)
            with caplog.at_level("WARNING"), pytest.raises(ConnectionError,
                                                           match=r"no Dask worker at \S+ for 1 s: the run.s tasks"):
                list(ex.map(abs, [-1, -2]))
        finally:
            ex.close()
    assert f"every Dask worker of {cluster.scheduler_address} has left" in caplog.text


def _times_out(x: int) -> int:
    if x == 2:
        raise TimeoutError("the task's own timeout")
    return x


def test_a_task_that_raises_timeouterror_fails_the_run_at_once():
    """The result wait took a task's own TimeoutError for its watch's and waited again, for ever."""
    with make_executor("dask", 1) as ex:
        with pytest.raises(TimeoutError, match="the task's own timeout"):
            list(ex.map(_times_out, [1, 2, 3]))


def test_rig_tolerance_does_not_choose_a_model_level(tmp_path, monkeypatch):
    """The Monte Carlo uses the chain's geometry only: reading the scene ran the fidelity choice, which simulates a
    level-2 revolution (and on a new machine compiled it: 11-38 s of a first 10^6 run that took 70 s)."""
    from rig.cli import main
    from rig.runner import config

    def never(*args, **kwargs):
        raise AssertionError("rig tolerance chose a model level")
    monkeypatch.setattr(config, "choose", never)
    assert main(["-q", "tolerance", "--samples", "200", "--executor", "serial", "-o", str(tmp_path)]) == 0


def test_ctrl_c_while_the_workers_close_keeps_the_tolerance_study(tmp_path, monkeypatch, capsys):
    """Ctrl-C after the last sample, while the workers closed: the finished study was lost (a leftover). Its table,
    chart and JSON are written, then one line says so; status 130."""
    from rig.cli import main
    from rig.executors.serial import SerialExecutor

    def close(self):
        raise KeyboardInterrupt
    monkeypatch.setattr(SerialExecutor, "close", close)
    assert main(["tolerance", "--samples", "200", "--executor", "serial", "-o", str(tmp_path),
                 "--json", str(tmp_path / "study.json")]) == 130
    captured = capsys.readouterr()
    assert json.loads((tmp_path / "study.json").read_text())["run"]["machines"] == 200
    assert (tmp_path / "pin_insertion.tolerance.png").read_bytes().startswith(b"\x89PNG")
    assert "chart: " in captured.out and f"JSON: {tmp_path / 'study.json'}" in captured.out
    assert [line for line in captured.err.splitlines() if line.startswith("rig:")] == [
        "rig: interrupted while the workers closed, after the study's last sample: its outputs above are whole"]


def test_closing_our_own_cluster_says_nothing_of_its_shutdown(caplog):
    """A sweep on worker processes ended with "rig: distributed.nanny: warning: Worker process still alive after 4.0
    seconds, killing" twice (an audit): the shutdown of the cluster the rig made is its own doing, no news. The
    notice is made here as the nanny makes it, inside the cluster's close."""
    import logging
    with make_executor("dask", workers=1) as ex:
        close = ex.cluster.close

        def noisy_close(*args, **kwargs):
            logging.getLogger("distributed.nanny").warning("Worker process still alive after 4.0 seconds, killing")
            return close(*args, **kwargs)
        ex.cluster.close = noisy_close
    assert not [r for r in caplog.records if "still alive" in r.getMessage()]
    logging.getLogger("distributed.nanny").warning("a notice outside the close")    # the level is given back after it
    assert [r for r in caplog.records if "outside the close" in r.getMessage()]


def test_ctrl_c_while_our_cluster_closes_is_raised_once_it_is_closed():
    """Ctrl-C inside the cluster's close left it half closed; distributed's exit handler then closed it again and
    printed a KeyboardInterrupt traceback after rig's one line (an audit's sweep). The close finishes first now."""
    import os
    import signal
    ex = make_executor("dask", workers=1)
    close = ex.cluster.close

    def interrupted_close(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)             # Ctrl-C arriving in the middle of the close
        return close(*args, **kwargs)
    ex.cluster.close = interrupted_close
    with pytest.raises(KeyboardInterrupt):
        ex.close()
    assert ex.cluster.status.name == "closed" and ex.client.status == "closed"
