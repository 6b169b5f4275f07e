"""Re-solve the hands of a review over the frames an edit touched."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from core.ik import solve_positions
from core.model import HandModel, MarkerSet, load_layout, load_template, resolve_layout
from core.prior import PosturePrior
from core.session import FrameSpan, ReviewTake, SetSolve

#: frames solved on each side of an edited span, so the warm start settles before the edit
RESOLVE_PAD = 10


def hand_models_for(review: ReviewTake, models: dict[str, HandModel] | None = None
                    ) -> list[tuple[HandModel, MarkerSet] | None]:
    """The hand model (``models`` per side, else the template) and resolved marker set of each hand of
    ``review``; None for a hand without a layout."""
    models = models or {}
    result: list[tuple[HandModel, MarkerSet] | None] = []
    for hand in review.hands:
        if not hand.layout:
            result.append(None)
            continue
        model = models.get(hand.side) or load_template(hand.side)
        result.append((model, resolve_layout(model, load_layout(hand.layout))))
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
                 models: dict[str, HandModel] | None = None, pad: int = RESOLVE_PAD) -> list[ResolveJob]:
    """What to re-solve after an edit of frames ``span``: every hand with a layout and data there, over
    the span ± ``pad`` frames, from the labelled positions (measured points and accepted fills)."""
    start, stop = int(span[0]), int(span[1])
    if stop <= start:
        return []
    first, last = max(0, start - pad), min(review.n_frames, stop + pad)
    positions = review.labelled_positions()
    jobs = []
    for number, (hand, pair) in enumerate(zip(review.hands, hand_models_for(review, models), strict=True)):
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
                  pad: int = RESOLVE_PAD, cancelled: Callable[[], bool] | None = None) -> list[SetSolve]:
    """:func:`resolve_jobs` and :func:`run_resolve_jobs` in one call (command line, tests)."""
    return run_resolve_jobs(resolve_jobs(review, span, models, pad), prior, cancelled=cancelled)
