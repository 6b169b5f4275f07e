"""An open take in the application: the take, its layout choice, its review and its IK result."""

from __future__ import annotations

from contextlib import suppress
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from handmocap.core.errors import HandMocapError
from handmocap.core.ik import IKResult
from handmocap.core.io import Take, looks_unlabelled
from handmocap.core.io.labelled_c3d import SubjectCalibration
from handmocap.core.model import (
    HandModel,
    MarkerSet,
    detect_hands,
    hand_layout,
    load_template,
    marker_columns,
    track_layout,
)
from handmocap.core.review import Command, CompoundCommand, DefineHand, FrameSpan, ReviewTake, SetSolve, UndoStack
from handmocap.core.review.commands import replaced_hand
from handmocap.core.session import OpenTake, Session
from handmocap.core.workflows.resolve import subject_markers


@dataclass
class LooseTake:
    """A take file reviewed outside a session: ``source`` (absolute path), the automatic ``session`` and its
    ``opened`` take (both None: reviewed in memory only), ``restored``: edits of an earlier review that
    came back, ``notice``: one line for the status bar when the take is first shown, ``warning``: why
    edits will not survive ("" when they will)."""

    source: Path
    session: Session | None = None
    opened: OpenTake | None = None
    restored: int = 0
    notice: str = ""
    warning: str = ""


@dataclass(eq=False)
class TakeDocument:
    """One take shown in the main window.

    ``auto_solve``: solve it as soon as the solver (:mod:`app.gui.solve_controller`) is free (demo takes,
    ``--solve``). ``current_frame``: where the operator left it (0-based).
    ``side``: the hand the next solve fits ("right", "left", or "both" for a take with two hands); each result
    knows its own. ``layout_name`` and ``side`` start as the review's hands or the hands the take's names show
    (:func:`core.model.detect_hands`: ``R_``/``L_``, a lab template's or a vendor's names). ``results``: the
    last solve's IK result per hand (``result`` is the first of them).
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
    results: list[IKResult] = field(default_factory=list)
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
    _columns: list[np.ndarray] = field(default_factory=list, repr=False)
    _marker_sets: dict[tuple, MarkerSet | None] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if self.open_take is not None:
            self.review, self.stack = self.open_take.review, self.open_take.stack
        hands = [(hand.side, hand.layout) for hand in self.review.hands] if self.review is not None else []
        if not hands and not self.is_raw:
            hands = [(hand.side, hand.layout_name) for hand in detect_hands(self.take.marker_names,
                                                                             self.layout_name)]
        if self.layout_name is None:
            self.layout_name = next((layout for _, layout in hands if layout), None)
        sides = {side for side, _ in hands}
        if sides:
            self.side = "both" if len(sides) > 1 else sides.pop()

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
        if self.open_take is not None:
            return self.open_take.push(command)
        assert self.stack is not None, "the take has no review yet"     # (the stack is made with the review)
        return self.stack.push(command)

    def attach(self, command: Command) -> FrameSpan:
        """Do ``command`` as part of the last step (a re-solve after an edit)."""
        if self.open_take is not None:
            return self.open_take.attach(command)
        assert self.stack is not None, "the take has no review yet"     # (the stack is made with the review)
        return self.stack.attach(command)

    def undo(self) -> FrameSpan:
        if self.open_take is not None:
            return self.open_take.undo()
        assert self.stack is not None, "the take has no review yet"     # (the stack is made with the review)
        return self.stack.undo()

    def redo(self) -> FrameSpan:
        if self.open_take is not None:
            return self.open_take.redo()
        assert self.stack is not None, "the take has no review yet"     # (the stack is made with the review)
        return self.stack.redo()

    def has_labels(self) -> bool:
        """Whether the review has labels (after auto-label, or a labelled take)."""
        return self.review is not None and self.review.n_labels > 0

    def has_solved_hands(self) -> bool:
        """Whether a hand of the review is solved in some frame."""
        return self.review is not None and self.review.has_solved_hand()

    def record_solve(self, result: IKResult | list[IKResult]) -> None:
        """Keep an IK solve (one result per hand) in the review as one undoable (and, in a session, journalled)
        step, defining a hand from its result's labels first when the review has none of them; nothing when the
        review has no labels or they do not cover the result's markers (the solve then stays on :attr:`results`
        only)."""
        results = result if isinstance(result, list) else [result]
        review = self.ensure_review()
        if not review.n_labels or not results:
            return
        hands = [SimpleNamespace(name=hand.name, labels=hand.labels) for hand in review.hands]  # as the steps go
        steps: list[Command] = []
        for solved in results:
            wanted = [name.lower() for name in solved.marker_names]
            number = next((index for index, hand in enumerate(review.hands)
                           if hand.side == solved.hand_side and len(hand.labels) == len(wanted)
                           and [review.label_names[label].lower() for label in hand.labels] == wanted), None)
            if number is None:
                try:
                    labels = np.array([review.label_index(name) for name in solved.marker_names], dtype=np.int64)
                except HandMocapError:
                    return
                steps.append(DefineHand(solved.hand_side, solved.hand_side, list(solved.marker_names),
                                        self.layout_name))
                number = replaced_hand(hands, solved.hand_side, labels)  # where DefineHand puts it
                if number is None:
                    number = len(hands)
                    hands.append(SimpleNamespace(name=solved.hand_side, labels=labels))
                else:
                    hands[number] = SimpleNamespace(name=solved.hand_side, labels=labels)
            steps.append(SetSolve(number, 0, solved.joint_angles, solved.residuals_mm))
        sides = " and ".join(solved.hand_side for solved in results)
        text = f"{results[0].method} IK solve ({sides} hand{'s' if len(results) > 1 else ''})"
        with suppress(HandMocapError):
            self.push(CompoundCommand(steps, text))

    def model_for(self, side: str) -> HandModel:
        """The hand model of ``side``: the subject's (calibrated) model when known, else the template."""
        if side not in self.hand_models:
            self.hand_models[side] = load_template(side)
        return self.hand_models[side]

    def marker_set_for(self, side: str, layout_name: str | None,
                       label_names: list[str] | None = None) -> MarkerSet | None:
        """The markers of layout ``layout_name`` (the ``side`` hand's markers of a template; those that
        ``label_names`` name, in that order, when given: :func:`core.model.track_layout`) on :meth:`model_for`
        ``side``: the subject's calibrated ones when :attr:`marker_sets` has them, else the layout resolved on
        the model (cached); None without a layout or when the labels are not its markers."""
        if not layout_name:
            return None
        model = self.model_for(side)
        calibrated = self.marker_sets.get(side)
        key = (side, layout_name, tuple(label_names or ()), id(model), id(calibrated))
        if key not in self._marker_sets:
            try:
                layout = (track_layout(layout_name, side, label_names) if label_names is not None
                          else hand_layout(layout_name, side))
                self._marker_sets[key] = subject_markers(model, layout, calibrated)
            except HandMocapError:
                self._marker_sets[key] = None
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
        """Take columns of the markers of the hands the chosen layout finds (all columns when it finds none)."""
        if self.layout_name is None:
            return np.arange(self.take.n_markers)
        try:
            hands = detect_hands(self.take.marker_names, self.layout_name)
        except HandMocapError:
            hands = []
        columns = np.concatenate([hand.labels for hand in hands]) if hands else np.zeros(0, dtype=np.int64)
        return np.unique(columns) if len(columns) else np.arange(self.take.n_markers)

    def columns_of(self, names: list[str]) -> np.ndarray:
        """Take column of each marker name, -1 where the take lacks it ``(len(names),)``."""
        return marker_columns(self.take.marker_names, names)

    def set_result(self, result: IKResult | list[IKResult]) -> None:
        """Attach an IK solve (one result per hand); their markers are matched to the take's columns by name."""
        self.results = list(result) if isinstance(result, list) else [result]
        self.result = self.results[0] if self.results else None
        self._columns = [self.columns_of(solved.marker_names) for solved in self.results]

    def residuals_per_take_marker(self, frame: int) -> np.ndarray | None:
        """IK residual (mm) of each take marker at ``frame`` ``(M_take,)`` (NaN: none), or None."""
        if not self.results:
            return None
        residuals = np.full(self.take.n_markers, np.nan)
        for solved, columns in zip(self.results, self._columns, strict=True):
            present = columns >= 0
            residuals[columns[present]] = solved.residuals_mm[frame, present]
        return residuals

    def mean_residual_per_frame(self) -> np.ndarray | None:
        """Mean IK residual over the observed markers of each frame ``(F,)`` mm (NaN: none), or None."""
        if not self.results:
            return None
        residuals = np.concatenate([solved.residuals_mm for solved in self.results], axis=1)
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
        """Effector positions ``(K,3)`` and the measured positions of their markers ``(K,3)`` mm (every hand)."""
        if not self.results:
            return None
        effectors, targets = [], []
        for solved, columns in zip(self.results, self._columns, strict=True):
            measured = np.full((len(columns), 3), np.nan)
            present = columns >= 0
            measured[present] = self.take.marker_positions[frame, columns[present]]
            effectors.append(solved.effector_positions[frame])
            targets.append(measured)
        return np.concatenate(effectors), np.concatenate(targets)
