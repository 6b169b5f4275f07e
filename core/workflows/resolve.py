"""Re-solve the hands of a review over the frames an edit touched."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from core.errors import InputError
from core.ik import IKResult, IKSettings, solve_positions
from core.io import Take
from core.model import HandModel, MarkerLayout, MarkerSet, load_layout, load_template, marker_columns, resolve_layout
from core.prior import PosturePrior
from core.review import FrameSpan, ReviewTake, SetSolve

#: frames solved on each side of an edited span, so the warm start settles before the edit
RESOLVE_PAD = 10


#: a solve needs at least this share of the layout's markers among the take's names
LAYOUT_MATCH_SHARE = 0.5


def hand_models_for(review: ReviewTake, models: dict[str, HandModel] | None = None,
                    marker_sets: dict[str, MarkerSet] | None = None) -> list[tuple[HandModel, MarkerSet] | None]:
    """The hand model (``models`` per side, else the template) and marker set of each hand of ``review``:
    ``marker_sets`` per side (the subject's calibrated markers, e.g. from auto-label) when it holds the
    hand's layout markers, else the layout resolved on the model; None for a hand without a layout."""
    models, marker_sets = models or {}, marker_sets or {}
    result: list[tuple[HandModel, MarkerSet] | None] = []
    for hand in review.hands:
        if not hand.layout:
            result.append(None)
            continue
        model = models.get(hand.side) or load_template(hand.side)
        result.append((model, subject_markers(model, load_layout(hand.layout), marker_sets.get(hand.side))))
    return result


def subject_markers(model: HandModel, layout: MarkerLayout, calibrated: MarkerSet | None) -> MarkerSet:
    """``calibrated`` (a subject's marker set) when it holds ``layout``'s markers in order, else ``layout``
    resolved on ``model``."""
    wanted = [name.lower() for name in layout.names]
    if calibrated is not None and [name.lower() for name in calibrated.names] == wanted:
        return calibrated
    return resolve_layout(model, layout)


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
