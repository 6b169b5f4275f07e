"""The review's problems (swap suspects, low confidence, gaps, auto-label warnings): counted, visited."""

from __future__ import annotations

from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.review import PROBLEM_KINDS


class ReviewProblems(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: the problem count and next problem."""

    def _refresh_problem_count(self) -> None:
        review = self.review
        if review is None or not review.n_labels:
            self.problem_label.setText("")
            return
        problems = review.problems()
        counts = {kind: sum(p.kind == kind for p in problems) for kind in PROBLEM_KINDS}
        warnings = f" · {counts['labelling']} auto-label warnings" if counts["labelling"] else ""
        self.problem_label.setText(f" {counts['swap']} swap suspects · {counts['low_confidence']} low-confidence"
                                   f" · {counts['gap']} gaps{warnings} ")
        self.problem_label.setToolTip("\n".join(problem.text for problem in problems if problem.kind == "labelling"))

    def go_to_problem(self, forward: bool = True) -> None:
        """Jump to the next (or previous) low-confidence stretch, swap suspect, unfilled gap or stretch an
        auto-label warning is about."""
        review = self.review
        if review is None:
            return
        problem = review.next_problem(self.app.frame, forward=forward)
        if problem is None:
            self.status_message.emit("No problems left in this take", 5000)
            return
        self.app.set_frame(problem.frame)
        self.select_label(problem.label)
        self.status_message.emit(problem.text, 8000)
