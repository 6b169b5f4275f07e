"""Re-solving the hands of the frames an edit touched, and which edits still wait for their re-solve
(undoing a step that carried a re-solve makes its edits unsolved again)."""

from __future__ import annotations

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.review import Command, FrameSpan
from handmocap.core.workflows import resolve_jobs, run_resolve_jobs


class Resolves(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: re-solves after edits."""

    def _init_resolves(self) -> None:
        # edits whose re-solve is not attached yet ({id: (step, frames)}) and, per step that carries a re-solve,
        # the edits that re-solve covered (undoing the step makes them unsolved again, redoing it solved)
        self._unsolved: dict[int, tuple[Command, FrameSpan]] = {}
        self._carried: dict[int, list[tuple[Command, FrameSpan]]] = {}
        self._job_covers: list[tuple[Command, FrameSpan]] = []

    def _needs_resolve(self, document: TakeDocument, span: FrameSpan) -> None:
        """The step just pushed on ``document`` (an edit of frames ``span``) needs its hands re-solved: when the
        worker is free, the frames of every edit still waiting for its re-solve are re-solved in one job."""
        stack = document.stack
        if document is not self.document or stack is None or not stack.can_undo() or span.empty:
            return
        step = stack.commands[stack.index - 1]
        self._unsolved[id(step)] = (step, span)
        self._start_resolve()

    def _waiting_edits(self) -> list[tuple[Command, FrameSpan]]:
        """The done steps of the shown take whose re-solve is not attached yet."""
        stack = None if self.document is None else self.document.stack
        if stack is None:
            return []
        done = {id(command) for command in stack.commands[:stack.index]}
        return [entry for key, entry in self._unsolved.items() if key in done]

    def _start_resolve(self) -> None:
        """Re-solve the frames of the edits waiting for it, unless a review job is running."""
        review, document = self.review, self.document
        if review is None or document is None or self.jobs.is_busy():
            return
        covers = self._waiting_edits()
        span = FrameSpan(0, 0)
        for _edit, frames in covers:
            span = span.union(frames)
        if span.empty or not review.hands:
            return
        jobs = resolve_jobs(review, span, document.hand_models, marker_sets=document.marker_sets)
        if not jobs:
            for edit, _frames in covers:
                self._unsolved.pop(id(edit), None)
            return
        self._job_covers = covers
        self._start_job("re-solve", lambda progress, cancelled: run_resolve_jobs(
            jobs, progress=progress, cancelled=cancelled))

    def _apply_resolve(self, document: TakeDocument, result: list[Command]) -> None:
        """Attach the re-solve to the last step; the edits it covered are solved (see :meth:`_step_moved`)."""
        for command in result:
            document.attach(command)
        stack = document.stack
        if result and stack is not None and stack.can_undo():
            self._carried[id(stack.commands[stack.index - 1])] = list(self._job_covers)
        for edit, _frames in self._job_covers:
            self._unsolved.pop(id(edit), None)

    def _step_moved(self, step: Command, undone: bool) -> None:
        """``step`` was undone (or redone): the re-solve it carried went with it, so the other edits that re-solve
        covered wait for a re-solve again (or no longer)."""
        for edit, span in self._carried.get(id(step), []):
            if edit is not step:
                if undone:
                    self._unsolved[id(edit)] = (edit, span)
                else:
                    self._unsolved.pop(id(edit), None)
