"""An open take in the application: the take, its layout choice, its IK result and its solve request."""

from __future__ import annotations

from contextlib import suppress
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from core.errors import HandMocapError
from core.ik import IKResult
from core.io import Take, looks_unlabelled
from core.io.labelled_c3d import SubjectCalibration
from core.model import HandModel, MarkerSet, best_layout_for, load_layout, load_template, marker_columns
from core.review import Command, CompoundCommand, DefineHand, FrameSpan, ReviewTake, SetSolve, UndoStack
from core.session import OpenTake
from core.workflows.resolve import subject_markers

if TYPE_CHECKING:
    from app.gui.loose_takes import LooseTake


@dataclass(eq=False)
class TakeDocument:
    """One take shown in the main window.

    ``solve_request`` is the id of the solve whose result may still be applied (0: none pending); a
    result arriving with another id is stale and dropped. ``auto_solve``: solve it as soon as the
    solver is free (demo takes, ``--solve``). ``current_frame``: where the operator left it (0-based).
    ``side``: the hand the next solve fits ("right" or "left"); the result knows its own.
    ``hand_models`` / ``marker_sets``: the subject's hand per side and its calibrated markers (from
    auto-label), used by drawing, solves and re-solves instead of the template; ``subjects``: those
    calibrations relative to the template, written into exported labelled C3D files.
    ``open_take``: the take in the session its review lives in (None: in memory only); ``session_take_id``:
    its id in the open session; ``loose``: a file opened outside a session, reviewed in an automatic
    session of its own (:mod:`app.gui.loose_takes`; then ``session_take_id`` is None).
    """

    take: Take
    title: str
    layout_name: str | None = None
    result: IKResult | None = None
    solve_request: int = 0
    auto_solve: bool = False
    current_frame: int = 0
    side: str = "right"
    review: ReviewTake | None = None
    stack: UndoStack | None = None
    open_take: OpenTake | None = None
    session_take_id: str | None = None
    loose: LooseTake | None = None
    hand_models: dict[str, HandModel] = field(default_factory=dict)
    marker_sets: dict[str, MarkerSet] = field(default_factory=dict)
    subjects: dict[str, SubjectCalibration] = field(default_factory=dict)
    _columns: np.ndarray | None = field(default=None, repr=False)
    _marker_sets: dict[tuple[str, str, int, int], MarkerSet] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if self.layout_name is None:
            self.layout_name = best_layout_for(self.take.marker_names)
        if self.open_take is not None:
            self.review, self.stack = self.open_take.review, self.open_take.stack

    # ------------------------------------------------------------------------------------ review
    @property
    def is_raw(self) -> bool:
        """Whether the take's points carry no labels yet: as the session recorded it, else by its point
        names (placeholders such as ``*12``)."""
        if self.open_take is not None:
            return not self.open_take.entry.labelled_source
        return looks_unlabelled(self.take.marker_names)

    def ensure_review(self) -> ReviewTake:
        """The review of this take: a labelled take's columns are its labels; a raw take starts with none."""
        if self.review is None:
            self.review = ReviewTake.unlabelled(self.take) if self.is_raw else ReviewTake.from_labelled_take(self.take)
            self.stack = UndoStack(self.review)
        return self.review

    def push(self, command: Command) -> FrameSpan:
        """Do ``command`` on the review (undoable; journalled when the take is in a session)."""
        self.ensure_review()
        return self.open_take.push(command) if self.open_take is not None else self.stack.push(command)

    def attach(self, command: Command) -> FrameSpan:
        """Do ``command`` as part of the last step (a re-solve after an edit)."""
        return self.open_take.attach(command) if self.open_take is not None else self.stack.attach(command)

    def undo(self) -> FrameSpan:
        return self.open_take.undo() if self.open_take is not None else self.stack.undo()

    def redo(self) -> FrameSpan:
        return self.open_take.redo() if self.open_take is not None else self.stack.redo()

    def has_labels(self) -> bool:
        """Whether the review has labels (after auto-label, or a labelled take)."""
        return self.review is not None and self.review.n_labels > 0

    def has_solved_hands(self) -> bool:
        """Whether a hand of the review is solved in some frame."""
        return self.review is not None and any(np.isfinite(hand.joint_angles).any() for hand in self.review.hands)

    def record_solve(self, result: IKResult) -> None:
        """Keep an IK solve in the review as one undoable (and, in a session, journalled) step, defining the
        hand from the layout's labels first when the review has none; nothing when the review has no labels
        or they do not cover the layout (the solve then stays on :attr:`result` only)."""
        review = self.ensure_review()
        if not review.n_labels:
            return
        names = [name.lower() for name in result.marker_names]
        number = next((index for index, hand in enumerate(review.hands)
                       if hand.side == result.hand_side and len(hand.labels) == len(names)
                       and [review.label_names[label].lower() for label in hand.labels] == names), None)
        steps: list[Command] = []
        if number is None:
            steps.append(DefineHand(result.hand_side, result.hand_side, list(result.marker_names), self.layout_name))
            number = len(review.hands)
        steps.append(SetSolve(number, 0, result.joint_angles, result.residuals_mm))
        with suppress(HandMocapError):
            self.push(CompoundCommand(steps, f"{result.method} IK solve ({result.hand_side} hand)"))

    def model_for(self, side: str) -> HandModel:
        """The hand model of ``side``: the subject's (calibrated) model when known, else the template."""
        if side not in self.hand_models:
            self.hand_models[side] = load_template(side)
        return self.hand_models[side]

    def marker_set_for(self, side: str, layout_name: str | None) -> MarkerSet | None:
        """The markers of layout ``layout_name`` on :meth:`model_for` ``side``: the subject's calibrated
        ones when :attr:`marker_sets` has them, else the layout resolved on the model (cached); None
        without a layout."""
        if not layout_name:
            return None
        model = self.model_for(side)
        calibrated = self.marker_sets.get(side)
        key = (side, layout_name, id(model), id(calibrated))
        if key not in self._marker_sets:
            self._marker_sets[key] = subject_markers(model, load_layout(layout_name), calibrated)
        return self._marker_sets[key]

    @cached_property
    def markers_seen(self) -> np.ndarray:
        """Observed markers per frame ``(F,)``."""
        return (~self.take.missing_mask).sum(axis=1)

    @cached_property
    def observed_fraction(self) -> np.ndarray:
        """Share of frames each marker is observed in ``(M,)``."""
        return 1.0 - self.take.missing_fraction_per_marker

    def hand_columns(self) -> np.ndarray:
        """Take columns of the chosen layout's markers (all columns when no layout matches)."""
        if self.layout_name is None:
            return np.arange(self.take.n_markers)
        columns = self.columns_of(load_layout(self.layout_name).names)
        return columns[columns >= 0] if (columns >= 0).any() else np.arange(self.take.n_markers)

    def columns_of(self, names: list[str]) -> np.ndarray:
        """Take column of each marker name, -1 where the take lacks it ``(len(names),)``."""
        return marker_columns(self.take.marker_names, names)

    def set_result(self, result: IKResult) -> None:
        """Attach an IK result; its markers are matched to the take's columns by name."""
        self._columns = self.columns_of(result.marker_names)
        self.result = result

    def residuals_per_take_marker(self, frame: int) -> np.ndarray | None:
        """IK residual (mm) of each take marker at ``frame`` ``(M_take,)`` (NaN: none), or None."""
        if self.result is None or self._columns is None:
            return None
        residuals = np.full(self.take.n_markers, np.nan)
        present = self._columns >= 0
        residuals[self._columns[present]] = self.result.residuals_mm[frame, present]
        return residuals

    def mean_residual_per_frame(self) -> np.ndarray | None:
        """Mean IK residual over the observed markers of each frame ``(F,)`` mm (NaN: none), or None."""
        if self.result is None:
            return None
        residuals = self.result.residuals_mm
        observed = np.isfinite(residuals)
        counts = observed.sum(axis=1)
        sums = np.where(observed, residuals, 0.0).sum(axis=1)
        return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)

    def review_residual_per_frame(self) -> np.ndarray:
        """Mean residual (mm) of the review's solved hands over the labelled samples of each frame ``(F,)``,
        NaN where none."""
        review = self.ensure_review()
        residuals = np.where(review.assignment >= 0, review.residuals_mm, np.nan)
        counts = np.isfinite(residuals).sum(axis=1)
        return np.where(counts > 0, np.nansum(residuals, axis=1) / np.maximum(counts, 1), np.nan)

    def effector_targets(self, frame: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Effector positions ``(K,3)`` and the measured positions of their markers ``(K,3)`` mm."""
        if self.result is None or self._columns is None:
            return None
        targets = np.full((len(self._columns), 3), np.nan)
        present = self._columns >= 0
        targets[present] = self.take.marker_positions[frame, self._columns[present]]
        return self.result.effector_positions[frame], targets
