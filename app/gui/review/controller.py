"""Take review: auto-label, the review views (label table, marker lanes, gap list and fill preview, the
review's drawing in the 3D view), undoable label edits with a re-solve of the touched frames, gap fills,
"next problem", and the exports of a review.

Every change of a review goes through a command on the document's undo stack (journalled when the take
belongs to a session); the views follow the stack's change events (passed on by the
:class:`~app.gui.application.Application`), whoever made the change. Long work runs on workers: ``jobs``
(auto-label, re-solves, fill all) and ``checks`` (fill checks and previews of the selected gap), so
checking a gap never cancels a re-solve. Workers only read copies; results are applied on the GUI
thread if the review has not changed since.

:class:`ReviewController` is composed of one part per responsibility, each in its own module of this
package; the parts share the controller's state and signals.
"""

from __future__ import annotations

from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import QWidget

from handmocap.app.gui.application import Application, Selection
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.actions import ReviewActions
from handmocap.app.gui.review.auto_label import AutoLabelling
from handmocap.app.gui.review.dialogs import AutoLabelSettings
from handmocap.app.gui.review.drawing import FrameDrawing
from handmocap.app.gui.review.edits import LabelEdits
from handmocap.app.gui.review.exports import ReviewExports
from handmocap.app.gui.review.fills import GapFills
from handmocap.app.gui.review.jobs import ReviewJobs
from handmocap.app.gui.review.problems import ReviewProblems
from handmocap.app.gui.review.resolve import Resolves
from handmocap.app.gui.review.selection import ReviewSelection
from handmocap.app.gui.review.take_events import TakeEvents
from handmocap.app.gui.review.views import ReviewViews
from handmocap.core.review import ReviewTake
from handmocap.widgets.deferred_viewport import DeferredViewport
from handmocap.widgets.timeline import TimelineWidget


class ReviewController(QObject, ReviewViews, FrameDrawing, ReviewActions, ReviewSelection, LabelEdits, TakeEvents,
                       ReviewProblems, GapFills, AutoLabelling, Resolves, ReviewJobs, ReviewExports):
    """The review of the shown take (see the module docstring). It builds its views and actions; the
    window places them (:attr:`table`, :attr:`lanes`, :attr:`gaps_panel`, the menus and :attr:`toolbar`)
    and shows what the signals below tell."""

    status_message = Signal(str, int)             # text, milliseconds to show it (0: until replaced)
    error_raised = Signal(str, str)               # title, message
    progress_started = Signal(str)                # progress bar format of a review job
    progressed = Signal(float)                    # its fraction 0..1
    progress_ended = Signal()
    auto_label_applied = Signal(object, object, object)  # document, hand models and marker sets it calibrated
    exported = Signal(object, str, str)           # document, kind (an export format name: "c3d", "angles-csv"...), path

    def __init__(self, app: Application, host: QWidget, viewport: DeferredViewport, timeline: TimelineWidget) -> None:
        super().__init__(host)
        self.app, self.host, self.viewport, self.timeline = app, host, viewport, timeline
        self.auto_settings = AutoLabelSettings()
        self._init_resolves()
        self._init_jobs()
        self._init_fills()
        self._build_views()
        self._build_actions()
        viewport.marker_clicked.connect(self.point_clicked)
        app.add_listener(self._app_changed)

    @property
    def document(self) -> TakeDocument | None:
        """The shown take."""
        return self.app.document

    @property
    def review(self) -> ReviewTake | None:
        return None if self.document is None else self.document.review

    @property
    def selection(self) -> Selection:
        return self.app.selection
