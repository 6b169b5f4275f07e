"""Fixtures of the batch tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def cluster():
    """A two-worker Dask LocalCluster (one thread each, processes) shared by a module's tests:
    ``(scheduler address, client)``."""
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as local, \
            Client(local) as client:
        yield local.scheduler_address, client
