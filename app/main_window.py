"""The main window: 3D viewport, timeline, marker table, take list, and IK solving on a worker."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QAction, QCloseEvent, QKeySequence
from PySide6.QtWidgets import (
    QComboBox,
    QDockWidget,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QToolBar,
    QWidget,
)

from app.document import TakeDocument
from app.workers import TaskRunner
from core.errors import HandMocapError
from core.ik import METHODS, solve_take
from core.io import Take, load_take
from core.model import layout_names, load_layout, load_template, skin_vertices
from widgets.marker_panel import MarkerPanel
from widgets.timeline import TimelineWidget
from widgets.viewport import HandViewport

HAND_MARKER_COLOR = (0.55, 0.80, 1.00)     # markers of the hand layout
OTHER_MARKER_COLOR = (0.62, 0.62, 0.66)    # arm, body and object markers
FRAMING_RADIUS_MM = 90.0                   # half-size of the box the camera frames around the hand
TAKE_FILTER = "Motion capture takes (*.c3d *.tsv *.trc *.csv);;All files (*)"


class MainWindow(QMainWindow):
    """Review takes: scrub the markers, solve IK on a worker, watch the hand follow the data."""

    def __init__(self, off_screen: bool | None = None) -> None:
        super().__init__()
        self.setWindowTitle("Hand Mocap Studio")
        self.resize(1500, 950)
        self.documents: list[TakeDocument] = []
        self.document: TakeDocument | None = None
        self.model = load_template("right")
        self.runner = TaskRunner(self)
        self.runner.progressed.connect(self._solve_progressed)
        self.runner.succeeded.connect(self._solve_succeeded)
        self.runner.failed.connect(self._solve_failed)
        self.runner.cancelled.connect(self._solve_cancelled)
        self.runner.busy_changed.connect(self._busy_changed)

        self.viewport = HandViewport(self, off_screen=off_screen)
        self.setCentralWidget(self.viewport)
        self.timeline = TimelineWidget(self)
        self.timeline.frame_changed.connect(self.show_frame)
        self.marker_panel = MarkerPanel(self)
        self.marker_panel.marker_selected.connect(self._marker_selected)
        self._add_dock("Timeline", self.timeline, Qt.DockWidgetArea.BottomDockWidgetArea)
        self._add_dock("Markers", self.marker_panel, Qt.DockWidgetArea.RightDockWidgetArea)
        self._build_actions()
        self._build_toolbar()
        self._build_status_bar()
        self._update_enabled()

    # ------------------------------------------------------------------------------------ building
    def _add_dock(self, title: str, widget: QWidget, area: Qt.DockWidgetArea) -> None:
        dock = QDockWidget(title, self)
        dock.setObjectName(title)
        dock.setWidget(widget)
        dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable
                         | QDockWidget.DockWidgetFeature.DockWidgetFloatable)
        self.addDockWidget(area, dock)
        if area == Qt.DockWidgetArea.RightDockWidgetArea:
            self.resizeDocks([dock], [470], Qt.Orientation.Horizontal)

    def _action(self, text: str, slot, shortcut: QKeySequence | str | None = None, checkable: bool = False,
                checked: bool = False) -> QAction:
        action = QAction(text, self)
        if shortcut is not None:
            action.setShortcut(QKeySequence(shortcut))
        action.setCheckable(checkable)
        if checkable:
            action.setChecked(checked)
            action.toggled.connect(slot)
        else:
            action.triggered.connect(slot)
        return action

    def _build_actions(self) -> None:
        self.open_action = self._action("&Open…", self.choose_file, QKeySequence.StandardKey.Open)
        self.demo_action = self._action("Open &demo session", self.open_demo)
        self.screenshot_action = self._action("Save &screenshot…", self.choose_screenshot, "Ctrl+Shift+S")
        self.export_action = self._action("Export joint angles (CSV)…", self.choose_export)
        quit_action = self._action("&Quit", self.close, QKeySequence.StandardKey.Quit)
        self.solve_action = self._action("&Solve", self.solve, "Ctrl+R")
        self.cancel_action = self._action("&Cancel", self.runner.cancel, "Esc")
        self.labels_action = self._action("Marker &names", self.viewport.set_labels_visible, "N", True, False)
        self.mesh_action = self._action("Hand &mesh", self.viewport.set_mesh_visible, "M", True, True)
        self.effectors_action = self._action("&Effectors and residuals", self.viewport.set_effectors_visible, "E",
                                             True, True)
        self.frame_action = self._action("&Frame the hand", self.frame_hand, "F")
        menus = self.menuBar()
        file_menu = menus.addMenu("&File")
        for action in (self.open_action, self.demo_action, None, self.export_action, self.screenshot_action,
                       None, quit_action):
            file_menu.addSeparator() if action is None else file_menu.addAction(action)
        view_menu = menus.addMenu("&View")
        for action in (self.labels_action, self.mesh_action, self.effectors_action, self.frame_action):
            view_menu.addAction(action)
        solve_menu = menus.addMenu("&Solve")
        solve_menu.addAction(self.solve_action)
        solve_menu.addAction(self.cancel_action)

    def _build_toolbar(self) -> None:
        toolbar = QToolBar("Main", self)
        toolbar.setObjectName("main-toolbar")
        toolbar.setMovable(False)
        self.addToolBar(toolbar)
        toolbar.addAction(self.open_action)
        toolbar.addSeparator()
        toolbar.addWidget(QLabel(" Take "))
        self.take_box = QComboBox(self)
        self.take_box.setMinimumWidth(300)
        self.take_box.currentIndexChanged.connect(self._take_chosen)
        toolbar.addWidget(self.take_box)
        toolbar.addSeparator()
        toolbar.addWidget(QLabel(" Layout "))
        self.layout_box = QComboBox(self)
        self.layout_box.addItems(layout_names())
        self.layout_box.currentTextChanged.connect(self._layout_chosen)
        toolbar.addWidget(self.layout_box)
        toolbar.addWidget(QLabel(" IK "))
        self.method_box = QComboBox(self)
        self.method_box.addItems(list(METHODS))
        toolbar.addWidget(self.method_box)
        toolbar.addAction(self.solve_action)

    def _build_status_bar(self) -> None:
        status = self.statusBar()
        self.info_label = QLabel("No take open — File ▸ Open… or File ▸ Open demo session")
        status.addWidget(self.info_label, 1)
        self.progress_bar = QProgressBar(self)
        self.progress_bar.setRange(0, 100)
        self.progress_bar.setMaximumWidth(240)
        self.progress_bar.setFormat("Solving… %p %")
        self.cancel_button = QPushButton("Cancel", self)
        self.cancel_button.clicked.connect(self.runner.cancel)
        status.addPermanentWidget(self.progress_bar)
        status.addPermanentWidget(self.cancel_button)
        self.progress_bar.hide()
        self.cancel_button.hide()

    # ---------------------------------------------------------------------------------- documents
    def choose_file(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open take", "", TAKE_FILTER)
        if path:
            self.open_file(path)

    def open_file(self, path: str | Path, solve: bool = False) -> bool:
        """Open a take file (and solve it when ``solve``); on failure show the one-line reason and
        keep what is open."""
        try:
            take = load_take(path)
        except HandMocapError as error:
            self.show_error("Cannot open the take", str(error))
            return False
        self.add_document(TakeDocument(take, Path(path).name, auto_solve=solve))
        return True

    def open_demo(self) -> None:
        """Open the demo takes and solve them one after the other."""
        from app.demo import demo_takes

        try:
            takes = demo_takes()
        except HandMocapError as error:
            self.show_error("Cannot open the demo session", str(error))
            return
        for title, take in takes:
            self.add_document(TakeDocument(take, title, auto_solve=True), make_current=False)
        self.take_box.setCurrentIndex(len(self.documents) - len(takes))

    def add_document(self, document: TakeDocument, make_current: bool = True) -> None:
        self.documents.append(document)
        self.take_box.addItem(document.title)
        if make_current:
            self.take_box.setCurrentIndex(len(self.documents) - 1)

    def _take_chosen(self, index: int) -> None:
        if 0 <= index < len(self.documents):
            self.set_document(self.documents[index])

    def set_document(self, document: TakeDocument) -> None:
        """Show ``document``: markers, table, timeline; the hand if it is solved."""
        self.runner.stop()
        self.document = document
        take = document.take
        if document.layout_name:
            self.layout_box.blockSignals(True)
            self.layout_box.setCurrentText(document.layout_name)
            self.layout_box.blockSignals(False)
        colors = np.tile(OTHER_MARKER_COLOR, (take.n_markers, 1))
        colors[document.hand_columns()] = HAND_MARKER_COLOR
        self.viewport.set_markers(take.marker_names, take.marker_positions[0], colors)
        self.marker_panel.set_markers(take.marker_names, document.observed_fraction)
        self._show_result_geometry()
        self.timeline.set_take(take.n_frames, take.first_frame, take.frame_rate, document.markers_seen)
        self.frame_hand()
        self.info_label.setText(self._take_summary(take))
        self.show_frame(self.timeline.frame)
        self._update_enabled()
        if document.auto_solve and document.result is None and document.layout_name:
            self.solve()

    @staticmethod
    def _take_summary(take: Take) -> str:
        return (f"{take.n_frames} frames · {take.frame_rate:g} Hz · {take.n_markers} markers · {take.vendor}"
                f" · {100 * take.missing_fraction:.1f} % missing")

    def frame_hand(self) -> None:
        """Point the camera at the hand at the current frame; the ground grid spans the whole take."""
        if self.document is None:
            return
        hand = self.document.take.marker_positions[:, self.document.hand_columns()]
        everything = hand.reshape(-1, 3)[:: max(1, hand.size // 60000)]
        if not np.isfinite(everything).any():
            return
        self.viewport.set_ground(everything, height=float(np.nanmin(everything[:, 2])) - 40.0)
        current = hand[self.timeline.frame]
        current = current[np.isfinite(current).all(axis=1)]
        if len(current) >= 3:
            centre = current.mean(axis=0)
            self.viewport.frame_bounds(np.vstack([current, centre - FRAMING_RADIUS_MM, centre + FRAMING_RADIUS_MM]))
        else:
            self.viewport.frame_bounds(everything)
        self.viewport.render()

    # --------------------------------------------------------------------------------------- frame
    def show_frame(self, frame: int) -> None:
        """Draw ``frame`` (0-based): markers, table values, and the solved hand when there is one."""
        document = self.document
        if document is None or not 0 <= frame < document.take.n_frames:
            return
        positions = document.take.marker_positions[frame]
        self.viewport.update_markers(positions)
        self.marker_panel.set_frame_values(positions, document.residuals_per_take_marker(frame))
        if document.result is not None:
            theta = document.result.joint_angles[frame]
            if np.isfinite(theta).all():
                self.viewport.update_hand_vertices(skin_vertices(self.model, theta))
            effectors, targets = document.effector_targets(frame)
            self.viewport.set_effectors(effectors, targets)
        self.viewport.render()

    def _show_result_geometry(self) -> None:
        document = self.document
        if document is None or document.result is None:
            self.viewport.set_hand_mesh(None)
            self.viewport.set_effectors(None)
            return
        self.viewport.set_hand_mesh(self.model.vertices, self.model.faces)

    def _marker_selected(self, row: int) -> None:
        self.viewport.set_selected_marker(None if row < 0 else row)
        self.viewport.render()

    def _layout_chosen(self, name: str) -> None:
        if self.document is not None and name:
            self.document.layout_name = name

    # --------------------------------------------------------------------------------------- solve
    def solve(self) -> None:
        """Run IK of the current take on the worker thread."""
        document = self.document
        if document is None:
            return
        try:
            layout = load_layout(self.layout_box.currentText())
        except HandMocapError as error:
            self.show_error("Cannot solve", str(error))
            return
        document.layout_name = layout.name
        take, model, method = document.take, self.model, self.method_box.currentText()

        def task(progress, cancelled):
            return solve_take(take, model, layout, method=method, progress=progress, cancelled=cancelled)

        document.solve_request = self.runner.start(task)
        self.statusBar().showMessage(f"Solving {document.title} with {method} IK ({layout.name})…")

    def _owner(self, request_id: int) -> TakeDocument | None:
        return next((d for d in self.documents if d.solve_request == request_id), None)

    def _solve_progressed(self, request_id: int, fraction: float) -> None:
        if self.document is not None and self.document.solve_request == request_id:
            self.progress_bar.setValue(int(100 * fraction))

    def _solve_succeeded(self, request_id: int, result) -> None:
        document = self._owner(request_id)
        if document is None:
            return
        document.solve_request = 0
        try:
            document.set_result(result)
        except HandMocapError as error:
            self.show_error("Cannot show the result", str(error))
            return
        self.statusBar().showMessage(f"{document.title}: {result.method} IK done, mean residual "
                                     f"{result.mean_residual_mm:.2f} mm", 15000)
        if document is self.document:
            self._show_result_geometry()
            self.show_frame(self.timeline.frame)
            self._update_enabled()
        else:
            self._solve_next_pending()

    def _solve_failed(self, request_id: int, message: str) -> None:
        document = self._owner(request_id)
        if document is not None:
            document.solve_request = 0
            self.show_error("Solve failed", message)

    def _solve_cancelled(self, request_id: int) -> None:
        document = self._owner(request_id)
        if document is not None:
            document.solve_request = 0
            self.statusBar().showMessage("Solve cancelled; the take is unchanged", 8000)

    def _solve_next_pending(self) -> None:
        """Auto-solve a demo take that has no result yet (one at a time)."""
        if self.runner.is_busy() or self.document is None:
            return
        if self.document.auto_solve and self.document.result is None:
            self.solve()

    def _busy_changed(self, busy: bool) -> None:
        self.progress_bar.setVisible(busy)
        self.cancel_button.setVisible(busy)
        self.progress_bar.setValue(0)
        self._update_enabled()

    def _update_enabled(self) -> None:
        has_take = self.document is not None
        busy = self.runner.is_busy()
        self.solve_action.setEnabled(has_take and not busy)
        self.cancel_action.setEnabled(busy)
        self.export_action.setEnabled(has_take and self.document.result is not None)

    # -------------------------------------------------------------------------------------- output
    def choose_screenshot(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Save screenshot", "handmocap.png", "PNG images (*.png)")
        if path:
            self.save_screenshot(path)

    def save_screenshot(self, path: str | Path) -> None:
        """Save the whole window (with the 3D view) as a PNG."""
        self.viewport.render()
        screen = self.screen()
        image = screen.grabWindow(self.winId()) if screen is not None else self.grab()
        if image.isNull() or not image.save(str(path)):
            self.show_error("Cannot save the screenshot", f"{path}: could not write the image")

    def choose_export(self) -> None:
        if self.document is None or self.document.result is None:
            return
        default = Path(self.document.title).with_suffix("").name + "_angles.csv"
        path, _ = QFileDialog.getSaveFileName(self, "Export joint angles", default, "CSV (*.csv)")
        if path:
            try:
                self.document.result.save_csv(path)
            except OSError as error:
                self.show_error("Cannot export", f"{path}: {error.strerror or error}")

    def show_error(self, title: str, message: str) -> None:
        self.statusBar().showMessage(message, 15000)
        QMessageBox.warning(self, title, message)

    def closeEvent(self, event: QCloseEvent) -> None:
        """Cancel and wait for the worker, release the render window."""
        self.timeline.pause()
        self.runner.stop()
        self.viewport.close_viewport()
        super().closeEvent(event)
