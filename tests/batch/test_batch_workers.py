"""The local cluster's workers cost what one process costs (issue 25): no malloc trimming at every free, no
statistical profiler, warmed before the first task; the driver's environment is left as it was."""

import os
import sys

import dask

from core.batch.runner import _local_cluster
from core.batch.worker import WORKER_CONFIG, restoring_environment


def _worker_state() -> dict:
    return {"trim": os.environ.get("MALLOC_TRIM_THRESHOLD_"), "warm": "core.batch.task" in sys.modules
            and "core.labelling.scene" in sys.modules,
            "profile": dask.config.get("distributed.worker.profile.enabled")}


def test_local_workers_are_warm_untrimmed_and_unprofiled_and_the_driver_environment_is_kept():
    from distributed import Client

    before = {name: os.environ.get(name) for name in ("MALLOC_TRIM_THRESHOLD_", "OMP_NUM_THREADS", "PYTHONHASHSEED")}
    with dask.config.set(WORKER_CONFIG), restoring_environment():
        cluster = _local_cluster(1)
        try:
            with Client(cluster) as client:
                states = list(client.run(_worker_state).values())
        finally:
            cluster.close()
    assert states == [{"trim": None, "warm": True, "profile": False}]
    assert {name: os.environ.get(name) for name in before} == before
