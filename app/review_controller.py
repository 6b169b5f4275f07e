"""Take review in the main window: auto-label, the Labels/Tracks/Gaps docks, undoable label edits with a
re-solve of the touched frames, gap fills, "next problem", and the exports of a review.

Every change of a review goes through a command on the document's undo stack (journalled when the take
belongs to a session). Long work runs on workers: ``jobs`` (auto-label, re-solves, fill all) and
``checks`` (fill checks and previews of the selected gap), so checking a gap never cancels a re-solve.
Workers only read copies; results are applied on the GUI thread if the review has not changed since.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QObject, Qt
from PySide6.QtGui import QCursor, QKeySequence
from PySide6.QtWidgets import (
    QApplication,
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
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

from app.document import TakeDocument
from app.workers import TaskRunner
from core.batch import (
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
from core.errors import HandMocapError
from core.gaps import FILL_METHODS, FillCheck
from core.ik import IKResult
from core.labeling.objects import load_scene_spec, rigid_body_from_points, save_scene_spec
from core.model import layout_names, marker_positions, skin_vertices
from core.session import (
    PROBLEM_KINDS,
    AcceptFills,
    AssignLabel,
    Command,
    CompoundCommand,
    DefineHand,
    FrameSpan,
    GapFill,
    MarkGhost,
    RejectFills,
    SetSolve,
    SwapLabels,
    Unlabel,
    export_bvh,
    export_joint_angles_csv,
    export_labelled_c3d,
)
from widgets.fill_preview import FillPreview
from widgets.gap_list import GapList, GapRow
from widgets.marker_lanes import MarkerLanes, lanes_from_review
from widgets.review_table import ReviewTable

if TYPE_CHECKING:
    from app.main_window import MainWindow

UNLABELLED_COLOR = (0.62, 0.62, 0.64)
GHOST_COLOR = (0.55, 0.22, 0.22)
FILL_COLOR = (0.45, 0.95, 0.55)
RIGID_SELECTION_COLOR = (1.0, 1.0, 1.0)
TRAIL_FRAMES = 60                  # frames of trail on each side of the current frame
SCOPE_TITLES = {"fragment": "to end of fragment", "range": "in the marked range", "take": "whole take"}
PALETTE = np.array([                # Tableau-like qualitative colours, distinct on a dark background
    (0.36, 0.62, 0.92), (0.98, 0.60, 0.25), (0.40, 0.80, 0.45), (0.93, 0.38, 0.40), (0.70, 0.55, 0.90),
    (0.72, 0.52, 0.42), (0.96, 0.56, 0.80), (0.85, 0.85, 0.40), (0.35, 0.85, 0.85), (0.60, 0.75, 1.00),
    (1.00, 0.78, 0.55), (0.65, 0.92, 0.60), (1.00, 0.65, 0.65), (0.82, 0.72, 0.96), (0.88, 0.72, 0.62),
])


def label_colors(count: int) -> np.ndarray:
    """A distinct colour per label ``(count, 3)`` in [0, 1]."""
    return PALETTE[np.arange(count) % len(PALETTE)]


@dataclass
class AutoLabelSettings:
    """What the operator chose in the auto-label dialog."""

    layout: str = "dense"
    hands: str = "auto"
    objects: str = ""
    online: bool = False
    relabel: bool = False


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
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel, self)
        buttons.button(QDialogButtonBox.StandardButton.Ok).setText("Auto-label")
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def _browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Scene objects", "", "Scene spec (*.json);;All files (*)")
        if path:
            self.objects_edit.setText(path)

    def settings(self) -> AutoLabelSettings:
        return AutoLabelSettings(self.layout_box.currentText(), self.hands_box.currentText(),
                                 self.objects_edit.text().strip(), self.online_box.isChecked(),
                                 self.relabel_box.isChecked())


class ReviewController(QObject):
    """The review side of :class:`~app.main_window.MainWindow` (see the module docstring)."""

    def __init__(self, window: MainWindow) -> None:
        super().__init__(window)
        self.window = window
        self.document: TakeDocument | None = None
        self.selected_label = -1
        self.selected_column = -1
        self.rigid_points: list[int] = []
        self.range_in: int | None = None
        self.range_out: int | None = None
        self.auto_settings = AutoLabelSettings()
        self._groups: list[GapGroup] = []
        self._gaps: list[ReviewGap] = []
        self._rows: list[GapRow] = []
        self._rejected: set[tuple[int, int]] = set()
        self._previews: dict[tuple[int, int, str, int], np.ndarray] = {}
        self._pending_span = FrameSpan(0, 0)
        self._job_document: TakeDocument | None = None
        self._job_kind = ""
        self._job_version = -1
        self._check_key: tuple | None = None

        self.jobs = TaskRunner(self)
        self.jobs.progressed.connect(self._job_progressed)
        self.jobs.succeeded.connect(self._job_succeeded)
        self.jobs.failed.connect(self._job_failed)
        self.jobs.cancelled.connect(self._job_cancelled)
        self.jobs.busy_changed.connect(lambda _busy: self.update_enabled())
        self.checks = TaskRunner(self)
        self.checks.succeeded.connect(self._check_done)
        self.checks.failed.connect(self._check_failed)

        self._build_docks()
        self._build_actions()

    # ---------------------------------------------------------------------------------- building
    def _build_docks(self) -> None:
        window = self.window
        area = Qt.DockWidgetArea
        self.table = ReviewTable(window)
        self.table.marker_selected.connect(self.select_label)
        self.labels_dock = window._add_dock("Labels", self.table, area.RightDockWidgetArea)
        window.tabifyDockWidget(window.markers_dock, self.labels_dock)
        self.lanes = MarkerLanes(window)
        self.lanes.frame_clicked.connect(window.timeline.set_frame)
        self.lanes.marker_clicked.connect(self.select_label)
        self.lanes.stretch_clicked.connect(self._stretch_clicked)
        self.tracks_dock = window._add_dock("Tracks", self.lanes, area.BottomDockWidgetArea)
        window.splitDockWidget(window.timeline_dock, self.tracks_dock, Qt.Orientation.Vertical)
        self.lanes.link_x(window.timeline.plot.getPlotItem().vb)
        self.gap_list = GapList(window)
        self.preview = FillPreview(window)
        splitter = QSplitter(Qt.Orientation.Vertical, window)
        splitter.addWidget(self.gap_list)
        splitter.addWidget(self.preview)
        splitter.setSizes([560, 200])
        self.gap_list.gap_selected.connect(self._gap_selected)
        self.gap_list.method_changed.connect(lambda _gap, method: self.preview.set_selected(method))
        self.gap_list.preview_requested.connect(self._preview_requested)
        self.gap_list.accept_requested.connect(self.accept_fill)
        self.gap_list.reject_requested.connect(self.reject_gap)
        self.gap_list.fill_all_requested.connect(self.fill_all)
        scroller = QScrollArea(window)           # the gap table, check and preview need more height than
        scroller.setWidgetResizable(True)        # a small screen has: scroll rather than grow the window
        scroller.setFrameShape(QScrollArea.Shape.NoFrame)
        scroller.setWidget(splitter)
        self.gaps_dock = window._add_dock("Gaps", scroller, area.RightDockWidgetArea)
        window.tabifyDockWidget(self.labels_dock, self.gaps_dock)
        self.labels_dock.raise_()

    def _build_actions(self) -> None:
        window = self.window
        action = window._action
        self.auto_label_action = action("&Auto-label…", self.choose_auto_label, "Ctrl+L")
        self.auto_label_action.setToolTip("Label the take's raw points automatically (Ctrl+L)")
        self.undo_action = action("&Undo", self.undo, QKeySequence.StandardKey.Undo)
        self.redo_action = action("&Redo", self.redo, "Ctrl+Shift+Z")
        self.assign_action = action("&Assign label…", self.choose_label_to_assign, "L")
        self.swap_action = action("S&wap labels…", self.choose_label_to_swap, "W")
        self.ghost_action = action("Mark as &ghost", self.mark_ghost, "Shift+G")
        self.unlabel_action = action("&Unlabel", self.unlabel, "U")
        self.range_in_action = action("Set range &start here", self.set_range_in, "I")
        self.range_out_action = action("Set range &end here", self.set_range_out, "O")
        self.clear_range_action = action("&Clear range", self.clear_range, "Shift+I")
        self.next_problem_action = action("&Next problem", lambda: self.go_to_problem(True), "F3")
        self.previous_problem_action = action("&Previous problem", lambda: self.go_to_problem(False), "Shift+F3")
        self.rigid_body_action = action("Define &rigid body from selected points…", self.choose_rigid_body_name,
                                        "Ctrl+B")
        self.rigid_body_action.setToolTip("Ctrl+click three or more points of an object in the 3D view, then "
                                          "name it: auto-label then tracks it as a rigid body")
        self.fill_all_action = action("&Fill short gaps…", lambda: self.fill_all(self.gap_list.max_length_box.value()),
                                      "Ctrl+Shift+F")
        self.cancel_job_action = action("Cancel review &job", self.jobs.cancel)
        self.export_c3d_action = action("Labelled &C3D…", self.choose_export_c3d)
        self.export_csv_action = action("Joint angles (CS&V)…", self.choose_export_csv)
        self.export_bvh_action = action("Joint angles (&BVH)…", self.choose_export_bvh)

        menus = window.menuBar()
        edit_menu = QMenu("&Edit", window)
        menus.insertMenu(menus.actions()[1], edit_menu)
        for item in (self.undo_action, self.redo_action, None, self.assign_action, self.swap_action,
                     self.unlabel_action, self.ghost_action, None, self.range_in_action, self.range_out_action,
                     self.clear_range_action):
            edit_menu.addSeparator() if item is None else edit_menu.addAction(item)
        review_menu = QMenu("&Review", window)
        menus.insertMenu(menus.actions()[-1], review_menu)
        for item in (self.auto_label_action, self.cancel_job_action, self.rigid_body_action, None,
                     self.next_problem_action,
                     self.previous_problem_action, None, self.fill_all_action):
            review_menu.addSeparator() if item is None else review_menu.addAction(item)
        self.export_menu = QMenu("E&xport", window)
        for item in (self.export_c3d_action, self.export_csv_action, self.export_bvh_action):
            self.export_menu.addAction(item)
        window.view_menu.addAction(self.labels_dock.toggleViewAction())
        window.view_menu.addAction(self.tracks_dock.toggleViewAction())
        window.view_menu.addAction(self.gaps_dock.toggleViewAction())

        toolbar = QToolBar("Review", window)
        toolbar.setObjectName("review-toolbar")
        toolbar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        window.addToolBar(toolbar)
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
        self.scope_box = QComboBox(window)
        for scope, title in SCOPE_TITLES.items():
            self.scope_box.addItem(title, scope)
        self.scope_box.setToolTip("Which frames an edit changes: from the current frame to the end of the "
                                  "point's fragment, the range marked with I and O, or the whole take")
        toolbar.addWidget(self.scope_box)
        self.range_label = QLabel("", window)
        toolbar.addWidget(self.range_label)
        toolbar.addSeparator()
        toolbar.addAction(self.previous_problem_action)
        toolbar.addAction(self.next_problem_action)
        self.problem_label = QLabel("", window)
        toolbar.addWidget(self.problem_label)

    # ------------------------------------------------------------------------------- documents
    @property
    def review(self):
        return None if self.document is None else self.document.review

    def attach(self, document: TakeDocument) -> None:
        """Show the review of ``document`` (creating an empty one for a new take)."""
        self.document = document
        document.ensure_review()
        self.selected_label = -1
        self.selected_column = -1
        self.rigid_points = []
        self.range_in = self.range_out = None
        self._rejected = set()
        self._previews = {}
        self._pending_span = FrameSpan(0, 0)
        self.refresh(structure=True)
        if document.review.health:
            self.window.statusBar().showMessage(document.review.health_summary())

    def detach(self) -> None:
        """No take is shown any more: clear the review views."""
        self.stop()
        self.document = None
        self.lanes.set_lanes([], np.zeros((0, 0), dtype=np.int8))
        self.gap_list.set_gaps([], [], 1)
        self.preview.clear()
        self.window.viewport.set_trails([])
        self.window.viewport.set_loose_points(None)
        self.window.viewport.set_rigid_bodies(None)
        self.update_enabled()

    def refresh(self, structure: bool = False) -> None:
        """Redraw the review views after a change; ``structure``: labels or hands may have changed."""
        review = self.review
        if review is None:
            return
        take = review.take
        colors = label_colors(review.n_labels)
        stats = review.marker_stats()
        states = lanes_from_review(review.lane_states(), review.provenance)
        if structure or self.lanes.n_markers != review.n_labels or self.lanes.n_frames != review.n_frames:
            self.lanes.set_lanes(review.label_names, states, take.first_frame, take.frame_rate)
            self.table.set_markers(stats, colors)
            self._set_hand_meshes()
        else:
            x_range = self.lanes.x_range()
            self.lanes.set_states(states)
            self.lanes.set_x_range(*x_range)
            self.table.update_stats(stats)
        self.lanes.set_frame(self.window.timeline.frame)
        if self.selected_label >= 0:
            self.lanes.set_selected_marker(self.selected_label)
        self._refresh_gaps()
        self._refresh_problem_count()
        if self.has_solved_hands():
            self.window.timeline.set_residuals(self._mean_residual_per_frame())
        self.update_enabled()
        self.window.show_frame(self.window.timeline.frame)

    def _mean_residual_per_frame(self) -> np.ndarray:
        """Mean residual (mm) over the labelled samples of each frame ``(F,)``, NaN where none."""
        residuals = np.where(self.review.assignment >= 0, self.review.residuals_mm, np.nan)
        counts = np.isfinite(residuals).sum(axis=1)
        return np.where(counts > 0, np.nansum(residuals, axis=1) / np.maximum(counts, 1), np.nan)

    def _set_hand_meshes(self) -> None:
        document = self.document
        meshes = []
        for hand in document.review.hands:
            model = document.model_for(hand.side)
            meshes.append((model.vertices, model.faces))
        if meshes:
            self.window.viewport.set_hand_meshes(meshes)

    def has_solved_hands(self) -> bool:
        review = self.review
        return review is not None and any(np.isfinite(hand.joint_angles).any() for hand in review.hands)

    def has_labels(self) -> bool:
        return self.review is not None and self.review.n_labels > 0

    def update_enabled(self) -> None:
        review, busy = self.review, self.jobs.is_busy()
        stack = None if self.document is None else self.document.stack
        self.auto_label_action.setEnabled(review is not None and not busy)
        self.rigid_body_action.setEnabled(review is not None and len(self.rigid_points) >= 3)
        self.cancel_job_action.setEnabled(busy)
        self.undo_action.setEnabled(stack is not None and stack.can_undo() and not busy)
        self.redo_action.setEnabled(stack is not None and stack.can_redo() and not busy)
        self.undo_action.setText(f"&Undo {stack.undo_text()}" if stack is not None and stack.can_undo() else "&Undo")
        self.redo_action.setText(f"&Redo {stack.redo_text()}" if stack is not None and stack.can_redo() else "&Redo")
        editable = self.has_labels() and not (busy and self._job_kind == "auto-label")
        for action in (self.assign_action, self.swap_action, self.ghost_action, self.unlabel_action,
                       self.next_problem_action, self.previous_problem_action, self.fill_all_action,
                       self.export_c3d_action):
            action.setEnabled(editable)
        for action in (self.export_csv_action, self.export_bvh_action):
            action.setEnabled(self.has_solved_hands())
        text = ""
        if self.range_in is not None or self.range_out is not None:
            first = review.take.first_frame if review is not None else 0
            start = "…" if self.range_in is None else str(self.range_in + first)
            stop = "…" if self.range_out is None else str(self.range_out + first)
            text = f" range {start}–{stop} "
        self.range_label.setText(text)

    # ---------------------------------------------------------------------------------- frames
    def show_frame(self, frame: int) -> None:
        """Draw ``frame`` of the review: every raw point coloured by the label it holds (grey when
        unlabelled, dark red for ghosts), accepted fills as green dots, the solved hands with their
        effectors and residual lines, and the trail of the selected label."""
        document, review = self.document, self.review
        viewport = self.window.viewport
        labels = review.assignment[frame]
        point_label = np.full(review.n_points, -1, dtype=np.int64)
        taken = labels >= 0
        point_label[labels[taken]] = np.flatnonzero(taken)
        colors = np.tile(UNLABELLED_COLOR, (review.n_points, 1))
        colors[review.ghost[frame]] = GHOST_COLOR
        palette = label_colors(review.n_labels)
        colors[point_label >= 0] = palette[point_label[point_label >= 0]]
        colors[self.rigid_points] = RIGID_SELECTION_COLOR
        names = [review.label_names[label] if label >= 0 else f"*{column}"
                 for column, label in enumerate(point_label)]
        viewport.set_marker_names(names)
        viewport.set_marker_colors(colors)
        viewport.set_rigid_bodies(review.rigid_body_segments(frame))
        fills = review.provenance[frame] > 0
        fill_colors = palette[fills] * 0.5 + np.array(FILL_COLOR) * 0.5
        viewport.set_loose_points(review.filled_positions[frame, fills], fill_colors)
        effectors, targets = [], []
        labelled = review.labelled_positions()[frame]
        for number, hand in enumerate(review.hands):
            theta = hand.joint_angles[frame]
            if not np.isfinite(theta).all():
                continue
            model = document.model_for(hand.side)
            viewport.update_hand_vertices(skin_vertices(model, theta), number)
            markers = document.marker_set_for(hand.side, hand.layout)
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
        review = self.review
        if self.selected_label < 0 or self.selected_label >= review.n_labels:
            self.window.viewport.set_trails([])
            return
        first, last = max(0, frame - TRAIL_FRAMES), min(review.n_frames, frame + TRAIL_FRAMES + 1)
        trail = review.labelled_positions()[first:last, self.selected_label]
        self.window.viewport.set_trails([trail], label_colors(review.n_labels)[[self.selected_label]])

    # ------------------------------------------------------------------------------- selection
    def select_label(self, label: int) -> None:
        """Select ``label`` everywhere: table row, lane, the point holding it now, its trail."""
        review = self.review
        if review is None:
            return
        self.selected_label = label if 0 <= label < review.n_labels else -1
        frame = self.window.timeline.frame
        self.selected_column = int(review.assignment[frame, label]) if self.selected_label >= 0 else -1
        self.table.select_marker(self.selected_label)
        self.lanes.set_selected_marker(self.selected_label)
        self.window.viewport.set_selected_marker(self.selected_column if self.selected_column >= 0 else None)
        self._draw_trail(frame)
        self.window._schedule_render()

    def point_clicked(self, column: int) -> None:
        """The operator clicked raw point ``column`` in the 3D view (-1: empty space)."""
        review = self.review
        if review is None:
            return
        frame = self.window.timeline.frame
        if QApplication.keyboardModifiers() & Qt.KeyboardModifier.ControlModifier and column >= 0:
            self.toggle_rigid_point(column)
            return
        self.selected_column = column
        label = review.label_of_point(frame, column) if column >= 0 else -1
        self.selected_label = label
        self.table.select_marker(label)
        self.lanes.set_selected_marker(label)
        self.window.viewport.set_selected_marker(column if column >= 0 else None)
        self._draw_trail(frame)
        self.window._schedule_render()

    def toggle_rigid_point(self, column: int) -> None:
        """Add raw point ``column`` to the points of a new rigid body (or take it out again)."""
        if column in self.rigid_points:
            self.rigid_points.remove(column)
        else:
            self.rigid_points.append(column)
        self.update_enabled()
        self.window.statusBar().showMessage(f"{len(self.rigid_points)} points selected for a rigid body "
                                            "(Review ▸ Define rigid body…)", 5000)
        self.window.show_frame(self.window.timeline.frame)

    def choose_rigid_body_name(self) -> None:
        name, accepted = QInputDialog.getText(self.window, "Rigid body", "Name of the object:", text="object")
        if accepted and name.strip():
            self.define_rigid_body(name.strip())

    def define_rigid_body(self, name: str) -> Path | None:
        """Make a rigid body named ``name`` from the selected points in the current frame and add it to the
        scene spec auto-label uses (in the session folder, or next to the take file). Returns the spec."""
        review = self.review
        frame = self.window.timeline.frame
        try:
            if len(self.rigid_points) < 3:
                raise HandMocapError("Ctrl+click at least 3 points of the object in the 3D view first")
            markers = [f"{name}{number + 1}" for number in range(len(self.rigid_points))]
            spec = rigid_body_from_points(name, markers, review.take.marker_positions[frame, self.rigid_points])
            path = Path(self.auto_settings.objects) if self.auto_settings.objects else self._default_spec_path()
            objects = [item for item in (load_scene_spec(path) if path.exists() else []) if item.name != name]
            path.parent.mkdir(parents=True, exist_ok=True)
            save_scene_spec([*objects, spec], path)
        except (HandMocapError, OSError) as error:
            self.window.show_error("Cannot define the rigid body", str(error))
            return None
        self.auto_settings.objects = str(path)
        self.rigid_points = []
        self.window.statusBar().showMessage(f"Rigid body '{name}' ({len(markers)} markers) added to the scene "
                                            f"{path.name}; the next auto-label tracks it", 8000)
        self.window.show_frame(frame)
        return path

    def _default_spec_path(self) -> Path:
        document = self.document
        if document.open_take is not None:
            return document.open_take.folder / "scene_objects.json"
        source = document.take.source_path
        folder = Path(source).parent if source else Path.home() / ".cache" / "handmocap"
        return folder / f"{Path(document.title).stem}_objects.json"

    def _stretch_clicked(self, marker: int, first: int, _last: int) -> None:
        self.select_label(marker)
        frame = self.window.timeline.frame
        if not first <= frame <= _last:
            self.window.timeline.set_frame(first)

    # -------------------------------------------------------------------------------- editing
    def _scope(self) -> tuple[str, int | None, int | None]:
        scope = self.scope_box.currentData()
        if scope != "range":
            return scope, None, None
        if self.range_in is None or self.range_out is None:
            raise HandMocapError("mark the range first: I at its first frame, O at its last")
        start, stop = sorted((self.range_in, self.range_out))
        return scope, start, stop + 1

    def _selected_point(self) -> tuple[int, int]:
        frame = self.window.timeline.frame
        column = self.selected_column
        if column < 0 and self.selected_label >= 0:
            column = int(self.review.assignment[frame, self.selected_label])
        if column < 0 or not np.isfinite(self.review.take.marker_positions[frame, column]).all():
            raise HandMocapError("select a point in the 3D view (or a label that has a point in this frame) first")
        return frame, column

    def run_edit(self, make: Callable[[], Command]) -> FrameSpan | None:
        """Build a command, push it on the undo stack, refresh, and re-solve the frames it touched.
        A problem becomes a one-line message; the review stays as it was."""
        document = self.document
        if document is None or document.review is None:
            return None
        try:
            command = make()
            span = document.push(command)
        except HandMocapError as error:
            self.window.show_error("Cannot edit", str(error))
            return None
        self._previews = {}
        self.refresh(structure=False)
        self.queue_resolve(span)
        self.window.statusBar().showMessage(command.text, 5000)
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
            if self.selected_label < 0:
                raise HandMocapError("select the label to swap first (click its point, lane or row)")
            frame = self.window.timeline.frame
            if self.range_in is not None and self.range_out is not None:
                start, stop = sorted((self.range_in, self.range_out))
                stop += 1
            else:
                start, stop = frame, self.review.n_frames
            return SwapLabels(self.review.label_names[self.selected_label], other, start, stop)
        return self.run_edit(make)

    def _label_menu(self, title: str, slot: Callable[[str], object], exclude: int = -1) -> None:
        review = self.review
        if review is None or not review.n_labels:
            return
        menu = QMenu(title, self.window)
        groups: dict[str, QMenu] = {}
        for label, name in enumerate(review.label_names):
            if label == exclude:
                continue
            hand = review.hand_of_label(label)
            group = review.hands[hand].name if hand >= 0 else "other"
            if len(review.hands) > 1 or (hand < 0 and review.hands):
                if group not in groups:
                    groups[group] = menu.addMenu(group)
                target = groups[group]
            else:
                target = menu
            item = target.addAction(name)
            item.triggered.connect(lambda _checked=False, chosen=name: slot(chosen))
        menu.exec(QCursor.pos())

    def choose_label_to_assign(self) -> None:
        self._label_menu("Assign label", self.assign_label)

    def choose_label_to_swap(self) -> None:
        if self.selected_label < 0:
            self.window.show_error("Cannot swap", "select the label to swap first (click its point, lane or row)")
            return
        self._label_menu("Swap with", self.swap_labels, exclude=self.selected_label)

    def undo(self) -> None:
        self._step(self.document.undo if self.document else None)

    def redo(self) -> None:
        self._step(self.document.redo if self.document else None)

    def _step(self, operation: Callable[[], FrameSpan] | None) -> None:
        if operation is None:
            return
        try:
            operation()
        except HandMocapError as error:
            self.window.show_error("Cannot undo", str(error))
            return
        self._previews = {}
        self.refresh(structure=True)

    def set_range_in(self) -> None:
        self.range_in = self.window.timeline.frame
        self.update_enabled()

    def set_range_out(self) -> None:
        self.range_out = self.window.timeline.frame
        self.update_enabled()

    def clear_range(self) -> None:
        self.range_in = self.range_out = None
        self.update_enabled()

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
        problem = review.next_problem(self.window.timeline.frame, forward=forward)
        if problem is None:
            self.window.statusBar().showMessage("No problems left in this take", 5000)
            return
        self.window.timeline.set_frame(problem.frame)
        self.select_label(problem.label)
        self.window.statusBar().showMessage(problem.text, 8000)

    # ----------------------------------------------------------------------------------- gaps
    def _refresh_gaps(self) -> None:
        document, review = self.document, self.review
        self._groups = gap_groups(review, document.hand_models, document.marker_sets) if review.n_labels else []
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
            row.donors = tuple(int(label) for label in self._groups[gap.group].labels if label != gap.label)
            rows.append(row)
        self._rows = rows
        selected = self.gap_list.selected_gap()
        self.gap_list.set_gaps(rows, review.label_names, review.take.first_frame)
        if 0 <= selected < len(rows):
            self.gap_list.select_gap(selected)
        else:
            self.preview.clear()

    def _gap_selected(self, index: int) -> None:
        if not 0 <= index < len(self._gaps):
            self.preview.clear()
            return
        gap = self._gaps[index]
        self.window.timeline.set_frame(gap.start)
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
            self.window.show_error("Cannot preview", str(error))
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
        try:
            gaps = [gap for gap in short_open_gaps(review, self._groups, max_length)
                    if (gap.label, gap.start) not in self._rejected]
        except HandMocapError as error:
            self.window.show_error("Cannot fill", str(error))
            return
        if not gaps:
            self.window.statusBar().showMessage(f"No open gap of at most {max_length} frames", 5000)
            return
        groups = self._groups
        self._start_job("fill", lambda progress, cancelled: fill_gaps(groups, gaps, "auto", progress, cancelled))

    # ----------------------------------------------------------------------------- auto-label
    def choose_auto_label(self) -> None:
        if self.document is None:
            return
        if self.document.layout_name:
            self.auto_settings.layout = self.document.layout_name
        dialog = AutoLabelDialog(self.window, self.auto_settings)
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

    def record_solve(self, document: TakeDocument, result: IKResult) -> None:
        """Keep an IK solve of ``document`` in its review as one undoable (and, in a session, journalled
        and saved) step, defining the hand from the layout's labels first when the review has none."""
        review = document.ensure_review()
        if not review.n_labels:
            return
        names = list(result.marker_names)
        number = next((index for index, hand in enumerate(review.hands)
                       if hand.side == result.hand_side and len(hand.labels) == len(names)
                       and [review.label_names[label].lower() for label in hand.labels] == [n.lower() for n in names]),
                      None)
        steps: list[Command] = []
        if number is None:
            steps.append(DefineHand(result.hand_side, result.hand_side, names, document.layout_name))
            number = len(review.hands)
        steps.append(SetSolve(number, 0, result.joint_angles, result.residuals_mm))
        try:
            document.push(CompoundCommand(steps, f"{result.method} IK solve ({result.hand_side} hand)"))
        except HandMocapError:
            return          # the take's labels do not cover the layout: the solve stays on the document
        if document is self.document:
            self.refresh(structure=True)

    # ------------------------------------------------------------------------------ re-solves
    def queue_resolve(self, span: FrameSpan) -> None:
        """Re-solve the hands over ``span`` (merged with frames still waiting) when the worker is free."""
        self._pending_span = self._pending_span.union(span)
        if not self.jobs.is_busy():
            self._start_resolve()

    def _start_resolve(self) -> None:
        review, document = self.review, self.document
        span = self._pending_span
        if review is None or span.empty or not review.hands:
            self._pending_span = FrameSpan(0, 0)
            return
        jobs = resolve_jobs(review, span, document.hand_models, marker_sets=document.marker_sets)
        self._pending_span = FrameSpan(0, 0)
        if jobs:
            self._start_job("re-solve", lambda progress, cancelled: run_resolve_jobs(
                jobs, progress=progress, cancelled=cancelled), keep_span=span)

    # ----------------------------------------------------------------------------------- jobs
    def _start_job(self, kind: str, task: Callable, keep_span: FrameSpan | None = None,
                   document: TakeDocument | None = None) -> None:
        self._job_document, self._job_kind = document or self.document, kind
        self._job_version = self._job_document.review.version
        self._job_span = keep_span
        self.jobs.start(task)
        self.window.show_progress(f"{kind.capitalize()}… %p %", self.jobs.cancel)
        self.update_enabled()

    def _job_progressed(self, _request: int, fraction: float) -> None:
        self.window.set_progress(fraction)

    def _job_finished(self) -> None:
        self.window.hide_progress()
        if not self._pending_span.empty and self.document is self._job_document:
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
                self.window.sessions.save_take_models(document, result.models, result.marker_sets)
                document.push(result.command)
                document.last_report = result.report
                if document is self.document:
                    self.attach(document)
                report, known = result.report, result.report["file_labels"]
                kept = (f"; kept from the file: {len(known['kept_labels'])} labels outside the layout, its hand "
                        f"labels ({known['disagreed_samples']} samples differed from auto-label)"
                        if known["kept_labels"] or known["file_label_samples"] else "")
                self.window.statusBar().showMessage(
                    document.review.health_summary() or
                    f"Auto-labelled {report['frames']} frames: {100 * report['labelled_share']:.1f} % of label "
                    f"samples found, {report['ghost_points']} ghost points left unlabelled{kept}",
                    0 if report["health"] else 10000)
                self.window.auto_label_finished(document)
            elif kind == "fill" and result is not None:
                span = document.push(result)
                self.window.statusBar().showMessage(result.text, 8000)
                if document is self.document:
                    self.refresh()
                    self.queue_resolve(span)
            elif kind == "re-solve":
                if document.review.version != self._job_version:
                    self._pending_span = self._pending_span.union(self._job_span)
                else:
                    for command in result:
                        document.attach(command)
                    if document is self.document:
                        self.refresh()
        except HandMocapError as error:
            self.window.show_error(f"Cannot apply the {kind}", str(error))
        self._job_finished()

    def _job_failed(self, _request: int, message: str) -> None:
        kind = self._job_kind
        self._job_document = None
        self._job_finished()
        self.window.show_error(f"{kind.capitalize()} failed", message)

    def _job_cancelled(self, _request: int) -> None:
        kind = self._job_kind
        if kind == "re-solve" and self._job_span is not None:
            self._pending_span = self._pending_span.union(self._job_span)
        self._job_document = None
        self.window.hide_progress()
        self.window.statusBar().showMessage(f"{kind.capitalize()} cancelled; the take is unchanged", 5000)
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
        stem = document.title.rsplit(".", 1)[0]
        path, _ = QFileDialog.getSaveFileName(self.window, title, f"{stem}{suffix}", filter_text)
        if not path:
            return
        try:
            write(path)
        except (HandMocapError, OSError) as error:
            self.window.show_error("Cannot export", str(error))
            return
        self.window.export_done(document, kind, path)
        self.window.statusBar().showMessage(f"Exported {path}", 5000)

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
