"""A batch's pipeline on a take that is open for editing in this program (the GUI's Process takes…).

A batch worker cannot process such a take: the open take holds its lock, and the worker would only get it
read-only. The window runs the same steps instead, in its own process, on a copy of the open review
(:func:`process_review_copy`, on a worker thread: the shown review is never touched off the GUI thread);
the result comes back as ONE command (:class:`~core.review.CompoundCommand` with the batch's step text, as
:func:`core.batch.task.process_take` pushes) that the window pushes through the open document, so it is
journalled and undoable like any edit, then records the batch state (:func:`record_done`) so the next run
finds the take done.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from handmocap.core.batch.pipeline import Pipeline
from handmocap.core.batch.state import file_sha256, write_state
from handmocap.core.batch.steps import StepsResult, export_take, output_paths, review_figures, run_steps, undo_all
from handmocap.core.batch.task import step_description
from handmocap.core.model import HandModel, MarkerSet
from handmocap.core.review import CompoundCommand, ReviewTake


@dataclass
class OpenTakeResult:
    """What the pipeline made of an open take's review copy: the ``command`` to push (None: the steps changed
    nothing), the exports written, the subject's hand ``models`` and ``marker_sets`` per side when calibrated,
    and the take's ``summary`` (as a batch task's, with ``applied`` False until the window pushed it)."""

    command: CompoundCommand | None
    outputs: dict[str, Path] = field(default_factory=dict)
    models: dict[str, HandModel] = field(default_factory=dict)
    marker_sets: dict[str, MarkerSet] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)


def process_review_copy(review: ReviewTake, pipeline: Pipeline, key: str, output: Path, stem: str,
                        cancelled: Callable[[], bool] | None = None) -> OpenTakeResult:
    """Run ``pipeline``'s steps on ``review`` (a copy of the open review: it is changed and put back), write its
    exports to ``output/<stem>.*`` and return the steps as one command to push on the open review."""
    started = time.perf_counter()
    done: StepsResult = run_steps(review, pipeline, cancelled)
    try:
        outputs = export_take(review, pipeline, done, output_paths(pipeline, output, stem)) \
            if pipeline.runs("export") else {}
        figures = review_figures(review)
    finally:
        undo_all(review, done.commands)
    command = CompoundCommand(done.commands, step_description(pipeline, key)) if done.commands else None
    summary = {"status": "done", "reason": "", "fills": done.fills,
               "outputs": {kind: str(path) for kind, path in outputs.items()},
               "output_sha256": {kind: file_sha256(path, "export") for kind, path in outputs.items()},
               "seconds": round(time.perf_counter() - started, 3)} | figures
    return OpenTakeResult(command, outputs, done.models, done.marker_sets, summary)


def record_done(folder: Path, take_id: str, key: str, summary: dict[str, Any]) -> None:
    """The batch state of an open take whose result was pushed: done with ``key`` (its exports' paths and
    sha256 in ``summary``), so the next run of the same pipeline finds it up to date."""
    write_state(folder, take_id, "done", key, summary=summary)
