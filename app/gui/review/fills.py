"""Gap fills: the gap list, fill checks and previews of the selected gap, accepting, rejecting, filling all."""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

import numpy as np
from PySide6.QtCore import QObject

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.part import ReviewPart
from handmocap.app.gui.workers import TaskRunner
from handmocap.core.errors import HandMocapError
from handmocap.core.gaps import FillCheck, fill_method_names
from handmocap.core.review import AcceptFills, Command, FrameSpan, GapFill, RejectFills, ReviewTake
from handmocap.core.workflows import (
    GapGroup,
    ReviewGap,
    check_review_gap,
    fill_gaps,
    find_review_gaps,
    gap_groups,
    preview_fill,
    short_open_gaps,
)
from handmocap.widgets.gap_list import GapRow


class GapFills(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: the gaps of the shown take."""

    def _init_fills(self) -> None:
        """The gaps of the shown take, their rows, what was rejected, cached previews, the gap check worker."""
        self._groups: list[GapGroup] = []
        self._gaps: list[ReviewGap] = []
        self._rows: list[GapRow] = []
        self._rejected: set[tuple[int, int]] = set()
        self._previews: dict[tuple[int, int, str, int], np.ndarray] = {}
        self._check_key: tuple | None = None
        self.checks = TaskRunner(cast(QObject, self))     # the controller: a QObject
        self.checks.succeeded.connect(self._check_done)
        self.checks.failed.connect(self._check_failed)

    def _refresh_gaps(self) -> None:
        document, review = self.document, self.review
        if document is None or review is None:
            return
        self._groups = (gap_groups(review, document.hand_models, self._marker_sets(document, review))
                        if review.n_labels else [])
        self._gaps = find_review_gaps(review, self._groups) if self._groups else []
        old = {(row.marker, row.start, row.length): row for row in self._rows}
        rows = []
        for gap in self._gaps:
            previous = old.get((gap.label, gap.start, gap.length))
            state = "filled" if gap.filled_method else ("rejected" if (gap.label, gap.start) in self._rejected
                                                        else "open")
            row = GapRow(gap.label, gap.name, gap.start, gap.length, state=state, method=gap.filled_method)
            if previous is not None:
                row.recommended, row.errors_mm = previous.recommended, previous.errors_mm
                row.reasons, row.check_error = previous.reasons, previous.check_error
            row.donors = tuple(int(label) for label in self._groups[gap.group].columns if label != gap.label)
            rows.append(row)
        self._rows = rows
        selected = self.gap_list.selected_gap()
        self.gap_list.set_gaps(rows, review.label_names, review.take.first_frame)
        if 0 <= selected < len(rows):
            self.gap_list.select_gap(selected)
        else:
            self.preview.clear()

    def _marker_sets(self, document: TakeDocument, review: ReviewTake) -> dict:
        """The marker set of each hand side of the shown take: the subject's calibrated one, else its layout
        resolved on the hand model once (the document keeps it) rather than at every refresh of the gaps."""
        sets = dict(document.marker_sets)
        for hand in review.hands:
            if hand.side not in sets and hand.layout:
                resolved = document.marker_set_for(hand.side, hand.layout)
                if resolved is not None:
                    sets[hand.side] = resolved
        return sets

    def _gap_selected(self, index: int) -> None:
        if not 0 <= index < len(self._gaps):
            self.preview.clear()
            return
        gap = self._gaps[index]
        self.app.set_frame(gap.start)
        self.select_label(gap.label)
        self._show_preview(index)
        if not self._rows[index].checked:
            self._start_check(index)

    def _start_check(self, index: int) -> None:
        review = self.review
        if review is None:
            return
        gap, group = self._gaps[index], self._groups[self._gaps[index].group]
        key = (id(self.document), review.version, index)
        self._check_key = key

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> tuple:
            check = check_review_gap(group, gap)
            previews = {}
            for method in fill_method_names():
                if cancelled():
                    break
                try:
                    previews[method] = preview_fill(group, gap, method)
                except HandMocapError:
                    continue
            return key, check, previews

        self.checks.start(task)

    def _check_done(self, _request: int, outcome: tuple) -> None:
        key: tuple[int, int, int]
        check: FillCheck
        previews: dict[str, np.ndarray]
        key, check, previews = outcome
        if key != self._check_key or self.review is None or key[1] != self.review.version:
            return
        index = key[2]
        row = self._rows[index]
        ranking = check.ranking()
        row.errors_mm, row.reasons = dict(check.errors_mm), dict(check.reasons)
        row.recommended = ranking[0] if ranking else None
        self.gap_list.update_gap(index, row)
        gap = self._gaps[index]
        for method, values in previews.items():
            self._previews[(gap.label, gap.start, method, -1)] = values
        if self.gap_list.selected_gap() == index:
            self._show_preview(index)

    def _check_failed(self, _request: int, message: str) -> None:
        if self._check_key is None:
            return
        index = self._check_key[2]
        if 0 <= index < len(self._rows):
            row = self._rows[index]
            row.errors_mm, row.check_error = {}, message
            self.gap_list.update_gap(index, row)

    def _show_preview(self, index: int) -> None:
        gap, review = self._gaps[index], self.review
        if review is None:
            return
        candidates = {method: values for (label, start, method, _donor), values in self._previews.items()
                      if label == gap.label and start == gap.start}
        trajectory = review.measured_positions()[:, gap.label]
        self.preview.show_gap(trajectory, gap.start, gap.length, candidates, self.gap_list.chosen_method(),
                              self._rows[index].errors_mm, review.take.first_frame, gap.name)

    def _fill_values(self, index: int, method: str, donor: int) -> np.ndarray:
        gap = self._gaps[index]
        key = (gap.label, gap.start, method, donor)
        if key not in self._previews:
            self._previews[key] = preview_fill(self._groups[gap.group], gap, method,
                                               None if donor < 0 else donor)
        return self._previews[key]

    def _preview_requested(self, index: int, method: str, donor: int) -> None:
        if not 0 <= index < len(self._gaps):
            return
        try:
            self._fill_values(index, method, donor)
        except HandMocapError as error:
            self.error_raised.emit("Cannot preview", str(error))
            return
        self._show_preview(index)
        self.preview.set_selected(method)

    def accept_fill(self, index: int, method: str, donor: int = -1) -> FrameSpan | None:
        """Accept ``method``'s fill of gap ``index`` (one undoable step, then the hand is re-solved)."""
        if not 0 <= index < len(self._gaps):
            return None
        gap = self._gaps[index]

        def make() -> Command:
            return AcceptFills([GapFill(gap.name, gap.start, method, self._fill_values(index, method, donor))])
        return self.run_edit(make)

    def reject_gap(self, index: int) -> None:
        """Reject the fill of gap ``index`` (undoable) or, for an open gap, mark it to be left as it is."""
        if not 0 <= index < len(self._gaps):
            return
        gap = self._gaps[index]
        if gap.filled_method is not None:
            self.run_edit(lambda: RejectFills(gap.name, gap.start, gap.start + gap.length))
            return
        self._rejected.add((gap.label, gap.start))
        self._refresh_gaps()

    def fill_all(self, max_length: int) -> None:
        """Fill every open gap of at most ``max_length`` frames with its recommended method, on a worker;
        the result is one undoable step."""
        review = self.review
        if review is None or self.jobs.is_busy():
            return
        self.flush_views()
        try:
            gaps = [gap for gap in short_open_gaps(review, self._groups, max_length)
                    if (gap.label, gap.start) not in self._rejected]
        except HandMocapError as error:
            self.error_raised.emit("Cannot fill", str(error))
            return
        if not gaps:
            self.status_message.emit(f"No open gap of at most {max_length} frames", 5000)
            return
        groups = self._groups
        self._start_job("fill", lambda progress, cancelled: fill_gaps(groups, gaps, "auto", progress, cancelled))

    def _apply_fill(self, document: TakeDocument, result: Command) -> None:
        """Push the fills of "fill all" (one undoable step); the hands are re-solved next."""
        span = document.push(result)
        self.status_message.emit(result.text, 8000)
        self._needs_resolve(document, span)
