"""The local cluster's workers cost what one process costs (issue 25): no MALLOC_TRIM_THRESHOLD_ (unless the user
started the process with one), no statistical profiler, warmed before the first task; the driver's environment is
left as it was.

Dask's nanny writes ``MALLOC_TRIM_THRESHOLD_=65536`` into the driver's environment and leaves it there, so after any
earlier cluster of the same process (``test_batch_run``'s) a new worker would inherit it: the test puts that value
in the environment first, whatever ran before.
"""

import os
import sys

import dask
import pytest

from handmocap.core.batch import worker as batch_worker
from handmocap.core.batch.runner import _local_cluster
from handmocap.core.batch.worker import TRIM, local_worker_settings, user_trim_threshold, worker_environment

pytest.importorskip("distributed")

NANNY_WRITES = (TRIM, "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "PYTHONHASHSEED")


def _worker_state() -> dict:
    return {"trim": os.environ.get(TRIM), "warm": "handmocap.core.batch.task" in sys.modules
            and "handmocap.core.labelling.scene" in sys.modules,
            "profile": dask.config.get("distributed.worker.profile.enabled")}


def test_local_workers_are_warm_untrimmed_and_unprofiled_and_the_driver_environment_is_kept(monkeypatch):
    from distributed import Client

    monkeypatch.setenv(TRIM, "65536")  # as an earlier cluster of this process leaves it
    before = {name: os.environ.get(name) for name in NANNY_WRITES}
    with local_worker_settings():
        cluster = _local_cluster(1)
        try:
            with Client(cluster) as client:
                states = list(client.run(_worker_state).values())
        finally:
            cluster.close()
    assert states == [{"trim": user_trim_threshold(), "warm": True, "profile": False}]
    assert {name: os.environ.get(name) for name in NANNY_WRITES} == before


def test_the_trim_threshold_the_user_started_with_is_kept(monkeypatch):
    monkeypatch.setattr(batch_worker, "user_trim_threshold", lambda: "131072")
    monkeypatch.setenv(TRIM, "65536")
    monkeypatch.delenv("PYTHONHASHSEED", raising=False)
    with worker_environment():
        assert os.environ[TRIM] == "131072"  # what the workers spawned now inherit
        os.environ["PYTHONHASHSEED"] = "6640"  # as the nanny writes it
    assert os.environ[TRIM] == "65536" and "PYTHONHASHSEED" not in os.environ


def test_the_users_threshold_is_read_from_the_start_up_environment(monkeypatch):
    started_with = user_trim_threshold()
    monkeypatch.setenv(TRIM, "4242")  # set by this process, e.g. by a nanny: not the user's
    assert user_trim_threshold() == started_with != "4242"
    monkeypatch.delenv(TRIM)
    assert user_trim_threshold() == started_with
