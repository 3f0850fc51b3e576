"""The Dask executors: a local cluster, or an existing cluster by scheduler address.

``dask``: ``distributed.LocalCluster`` with ``workers`` single-threaded workers as threads of this process
(in-process transport; one process's memory; right for numpy/numba work that releases the GIL, like the
Monte-Carlo kernels). ``dask-processes``: the workers as processes behind nannies, talking over 127.0.0.1
(for tasks that hold the GIL; each worker process costs ~250 MB). Either way every socket is on 127.0.0.1 at
a free port, the HTTP status servers of scheduler and workers included (Dask's default would put those on
every interface); the scheduler's dashboard is off (a worker's would need bokeh, which rig does not install).
With ``scheduler``: ``distributed.Client(address)`` of an existing cluster, whose workers need mechrig
installed (tasks are functions of rig's modules).
"""
from __future__ import annotations

import logging
import socket
import threading
import time
from collections import deque
from typing import Any, Callable, Iterable, Iterator

from rig.executors import Executor

LOOPBACK_HTTP = "127.0.0.1:0"   # scheduler's and workers' HTTP status servers (else on every interface)
CONNECT_TIMEOUT = 10  # s to reach a scheduler given by address
WORKER_TIMEOUT = 10   # s a scheduler given by address has for its first worker to join
IN_FLIGHT = 2  # tasks per worker submitted ahead of the one whose result is awaited
WATCH = 5.0     # s between looks at the cluster while a task's result is awaited
NO_WORKERS = 60.0   # s without a single worker before a run stops (its tasks would wait for ever)
log = logging.getLogger(__name__)


HANDSHAKE_GRACE = 5   # s beyond CONNECT_TIMEOUT for the Dask handshake (a port that takes connections but is silent)
_abandoned: list[Any] = []   # connection attempts given up: kept, so that no half-made Client is collected (its
#                              __del__ would wait 20 s for a close that cannot come, and print a traceback)


def _probe(scheduler: str) -> None:
    """For a TCP address (``tcp://``, ``tls://``), ConnectionError at once naming why nothing can be reached there — a
    name that does not resolve, a connection refused — rather than Dask's "timed out after 10 s" for every cause."""
    scheme, _, rest = scheduler.rpartition("://")
    if (scheme.lower() or "tcp") not in ("tcp", "tls"):          # host:port alone is Dask's tcp
        return
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT).close()
    except socket.gaierror as exc:
        raise ConnectionError(f"cannot reach the Dask scheduler at {scheduler}: host name {host!r} does not resolve "
                              f"({exc.strerror or exc})") from None
    except ConnectionRefusedError:
        raise ConnectionError(f"cannot reach the Dask scheduler at {scheduler}: connection refused (nothing listens on "
                              f"port {port} of {host}: is the scheduler running, and is this its port?)") from None
    except (TimeoutError, socket.timeout):
        raise ConnectionError(f"cannot reach the Dask scheduler at {scheduler}: no answer within {CONNECT_TIMEOUT:g} s "
                              f"(host down, or a firewall drops the connection)") from None
    except (OSError, ValueError):
        return                      # another cause: Dask's own attempt below says it


def _connect(client: Callable[..., Any], scheduler: str) -> Any:
    """``client(scheduler)`` (distributed.Client) after :func:`_probe` (up to CONNECT_TIMEOUT s) within CONNECT_TIMEOUT +
    HANDSHAKE_GRACE s, else ConnectionError in one line: Client's own timeout covers reaching the address, not a peer
    that accepts the connection and never answers (it waited forever) or answers with something else (a traceback
    ending in a 3 EiB allocation)."""
    _probe(scheduler)
    attempt: dict[str, Any] = {}

    def connect() -> None:
        try:
            attempt["client"] = client(scheduler, set_as_default=False, timeout=CONNECT_TIMEOUT)
        except BaseException as exc:  # noqa: BLE001 - whatever the peer made of it is reported in one line below
            attempt["error"] = exc

    thread = threading.Thread(target=connect, name="rig-dask-connect", daemon=True)
    thread.start()
    thread.join(CONNECT_TIMEOUT + HANDSHAKE_GRACE)
    if "client" in attempt:
        return attempt["client"]
    _abandoned.append(attempt)
    if thread.is_alive():
        raise ConnectionError(f"no Dask scheduler answered at {scheduler} within {CONNECT_TIMEOUT + HANDSHAKE_GRACE:g} s: "
                              f"something takes connections there but does not speak Dask's protocol (the scheduler's "
                              f"port, e.g. tcp://host:8786, not its dashboard's?)")
    exc = attempt["error"]
    if isinstance(exc, KeyboardInterrupt):
        raise exc
    what = " ".join(str(exc).split())[:200] or type(exc).__name__
    if isinstance(exc, OSError):
        raise ConnectionError(f"cannot reach the Dask scheduler at {scheduler}: {what}") from None   # exit 1
    raise ConnectionError(f"no Dask scheduler at {scheduler}: the peer did not answer as one ({type(exc).__name__}: "
                          f"{what})") from None


class DaskExecutor(Executor):
    """Tasks on Dask workers (threads of a local cluster, or a cluster's by ``scheduler``), results in task
    order."""

    name = "dask"
    processes = False

    def __init__(self, workers: int = 2, scheduler: str | None = None):
        from distributed import Client, LocalCluster
        logging.getLogger("distributed").setLevel(logging.WARNING)   # its start/stop notices are no news
        # the tasks map() cancels when it stops early (Ctrl-C, an error) end "with CancelledError": our doing, no news
        logging.getLogger("distributed.worker.state_machine").setLevel(logging.ERROR)
        self.cluster = None
        if scheduler is None:
            where = {"host": "127.0.0.1"} if self.processes else {}   # threads: in-process transport
            self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=self.processes,
                                        dashboard_address=LOOPBACK_HTTP, worker_dashboard_address=LOOPBACK_HTTP,
                                        scheduler_kwargs={"dashboard": False}, silence_logs=logging.WARNING,
                                        **where)
            self.client = Client(self.cluster, set_as_default=False)
        else:
            self.client = _connect(Client, scheduler)
            try:                               # a scheduler without workers would take the tasks and never run them
                self.client.wait_for_workers(1, timeout=WORKER_TIMEOUT)
            except (TimeoutError, OSError):
                self.client.close()
                raise ConnectionError(f"the Dask scheduler at {scheduler} has no workers (none joined within "
                                      f"{WORKER_TIMEOUT:g} s): start some with 'dask worker {scheduler}'") from None
        self.address = scheduler
        self.workers = sum(self.client.nthreads().values())
        if not self.workers:               # every worker left since: map() would submit nothing and yield nothing
            self.close()
            raise ConnectionError(f"the Dask scheduler at {scheduler} has no workers left")

    def map(self, fn: Callable[[Any], Any], tasks: Iterable[Any]) -> Iterator[Any]:
        tasks = iter(tasks)
        pending: deque = deque()

        def submit() -> None:
            for task in tasks:
                pending.append(self.client.submit(fn, task, pure=False))
                return

        for _ in range(IN_FLIGHT * self.workers):
            submit()
        try:
            while pending:
                future = pending.popleft()
                result = self._result(future)
                future.release()
                submit()
                yield result
        finally:
            for future in pending:
                future.cancel()

    def _result(self, future: Any) -> Any:
        """The task's result, looking at the cluster every :data:`WATCH` s meanwhile: with every worker gone (killed,
        their machine down) the tasks would wait for ever without a word — a warning says so at once, and after
        :data:`NO_WORKERS` s with none back the run stops with a ConnectionError."""
        gone_since = None
        while True:
            try:
                return future.result(timeout=WATCH)
            except TimeoutError:
                if future.done():       # the task's own TimeoutError (or it ended as the wait ran out): its result
                    return future.result()
            if self.client.nthreads():
                gone_since = None
                continue
            now = time.monotonic()
            if gone_since is None:
                gone_since = now
                log.warning("every Dask worker of %s has left: the run waits up to %g s for one to join",
                            self.address or "the local cluster", NO_WORKERS)
            elif now - gone_since > NO_WORKERS:
                raise ConnectionError(f"no Dask worker at {self.address or 'the local cluster'} for {NO_WORKERS:g} s: "
                                      f"the run's tasks cannot go on" + (f" (start workers with 'dask worker "
                                                                         f"{self.address}' and run again)"
                                                                         if self.address else ""))

    def describe(self) -> str:
        where = (f"scheduler {self.address}" if self.address else
                 "local cluster, worker processes on 127.0.0.1" if self.processes else "local cluster, worker threads")
        return f"dask ({where}), {self.workers} worker{'s' if self.workers != 1 else ''}"

    def close(self) -> None:
        """Close the client and our own cluster; a Ctrl-C meanwhile is raised once the cluster is closed (raised inside
        its close, it left the cluster half closed for distributed's exit handler, whose second close printed a
        traceback after rig's line)."""
        from rig.interrupt import deferred_interrupt
        with deferred_interrupt():
            self.client.close()
            if self.cluster is not None:      # our own cluster: its shutdown's notices ("Worker process still alive
                quiet = logging.getLogger("distributed")  # after 4.0 seconds, killing", heartbeats of workers leaving)
                level = quiet.level                       # are our doing, no news
                quiet.setLevel(logging.ERROR)
                try:
                    self.cluster.close()
                finally:
                    quiet.setLevel(level)


class DaskProcessesExecutor(DaskExecutor):
    """A local cluster of worker processes on 127.0.0.1 (``dask-processes``)."""

    name = "dask-processes"
    processes = True
