"""What a batch's local Dask workers are started with, so that a take costs in a worker what it costs in one process.

* ``MALLOC_TRIM_THRESHOLD_``: Dask's nanny starts every worker with it set to 64 kB (``distributed.nanny.pre-spawn-
  environ``), so that glibc hands freed memory back to the system at once; our tasks allocate and free large
  arrays all the time, and each one is then mapped afresh from the system. The
  workers start without it instead, with glibc's default (dynamic) thresholds: a worker holds one take at a time,
  and the memory a task frees is reused by the next. A value the user set in the environment before this
  process started is kept (:func:`user_trim_threshold`).

  The nanny does not pass its variables to the worker: it writes them into the driver's own environment
  (``os.environ.update``) just before it spawns each worker, which inherits them, and never puts them back. Leaving
  the variable out of ``pre-spawn-environ`` is therefore not enough: after any earlier cluster of this process
  (one without these settings, e.g. a test's), the driver's environment still holds 65536 and every new worker
  inherits it. :func:`worker_environment` takes it out of the driver's environment for as long as the cluster
  lives (the nanny spawns a worker again when one dies), and puts every variable the nanny writes back as it was
  on leaving.
* the statistical profiler of each worker (a thread sampling every task's stack every 10 ms) is off.
* each worker imports the pipeline's modules and loads its compiled kernels before it takes its first task
  (:func:`dask_setup`, a Dask preload): the first take of every worker no longer pays for them. The warm-up costs
  a worker about 1.5-2 s of CPU at its start, all but 0.4-0.9 s of which its first task would have paid (a test's
  cluster of one or two workers running two small takes: 0.3-1.1 s longer in all).
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: glibc's variable that fixes the heap's trim threshold (and with it turns glibc's dynamic thresholds off)
TRIM = "MALLOC_TRIM_THRESHOLD_"
#: the Dask settings of the local cluster's workers (module docstring; :func:`local_worker_settings` sets them)
WORKER_CONFIG: dict[str, Any] = {
    f"distributed.nanny.pre-spawn-environ.{TRIM}": None,
    "distributed.worker.profile.enabled": False,
}
#: the preload that warms each worker (this module's :func:`dask_setup`)
PRELOAD = __name__
#: the variable as this module found it on import: where the process's start-up environment cannot be read
_TRIM_ON_IMPORT = os.environ.get(TRIM)


def user_trim_threshold() -> str | None:
    """``MALLOC_TRIM_THRESHOLD_`` as it was in the environment this process was started with (the user's, and
    never a value Dask's nanny wrote into this process later): from ``/proc/self/environ``, which keeps the
    environment given at start-up whatever the process sets since; elsewhere, its value when this module was
    first imported (before this process started any cluster of the batch)."""
    try:
        start_up = Path("/proc/self/environ").read_bytes()
    except OSError:
        return _TRIM_ON_IMPORT
    prefix = TRIM.encode() + b"="
    for entry in start_up.split(b"\0"):
        if entry.startswith(prefix):
            return os.fsdecode(entry[len(prefix):])
    return None


@contextlib.contextmanager
def worker_environment() -> Iterator[None]:
    """For a local cluster's life: ``MALLOC_TRIM_THRESHOLD_`` in this process's environment as the user started
    it (:func:`user_trim_threshold`; unset when the user did not set it), so that the workers the nanny spawns
    inherit that and not a value an earlier cluster left; on leaving, every variable the nanny writes
    (``pre-spawn-environ``, the hash seed) put back exactly as it was on entering."""
    import dask

    names = set(dask.config.get("distributed.nanny.pre-spawn-environ", default={})) | {TRIM, "PYTHONHASHSEED"}
    before = {name: os.environ.get(name) for name in names}
    user = user_trim_threshold()
    try:
        _set(TRIM, user)
        yield
    finally:
        for name, value in before.items():
            _set(name, value)


@contextlib.contextmanager
def local_worker_settings() -> Iterator[None]:
    """What a local cluster's workers are started with (module docstring): :data:`WORKER_CONFIG` and
    :func:`worker_environment`. Hold it from before the cluster starts until it is closed."""
    import dask

    with dask.config.set(WORKER_CONFIG), worker_environment():
        yield


def _set(name: str, value: str | None) -> None:
    if value is None:
        os.environ.pop(name, None)
    else:
        os.environ[name] = value


#: frames of the take the warm-up processes: enough for each step to call its kernels, few enough to cost little
WARM_UP_FRAMES = 30
#: frames of the take whose gap the warm-up fills by PCA (the fill needs as many frames as the take has columns)
PCA_FRAMES = 60
#: the steps the warm-up runs (every step that calls a compiled kernel; the exports only write files)
WARM_UP_PIPELINE = {"steps": ["label", "calibrate", "fill", "solve"], "layout": "glove-13", "hands": "right",
                    "max_gap": 20}


def warm_up() -> float:
    """Import the task's modules and load the compiled kernels a take's pipeline calls, by running the batch's
    own steps (:func:`core.batch.steps.run_steps`: label, calibrate, fill, solve) on a tiny take, and the PCA gap
    fill (the tiny take's gap is filled from the hand model); returns the seconds it took. The kernels load
    from numba's cache (they are compiled only when the installer's warm-up never ran). Objects' kernels are
    left to the first task that labels objects."""
    started = time.perf_counter()
    import handmocap.core.batch.task  # noqa: F401  (the task's own imports: session, review, exports)
    from handmocap.core.batch.pipeline import pipeline_from_dict
    from handmocap.core.batch.steps import run_steps
    from handmocap.core.gaps.pca import fill_pca
    from handmocap.core.io import Take
    from handmocap.core.review import ReviewTake

    points = _hand_points(WARM_UP_FRAMES, unlabelled=True)
    take = Take(marker_names=[f"point_{index:03d}" for index in range(points.shape[1])], marker_positions=points,
                frame_rate=100.0)
    run_steps(ReviewTake.unlabelled(take), pipeline_from_dict(WARM_UP_PIPELINE))
    fill_pca(_hand_points(PCA_FRAMES, unlabelled=False), 0, PCA_FRAMES // 2, 5)
    return time.perf_counter() - started


def _hand_points(frames: int, unlabelled: bool) -> Any:
    """``(frames, 13, 3)`` mm: the glove-13 markers of the template hand moving and bending its fingers at 100 Hz,
    0.3 mm of noise, one marker missing for 4 frames; ``unlabelled``: each frame's points in a random order. (Not
    the simulator, whose imports and take cost more than the steps warmed here.)"""
    import numpy as np

    from handmocap.core.model import load_layout, load_template, marker_positions_batch, resolve_layout

    model = load_template()
    seconds = np.arange(frames) / 100.0
    thetas = np.zeros((frames, 26))
    thetas[:, 2] = 1000.0                                               # the wrist 1 m up,
    thetas[:, 0] = 200.0 * seconds                                      # moving 2 mm a frame
    thetas[:, 6:] = 0.3 + 0.2 * np.sin(2.0 * np.pi * seconds)[:, None]  # the fingers bending
    rng = np.random.default_rng(0)
    positions = marker_positions_batch(model, resolve_layout(model, load_layout("glove-13")), thetas)
    positions += rng.normal(0.0, 0.3, positions.shape)
    positions[frames // 3:frames // 3 + 4, 2] = np.nan
    if unlabelled:
        positions = np.take_along_axis(positions, np.argsort(rng.random(positions.shape[:2]), axis=1)[:, :, None],
                                       axis=1)
    return positions


def dask_setup(worker: Any) -> None:
    """Dask preload hook: warm the worker (:func:`warm_up`) before it registers with the scheduler. A warm-up
    that fails only leaves the worker cold (its first task pays for it): it never keeps the worker from starting."""
    try:
        warm_up()
    except Exception:  # the first task meets the same error, and reports it
        logging.getLogger(__name__).warning("the batch worker's warm-up failed", exc_info=True)
