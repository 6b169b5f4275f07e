"""Re-solve the hands of a review over the frames an edit touched."""

from __future__ import annotations

from collections.abc import Callable

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


def resolve_hands(review: ReviewTake, span: FrameSpan | tuple[int, int],
                  models: dict[str, HandModel] | None = None, prior: PosturePrior | None = None,
                  pad: int = RESOLVE_PAD, cancelled: Callable[[], bool] | None = None) -> list[SetSolve]:
    """Layered IK of every hand of ``review`` over frames ``span`` (± ``pad``) from the labelled positions
    (measured points and accepted fills); one :class:`SetSolve` per hand to attach to the edit."""
    start, stop = int(span[0]), int(span[1])
    if stop <= start:
        return []
    first, last = max(0, start - pad), min(review.n_frames, stop + pad)
    positions = review.labelled_positions()
    commands = []
    for number, (hand, pair) in enumerate(zip(review.hands, hand_models_for(review, models), strict=True)):
        if pair is None or not len(hand.labels):
            continue
        model, markers = pair
        targets = positions[first:last][:, hand.labels]
        if not np.isfinite(targets).any():
            continue
        result = solve_positions(targets, model, markers, prior, cancelled=cancelled)
        commands.append(SetSolve(number, first, result.joint_angles, result.residuals_mm))
    return commands
