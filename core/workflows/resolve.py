"""Re-solve the hands of a review over the frames an edit touched."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.ik import IKResult, IKSettings, solve_positions
from handmocap.core.io import Take
from handmocap.core.model import (
    HandColumns,
    HandModel,
    MarkerLayout,
    MarkerSet,
    load_template,
    marker_columns,
    resolve_layout,
    track_layout,
)
from handmocap.core.prior import PosturePrior
from handmocap.core.review import FrameSpan, ReviewTake, SetSolve

#: frames solved on each side of an edited span, so the warm start settles before the edit
RESOLVE_PAD = 10


#: a solve needs at least this share of the layout's markers among the take's names
LAYOUT_MATCH_SHARE = 0.5


def hand_models_for(review: ReviewTake, models: dict[str, HandModel] | None = None,
                    marker_sets: dict[str, MarkerSet] | None = None) -> list[tuple[HandModel, MarkerSet] | None]:
    """The hand model (``models`` per side, else the template) and marker set of each hand of ``review``:
    ``marker_sets`` per side (the subject's calibrated markers, e.g. from auto-label) when it holds the
    hand's layout markers, else the layout resolved on the model; None for a hand without a layout (or whose
    labels are not markers of its layout). The marker set holds the markers of the hand's labels, in order
    (:func:`core.model.track_layout`: ``R_``/``L_``, a lab template's or a vendor's names)."""
    models, marker_sets = models or {}, marker_sets or {}
    result: list[tuple[HandModel, MarkerSet] | None] = []
    for hand in review.hands:
        if not hand.layout:
            result.append(None)
            continue
        try:
            layout = track_layout(hand.layout, hand.side, [review.label_names[label] for label in hand.labels])
        except InputError:
            result.append(None)
            continue
        model = models.get(hand.side) or load_template(hand.side)
        result.append((model, subject_markers(model, layout, marker_sets.get(hand.side))))
    return result


def subject_markers(model: HandModel, layout: MarkerLayout, calibrated: MarkerSet | None) -> MarkerSet:
    """``calibrated`` (a subject's marker set) when it holds ``layout``'s markers (those of them, in the layout's
    order), else ``layout`` resolved on ``model``."""
    if calibrated is not None:
        columns = marker_columns(calibrated.names, layout.names)
        if (columns >= 0).all():
            return calibrated if np.array_equal(columns, np.arange(len(calibrated.names))) else \
                calibrated.subset(columns)
    return resolve_layout(model, layout)


def hand_marker_set(hand: HandColumns, marker_names: list[str], model: HandModel,
                    calibrated: MarkerSet | None = None) -> MarkerSet:
    """The markers of ``hand`` (:func:`core.model.detect_hands`) that a take with columns ``marker_names`` has,
    on ``model`` (the subject's ``calibrated`` ones when they hold them), named as the take's columns so that
    :func:`solve_labelled_take` takes each from its column (``R_index_tip`` for the layout's ``index_tip``)."""
    markers = subject_markers(model, hand.present_layout, calibrated)
    return replace(markers, names=[marker_names[column] for column in hand.labels])


def solve_hands(take: Take, hands: list[HandColumns], models: dict[str, HandModel] | None = None,
                marker_sets: dict[str, MarkerSet] | None = None, prior: PosturePrior | None = None,
                method: str = "layered", progress: Callable[[float], None] | None = None,
                cancelled: Callable[[], bool] | None = None) -> list[IKResult]:
    """IK of each of ``hands`` of a labelled ``take`` (one :class:`IKResult` per hand, its ``marker_names`` the
    take's columns), on ``models`` per side (else the template) with the subject's calibrated ``marker_sets``."""
    models, marker_sets = models or {}, marker_sets or {}
    results = []
    for number, hand in enumerate(hands):
        model = models.get(hand.side) or load_template(hand.side)
        markers = hand_marker_set(hand, list(take.marker_names), model, marker_sets.get(hand.side))
        part = None if progress is None else (
            lambda fraction, number=number: progress((number + fraction) / len(hands)))
        results.append(solve_labelled_take(take, model, markers, prior, method, part, cancelled))
    return results


def check_layout_names(marker_names: list[str], layout: MarkerLayout) -> None:
    """InputError (one line, naming a few missing markers) when fewer than :data:`LAYOUT_MATCH_SHARE` of
    ``layout``'s markers are among a take's ``marker_names`` (case-insensitive)."""
    columns = marker_columns(marker_names, layout.names)
    found = int((columns >= 0).sum())
    if found >= LAYOUT_MATCH_SHARE * len(layout.names) and found:
        return
    missing = [name for name, column in zip(layout.names, columns, strict=True) if column < 0]
    more = f" and {len(missing) - 4} more" if len(missing) > 4 else ""
    raise InputError(f"the take has only {found} of the {len(layout.names)} markers of layout '{layout.name}' "
                     f"(missing {', '.join(missing[:4])}{more}): give the layout the take is labelled with")


def solve_labelled_take(take: Take, model: HandModel, markers: MarkerSet, prior: PosturePrior | None = None,
                        method: str = "layered", progress: Callable[[float], None] | None = None,
                        cancelled: Callable[[], bool] | None = None) -> IKResult:
    """IK of a labelled ``take`` (points ``(F,P,3)`` mm, matched to ``markers`` by name) with a resolved
    marker set, e.g. the subject's calibrated markers; the result knows the take's frame rate and
    first frame."""
    if take.n_frames == 0:
        raise InputError("the take has no frames")
    columns = marker_columns(take.marker_names, markers.names)
    targets = np.full((take.n_frames, len(columns), 3), np.nan)
    present = columns >= 0
    targets[:, present] = take.marker_positions[:, columns[present]]
    result = solve_positions(targets, model, markers, prior, IKSettings(method=method), progress, cancelled)
    result.frame_rate, result.first_frame = take.frame_rate, take.first_frame
    return result


@dataclass(eq=False)
class ResolveJob:
    """The IK of one hand over frames ``first ..``: ``targets (n,K,3)`` mm copied from the review (so the
    job can run on a worker while the review changes), the hand's index, model and marker set."""

    hand: int
    first: int
    targets: np.ndarray
    model: HandModel
    markers: MarkerSet


def resolve_jobs(review: ReviewTake, span: FrameSpan | tuple[int, int],
                 models: dict[str, HandModel] | None = None, pad: int = RESOLVE_PAD,
                 marker_sets: dict[str, MarkerSet] | None = None) -> list[ResolveJob]:
    """What to re-solve after an edit of frames ``span``: every hand with a layout and data there, over
    the span ± ``pad`` frames, from the labelled positions (measured points and accepted fills), with
    the subject's ``models`` and calibrated ``marker_sets`` per side when given."""
    start, stop = int(span[0]), int(span[1])
    if stop <= start:
        return []
    first, last = max(0, start - pad), min(review.n_frames, stop + pad)
    positions = review.labelled_positions()
    jobs = []
    for number, (hand, pair) in enumerate(zip(review.hands, hand_models_for(review, models, marker_sets),
                                                               strict=True)):
        if pair is None or not len(hand.labels):
            continue
        targets = positions[first:last][:, hand.labels].copy()
        if np.isfinite(targets).any():
            jobs.append(ResolveJob(number, first, targets, *pair))
    return jobs


def run_resolve_jobs(jobs: list[ResolveJob], prior: PosturePrior | None = None,
                     progress: Callable[[float], None] | None = None,
                     cancelled: Callable[[], bool] | None = None) -> list[SetSolve]:
    """Layered IK of each job; one :class:`SetSolve` per hand to attach to the edit."""
    commands = []
    for number, job in enumerate(jobs):
        result = solve_positions(job.targets, job.model, job.markers, prior, cancelled=cancelled)
        commands.append(SetSolve(job.hand, job.first, result.joint_angles, result.residuals_mm))
        if progress is not None:
            progress((number + 1) / len(jobs))
    return commands


def resolve_hands(review: ReviewTake, span: FrameSpan | tuple[int, int],
                  models: dict[str, HandModel] | None = None, prior: PosturePrior | None = None,
                  pad: int = RESOLVE_PAD, cancelled: Callable[[], bool] | None = None,
                  marker_sets: dict[str, MarkerSet] | None = None) -> list[SetSolve]:
    """:func:`resolve_jobs` and :func:`run_resolve_jobs` in one call (command line, tests)."""
    return run_resolve_jobs(resolve_jobs(review, span, models, pad, marker_sets), prior, cancelled=cancelled)


def solve_unsolved_hands(review: ReviewTake, models: dict[str, HandModel] | None = None,
                         marker_sets: dict[str, MarkerSet] | None = None,
                         progress: Callable[[float], None] | None = None,
                         cancelled: Callable[[], bool] | None = None) -> None:
    """Solve, in ``review``, every hand that has no solved frame yet (layered IK over the whole take, on the
    subject's ``models`` and ``marker_sets`` per side when given): what an export of joint angles needs."""
    if all(np.isfinite(hand.joint_angles).all(axis=1).any() for hand in review.hands):
        return
    jobs = [job for job in resolve_jobs(review, (0, review.n_frames), models, pad=0, marker_sets=marker_sets)
            if not np.isfinite(review.hands[job.hand].joint_angles).all(axis=1).any()]
    for command in run_resolve_jobs(jobs, progress=progress, cancelled=cancelled):
        command.do(review)
