"""The steps of a pipeline on one review: label → subject calibration → fill → solve, then the exports.

:func:`run_steps` does each step's command on the review as it goes (each step works on the result of
the one before) and returns them, so the caller can undo them and push them again as one undoable
review step. Nothing here touches the session or the scheduler: the same steps run in a test, in a
Dask worker, or in a plain loop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from handmocap.core.batch.pipeline import Pipeline
from handmocap.core.errors import CancelledError, InputError
from handmocap.core.gaps import find_gaps
from handmocap.core.ik import IKSettings, solve_positions
from handmocap.core.io.labelled_c3d import SubjectCalibration, subject_calibrations
from handmocap.core.model import HandModel, MarkerSet, load_layout, load_template
from handmocap.core.model.provenance import MEASURED
from handmocap.core.review import ReviewTake, SetSolve
from handmocap.core.review.commands import Command
from handmocap.core.review.export import export_review
from handmocap.core.review.export_formats import export_format
from handmocap.core.workflows.filling import fill_review_gaps, gap_groups
from handmocap.core.workflows.labelling import auto_label, subject_model
from handmocap.core.workflows.resolve import resolve_jobs

HEALTH_LINES = 5  #: health warnings a take's summary quotes (the count is always given)


@dataclass
class StepsResult:
    """What :func:`run_steps` did: ``commands`` in order (done on the review), the subject's hand
    ``models`` and ``marker_sets`` per side and ``subjects`` (for a labelled C3D) when calibrated, and
    figures (``fills``: gaps filled per method, ``labelling``: the labeller's report or None)."""

    commands: list[Command] = field(default_factory=list)
    models: dict[str, HandModel] = field(default_factory=dict)
    marker_sets: dict[str, MarkerSet] = field(default_factory=dict)
    subjects: list[SubjectCalibration] = field(default_factory=list)
    fills: dict[str, int] = field(default_factory=dict)
    labelling: dict | None = None


def run_steps(review: ReviewTake, pipeline: Pipeline, cancelled: Callable[[], bool] | None = None) -> StepsResult:
    """Do the pipeline's label, calibrate, fill and solve steps on ``review``; on any error the commands
    already done are undone (the review is as it was) and the error raised."""
    done = StepsResult()

    def do(command: Command) -> None:
        if cancelled is not None and cancelled():
            raise CancelledError("cancelled")
        command.do(review)
        done.commands.append(command)

    try:
        _steps(review, pipeline, done, do)
    except BaseException:
        undo_all(review, done.commands)
        raise
    return done


def undo_all(review: ReviewTake, commands: list[Command]) -> None:
    """Undo ``commands`` (done on ``review`` in this order), last first."""
    for command in reversed(commands):
        command.undo(review)


def _steps(review: ReviewTake, pipeline: Pipeline, done: StepsResult, do: Callable[[Command], None]) -> None:
    if pipeline.runs("label"):
        outcome = auto_label(review.take, load_layout(pipeline.layout), pipeline.hands, pipeline.objects or None,
                             pipeline.online, relabel=pipeline.relabel)
        do(outcome.command)
        done.labelling = outcome.report
        if pipeline.runs("calibrate"):
            done.models, done.marker_sets, done.subjects = outcome.models, outcome.marker_sets, outcome.subjects
    elif pipeline.runs("calibrate"):
        done.subjects = subject_calibrations(review.take.parameters, review.take.source_path)
        for subject in done.subjects:
            done.models[subject.side], done.marker_sets[subject.side] = subject_model(
                subject, load_layout(subject.layout))
    if (pipeline.runs("fill") or pipeline.runs("solve")) and not (review.assignment >= 0).any():
        raise InputError("the take has no labelled point: add the label step to the pipeline")
    if pipeline.runs("fill"):
        command = fill_review_gaps(review, gap_groups(review, done.models, done.marker_sets), pipeline.max_gap,
                                   pipeline.fill_method)
        if command is not None:
            do(command)
            for fill in command.fills:
                done.fills[fill.method] = done.fills.get(fill.method, 0) + 1
    if pipeline.runs("solve"):
        settings = IKSettings(method=pipeline.solve_method)
        for job in resolve_jobs(review, (0, review.n_frames), done.models, 0, done.marker_sets):
            result = solve_positions(job.targets, job.model, job.markers, None, settings)
            do(SetSolve(job.hand, job.first, result.joint_angles, result.residuals_mm))


def output_paths(pipeline: Pipeline, folder: Path, stem: str) -> dict[str, Path]:
    """Every file the export step may write for a take named ``stem`` into ``folder``, by kind: each export
    format's name (``<stem><batch_ending>``, :class:`core.review.export_formats.ExportFormat`), and for a
    per-hand format ``<name>-right``/``<name>-left`` (``<stem>.<side><batch_ending>``, one file per hand found)."""
    paths: dict[str, Path] = {}
    for kind in pipeline.exports:
        chosen = export_format(kind)
        if chosen.per_hand:
            paths |= {f"{kind}-{side}": folder / f"{stem}.{side}{chosen.batch_ending}" for side in ("right", "left")}
        else:
            paths[kind] = folder / f"{stem}{chosen.batch_ending}"
    return paths


def export_take(review: ReviewTake, pipeline: Pipeline, done: StepsResult, paths: dict[str, Path]) -> dict[str, Path]:
    """Write the pipeline's exports of ``review`` (atomically, each file) to ``paths`` (:func:`output_paths`) as
    ``handmocap export`` does (:func:`core.review.export.export_review`; the subject's calibrated hands, else the
    template); returns the ones written. InputError when one cannot be made (e.g. joint angles of a take
    without a solved hand)."""
    written: dict[str, Path] = {}
    models = {hand.side: done.models.get(hand.side) or load_template(hand.side) for hand in review.hands}
    for kind in pipeline.exports:
        chosen = export_format(kind)
        if chosen.joint_angles and not review.hands:
            raise InputError(f"this take has no solved hand; no {kind} to export")
        if not chosen.per_hand:
            export_review(review, paths[kind], kind, models=models, subjects=done.subjects or None)
            written[kind] = paths[kind]
            continue
        for side in dict.fromkeys(hand.side for hand in review.hands):   # one file per side
            key = f"{kind}-{side}"
            export_review(review, paths[key], kind, hand=side, models=models)
            written[key] = paths[key]
    return written


def review_figures(review: ReviewTake) -> dict:
    """What an operator needs to rank a processed take: ``labelled_share`` (label samples measured),
    ``filled_share`` (label samples filled), ``longest_gap`` (frames of the longest gap left between two
    positions of a label), ``mean_residual_mm`` (IK residual over the measured labels; None when
    unsolved), ``hands`` (solved), ``health_count`` and the first :data:`HEALTH_LINES` ``health`` warnings
    of the labelling (one line each)."""
    provenance = review.provenance
    gaps = [gap.length for gap in find_gaps(review.labelled_take()) if not gap.open]
    residuals = np.where(review.assignment >= 0, review.residuals_mm, np.nan)
    solved = [hand.name for hand in review.hands if np.isfinite(hand.joint_angles).all(axis=1).any()]
    return {
        "frames": review.n_frames, "labels": review.n_labels,
        "labelled_share": round(float((provenance == MEASURED).mean()), 4) if provenance.size else 0.0,
        "filled_share": round(float((provenance > 0).mean()), 4) if provenance.size else 0.0,
        "longest_gap": max(gaps, default=0),
        "mean_residual_mm": round(float(np.nanmean(residuals)), 3) if np.isfinite(residuals).any() else None,
        "hands": solved,
        "health_count": len(review.health),
        "health": [f"{warning.kind}: {warning.message}" for warning in review.health[:HEALTH_LINES]],
    }
