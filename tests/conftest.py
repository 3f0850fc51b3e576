"""Shared fixtures: a small Dask cluster for the executor, sweep and batch tests (2 worker threads in this
process, in-process transport, HTTP status servers on 127.0.0.1 only), started once when first asked for."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def dask_scheduler():
    """Address of a running LocalCluster (2 single-threaded workers, processes=False)."""
    from distributed import LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address="127.0.0.1:0",
                      worker_dashboard_address="127.0.0.1:0") as cluster:
        yield cluster.scheduler_address
