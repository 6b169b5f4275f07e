"""The driver of a batch: which takes to run, their tasks on a Dask cluster, progress and the batch state.

:func:`plan_batch` picks the takes (``only`` glob on name or id; takes done with the same input key whose
exports are still there unchanged, where this batch writes them, are skipped unless ``redo``) and checks the
inputs (the layout, the objects spec, each take's id and raw file) and the outputs, all before a cluster or
an output folder exists; a take that cannot be used fails alone with its reason. :func:`run_batch` checks
the scheduler address (:mod:`core.batch.scheduler`), then submits one task per take
(:func:`core.batch.task.process_take`) to a ``LocalCluster`` (``workers`` processes of one thread: the
numba kernels are single-threaded, and one task per process makes a worker's death that task's; each started,
configured and warmed as :mod:`core.batch.worker` says, so that a take costs there what it costs in one process) or
to the scheduler at ``scheduler``, and reports progress as the tasks finish. Tasks return small summaries;
the driver records failures and skips in the batch state (a task records its own progress).

The driver releases each task's result once it has read it: a result still held would be computed
again when the worker keeping it dies, and that second run, cancelled when the batch ends, would leave
its take half processed. A worker that dies (killed, out of memory) has its task tried once more on another worker
(:data:`ALLOWED_FAILURES`: the death may be someone else's, e.g. the OS killing the largest process);
a task that kills two workers fails its take with that reason. ``stop()`` returning True (Ctrl+C in the
CLI, Cancel in the GUI) cancels what has not finished: finished takes are kept, the others untouched.
"""

from __future__ import annotations

import contextlib
import fnmatch
import logging
import re
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from handmocap.core.batch.pipeline import Pipeline
from handmocap.core.batch.scheduler import check_scheduler_address
from handmocap.core.batch.state import file_sha256, input_key, read_state, valid_take_id, write_state
from handmocap.core.batch.task import exports_complete, process_take
from handmocap.core.batch.worker import PRELOAD, local_worker_settings
from handmocap.core.errors import InputError
from handmocap.core.io import READ_SUFFIXES, FrameRateMissingError, recognised_format
from handmocap.core.session.session import Session

#: times a task may be on a worker that dies before its take fails (Dask's ``allowed-failures``)
ALLOWED_FAILURES = 1
#: seconds between two progress reports while nothing finishes
POLL_S = 0.5
SESSION_SUBFOLDER = "handmocap-session"


@dataclass(frozen=True)
class TakeJob:
    """One take to process: session ``take_id``, ``name``, ``frames``, input ``key`` and output ``stem``."""

    take_id: str
    name: str
    frames: int
    key: str
    stem: str


@dataclass
class BatchPlan:
    """The takes to run (``jobs``), those ``up_to_date`` (done with the same key), those ``failed``
    before running ({take id: reason}, e.g. a missing raw file) and the ``output`` folder."""

    session: Session
    pipeline: Pipeline
    jobs: list[TakeJob]
    up_to_date: list[str]
    failed: dict[str, str]
    output: Path
    #: take files of a folder of takes that could not be added to its session ({file: reason}); they fail
    #: in the report like takes
    rejected: dict[str, str] = field(default_factory=dict)


@dataclass
class BatchProgress:
    """Where a batch is: per take id its ``states`` ("queued", "running", "done", "failed", "skipped"),
    the ``summaries`` of the finished ones, ``frames`` processed and seconds ``elapsed``."""

    total: int
    states: dict[str, str] = field(default_factory=dict)
    summaries: dict[str, dict[str, Any]] = field(default_factory=dict)
    frames: int = 0
    elapsed: float = 0.0
    dashboard: str = ""
    interrupted: bool = False

    def count(self, state: str) -> int:
        return sum(1 for value in self.states.values() if value == state)

    @property
    def frames_per_s(self) -> float:
        return self.frames / self.elapsed if self.elapsed > 0 else 0.0

    def seconds_left(self, frames_left: int) -> float | None:
        """Time left at the rate so far (None before the first take finishes)."""
        return frames_left / self.frames_per_s if self.frames else None


def open_study(path: str | Path, pipeline: Pipeline, rejected: dict[str, str] | None = None) -> Session:
    """The session at ``path``; for a folder of take files that is not a session, the session
    ``<path>/handmocap-session`` (created when missing) with every take file of the folder added
    (with the pipeline's layout and hands). A file that cannot be added (empty, unreadable, a link to
    something that is no take) goes into ``rejected`` ({file path: reason}) and the others are added; without
    ``rejected`` its error is raised. InputError when there is neither a session nor take files."""
    folder = Path(path).expanduser().absolute()
    if (folder / "session.json").exists():
        return Session.open(folder)
    if not folder.is_dir():
        raise InputError(f"{folder} is neither a session nor a folder of takes")
    files = sorted(item for item in folder.iterdir() if item.suffix.lower() in READ_SUFFIXES and item.is_file()
                   and _is_take_file(item))
    if not files:
        raise InputError(f"{folder} is neither a session nor a folder of takes (no C3D, TSV, TRC or CSV)")
    target = folder / SESSION_SUBFOLDER
    session = Session.open(target) if (target / "session.json").exists() else Session.create(target)
    known = {Path(entry.source) for entry in session.takes}
    hands = ["right", "left"] if pipeline.hands == "both" else [pipeline.hands if pipeline.hands != "auto" else "right"]
    for item in files:
        if item in known:
            continue
        try:
            _add_take(session, item, pipeline, hands)
        except (InputError, OSError, ValueError) as error:
            if rejected is None:
                raise
            rejected[str(item)] = _one_line(error)
    return session


def _one_line(error: BaseException) -> str:
    return (str(error).splitlines() or [type(error).__name__])[0][:300] or type(error).__name__


def _is_take_file(path: Path) -> bool:
    """Whether a file of a folder of takes is a take (a .csv or .txt file only when a format recognises it,
    so that notes and other tables are left alone; a file that cannot be read is reported when added)."""
    try:
        return recognised_format(path) is not None
    except OSError:
        return True


def _add_take(session: Session, path: Path, pipeline: Pipeline, hands: list[str]) -> None:
    """Add the take file ``path`` at its own rate, or at the pipeline's ``rate`` when the file states none."""
    try:
        session.add_take(path, layout=Path(pipeline.layout).stem, hands=hands)
    except FrameRateMissingError:
        if not pipeline.rate:
            raise InputError(f"{path.name}: the file has no frame rate; give it with rate = HZ in the pipeline"
                             ) from None
        session.add_take(path, layout=Path(pipeline.layout).stem, hands=hands, frame_rate=pipeline.rate)


def check_pipeline_inputs(pipeline: Pipeline) -> None:
    """InputError (one line) when the pipeline's layout (or lab template) or objects spec cannot be read,
    so that a bad one stops the batch before anything starts rather than failing every take."""
    from handmocap.core.model import load_layout
    from handmocap.core.model.lab_template import load_lab_template
    from handmocap.core.model.objects import load_scene_spec

    if pipeline.runs("label") or pipeline.runs("calibrate") or pipeline.runs("solve"):
        load_layout(pipeline.layout)
        load_lab_template(pipeline.layout)
    if pipeline.objects:
        load_scene_spec(pipeline.objects)


def plan_batch(session: Session, pipeline: Pipeline, only: str | None = None, redo: bool = False,
               overwrite: bool = False, rejected: dict[str, str] | None = None) -> BatchPlan:
    """The takes of ``session`` to run (module docstring); ``rejected``: files :func:`open_study` could not
    add. InputError when the pipeline's inputs cannot be read, ``only`` matches no take or an output file
    exists that no earlier batch of that take wrote (unless ``overwrite``)."""
    check_pipeline_inputs(pipeline)
    takes = [entry for entry in session.takes
             if only is None or fnmatch.fnmatchcase(entry.name, only) or fnmatch.fnmatchcase(entry.id, only)]
    if not takes:
        raise InputError(f"no take of session {session.name} matches '{only}'" if only else
                         f"session {session.name} has no take")
    output = Path(pipeline.output) if pipeline.output else session.folder / "exports"
    state = read_state(session.folder, [entry.id for entry in takes])
    pipeline_key = pipeline.key()
    jobs, up_to_date, failed = [], [], {}
    for entry in takes:
        if not valid_take_id(entry.id):
            failed[entry.id] = (f"take id {entry.id[:40]!r} is not a valid take id (letters, digits, '.', '_', "
                                "'-'); the session manifest is damaged")
            continue
        try:
            key = input_key(session.source_path(entry.id), pipeline_key)
        except (InputError, OSError) as error:
            failed[entry.id] = _one_line(error)
            continue
        known = state.get(entry.id, {})
        stem = _stem(entry.id, entry.name)
        if (known.get("state") == "done" and known.get("key") == key and not redo
                and _outputs_current(known, pipeline, output, stem)):
            up_to_date.append(entry.id)
            continue
        jobs.append(TakeJob(entry.id, entry.name, entry.frames, key, stem))
    if pipeline.runs("export") and not overwrite:
        _check_outputs(jobs, pipeline, output, state)
    if pipeline.runs("export") and output.exists() and not output.is_dir():
        raise InputError(f"the output folder {output} exists and is not a folder")
    return BatchPlan(session, pipeline, jobs, up_to_date, failed, output, dict(rejected or {}))


def _outputs_current(known: dict[str, Any], pipeline: Pipeline, output: Path, stem: str) -> bool:
    """Whether the exports a done take's state records are those this batch writes (same kinds, same paths
    in ``output``) and are still there with the content they were written with (sha256)."""
    from handmocap.core.batch.steps import output_paths

    if not pipeline.runs("export"):
        return True
    summary = known.get("summary")
    recorded = summary.get("outputs") if isinstance(summary, dict) else None
    hashes = summary.get("output_sha256") if isinstance(summary, dict) else None
    if not isinstance(recorded, dict) or not isinstance(hashes, dict):
        return False
    expected = output_paths(pipeline, output, stem)
    present = {kind: expected[kind] for kind in recorded if kind in expected}
    if len(present) != len(recorded) or not exports_complete(pipeline, present):
        return False
    for kind, path in present.items():
        if recorded[kind] != str(path):
            return False
        try:
            if file_sha256(path, "export") != hashes.get(kind):
                return False
        except InputError:
            return False
    return True


def _stem(take_id: str, name: str) -> str:
    """The file name stem of a take's exports: its id (unique) and its name made file-name-safe."""
    return f"{take_id}_{re.sub(r'[^A-Za-z0-9._-]+', '_', name).strip('._') or 'take'}"


def _check_outputs(jobs: list[TakeJob], pipeline: Pipeline, output: Path, state: dict) -> None:
    """InputError naming the first output that exists and was not written by a batch of its take."""
    from handmocap.core.batch.steps import output_paths

    for job in jobs:
        if job.take_id in state:
            continue  # a batch of this take (maybe interrupted) wrote them
        for path in output_paths(pipeline, output, job.stem).values():
            if path.exists():
                raise InputError(f"{path} exists; use --overwrite to replace it")


def run_batch(plan: BatchPlan, workers: int = 2, scheduler: str | None = None,
              on_progress: Callable[[BatchProgress], None] | None = None,
              stop: Callable[[], bool] | None = None) -> BatchProgress:
    """Run ``plan`` on Dask (module docstring); ``on_progress`` hears the progress after every change
    and every :data:`POLL_S` seconds. Returns the final progress (``interrupted`` when stopped)."""
    import dask
    from distributed import Client

    if scheduler:
        scheduler = check_scheduler_address(scheduler)
    elif workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    folder = plan.session.folder
    progress = BatchProgress(len(plan.jobs) + len(plan.failed) + len(plan.rejected))
    for take_id, reason in plan.failed.items():
        if valid_take_id(take_id):   # a damaged id gets no state file (it would name a path)
            write_state(folder, take_id, "failed", reason=reason)
        progress.states[take_id] = "failed"
        progress.summaries[take_id] = {"take": take_id, "status": "failed", "reason": reason}
    for file, reason in plan.rejected.items():
        progress.states[file] = "failed"
        progress.summaries[file] = {"take": Path(file).name, "name": Path(file).name, "status": "failed",
                                    "reason": reason}
    if not plan.jobs:
        return progress
    if plan.pipeline.runs("export"):
        try:
            plan.output.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(f"cannot create the output folder {plan.output} ({error.strerror or error})") from None
    progress.states |= {job.take_id: "queued" for job in plan.jobs}
    logging.getLogger("distributed").setLevel(logging.ERROR)
    started = time.perf_counter()
    # one task per worker thread at a time: a worker's death is its task's, and "running" means running; a local
    # cluster's workers set up as core.batch.worker says for the cluster's whole life (a dead worker is spawned again)
    with dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
                          "distributed.scheduler.worker-saturation": 1.0}), \
            contextlib.nullcontext() if scheduler else local_worker_settings():
        cluster = None
        try:
            if scheduler:
                client = Client(scheduler, timeout="20s")
            else:
                cluster = _local_cluster(workers)
                client = Client(cluster)
        except (OSError, TypeError, ValueError) as error:
            raise InputError(f"cannot reach the Dask scheduler {scheduler or '(local)'} "
                             f"({_one_line(error)[:200]})") from None
        try:
            progress.dashboard = client.dashboard_link or ""
            _drive(client, plan, progress, started, on_progress, stop)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    return progress


def _local_cluster(workers: int) -> Any:
    """A LocalCluster of ``workers`` one-thread worker processes that ignore Ctrl+C (it reaches the whole
    process group; the driver stops them cleanly instead of each printing a traceback), each warmed before its
    first task (:data:`core.batch.worker.PRELOAD`); the caller holds :func:`core.batch.worker.local_worker_settings`
    while the cluster lives."""
    from distributed import LocalCluster

    ignoring = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if ignoring else None
    try:
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                            silence_logs=logging.ERROR, preload=[PRELOAD])
    finally:
        if ignoring:
            signal.signal(signal.SIGINT, previous)


def _drive(client: Any, plan: BatchPlan, progress: BatchProgress, started: float,
           on_progress: Callable[[BatchProgress], None] | None, stop: Callable[[], bool] | None) -> None:
    """Submit the tasks and follow them until every one finished or ``stop()``."""
    from distributed import wait

    settings = plan.pipeline.to_dict() | {"output": str(plan.output)}
    futures = {client.submit(process_take, str(plan.session.folder), job.take_id, settings, job.key,
                             str(plan.output), job.stem, key=f"take-{job.take_id}-{job.key[:12]}", pure=False): job
               for job in plan.jobs}
    by_key = {future.key: job for future, job in futures.items()}
    pending = set(futures)
    try:
        while pending:
            if stop is not None and stop():
                raise KeyboardInterrupt
            with contextlib.suppress(TimeoutError):
                wait(list(pending), timeout=POLL_S, return_when="FIRST_COMPLETED")
            finished = {future for future in pending if future.done()}
            pending -= finished
            for future in finished:
                _finished(plan, progress, futures.pop(future), future)
                future.release()  # else Dask recomputes it when the worker holding its result dies
            _mark_running(client, progress, by_key)
            progress.elapsed = time.perf_counter() - started
            if on_progress is not None:
                on_progress(progress)
    except KeyboardInterrupt:
        progress.interrupted = True
        client.cancel(list(pending))
        for future in pending:
            progress.states[futures[future].take_id] = "queued"


def _mark_running(client: Any, progress: BatchProgress, by_key: dict[str, TakeJob]) -> None:
    """The takes whose tasks a worker is running: the first ones of each worker's list, as many as its
    threads (the scheduler may already have given it the next one)."""
    threads = client.nthreads()
    running = {key for worker, keys in client.processing().items() for key in list(keys)[:threads.get(worker, 1)]}
    for key, job in by_key.items():
        state = progress.states.get(job.take_id)
        if state in ("queued", "running"):
            progress.states[job.take_id] = "running" if key in running else "queued"


def _finished(plan: BatchPlan, progress: BatchProgress, job: TakeJob, future: Any) -> None:
    """Record one finished task: its summary, or the reason it failed (its worker died, or it could not
    be run at all)."""
    from distributed import KilledWorker

    if future.status == "finished":
        summary = future.result()
    else:
        error = future.exception()
        if isinstance(error, KilledWorker):
            reason = (f"its worker died {ALLOWED_FAILURES + 1} times while processing it (out of memory, or "
                      "killed): run it alone to see why")
        else:
            reason = f"{type(error).__name__}: {error}".splitlines()[0]
        summary = {"take": job.take_id, "status": "failed", "reason": reason}
    summary["name"] = job.name
    status = summary["status"]
    progress.states[job.take_id] = status
    progress.summaries[job.take_id] = summary
    if status == "done":
        progress.frames += job.frames
    else:
        try:
            write_state(plan.session.folder, job.take_id, status, reason=summary["reason"],
                        summary=_json_ready(summary))
        except InputError as error:   # the state cannot be written: the take still fails alone
            summary["reason"] += f" (and its batch state could not be written: {_one_line(error)})"


def _json_ready(summary: dict[str, Any]) -> dict[str, Any]:
    """The summary without the traceback (kept in memory for the report, not in the state file)."""
    return {key: value for key, value in summary.items() if key != "trace"}
