"""One take of a batch, as a Dask task (or a plain call): the worker does everything and returns a summary.

The worker applies its result itself, under the take's lock, rather than sending it to the driver:
the lock is taken when the task opens the take and kept until the new review step is saved, so the
steps start from the review exactly as the session holds it (earlier edits included), no one can
open the take for editing meanwhile (the GUI gets it read-only), no array crosses the scheduler (a
task returns a summary of a few hundred bytes) and the driver is not a queue every result waits in.
A take already open for editing elsewhere is skipped with that reason.

Order, so that a take is either fully processed or untouched: the steps are done on the review, the
exports written (each atomically), the steps undone and pushed again as ONE compound review step
(one journal record: undoable in the GUI as "batch …"), the take saved, then the batch state says
"done" with each export's path and sha256. A worker killed before the push leaves the review as it was
(the exports are rewritten on the next run); killed after it, the next run finds its step on top of the
take's history and, when every export is there, only records it as done. A take run again after it was
done (``--redo``, another output folder, an export deleted or changed) has that step undone and the
pipeline run afresh, so that every export is written again from the same review.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from numba.core import event

from handmocap.core.batch.pipeline import Pipeline, pipeline_from_dict
from handmocap.core.batch.state import file_sha256, read_state, write_state
from handmocap.core.batch.steps import export_take, output_paths, review_figures, run_steps, undo_all
from handmocap.core.errors import HandMocapError
from handmocap.core.review import CompoundCommand
from handmocap.core.review.export_formats import export_format
from handmocap.core.session.session import OpenTake, Session


def step_description(pipeline: Pipeline, key: str) -> str:
    """The text of a batch's review step (the Edit menu shows it): its steps and its input key."""
    return f"batch {key[:12]}: {', '.join(pipeline.steps)}"


def process_take(folder: str, take_id: str, settings: dict[str, Any], key: str, output: str, stem: str
                 ) -> dict[str, Any]:
    """Run the pipeline ``settings`` on take ``take_id`` of the session in ``folder``, exports to
    ``output/<stem>.*``; ``key`` is the take's input key. Never raises: returns ``{"take", "status":
    "done"|"failed"|"skipped", "reason", "seconds" (wall), "cpu_seconds" (this thread's CPU time: the
    machine's load does not change it), "compilations" (numba compilations in this task),
    ...figures}``."""
    started, cpu_started = time.perf_counter(), time.thread_time()
    summary: dict[str, Any] = {"take": take_id, "status": "failed", "reason": ""}
    with event.install_recorder("numba:compile") as recorder:
        try:
            summary |= _process(Path(folder), take_id, pipeline_from_dict(settings, "pipeline"), key,
                                Path(output), stem, lambda: _compilations(recorder))
        except MemoryError:
            summary["reason"] = "out of memory"
        except (HandMocapError, OSError, ValueError) as error:
            summary["reason"] = (str(error).splitlines() or [type(error).__name__])[0]
        except Exception as error:  # noqa: BLE001 - a bug fails its take, not the batch; the trace is kept
            summary["reason"] = f"internal error: {type(error).__name__}: {error}"
            summary["trace"] = traceback.format_exc(limit=8)
    summary["seconds"] = round(time.perf_counter() - started, 3)
    summary["cpu_seconds"] = round(time.thread_time() - cpu_started, 3)
    summary["compilations"] = _compilations(recorder)
    return summary


def _compilations(recorder: event.RecordingListener) -> int:
    """Numba compilations the recorder saw (a kernel loaded from the cache is not one)."""
    return sum(1 for _, entry in recorder.buffer if entry.is_start)


def _process(folder: Path, take_id: str, pipeline: Pipeline, key: str, output: Path, stem: str,
             compilations: Callable[[], int]) -> dict[str, Any]:
    started = time.perf_counter()
    session = Session.open(folder)
    opened = session.open_take(take_id)
    try:
        if opened.read_only:   # another program (or window) holds the take: it is not ours to change
            reason = (f"another program is editing it ({opened.held_by}): close it there, then process it again"
                      if opened.held_by else opened.read_only_reason())
            return {"status": "skipped", "reason": reason}
        before = read_state(folder, [take_id]).get(take_id, {})
        write_state(folder, take_id, "running", key)  # from now on its exports are the batch's to replace
        description = step_description(pipeline, key)
        review = opened.review
        outputs: dict[str, Path] = {}
        fills: dict[str, int] = {}
        present = {kind: path for kind, path in output_paths(pipeline, output, stem).items()
                   if pipeline.runs("export") and path.is_file()}
        interrupted = opened.stack.undo_text() == description and before.get("state") != "done"
        if interrupted and exports_complete(pipeline, present):  # done by a run stopped before it said so
            outputs = present
        else:
            undone = opened.stack.undo_text() == description
            if undone:  # done before: run afresh from the review before it
                opened.undo()
            try:
                done = run_steps(review, pipeline)
                try:
                    if pipeline.runs("export"):
                        outputs = export_take(review, pipeline, done, output_paths(pipeline, output, stem))
                finally:
                    undo_all(review, done.commands)
            except BaseException:
                if undone:  # the take keeps its earlier batch result
                    opened.redo()
                raise
            if done.commands:
                opened.push(CompoundCommand(done.commands, description))
            fills = done.fills
        _record_take(session, opened, outputs)
        if opened.is_modified():
            opened.save()
        summary = {"take": take_id, "status": "done", "reason": "", "name": opened.entry.name, "fills": fills,
                   "outputs": {kind: str(path) for kind, path in outputs.items()},
                   "output_sha256": {kind: file_sha256(path, "export") for kind, path in outputs.items()}
                   } | review_figures(review)
        summary["seconds"] = round(time.perf_counter() - started, 3)
        summary["compilations"] = compilations()
        write_state(folder, take_id, "done", key, summary=summary)
        return summary
    finally:
        opened.close(save=False)
        session.close()


def exports_complete(pipeline: Pipeline, present: dict[str, Path]) -> bool:
    """Whether the exports ``present`` are every one the pipeline writes (a per-hand format: at least one hand's)."""
    if not pipeline.runs("export"):
        return True
    return all(any(key.startswith(f"{kind}-") for key in present) if export_format(kind).per_hand else kind in present
               for kind in pipeline.exports)


def _record_take(session: Session, opened: OpenTake, outputs: dict[str, Path]) -> None:
    """One manifest update for the take (each one rewrites the whole manifest under the session lock, so
    with many workers they are what waits): its review snapshot (saved right after), its exports and its
    state ("exported" with exports, else "labelled" once labelled), so that the save finds nothing left
    to update and the session browser shows the take's new state."""
    relative = str(opened.snapshot_path.relative_to(session.folder))
    labelled = bool((opened.review.assignment >= 0).any())

    def change() -> None:
        entry = session.take(opened.entry.id)
        entry.results["review"] = relative
        entry.exports.update({kind: str(path) for kind, path in outputs.items()})
        if outputs:
            entry.state = "exported"
        elif entry.state == "raw" and labelled and not entry.labelled_source:
            entry.state = "labelled"

    session.update(change)
