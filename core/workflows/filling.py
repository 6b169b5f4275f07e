"""Gaps of a review: which labels belong together (a hand, or the rest), the gaps, their fill check,
previews of each method, "fill all short gaps" as one undoable command, and its accuracy on many gaps
hidden at once in a labelled take.

A *group* is a hand's labels in layout order (the model fill uses that hand's model, layout and solved
joint angles), or the labels no hand owns (the model fill then applies only when their names are one hand's
markers, :func:`core.model.detect_hands`, and solves IK around each gap itself). A group's gaps are those of
its own labels, but the fills that reconstruct a marker from others (PCA, pattern, rigid body) and the fill
check of its hidden stretches use every labelled marker of the take: the group's take holds the other labels
after its own as read-only donor columns (a glove's fingers follow its arm, back and object markers too).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from handmocap.core.errors import CancelledError, InputError
from handmocap.core.gaps import (
    AUTO,
    FillCheck,
    Gap,
    ModelContext,
    check_fill_choice,
    check_gap,
    fill_gap,
    find_gaps,
    provenance_names,
)
from handmocap.core.gaps.check import FillChooser
from handmocap.core.gaps.fills import fill_pattern
from handmocap.core.io import Take
from handmocap.core.model import HandModel, MarkerSet, detect_hands, load_template, track_layout
from handmocap.core.review import AcceptFills, GapFill, ReviewTake
from handmocap.core.workflows.resolve import subject_markers


@dataclass(eq=False)
class GapGroup:
    """Labels filled together: ``labels (K,)`` review label indices; ``take`` the measured positions (fills
    left out) of those K labels, named by layout marker names, followed by the ``donors (D,)``: every other
    review label, by its own name, read-only (their gaps belong to their own group); ``context`` for the
    model fill (or None; its columns are among the first K); ``joint_angles (F,26)`` of the hand when solved
    (or None)."""

    labels: np.ndarray
    take: Take
    context: ModelContext | None
    joint_angles: np.ndarray | None
    donors: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def columns(self) -> np.ndarray:
        """``(K + D,)`` the review label of each column of ``take``: the group's labels, then the donors."""
        return np.concatenate([self.labels, self.donors]).astype(np.int64)


@dataclass(frozen=True)
class ReviewGap:
    """A gap of review label ``label`` (``name``): frames ``start .. start + length - 1``; ``group`` index
    and the same gap in the group's take (``gap``); ``filled_method``: the accepted fill covering it
    (None when open); ``filled``: per frame of the gap, whether an accepted fill already covers it (an
    earlier fill is kept: a new fill of the gap covers only the other frames)."""

    label: int
    name: str
    start: int
    length: int
    group: int
    gap: Gap
    filled_method: str | None
    filled: tuple[bool, ...] = ()


def _group(review: ReviewTake, measured: np.ndarray, labels: np.ndarray, names: list[str],
           context: ModelContext | None, joint_angles: np.ndarray | None) -> GapGroup:
    """The group of ``labels`` named ``names`` with every other label of ``review`` as its donor columns;
    ``measured (F, L, 3)`` mm: the review's measured positions."""
    donors = np.setdiff1d(np.arange(review.n_labels, dtype=np.int64), labels)
    columns = np.concatenate([labels, donors]).astype(np.int64)
    taken = set(names)      # a donor named as one of the group's layout markers (the other hand's) gets its index
    donor_names = [name if name not in taken else f"{name} #{label}"
                   for label, name in ((label, review.label_names[label]) for label in donors)]
    take = Take(marker_names=names + donor_names,
                marker_positions=measured[:, columns], frame_rate=review.take.frame_rate,
                first_frame=review.take.first_frame, vendor=review.take.vendor)
    return GapGroup(labels, take, context, joint_angles, donors)


def gap_groups(review: ReviewTake, models: dict[str, HandModel] | None = None,
               marker_sets: dict[str, MarkerSet] | None = None) -> list[GapGroup]:
    """The hands of ``review`` (model fill with their solved angles, the subject's ``models`` and calibrated
    ``marker_sets`` per side when given) and the remaining labels."""
    models, marker_sets = models or {}, marker_sets or {}
    measured = review.measured_positions()
    groups = []
    owned = np.zeros(review.n_labels, dtype=bool)
    for hand in review.hands:
        labels = np.asarray(hand.labels, dtype=np.int64)
        if not len(labels):
            continue
        owned[labels] = True
        label_names = [review.label_names[label] for label in labels]
        try:
            layout = track_layout(hand.layout, hand.side, label_names) if hand.layout else None
        except InputError:
            layout = None   # labels that are not the layout's markers: no model fill for this hand
        names = list(layout.names) if layout is not None else label_names
        model = models.get(hand.side) or load_template(hand.side)
        context = (ModelContext.for_take(names, model, layout,
                                         subject_markers(model, layout, marker_sets.get(hand.side)))
                   if layout is not None else None)
        angles = hand.joint_angles.copy() if np.isfinite(hand.joint_angles).all(axis=1).any() else None
        groups.append(_group(review, measured, labels, names, context, angles))
    rest = np.flatnonzero(~owned)
    if len(rest):
        names = [review.label_names[label] for label in rest]
        hint = next(iter(models)) if len(models) == 1 else None     # a lone subject hand's side
        found = detect_hands(names, side=hint)
        context = None
        if len(found) == 1:   # labels no hand owns that still name one hand's markers (R_, a vendor's names...)
            side, layout = found[0].side, found[0].present_layout
            model = models.get(side) or load_template(side)
            context = ModelContext(model, layout, subject_markers(model, layout, marker_sets.get(side)),
                                   found[0].labels)
        groups.append(_group(review, measured, rest, names, context, None))
    return groups


def find_review_gaps(review: ReviewTake, groups: list[GapGroup]) -> list[ReviewGap]:
    """Every closed gap (observed on both sides) of every label (in its own group), by label then frame."""
    found = []
    for number, group in enumerate(groups):
        for gap in find_gaps(group.take):
            if gap.open or gap.marker >= len(group.labels):   # a donor column: its own group has the gap
                continue
            label = int(group.labels[gap.marker])
            codes = review.provenance[gap.start:gap.end, label]
            method = None
            if (codes > 0).all():
                method = provenance_names()[int(np.bincount(codes.astype(np.int64)).argmax())]
            found.append(ReviewGap(label, review.label_names[label], gap.start, gap.length, number, gap, method,
                                   tuple(bool(code > 0) for code in codes)))
    return sorted(found, key=lambda item: (item.label, item.start))


def check_review_gap(group: GapGroup, gap: ReviewGap) -> FillCheck:
    """The fill check of ``gap``: each method's mean error (mm) on a hidden known stretch beside it (the
    fills with the same donors as :func:`preview_fill`: the group's labels and its donor columns)."""
    return check_gap(group.take, gap.gap, group.context)


def preview_fill(group: GapGroup, gap: ReviewGap, method: str, donor: int | None = None) -> np.ndarray:
    """Positions ``(length, 3)`` mm of ``method`` over ``gap``; ``donor``: the review label a pattern fill
    follows (default: the steadiest one, as for the rigid body and PCA fills among every labelled marker of
    the take). InputError when the method cannot apply."""
    if method == "pattern" and donor is not None:
        columns = np.flatnonzero((group.columns == donor) & (donor != gap.label))
        if not columns.size:
            raise InputError("the pattern donor must be another labelled marker of the take")
        positions = group.take.marker_positions
        donor_trajectory = positions[:, columns[0]]
        span = donor_trajectory[max(0, gap.start - 1):gap.start + gap.length + 1]
        if not np.isfinite(span).all():
            raise InputError("the donor is not measured through the gap")
        return fill_pattern(positions[:, gap.gap.marker], gap.start, gap.length, donor_trajectory)
    return fill_gap(group.take.marker_positions, gap.gap.marker, gap.start, gap.length, method, group.context,
                    group.joint_angles)


def short_open_gaps(review: ReviewTake, groups: list[GapGroup], max_gap: int) -> list[ReviewGap]:
    """The gaps of at most ``max_gap`` frames that no accepted fill covers yet."""
    if max_gap < 1:
        raise InputError(f"the maximum gap length must be at least 1 frame, got {max_gap}")
    return [gap for gap in find_review_gaps(review, groups) if gap.length <= max_gap and gap.filled_method is None]


def fill_gaps(groups: list[GapGroup], gaps: list[ReviewGap], method: str = "auto",
              progress: Callable[[float], None] | None = None,
              cancelled: Callable[[], bool] | None = None) -> AcceptFills | None:
    """One undoable command filling ``gaps`` with ``method`` ("auto": per gap, the first method of its fill
    check ranking that applies, the check learned along the gaps of each marker (:class:`core.gaps.check.
    FillChooser`), else PCA, model, spline, linear); None when nothing could be filled. Reads only the
    groups (copies), so it may run on a worker while the review changes."""
    check_fill_choice(method)
    fills = []
    chooser = FillChooser()
    for number, gap in enumerate(gaps):
        if cancelled is not None and cancelled():
            raise CancelledError("gap filling cancelled; nothing was filled")
        group = groups[gap.group]
        order = chooser.order(group.take, gap.gap, group.context, gap.group) if method == AUTO else (method,)
        for name in order:
            try:
                values = preview_fill(group, gap, name)
            except InputError:
                continue
            if np.isfinite(values).all():
                fills += _open_parts(gap, name, values)
                break
        if progress is not None:
            progress((number + 1) / len(gaps))
    return AcceptFills(fills) if fills else None


def _open_parts(gap: ReviewGap, method: str, values: np.ndarray) -> list[GapFill]:
    """The fill ``values (length, 3)`` of ``gap`` cut to the frames no earlier fill covers (one GapFill per
    run of them), so that the earlier fills and their methods stay as they were."""
    if not any(gap.filled):
        return [GapFill(gap.name, gap.start, method, values)]
    open_frames = ~np.asarray(gap.filled, dtype=bool)
    edges = np.diff(np.concatenate([[0], open_frames.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return [GapFill(gap.name, gap.start + int(first), method, values[first:last])
            for first, last in zip(starts, stops, strict=True)]


def fill_review_gaps(review: ReviewTake, groups: list[GapGroup], max_gap: int, method: str = "auto",
                     progress: Callable[[float], None] | None = None,
                     cancelled: Callable[[], bool] | None = None) -> AcceptFills | None:
    """:func:`short_open_gaps` filled by :func:`fill_gaps` in one call (command line, tests)."""
    return fill_gaps(groups, short_open_gaps(review, groups, max_gap), method, progress, cancelled)
