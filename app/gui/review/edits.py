"""Label edits (assign, unlabel, ghost, swap) as undoable commands, and undo/redo of the take's steps."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from PySide6.QtGui import QCursor

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.errors import HandMocapError
from handmocap.core.review import AssignLabel, Command, FrameSpan, MarkGhost, SwapLabels, Unlabel
from handmocap.widgets.label_picker import LabelPicker


class LabelEdits(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: edits on the undo stack."""

    def _scope(self) -> tuple[str, int | None, int | None]:
        scope, selection = self.scope_box.currentData(), self.selection
        if scope != "range":
            return scope, None, None
        if selection.range_in is None or selection.range_out is None:
            raise HandMocapError("mark the range first: I at its first frame, O at its last")
        start, stop = sorted((selection.range_in, selection.range_out))
        return scope, start, stop + 1

    def _selected_point(self) -> tuple[int, int]:
        frame, label, column = self.app.frame, self.selection.label, self.selection.column
        review = self.review
        assert review is not None, "no take is shown"    # an edit's make(): run_edit checked
        if column < 0 and label >= 0:
            column = int(review.assignment[frame, label])
        if column < 0 or not np.isfinite(review.take.marker_positions[frame, column]).all():
            raise HandMocapError("select a point in the 3D view (or a label that has a point in this frame) first")
        return frame, column

    def run_edit(self, make: Callable[[], Command]) -> FrameSpan | None:
        """Build a command, push it on the undo stack (the views follow its change event), and re-solve
        the frames it touched. A problem becomes a one-line message; the review stays as it was."""
        document = self.document
        if document is None or document.review is None:
            return None
        try:
            command = make()
            span = document.push(command)
        except HandMocapError as error:
            self.error_raised.emit("Cannot edit", str(error))
            return None
        self._needs_resolve(document, span)
        self.status_message.emit(command.text, 5000)
        return span

    def _point_edit(self, command: type, *arguments: str) -> FrameSpan | None:
        """Run a point command (``AssignLabel``, ``Unlabel``, ``MarkGhost``) on the selected point over
        the chosen scope; ``arguments`` follow the point (the new label of an assignment)."""
        def make() -> Command:
            frame, column = self._selected_point()
            scope, start, stop = self._scope()
            return command(frame, column, *arguments, scope=scope, start=start, stop=stop)
        return self.run_edit(make)

    def assign_label(self, new_label: str) -> FrameSpan | None:
        """Give ``new_label`` to the selected point over the chosen scope."""
        span = self._point_edit(AssignLabel, new_label)
        review = self.review
        if span is not None and review is not None:
            self.select_label(review.label_index(new_label))
        return span

    def unlabel(self) -> FrameSpan | None:
        """Remove the label of the selected point over the chosen scope."""
        return self._point_edit(Unlabel)

    def mark_ghost(self) -> FrameSpan | None:
        """Mark the selected point as a ghost over the chosen scope."""
        return self._point_edit(MarkGhost)

    def swap_labels(self, other: str) -> FrameSpan | None:
        """Swap the selected label with ``other`` over the marked range (or from here to the end)."""
        def make() -> Command:
            selection, review = self.selection, self.review
            assert review is not None, "no take is shown"    # run_edit checked
            if selection.label < 0:
                raise HandMocapError("select the label to swap first (click its point, lane or row)")
            if selection.range_in is not None and selection.range_out is not None:
                start, stop = sorted((selection.range_in, selection.range_out))
                stop += 1
            else:
                start, stop = self.app.frame, review.n_frames
            return SwapLabels(review.label_names[selection.label], other, start, stop)
        return self.run_edit(make)

    def _label_menu(self, title: str, slot: Callable[[str], object], exclude: int = -1) -> None:
        """Ask for a label (grouped by hand; typing finds it: :class:`widgets.label_picker.LabelPicker`) and
        call ``slot`` with its name."""
        review = self.review
        if review is None or not review.n_labels:
            return
        groups: dict[str, list[str]] = {}
        for label, name in enumerate(review.label_names):
            if label == exclude:
                continue
            hand = review.hand_of_label(label)
            grouped = len(review.hands) > 1 or (hand < 0 and bool(review.hands))
            group = (review.hands[hand].name if hand >= 0 else "other") if grouped else ""
            groups.setdefault(group, []).append(name)
        chosen = LabelPicker.choose(self.host, title, list(groups.items()), QCursor.pos())
        if chosen is not None:
            slot(chosen)

    def choose_label_to_assign(self) -> None:
        self._label_menu("Assign label", self.assign_label)

    def choose_label_to_swap(self) -> None:
        if self.selection.label < 0:
            self.error_raised.emit("Cannot swap", "select the label to swap first (click its point, lane or row)")
            return
        self._label_menu("Swap with", self.swap_labels, exclude=self.selection.label)

    def undo(self) -> None:
        """Undo the take's last step at once: a review job running on the take (a re-solve, a fill, auto-label)
        and a solve of it are cancelled first, without waiting for them."""
        self._step(True)

    def redo(self) -> None:
        """Redo the next step at once (cancelling a review job or solve of the take, as :meth:`undo`); an edit
        whose re-solve was cancelled is re-solved again."""
        self._step(False)

    def _step(self, undo: bool) -> None:
        document = self.document
        if document is None or document.stack is None:
            return
        stack = document.stack
        if not (stack.can_undo() if undo else stack.can_redo()):
            return
        cancelled = self._cancel_jobs_of(document)
        step = stack.commands[stack.index - 1] if undo else stack.commands[stack.index]
        try:
            document.undo() if undo else document.redo()
        except HandMocapError as error:
            self.error_raised.emit("Cannot undo" if undo else "Cannot redo", str(error))
            return
        self._step_moved(step, undo)
        done = f"{'Undone' if undo else 'Redone'}: {step.text}"
        self.status_message.emit(f"{cancelled} cancelled; {done[0].lower()}{done[1:]}" if cancelled else done, 5000)
        self._start_resolve()

    def _cancel_jobs_of(self, document: TakeDocument) -> str:
        """Cancel, without waiting, the review job and the solve running on ``document``; what was cancelled
        ("" for nothing)."""
        cancelled = []
        if self.jobs.is_busy() and self._job_document is document:
            cancelled.append(self._job_kind)
            self.jobs.abandon()
            self._job_document = None
            self.progress_ended.emit()
        solve = self.app.jobs.get("solve")
        if solve is not None and solve.document is document:
            solve.cancel()
            cancelled.append("solve")
        return " and ".join(kind.capitalize() if number == 0 else kind for number, kind in enumerate(cancelled))
