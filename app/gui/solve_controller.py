"""The whole-take IK solve of a take on a worker, one at a time, automatic solves queued.

The running solve is a job of the application (:attr:`Application.jobs` under :data:`SOLVE_JOB`); its result
is kept through :meth:`Application.apply_solve`, whose events the views follow like every other change.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from PySide6.QtCore import QObject, Signal

from handmocap.app.gui.application import Application, CurrentDocumentChanged, DocumentClosing, Job
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.workers import TaskRunner
from handmocap.core.errors import HandMocapError, InputError
from handmocap.core.ik import IKResult
from handmocap.core.model import detect_hands, skin_vertices
from handmocap.core.workflows.resolve import hand_marker_set, solve_labelled_take

SOLVE_JOB = "solve"                        # the IK solver's worker in Application.jobs


@dataclass(frozen=True)
class SolveChoice:
    """What the window's toolbar chooses for a solve of the shown take: the layout, the hand ("right", "left" or
    "both") and the IK method."""

    layout: str
    side: str
    method: str


class SolveController(QObject):
    """Solves takes on its worker; ``choice()`` gives the toolbar's choice at the time of a solve."""

    status_message = Signal(str, int)             # text, milliseconds to show it (0: until replaced)
    error_raised = Signal(str, str)               # title, message
    progress_started = Signal(str)                # progress bar format of the solve
    progressed = Signal(float)                    # its fraction 0..1
    progress_ended = Signal()

    def __init__(self, app: Application, parent: QObject, choice: Callable[[], SolveChoice]) -> None:
        super().__init__(parent)
        self.app, self.choice = app, choice
        self._requests: dict[int, TakeDocument] = {}    # the take each started solve belongs to, until it ends
        self.runner = TaskRunner(self)
        self.runner.progressed.connect(self._progressed)
        self.runner.succeeded.connect(self._succeeded)
        self.runner.failed.connect(self._failed)
        self.runner.cancelled.connect(self._cancelled)
        self.runner.busy_changed.connect(self._busy_changed)
        app.add_listener(self._app_changed)

    def solving(self) -> TakeDocument | None:
        """The take being solved (None: none)."""
        job = self.app.jobs.get(SOLVE_JOB)
        return None if job is None else job.document

    def is_busy(self) -> bool:
        return self.runner.is_busy()

    def solve(self, document: TakeDocument | None = None) -> None:
        """Run IK of ``document`` (default: the shown take) on the worker with the chosen layout, hand and method
        (the toolbar's for the shown take, else the take's own): each hand :func:`core.model.detect_hands` finds
        with that layout (both hands of a two-hand take, or the chosen side), on the review's labels when it has
        any (after auto-label) else on the take's names, with the subject's hand and calibrated markers when
        auto-label made them; a solve running for another take is cancelled (it is retried later when it was an
        automatic one)."""
        document = document or self.app.document
        if document is None:
            return
        choice = self.choice()
        shown = document is self.app.document
        layout_name = choice.layout if shown else document.layout_name or choice.layout
        side = choice.side if shown else document.side
        review = document.review
        take = review.labelled_take() if review is not None and review.n_labels else document.take
        try:
            hands = detect_hands(take.marker_names, layout_name, side if side in ("right", "left") else None,
                                 required=True)
            if side in ("right", "left"):
                hands = ([hand for hand in hands if hand.side == side]
                         or [hand for hand in hands if not hand.side_from_names])[:1]
                if not hands:
                    raise InputError(f"the take has no {side} hand with layout '{layout_name}' (choose the hand "
                                     "'both' or the other side)")
        except HandMocapError as error:
            self.error_raised.emit("Cannot solve", str(error))
            return
        document.layout_name = layout_name
        document.side = side
        method = choice.method
        models = {hand.side: document.model_for(hand.side) for hand in hands}
        calibrated = {hand.side: document.marker_sets.get(hand.side) for hand in hands}
        names = list(take.marker_names)

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> list[IKResult]:
            results = []
            for number, hand in enumerate(hands):
                model = models[hand.side]
                markers = hand_marker_set(hand, names, model, calibrated[hand.side])

                def hand_progress(fraction: float, number: int = number) -> None:
                    progress((number + fraction) / len(hands))
                results.append(solve_labelled_take(take, model, markers, method=method, cancelled=cancelled,
                                                   progress=hand_progress))
                skin_vertices(model, results[-1].joint_angles[0])  # compiles the skinning kernel off the GUI thread
            return results

        self._requests[self.runner.start(task)] = document
        self.app.job_started(SOLVE_JOB, Job("solve", document, self.cancel))
        self.progress_started.emit("Solving… %p %")
        which = " and ".join(hand.side for hand in hands)
        self.status_message.emit(f"Solving {document.title} with {method} IK ({Path(layout_name).stem}, "
                                 f"{which} hand{'s' if len(hands) > 1 else ''})…", 0)

    def cancel(self) -> None:
        """Stop the running solve; its take stays as it was and is not solved automatically again."""
        document = self.solving()
        if document is not None:
            document.auto_solve = False
        self.runner.cancel()

    def solve_next_pending(self) -> None:
        """Start the next automatic solve (the shown take first), one at a time."""
        if self.runner.is_busy():
            return
        waiting = [document for document in self.app.documents
                   if document.auto_solve and document.result is None and document not in self._requests.values()]
        if self.app.document in waiting:
            self.solve(self.app.document)
        elif waiting:
            self.solve(waiting[0])

    def stop(self) -> None:
        """Cancel and wait for the worker (the window is closing)."""
        self.runner.stop()

    def _app_changed(self, event: object) -> None:
        """A closing take's solve stops; a shown take waiting for its automatic solve gets it."""
        if isinstance(event, DocumentClosing) and self.solving() is event.document:
            self.runner.stop()
        elif (isinstance(event, CurrentDocumentChanged) and event.document is not None
              and event.document.auto_solve and event.document.result is None):
            self.solve_next_pending()

    def _ended(self, request_id: int) -> TakeDocument | None:
        """The open take the ended solve ``request_id`` was for (None: it was closed meanwhile)."""
        document = self._requests.pop(request_id, None)
        return document if document in self.app.documents else None

    def _progressed(self, request_id: int, fraction: float) -> None:
        if request_id in self._requests:
            self.progressed.emit(fraction)

    def _succeeded(self, request_id: int, results: list[IKResult]) -> None:
        document = self._ended(request_id)
        if document is None:
            return
        self.app.apply_solve(document, results)
        residuals = ", ".join(f"{result.hand_side} {result.mean_residual_mm:.2f} mm" for result in results)
        self.status_message.emit(f"{document.title}: {results[0].method} IK done, mean residual {residuals}", 15000)
        self.solve_next_pending()

    def _failed(self, request_id: int, message: str) -> None:
        document = self._ended(request_id)
        if document is not None:
            document.auto_solve = False
            self.solve_next_pending()
            self.error_raised.emit("Solve failed", f"{document.title}: {message}")

    def _cancelled(self, request_id: int) -> None:
        document = self._ended(request_id)
        if document is not None:
            self.status_message.emit(f"{document.title}: solve cancelled; the take is unchanged", 8000)

    def _busy_changed(self, busy: bool) -> None:
        if not busy:
            self.app.job_ended(SOLVE_JOB)
            self.progress_ended.emit()
