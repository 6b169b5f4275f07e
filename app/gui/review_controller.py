"""Take review: auto-label, the review views (label table, marker lanes, gap list and fill preview, the
review's drawing in the 3D view), undoable label edits with a re-solve of the touched frames, gap fills,
"next problem", and the exports of a review.

Every change of a review goes through a command on the document's undo stack (journalled when the take
belongs to a session); the views follow the stack's change events (passed on by the
:class:`~app.gui.application.Application`), whoever made the change. Long work runs on workers: ``jobs``
(auto-label, re-solves, fill all) and ``checks`` (fill checks and previews of the selected gap), so
checking a gap never cancels a re-solve. Workers only read copies; results are applied on the GUI
thread if the review has not changed since.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtGui import QCursor
from PySide6.QtWidgets import (
    QApplication,
    QCheckBox,
    QComboBox,
    QDialog,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QLineEdit,
    QMenu,
    QPushButton,
    QScrollArea,
    QSplitter,
    QToolBar,
    QWidget,
)

from handmocap.app.gui.actions import make_action
from handmocap.app.gui.application import (
    Application,
    CurrentDocumentChanged,
    DocumentClosing,
    Job,
    JobsChanged,
    Selection,
    SelectionChanged,
)
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.export_dialog import default_export_path
from handmocap.app.gui.workers import TaskRunner
from handmocap.core.errors import HandMocapError
from handmocap.core.gaps import FILL_METHODS, FillCheck
from handmocap.core.io.c3d_events import CONTEXTS
from handmocap.core.model import layout_names, marker_positions, skin_vertices
from handmocap.core.model.objects import load_scene_spec, rigid_body_from_points, save_scene_spec
from handmocap.core.review import (
    PROBLEM_KINDS,
    AcceptFills,
    AddEvent,
    AssignLabel,
    Command,
    FrameSpan,
    GapFill,
    MarkGhost,
    RejectFills,
    RemoveEvent,
    ReviewTake,
    SwapLabels,
    TrimTake,
    Unlabel,
    export_bvh,
    export_joint_angles_csv,
    export_labelled_c3d,
)
from handmocap.core.review.events import Change, ReviewChanged
from handmocap.core.workflows import (
    GapGroup,
    ReviewGap,
    auto_label,
    check_review_gap,
    fill_gaps,
    find_review_gaps,
    gap_groups,
    preview_fill,
    resolve_jobs,
    run_resolve_jobs,
    short_open_gaps,
)
from handmocap.widgets.dialog_buttons import ok_cancel_buttons
from handmocap.widgets.fill_preview import FillPreview
from handmocap.widgets.gap_list import GapList, GapRow
from handmocap.widgets.label_picker import LabelPicker
from handmocap.widgets.marker_lanes import MarkerLanes, lanes_from_review
from handmocap.widgets.review_table import ReviewTable
from handmocap.widgets.timeline import TimelineWidget
from handmocap.widgets.viewport import HandViewport

_log = logging.getLogger(__name__)
UNLABELLED_COLOUR = (0.62, 0.62, 0.64)
GHOST_COLOUR = (0.55, 0.22, 0.22)
FILL_COLOUR = (0.45, 0.95, 0.55)
RIGID_SELECTION_COLOUR = (1.0, 1.0, 1.0)
JOB_NAME = "review"                # the worker of auto-label, re-solves and fills in Application.jobs
TRAIL_FRAMES = 60                  # frames of trail on each side of the current frame
SCOPE_TITLES = {"fragment": "to end of fragment", "range": "in the marked range", "take": "whole take"}
PALETTE = np.array([                # Tableau-like qualitative colours, distinct on a dark background
    (0.36, 0.62, 0.92), (0.98, 0.60, 0.25), (0.40, 0.80, 0.45), (0.93, 0.38, 0.40), (0.70, 0.55, 0.90),
    (0.72, 0.52, 0.42), (0.96, 0.56, 0.80), (0.85, 0.85, 0.40), (0.35, 0.85, 0.85), (0.60, 0.75, 1.00),
    (1.00, 0.78, 0.55), (0.65, 0.92, 0.60), (1.00, 0.65, 0.65), (0.82, 0.72, 0.96), (0.88, 0.72, 0.62),
])


def label_colours(count: int) -> np.ndarray:
    """A distinct colour per label ``(count, 3)`` in [0, 1]."""
    return PALETTE[np.arange(count) % len(PALETTE)]


def point_colours(review: ReviewTake, frame: int) -> np.ndarray:
    """``(P, 3)`` colours of the raw points at ``frame`` as the 3D view and the camera dock draw them: the
    colour of the label a point holds, grey when unlabelled, dark red for ghosts."""
    labels = review.assignment[frame]
    colours = np.tile(UNLABELLED_COLOUR, (review.n_points, 1))
    colours[review.ghost[frame]] = GHOST_COLOUR
    taken = labels >= 0
    colours[labels[taken]] = label_colours(review.n_labels)[np.flatnonzero(taken)]
    return colours


@dataclass
class AutoLabelSettings:
    """What the operator chose in the auto-label dialog."""

    layout: str = "dense"
    hands: str = "auto"
    objects: str = ""
    online: bool = False
    relabel: bool = False


#: event names offered first (an operator types any other; the names used in the session come after)
EVENT_NAMES = ("grasp on", "grasp off", "contact", "release", "start", "end")


class EventDialog(QDialog):
    """Name an event at a frame: a name (typed, or one used before) and its context (General, Left, Right,
    as the C3D EVENT group has it)."""

    def __init__(self, parent: QWidget, frame_number: int, names: list[str]) -> None:
        super().__init__(parent)
        self.setWindowTitle("Add event")
        form = QFormLayout(self)
        self.name_box = QComboBox(self)
        self.name_box.setEditable(True)
        self.name_box.addItems(list(dict.fromkeys([*names, *EVENT_NAMES])))
        self.name_box.setCurrentText(names[0] if names else EVENT_NAMES[0])
        self.name_box.lineEdit().selectAll()
        self.context_box = QComboBox(self)
        self.context_box.addItems(list(CONTEXTS))
        self.context_box.setToolTip("Which side the event is about (the C3D EVENT group's context)")
        form.addRow(QLabel(f"At frame {frame_number}"))
        form.addRow("Name", self.name_box)
        form.addRow("Side", self.context_box)
        form.addRow(ok_cancel_buttons(self, "Add event"))

    def chosen(self) -> tuple[str, str]:
        """The name and the context given."""
        return self.name_box.currentText().strip(), self.context_box.currentText()


class AutoLabelDialog(QDialog):
    """Layout, hands ("auto": the labeller decides), rigid objects (a scene spec JSON), online/offline mode
    and whether to relabel from scratch (ignore the labels the file already has)."""

    def __init__(self, parent: QWidget, settings: AutoLabelSettings) -> None:
        super().__init__(parent)
        self.setWindowTitle("Auto-label")
        form = QFormLayout(self)
        self.layout_box = QComboBox(self)
        self.layout_box.addItems(layout_names())
        self.layout_box.setCurrentText(settings.layout)
        self.hands_box = QComboBox(self)
        self.hands_box.addItems(["auto", "right", "left", "both"])
        self.hands_box.setToolTip("auto: the labeller decides which hands the take shows (and warns when it "
                                  "cannot tell)")
        self.hands_box.setCurrentText(settings.hands)
        self.objects_edit = QLineEdit(settings.objects, self)
        self.objects_edit.setPlaceholderText("none")
        browse = QPushButton("Browse…", self)
        browse.clicked.connect(self._browse)
        objects = QHBoxLayout()
        objects.addWidget(self.objects_edit, 1)
        objects.addWidget(browse)
        self.online_box = QCheckBox("Online (causal: no backward pass, as in live tracking)", self)
        self.online_box.setChecked(settings.online)
        self.relabel_box = QCheckBox("Relabel from scratch (ignore the labels the file already has)", self)
        self.relabel_box.setToolTip("Off: labels outside the layout (arm, body, objects) are kept, and where the "
                                    "file labels a point with a layout marker's name that label is kept.")
        self.relabel_box.setChecked(settings.relabel)
        form.addRow("Marker layout", self.layout_box)
        form.addRow("Hands", self.hands_box)
        form.addRow("Rigid objects", objects)
        form.addRow("", self.online_box)
        form.addRow("", self.relabel_box)
        form.addRow(ok_cancel_buttons(self, "Auto-label"))

    def _browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Scene objects", "", "Scene spec (*.json);;All files (*)")
        if path:
            self.objects_edit.setText(path)

    def settings(self) -> AutoLabelSettings:
        return AutoLabelSettings(self.layout_box.currentText(), self.hands_box.currentText(),
                                 self.objects_edit.text().strip(), self.online_box.isChecked(),
                                 self.relabel_box.isChecked())


class ReviewController(QObject):
    """The review of the shown take (see the module docstring). It builds its views and actions; the
    window places them (:attr:`table`, :attr:`lanes`, :attr:`gaps_panel`, the menus and :attr:`toolbar`)
    and shows what the signals below tell."""

    status_message = Signal(str, int)             # text, milliseconds to show it (0: until replaced)
    error_raised = Signal(str, str)               # title, message
    progress_started = Signal(str)                # progress bar format of a review job
    progressed = Signal(float)                    # its fraction 0..1
    progress_ended = Signal()
    auto_label_applied = Signal(object, object, object)  # document, hand models and marker sets it calibrated
    exported = Signal(object, str, str)           # document, kind ("c3d", "csv" or "bvh"), path

    def __init__(self, app: Application, host: QWidget, viewport: HandViewport, timeline: TimelineWidget) -> None:
        super().__init__(host)
        self.app, self.host, self.viewport, self.timeline = app, host, viewport, timeline
        self.auto_settings = AutoLabelSettings()
        self._groups: list[GapGroup] = []
        self._gaps: list[ReviewGap] = []
        self._rows: list[GapRow] = []
        self._rejected: set[tuple[int, int]] = set()
        self._previews: dict[tuple[int, int, str, int], np.ndarray] = {}
        # edits whose re-solve is not attached yet ({id: (step, frames)}) and, per step that carries a re-solve,
        # the edits that re-solve covered (undoing the step makes them unsolved again, redoing it solved)
        self._unsolved: dict[int, tuple[Command, FrameSpan]] = {}
        self._carried: dict[int, list[tuple[Command, FrameSpan]]] = {}
        self._job_covers: list[tuple[Command, FrameSpan]] = []
        self._job_document: TakeDocument | None = None
        self._job_kind = ""
        self._job_version = -1
        self._check_key: tuple | None = None

        self.jobs = TaskRunner(self)
        self.jobs.progressed.connect(lambda _request, fraction: self.progressed.emit(fraction))
        self.jobs.succeeded.connect(self._job_succeeded)
        self.jobs.failed.connect(self._job_failed)
        self.jobs.cancelled.connect(self._job_cancelled)
        self.jobs.busy_changed.connect(self._jobs_busy_changed)
        self.checks = TaskRunner(self)
        self.checks.succeeded.connect(self._check_done)
        self.checks.failed.connect(self._check_failed)

        self._views_timer = QTimer(self)     # the whole-take views after a change, once the change is drawn
        self._views_timer.setSingleShot(True)
        self._views_timer.setInterval(0)
        self._views_timer.timeout.connect(self._refresh_views)
        self._build_views()
        self._build_actions()
        viewport.marker_clicked.connect(self.point_clicked)
        app.add_listener(self._app_changed)

    # ---------------------------------------------------------------------------------- building
    def _build_views(self) -> None:
        host = self.host
        self.table = ReviewTable(host)
        self.table.marker_selected.connect(self.select_label)
        self.lanes = MarkerLanes(host)
        self.lanes.frame_clicked.connect(self.app.set_frame)
        self.lanes.marker_clicked.connect(self.select_label)
        self.lanes.stretch_clicked.connect(self._stretch_clicked)
        self.lanes.link_x(self.timeline.plot.getPlotItem().vb)
        self.gap_list = GapList(host)
        self.preview = FillPreview(host)
        gaps = QScrollArea(host)             # the gap table, check and fill-all need more height than a small
        gaps.setWidgetResizable(True)        # screen has: they scroll, the preview beside them stays in view
        gaps.setFrameShape(QScrollArea.Shape.NoFrame)
        gaps.setWidget(self.gap_list)
        self.gaps_panel = QSplitter(Qt.Orientation.Horizontal, host)
        self.gaps_panel.addWidget(gaps)
        self.gaps_panel.addWidget(self.preview)
        self.gaps_panel.setStretchFactor(0, 3)    # the list's columns and buttons first; the preview the rest
        self.gaps_panel.setStretchFactor(1, 1)
        self.gaps_panel.setSizes([450, 200])
        self.gaps_panel.setChildrenCollapsible(False)
        self.gap_list.gap_selected.connect(self._gap_selected)
        self.gap_list.method_changed.connect(lambda _gap, method: self.preview.set_selected(method))
        self.gap_list.preview_requested.connect(self._preview_requested)
        self.gap_list.accept_requested.connect(self.accept_fill)
        self.gap_list.reject_requested.connect(self.reject_gap)
        self.gap_list.fill_all_requested.connect(self.fill_all)

    def _build_actions(self) -> None:
        host = self.host

        def action(text: str, slot: Callable, shortcut: str | None = None, tooltip: str | None = None):
            return make_action(host, text, slot, shortcut, tooltip=tooltip)

        self.auto_label_action = action("&Auto-label…", self.choose_auto_label, "auto_label")
        self.undo_action = action("&Undo", self.undo, "undo")
        self.redo_action = action("&Redo", self.redo, "redo")
        self.undo_action.setIconText("Undo")     # the toolbar stays short; the menu and tooltip say what
        self.redo_action.setIconText("Redo")
        self.assign_action = action("&Assign label…", self.choose_label_to_assign, "assign")
        self.swap_action = action("S&wap labels…", self.choose_label_to_swap, "swap")
        self.ghost_action = action("Mark as &ghost", self.mark_ghost, "ghost")
        self.unlabel_action = action("&Unlabel", self.unlabel, "unlabel")
        self.range_in_action = action("Set range &start here", self.set_range_in, "range_in")
        self.range_out_action = action("Set range &end here", self.set_range_out, "range_out")
        self.clear_range_action = action("&Clear range", self.clear_range, "clear_range")
        self.next_problem_action = action("&Next problem", lambda: self.go_to_problem(True), "next_problem")
        self.previous_problem_action = action("&Previous problem", lambda: self.go_to_problem(False),
                                              "previous_problem")
        self.rigid_body_action = action("Define &rigid body from selected points…", self.choose_rigid_body_name,
                                        "rigid_body", "Ctrl+click three or more points of an object in the 3D "
                                        "view, then name it: auto-label then tracks it as a rigid body")
        self.fill_all_action = action("&Fill short gaps…", lambda: self.fill_all(self.gap_list.max_length_box.value()),
                                      "fill_short_gaps")
        self.add_event_action = action("Add &event here…", self.choose_event_to_add, "add_event")
        self.remove_event_action = action("Remo&ve event here", self.remove_event_here,
                                          tooltip="Remove the event at the current frame")
        self.next_event_action = action("Next e&vent", lambda: self.go_to_event(True), "next_event")
        self.previous_event_action = action("Previous ev&ent", lambda: self.go_to_event(False), "previous_event")
        self.trim_action = action("&Trim to the marked range", self.trim_to_range, "trim",
                                  "Trim the take to the range marked with I and O: the frames outside are no longer "
                                  "shown, played or exported (undo brings them back)")
        self.untrim_action = action("&Keep the whole take", self.keep_whole_take,
                                    tooltip="Undo the trim: show, play and export every frame again")
        self.cancel_job_action = action("Cancel review &job", self.jobs.cancel)
        self.export_c3d_action = action("Labelled &C3D…", self.choose_export_c3d)
        self.export_csv_action = action("Joint angles (CS&V)…", self.choose_export_csv)
        self.export_bvh_action = action("Joint angles (&BVH)…", self.choose_export_bvh)

        self.edit_menu = QMenu("&Edit", host)
        for item in (self.undo_action, self.redo_action, None, self.assign_action, self.swap_action,
                     self.unlabel_action, self.ghost_action, None, self.range_in_action, self.range_out_action,
                     self.clear_range_action, None, self.trim_action, self.untrim_action):
            self.edit_menu.addSeparator() if item is None else self.edit_menu.addAction(item)
        self.events_menu = QMenu("&Go to event", host)
        self.review_menu = QMenu("&Review", host)
        for item in (self.auto_label_action, self.cancel_job_action, self.rigid_body_action, None,
                     self.next_problem_action,
                     self.previous_problem_action, None, self.fill_all_action, None, self.add_event_action,
                     self.remove_event_action, self.next_event_action, self.previous_event_action):
            self.review_menu.addSeparator() if item is None else self.review_menu.addAction(item)
        self.review_menu.addMenu(self.events_menu)
        self.export_menu = QMenu("E&xport", host)
        for item in (self.export_c3d_action, self.export_csv_action, self.export_bvh_action):
            self.export_menu.addAction(item)

        toolbar = self.toolbar = QToolBar("Review", host)
        toolbar.setObjectName("review-toolbar")
        toolbar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        toolbar.addAction(self.auto_label_action)
        toolbar.addSeparator()
        toolbar.addAction(self.undo_action)
        toolbar.addAction(self.redo_action)
        toolbar.addSeparator()
        toolbar.addAction(self.assign_action)
        toolbar.addAction(self.swap_action)
        toolbar.addAction(self.unlabel_action)
        toolbar.addAction(self.ghost_action)
        toolbar.addWidget(QLabel(" Scope "))
        self.scope_box = QComboBox(host)
        for scope, title in SCOPE_TITLES.items():
            self.scope_box.addItem(title, scope)
        self.scope_box.setToolTip("Which frames an edit changes: from the current frame to the end of the "
                                  "point's fragment, the range marked with I and O, or the whole take")
        toolbar.addWidget(self.scope_box)
        self.range_label = QLabel("", host)
        toolbar.addWidget(self.range_label)
        toolbar.addSeparator()
        toolbar.addAction(self.previous_problem_action)
        toolbar.addAction(self.next_problem_action)
        self.problem_label = QLabel("", host)
        toolbar.addWidget(self.problem_label)

    # ------------------------------------------------------------------------------- documents
    @property
    def document(self) -> TakeDocument | None:
        """The shown take."""
        return self.app.document

    @property
    def review(self):
        return None if self.document is None else self.document.review

    @property
    def selection(self) -> Selection:
        return self.app.selection

    def _app_changed(self, event: object) -> None:
        """Follow the application: another take shown, a take closing, a change of the shown take's review,
        another selection."""
        if isinstance(event, CurrentDocumentChanged):
            self._show_document(event.document)
        elif isinstance(event, DocumentClosing) and event.document is self.document:
            self.stop()
        elif isinstance(event, ReviewChanged) and event.operation != "clean":
            if event.operation != "attach":       # a re-solve attached to an edit leaves the gaps as they are
                self._previews = {}
            if event.what & Change.TIMELINE:
                self._show_timeline_marks()
            if event.what & ~Change.TIMELINE:
                self._refresh(structure=event.structure)
            else:
                self.update_enabled()
        elif isinstance(event, SelectionChanged):
            self._show_selection()
        elif isinstance(event, JobsChanged):
            self.update_enabled()

    def _show_document(self, document: TakeDocument | None) -> None:
        """Show the review of ``document`` (None: no take is shown any more, the views are cleared)."""
        self._rejected = set()
        self._previews = {}
        self._unsolved, self._carried = {}, {}
        if document is not None:
            self._refresh(structure=True)
            self._show_timeline_marks()
            if document.review.health:
                self.status_message.emit(document.review.health_summary(), 0)
            return
        self.stop()
        self.lanes.set_lanes([], np.zeros((0, 0), dtype=np.int8))
        self.gap_list.set_gaps([], [], 1)
        self.preview.clear()
        self.viewport.set_trails([])
        self.viewport.set_loose_points(None)
        self.viewport.set_rigid_bodies(None)
        self.update_enabled()

    def _refresh(self, structure: bool = False) -> None:
        """Redraw the review views; ``structure``: labels or hands may have changed (then at once). Otherwise
        the views of the whole take (lanes, label table, gap list, problem count) follow once the window has
        drawn the change (an undo on a 20 000-frame take shows in the 3D view at once; the whole-take views
        take a few hundred ms more): changes in between are drawn once. :meth:`flush_views` brings them up
        to date now."""
        review = self.review
        if review is None:
            return
        if structure or self.lanes.n_markers != review.n_labels or self.lanes.n_frames != review.n_frames:
            self._views_timer.stop()
            self._refresh_views(structure=True)
            return
        if self.document.has_solved_hands() and self.viewport.hand_count() != len(review.hands):
            self._set_hand_meshes()     # the first solve of a hand: the view showed another surface
        self.update_enabled()
        self._views_timer.start()

    def flush_views(self) -> None:
        """Bring the whole-take views up to date now if a change is waiting to be shown in them."""
        if self._views_timer.isActive():
            self._views_timer.stop()
            self._refresh_views()

    def _refresh_views(self, structure: bool = False) -> None:
        """The whole-take views of the review: lanes, label table, gap list and problem count."""
        review = self.review
        if review is None:
            return
        take = review.take
        colours = label_colours(review.n_labels)
        stats = review.marker_stats()
        states = lanes_from_review(review.lane_states(), review.provenance)
        if structure:
            self.lanes.set_lanes(review.label_names, states, take.first_frame, take.frame_rate)
            self.table.set_markers(stats, colours)
            self._set_hand_meshes()
        else:
            x_range = self.lanes.x_range()
            self.lanes.set_states(states)
            self.lanes.set_x_range(*x_range)
            self.table.update_stats(stats)
        self.lanes.set_frame(self.app.frame)
        if self.selection.label >= 0:
            self.lanes.set_selected_marker(self.selection.label)
        self._refresh_gaps()
        self._refresh_problem_count()
        self.update_enabled()

    def _set_hand_meshes(self) -> None:
        document = self.document
        meshes = []
        for hand in document.review.hands:
            model = document.model_for(hand.side)
            meshes.append((model.vertices, model.faces))
        if meshes:
            self.viewport.set_hand_meshes(meshes)

    def update_enabled(self) -> None:
        document, review, busy = self.document, self.review, self.jobs.is_busy()
        stack = None if document is None else document.stack
        selection = self.selection
        self.auto_label_action.setEnabled(review is not None and not busy)
        self.rigid_body_action.setEnabled(review is not None and len(selection.rigid_points) >= 3)
        self.cancel_job_action.setEnabled(busy)
        # never disabled by a job: undo cancels the review job running on the take and undoes at once
        self.undo_action.setEnabled(stack is not None and stack.can_undo())
        self.redo_action.setEnabled(stack is not None and stack.can_redo())
        self.undo_action.setText(f"&Undo {stack.undo_text()}" if stack is not None and stack.can_undo() else "&Undo")
        self.redo_action.setText(f"&Redo {stack.redo_text()}" if stack is not None and stack.can_redo() else "&Redo")
        editable = (document is not None and document.has_labels()
                    and not (busy and self._job_kind == "auto-label"))
        for action in (self.assign_action, self.swap_action, self.ghost_action, self.unlabel_action,
                       self.next_problem_action, self.previous_problem_action, self.fill_all_action,
                       self.export_c3d_action):
            action.setEnabled(editable)
        for action in (self.export_csv_action, self.export_bvh_action):
            action.setEnabled(document is not None and document.has_solved_hands())
        for action in (self.add_event_action, self.remove_event_action, self.next_event_action,
                       self.previous_event_action):
            action.setEnabled(review is not None)
        self.trim_action.setEnabled(review is not None and selection.range_in is not None
                                    and selection.range_out is not None)
        self.untrim_action.setEnabled(review is not None and review.trim is not None)
        text = ""
        if selection.range_in is not None or selection.range_out is not None:
            first = review.take.first_frame if review is not None else 0
            start = "…" if selection.range_in is None else str(selection.range_in + first)
            stop = "…" if selection.range_out is None else str(selection.range_out + first)
            text = f" range {start}–{stop} "
        self.range_label.setText(text)

    # ---------------------------------------------------------------------------------- frames
    def draw_frame(self, frame: int) -> None:
        """Draw ``frame`` of the review when the take has labels or is raw: every raw point coloured by the
        label it holds (grey when unlabelled, dark red for ghosts), accepted fills as green dots, the solved
        hands with their effectors and residual lines, and the trail of the selected label."""
        document, review = self.document, self.review
        if document is None or not (document.has_labels() or document.is_raw):
            return
        viewport = self.viewport
        labels = review.assignment[frame]
        point_label = np.full(review.n_points, -1, dtype=np.int64)
        taken = labels >= 0
        point_label[labels[taken]] = np.flatnonzero(taken)
        colours = point_colours(review, frame)
        colours[self.selection.rigid_points] = RIGID_SELECTION_COLOUR
        palette = label_colours(review.n_labels)
        names = [review.label_names[label] if label >= 0 else f"*{column}"
                 for column, label in enumerate(point_label)]
        viewport.set_marker_names(names)
        viewport.set_marker_colours(colours)
        viewport.set_rigid_bodies(review.rigid_body_segments(frame))
        fills = review.provenance[frame] > 0
        fill_colours = palette[fills] * 0.5 + np.array(FILL_COLOUR) * 0.5
        viewport.set_loose_points(review.filled_positions[frame, fills], fill_colours)
        effectors, targets = [], []
        labelled = review.labelled_positions_in(frame, frame + 1)[0]
        for number, hand in enumerate(review.hands):
            theta = hand.joint_angles[frame]
            if not np.isfinite(theta).all():
                continue
            model = document.model_for(hand.side)
            viewport.update_hand_vertices(skin_vertices(model, theta), number)
            markers = document.marker_set_for(hand.side, hand.layout, [review.label_names[label]
                                                                        for label in hand.labels])
            if markers is not None and len(markers.names) == len(hand.labels):
                effectors.append(marker_positions(model, markers, theta))
                targets.append(labelled[hand.labels])
        if effectors:
            viewport.set_effectors(np.concatenate(effectors), np.concatenate(targets))
        else:
            viewport.set_effectors(None)
        self._draw_trail(frame)
        self.lanes.set_frame(frame)

    def _draw_trail(self, frame: int) -> None:
        review, label = self.review, self.selection.label
        if label < 0 or label >= review.n_labels:
            self.viewport.set_trails([])
            return
        first, last = max(0, frame - TRAIL_FRAMES), min(review.n_frames, frame + TRAIL_FRAMES + 1)
        trail = review.labelled_positions_in(first, last)[:, label]
        self.viewport.set_trails([trail], label_colours(review.n_labels)[[label]])

    # ------------------------------------------------------------------------------- selection
    def _show_selection(self) -> None:
        """Show the selection everywhere: table row, lane, the selected point, its trail, the points picked
        for a rigid body, the marked range."""
        if self.review is None:
            return
        label, column = self.selection.label, self.selection.column
        self.table.select_marker(label)
        self.lanes.set_selected_marker(label)
        self.viewport.set_selected_marker(column if column >= 0 else None)
        self.update_enabled()
        self.draw_frame(self.app.frame)
        self.viewport.request_render()

    def select_label(self, label: int) -> None:
        """Select ``label`` and the point holding it now."""
        review = self.review
        if review is None:
            return
        label = label if 0 <= label < review.n_labels else -1
        self.app.select(label, int(review.assignment[self.app.frame, label]) if label >= 0 else -1)

    def point_clicked(self, column: int) -> None:
        """The operator clicked raw point ``column`` in the 3D view (-1: empty space); with Ctrl, the point
        is picked for a rigid body."""
        review = self.review
        if review is None:
            return
        if QApplication.keyboardModifiers() & Qt.KeyboardModifier.ControlModifier and column >= 0:
            self.toggle_rigid_point(column)
            return
        self.app.select(review.label_of_point(self.app.frame, column) if column >= 0 else -1, column)

    def toggle_rigid_point(self, column: int) -> None:
        """Add raw point ``column`` to the points of a new rigid body (or take it out again)."""
        self.app.toggle_rigid_point(column)
        self.status_message.emit(f"{len(self.selection.rigid_points)} points selected for a rigid body "
                                 "(Review ▸ Define rigid body…)", 5000)

    def choose_rigid_body_name(self) -> None:
        name, accepted = QInputDialog.getText(self.host, "Rigid body", "Name of the object:", text="object")
        if accepted and name.strip():
            self.define_rigid_body(name.strip())

    def define_rigid_body(self, name: str) -> Path | None:
        """Make a rigid body named ``name`` from the selected points in the current frame and add it to the
        scene spec auto-label uses (in the session folder, or next to the take file). Returns the spec."""
        review, points = self.review, self.selection.rigid_points
        frame = self.app.frame
        try:
            if len(points) < 3:
                raise HandMocapError("Ctrl+click at least 3 points of the object in the 3D view first")
            markers = [f"{name}{number + 1}" for number in range(len(points))]
            spec = rigid_body_from_points(name, markers, review.take.marker_positions[frame, points])
            path = Path(self.auto_settings.objects) if self.auto_settings.objects else self._default_spec_path()
            objects = [item for item in (load_scene_spec(path) if path.exists() else []) if item.name != name]
            path.parent.mkdir(parents=True, exist_ok=True)
            save_scene_spec([*objects, spec], path)
        except (HandMocapError, OSError) as error:
            self.error_raised.emit("Cannot define the rigid body", str(error))
            return None
        self.auto_settings.objects = str(path)
        self.app.clear_rigid_points()
        self.status_message.emit(f"Rigid body '{name}' ({len(markers)} markers) added to the scene "
                                 f"{path.name}; the next auto-label tracks it", 8000)
        return path

    def _default_spec_path(self) -> Path:
        document = self.document
        if document.open_take is not None:
            return document.open_take.folder / "scene_objects.json"
        source = document.take.source_path
        folder = Path(source).parent if source else Path.home() / ".cache" / "handmocap"
        return folder / f"{Path(document.title).stem}_objects.json"

    def _stretch_clicked(self, marker: int, first: int, last: int) -> None:
        self.select_label(marker)
        if not first <= self.app.frame <= last:
            self.app.set_frame(first)

    # -------------------------------------------------------------------------------- editing
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
        if column < 0 and label >= 0:
            column = int(self.review.assignment[frame, label])
        if column < 0 or not np.isfinite(self.review.take.marker_positions[frame, column]).all():
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
        if span is not None:
            self.select_label(self.review.label_index(new_label))
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
            selection = self.selection
            if selection.label < 0:
                raise HandMocapError("select the label to swap first (click its point, lane or row)")
            if selection.range_in is not None and selection.range_out is not None:
                start, stop = sorted((selection.range_in, selection.range_out))
                stop += 1
            else:
                start, stop = self.app.frame, self.review.n_frames
            return SwapLabels(self.review.label_names[selection.label], other, start, stop)
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
        for edit, span in self._carried.get(id(step), []):   # the re-solve that step carried went with it
            if edit is not step:
                if undo:
                    self._unsolved[id(edit)] = (edit, span)
                else:
                    self._unsolved.pop(id(edit), None)
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

    def set_range_in(self) -> None:
        self.app.mark_range(self.app.frame, self.selection.range_out)

    def set_range_out(self) -> None:
        self.app.mark_range(self.selection.range_in, self.app.frame)

    def clear_range(self) -> None:
        self.app.mark_range(None, None)

    # ------------------------------------------------------------------------------ events, trim
    def _show_timeline_marks(self) -> None:
        """The events on the timeline (and in Review ▸ Go to event), the trim range shaded; the current frame
        kept inside the range."""
        review = self.review
        if review is None:
            self.timeline.set_events([])
            self.events_menu.clear()
            return
        marks = review.event_frames()
        self.timeline.set_events([(frame, event.name) for frame, event in marks])
        self.timeline.set_trim(*(review.trim or (None, None)))
        self.events_menu.clear()
        for frame, event in marks:
            item = self.events_menu.addAction(f"{event.name} — frame {event.frame_number}"
                                              + (f" ({event.context})" if event.context != "General" else ""))
            item.triggered.connect(lambda _checked=False, target=frame: self.app.set_frame(target))
        self.events_menu.setEnabled(bool(marks))
        self.app.set_frame(self.app.frame)          # clamped into the trim range

    def choose_event_to_add(self) -> None:
        """Ask for an event's name and side, and add it at the current frame."""
        review = self.review
        if review is None:
            return
        names = list(dict.fromkeys(event.name for event in reversed(review.events or [])))
        dialog = EventDialog(self.host, review.frame_number(self.app.frame), names)
        if dialog.exec() == QDialog.DialogCode.Accepted:
            self.add_event(*dialog.chosen())

    def add_event(self, name: str, context: str = "General") -> FrameSpan | None:
        """Name the current frame ``name`` (an undoable step)."""
        review = self.review
        if review is None:
            return None
        return self.run_edit(lambda: AddEvent(name, review.frame_number(self.app.frame), context))

    def remove_event_here(self) -> FrameSpan | None:
        """Remove the event at the current frame (the last one named, when there are several)."""
        review = self.review
        if review is None:
            return None
        number = review.frame_number(self.app.frame)
        here = [event for event in review.events or [] if event.frame_number == number]
        if not here:
            self.status_message.emit(f"No event at frame {number}", 5000)
            return None
        return self.run_edit(lambda: RemoveEvent(here[-1].name, number))

    def go_to_event(self, forward: bool = True) -> None:
        """Go to the next (or previous) event, wrapping around the take."""
        review = self.review
        found = None if review is None else review.next_event(self.app.frame, forward)
        if found is None:
            self.status_message.emit("This take has no event (Review ▸ Add event here…)", 5000)
            return
        self.app.set_frame(found[0])
        event = found[1]
        self.status_message.emit(f"Event '{event.name}' at frame {event.frame_number}", 5000)

    def trim_to_range(self) -> FrameSpan | None:
        """Trim the take to the range marked with I and O (an undoable step)."""
        def make() -> Command:
            selection = self.selection
            if selection.range_in is None or selection.range_out is None:
                raise HandMocapError("mark the range to keep first: I at its first frame, O at its last")
            start, stop = sorted((selection.range_in, selection.range_out))
            return TrimTake(start, stop + 1)
        return self.run_edit(make)

    def keep_whole_take(self) -> FrameSpan | None:
        """Undo the trim: every frame is shown, played and exported again (an undoable step)."""
        return self.run_edit(lambda: TrimTake(None, None))

    # ------------------------------------------------------------------------------- problems
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

    # ----------------------------------------------------------------------------------- gaps
    def _refresh_gaps(self) -> None:
        document, review = self.document, self.review
        self._groups = gap_groups(review, document.hand_models, self._marker_sets()) if review.n_labels else []
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

    def _marker_sets(self) -> dict:
        """The marker set of each hand side of the shown take: the subject's calibrated one, else its layout
        resolved on the hand model once (the document keeps it) rather than at every refresh of the gaps."""
        document = self.document
        sets = dict(document.marker_sets)
        for hand in document.review.hands:
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
        gap, group = self._gaps[index], self._groups[self._gaps[index].group]
        key = (id(self.document), self.review.version, index)
        self._check_key = key

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> tuple:
            check = check_review_gap(group, gap)
            previews = {}
            for method in FILL_METHODS:
                if cancelled():
                    break
                try:
                    previews[method] = preview_fill(group, gap, method)
                except HandMocapError:
                    continue
            return key, check, previews

        self.checks.start(task)

    def _check_done(self, _request: int, outcome: tuple) -> None:
        key, check, previews = outcome
        if key != self._check_key or self.review is None or key[1] != self.review.version:
            return
        index = key[2]
        check: FillCheck
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

    # ----------------------------------------------------------------------------- auto-label
    def choose_auto_label(self) -> None:
        if self.document is None:
            return
        if self.document.layout_name:
            self.auto_settings.layout = self.document.layout_name
        dialog = AutoLabelDialog(self.host, self.auto_settings)
        if dialog.exec() == QDialog.DialogCode.Accepted:
            self.auto_settings = dialog.settings()
            self.start_auto_label(self.auto_settings)

    def start_auto_label(self, settings: AutoLabelSettings, document: TakeDocument | None = None) -> None:
        """Auto-label ``document`` (default: the current take) on a worker; the result is one undoable step."""
        document = document or self.document
        if document is None:
            return
        take = document.ensure_review().take
        models = dict(document.hand_models)

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]):
            return auto_label(take, settings.layout, settings.hands, settings.objects or None, settings.online,
                              models=models or None, relabel=settings.relabel, progress=progress,
                              cancelled=cancelled)

        self._start_job("auto-label", task, document=document)

    # ------------------------------------------------------------------------------ re-solves
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
        if review is None or self.jobs.is_busy():
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

    # ----------------------------------------------------------------------------------- jobs
    def _start_job(self, kind: str, task: Callable, document: TakeDocument | None = None) -> None:
        self._job_document, self._job_kind = document or self.document, kind
        self._job_version = self._job_document.review.version
        self.jobs.start(task)
        self.app.job_started(JOB_NAME, Job(kind, self._job_document, self.jobs.cancel))
        self.progress_started.emit(f"{kind.capitalize()}… %p %")

    def _jobs_busy_changed(self, busy: bool) -> None:
        if not busy:
            self.app.job_ended(JOB_NAME)

    def _job_finished(self) -> None:
        self.progress_ended.emit()
        self._start_resolve()
        self.update_enabled()

    def _job_succeeded(self, _request: int, result: object) -> None:
        document, kind = self._job_document, self._job_kind
        self._job_document = None
        if document is None or document.review is None:
            self._job_finished()
            return
        try:
            if kind == "auto-label":
                document.hand_models.update(result.models)
                document.marker_sets.update(result.marker_sets)
                for side in result.models:
                    document.subjects.pop(side, None)
                document.subjects.update({subject.side: subject for subject in result.subjects})
                if document is self.document:            # a new labelling: start afresh on it
                    self._rejected = set()
                    self.app.clear_selection()
                document.push(result.command)
                report, known = result.report, result.report["file_labels"]
                kept = (f"; kept from the file: {len(known['kept_labels'])} labels outside the layout, its hand "
                        f"labels ({known['disagreed_samples']} samples differed from auto-label)"
                        if known["kept_labels"] or known["file_label_samples"] else "")
                self.status_message.emit(
                    document.review.health_summary() or
                    f"Auto-labelled {report['frames']} frames: {100 * report['labelled_share']:.1f} % of label "
                    f"samples found, {report['ghost_points']} ghost points left unlabelled{kept}",
                    0 if report["health"] else 10000)
                for warning in document.review.health:      # into the message panel, not only the status bar
                    _log.warning("%s: auto-label: %s", document.title, warning.message)
                self.auto_label_applied.emit(document, result.models, result.marker_sets)
            elif kind == "fill" and result is not None:
                span = document.push(result)
                self.status_message.emit(result.text, 8000)
                self._needs_resolve(document, span)
            elif kind == "re-solve" and document.review.version == self._job_version:
                for command in result:       # else the review changed meanwhile: its edits are re-solved again
                    document.attach(command)
                stack = document.stack
                if result and stack is not None and stack.can_undo():
                    self._carried[id(stack.commands[stack.index - 1])] = list(self._job_covers)
                for edit, _frames in self._job_covers:
                    self._unsolved.pop(id(edit), None)
        except HandMocapError as error:
            self.error_raised.emit(f"Cannot apply the {kind}", str(error))
        self._job_finished()

    def _job_failed(self, _request: int, message: str) -> None:
        kind = self._job_kind
        self._job_document = None
        self._job_finished()
        self.error_raised.emit(f"{kind.capitalize()} failed", message)

    def _job_cancelled(self, _request: int) -> None:
        kind = self._job_kind
        self._job_document = None
        self.progress_ended.emit()
        self.status_message.emit(f"{kind.capitalize()} cancelled; the take is unchanged", 5000)
        self.update_enabled()

    def stop(self) -> None:
        """Cancel and wait for the workers (the window is closing)."""
        self.jobs.stop()
        self.checks.stop()

    # -------------------------------------------------------------------------------- exports
    def _export(self, title: str, filter_text: str, suffix: str, write: Callable[[str], None], kind: str) -> None:
        document = self.document
        if document is None:
            return
        ending, extension = suffix.rsplit(".", 1)
        proposed = default_export_path(document.review, document.title, ending, f".{extension}")
        path, _ = QFileDialog.getSaveFileName(self.host, title, str(proposed), filter_text)
        if not path:
            return
        try:
            write(path)
        except (HandMocapError, OSError) as error:
            self.error_raised.emit("Cannot export", str(error))
            return
        self.exported.emit(document, kind, path)
        self.status_message.emit(f"Exported {path}", 5000)

    def export_c3d(self, path: str) -> None:
        """The review as a labelled C3D, with the subject calibrations auto-label made (``HAND_SUBJECT``)."""
        export_labelled_c3d(self.review, path, subjects=list(self.document.subjects.values()))

    def export_csv(self, path: str) -> None:
        export_joint_angles_csv(self.review, path)

    def export_bvh(self, path: str) -> None:
        hand = self.review.hands[0]
        export_bvh(self.review, path, self.document.model_for(hand.side), 0)

    def choose_export_c3d(self) -> None:
        self._export("Export labelled C3D", "C3D (*.c3d)", "_labelled.c3d", self.export_c3d, "c3d")

    def choose_export_csv(self) -> None:
        self._export("Export joint angles", "CSV (*.csv)", "_angles.csv", self.export_csv, "csv")

    def choose_export_bvh(self) -> None:
        self._export("Export joint angles", "BVH (*.bvh)", ".bvh", self.export_bvh, "bvh")
