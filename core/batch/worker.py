"""What a batch's local Dask workers are started with, so that a take costs in a worker what it costs in one process.

* ``MALLOC_TRIM_THRESHOLD_``: Dask's nanny sets it to 64 kB in every worker (``distributed.nanny.pre-spawn-
  environ``), so that glibc hands freed memory back to the system at once; our tasks allocate and free large
  arrays all the time, and each one is then mapped afresh (tens of thousands of page faults per task). The
  workers keep glibc's default instead (a worker holds one take at a time; its memory is freed when the task
  ends and reused by the next). The nanny also writes its variables into the driver's environment: the
  driver's environment is put back once the workers have started (:func:`restoring_environment`).
* the statistical profiler of each worker (a thread sampling every task's stack every 10 ms) is off.
* each worker imports the pipeline's modules and loads its compiled kernels before it takes its first task
  (:func:`dask_setup`, a Dask preload): the first take of every worker no longer pays for them.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Iterator
from typing import Any

#: the Dask settings of the local cluster's workers (module docstring)
WORKER_CONFIG: dict[str, Any] = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
}
#: the preload that warms each worker (this module's :func:`dask_setup`)
PRELOAD = __name__


def warm_up() -> float:
    """Import the pipeline's modules and load every compiled kernel a take's pipeline calls, by running its
    steps on tiny simulated takes (:mod:`core.workflows.warm_up`: labelling, IK, gap fill); returns the
    seconds it took. Loads from numba's cache (compiles only when the installer's warm-up never ran)."""
    started = time.perf_counter()
    import core.batch.task  # noqa: F401  (the task's own imports: session, review, exports)
    from core.workflows.warm_up import _labelling, _solve_and_fill

    _labelling()
    _solve_and_fill()
    return time.perf_counter() - started


def dask_setup(worker: Any) -> None:
    """Dask preload hook: warm the worker (:func:`warm_up`) before it registers with the scheduler."""
    warm_up()


@contextlib.contextmanager
def restoring_environment() -> Iterator[None]:
    """Put the variables the nanny writes into this process's environment (``pre-spawn-environ``, the hash
    seed) back as they were on leaving."""
    import dask

    names = set(dask.config.get("distributed.nanny.pre-spawn-environ")) | {"PYTHONHASHSEED"}
    before = {name: os.environ.get(name) for name in names}
    try:
        yield
    finally:
        for name, value in before.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
