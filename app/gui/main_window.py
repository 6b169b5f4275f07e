"""The main window: 3D viewport, timeline, marker table, take list; opening takes on a worker.

The window holds the :class:`~app.gui.application.Application` (the open takes, the shown one, the session,
the selection, the running jobs) and places the views of its controllers (review, solve, session). Views follow
the application's events: the window sets up its own views for a shown take first, the controllers
theirs next, then the window draws the frame, so that the review's drawing comes on top of the raw
markers. The current frame is the application's (:attr:`Application.frame`): the timeline sets it and
follows it like every other view.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QAction, QCloseEvent, QDragEnterEvent, QDropEvent, QImage
from PySide6.QtWidgets import (
    QComboBox,
    QDockWidget,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMessageBox,
    QStyle,
    QToolBar,
    QToolButton,
    QWidget,
)

from handmocap.app.gui.actions import make_action
from handmocap.app.gui.application import (
    Application,
    CurrentDocumentChanged,
    DocumentClosed,
    DocumentOpened,
    FrameChanged,
    JobsChanged,
    SessionChanged,
    SessionFolderChanged,
    SessionPart,
    SolveApplied,
)
from handmocap.app.gui.camera_controller import CameraController
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.export_dialog import default_export_path, export_action
from handmocap.app.gui.fusion_controller import FusionController
from handmocap.app.gui.load_queue import LoadQueue
from handmocap.app.gui.loose_takes import loose_document, remembered_frame_rate
from handmocap.app.gui.plots_controller import PlotsController
from handmocap.app.gui.review.controller import ReviewController
from handmocap.app.gui.session_controller import SessionController
from handmocap.app.gui.solve_controller import SOLVE_JOB, SolveChoice, SolveController
from handmocap.app.gui.workers import one_line
from handmocap.core.errors import CancelledError, HandMocapError
from handmocap.core.ik import METHODS
from handmocap.core.io import READ_SUFFIXES, TAKE_FILE_FILTER, FrameRateMissingError, Take, load_take
from handmocap.core.model import layout_names, skin_vertices
from handmocap.core.review.events import ReviewChanged
from handmocap.widgets.deferred_viewport import DeferredViewport
from handmocap.widgets.elided_combo import ElidedComboBox
from handmocap.widgets.frame_rate_dialog import FrameRatePrompt
from handmocap.widgets.marker_panel import MarkerPanel
from handmocap.widgets.message_panel import MessagePanel, PanelLogHandler
from handmocap.widgets.progress_bar import ProgressBar
from handmocap.widgets.shortcuts import bind
from handmocap.widgets.shortcuts_dialog import ShortcutsDialog
from handmocap.widgets.timeline import TimelineWidget
from handmocap.widgets.window_image import save_screenshot, window_image

HAND_SIDES = ("right", "left", "both")
APP_NAME = "Hand Mocap Studio"
HAND_MARKER_COLOUR = (0.55, 0.80, 1.00)     # markers of the hand layout
OTHER_MARKER_COLOUR = (0.62, 0.62, 0.66)    # arm, body and object markers
FRAMING_RADIUS_MM = 90.0                   # half-size of the box the camera frames around the hand
TAKE_SUFFIXES = READ_SUFFIXES
TAKE_FILTER = TAKE_FILE_FILTER
TAKE_NAME_CHARACTERS = 28                  # the take choice's width; longer names are elided in the middle


@dataclass
class OpenedTakes:
    """What an opening task produced: the new documents, one line per file that failed, the files that state
    no frame rate (their rate is asked, then they are opened again) and whether to solve the takes."""

    documents: list[TakeDocument] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    rate_needed: list[Path] = field(default_factory=list)
    solve: bool = False


def _open_files_task(paths: list[Path], solve: bool, rates: dict[Path, float] | None = None) -> Callable:
    """Worker task loading ``paths`` one after the other (at ``rates[path]`` Hz when given, else at the rate the
    file states or the user gave when it was last opened); a bad file is reported, not fatal."""

    def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> OpenedTakes:
        opened = OpenedTakes(solve=solve)
        for index, path in enumerate(paths):
            if cancelled():
                for document in opened.documents:     # release the takes opened in their automatic sessions
                    if document.open_take is not None:
                        document.open_take.close()
                raise CancelledError("opening cancelled")
            try:
                try:
                    take = load_take(path, frame_rate=(rates or {}).get(path))
                except FrameRateMissingError:
                    remembered = remembered_frame_rate(path)
                    if remembered is None:
                        opened.rate_needed.append(path)
                        progress((index + 1) / len(paths))
                        continue
                    take = load_take(path, frame_rate=remembered)
                opened.documents.append(loose_document(path, take, auto_solve=solve))
            except HandMocapError as error:
                opened.errors.append(one_line(str(error)))
            except Exception as error:  # noqa: BLE001 - a file must never crash the application
                opened.errors.append(one_line(f"{path.name}: cannot read it ({type(error).__name__}: {error})"))
            progress((index + 1) / len(paths))
        return opened

    return task


class MainWindow(QMainWindow):
    """Review takes: scrub the markers, solve IK on a worker, watch the hand follow the data."""

    frame_drawn = Signal(int)   # a frame's raw markers were drawn: the review draws its part now

    def __init__(self, off_screen: bool | None = None) -> None:
        super().__init__()
        self.setWindowTitle(APP_NAME)
        self.resize(1500, 950)
        self.setAcceptDrops(True)
        self.app = Application()
        self.app.add_listener(self._set_up_views)        # before the controllers' listeners (module docstring)

        self.loader = LoadQueue(self)         # opening files and session takes, the demo session
        self.loader.failed.connect(lambda message: self.show_error("Cannot open", message))
        self.loader.busy_changed.connect(self._loader_busy_changed)

        self.viewport = DeferredViewport(self, off_screen=off_screen)   # the 3D view, built once the window shows
        self.viewport.marker_clicked.connect(self._marker_clicked)
        self.setCentralWidget(self.viewport)
        self.timeline = TimelineWidget(self)
        self.timeline.frame_changed.connect(self.app.set_frame)
        self.marker_panel = MarkerPanel(self)
        self.marker_panel.marker_selected.connect(self._marker_selected)
        self.timeline_dock = self._add_dock("Timeline", self.timeline, Qt.DockWidgetArea.BottomDockWidgetArea)
        self.markers_dock = self._add_dock("Markers", self.marker_panel, Qt.DockWidgetArea.RightDockWidgetArea)
        self._build_actions()
        self._build_toolbar()
        self._build_status_bar()
        self.loader.started.connect(self.opening_label.setText)
        self.review = ReviewController(self.app, self, self.viewport, self.timeline)
        self.rate_prompt = FrameRatePrompt(self)   # the rate of files that state none, asked once per file
        self.sessions = SessionController(self.app, self, self.loader, self.rate_prompt)
        self.plots = PlotsController(self.app, self)
        self.cameras = CameraController(self.app, self, self.viewport)
        self.fusion = FusionController(self.app, self, self.cameras)
        self.solver = SolveController(self.app, self, self._solve_choice)   # solves a shown take after the others
        self._place_review()
        self._place_sessions()
        self._place_plots()
        self._place_cameras()
        self._place_messages()
        self._connect_controllers()
        self.app.add_listener(self._draw_views)           # after the controllers' listeners
        self.resizeDocks([self.timeline_dock, self.tracks_dock], [140, 190], Qt.Orientation.Vertical)
        self.resizeDocks([self.session_dock, self.markers_dock], [280, 640], Qt.Orientation.Horizontal)
        self._update_enabled()

    @property
    def document(self) -> TakeDocument | None:
        """The shown take."""
        return self.app.document

    # ------------------------------------------------------------------------------------ building
    def _add_dock(self, title: str, widget: QWidget, area: Qt.DockWidgetArea) -> QDockWidget:
        dock = QDockWidget(title, self)
        dock.setObjectName(title)
        dock.setWidget(widget)
        dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable
                         | QDockWidget.DockWidgetFeature.DockWidgetFloatable
                         | QDockWidget.DockWidgetFeature.DockWidgetClosable)
        self.addDockWidget(area, dock)
        return dock

    def _action(self, text: str, slot: Callable, shortcut: str | None = None,
                checkable: bool = False, checked: bool = False,
                icon: QStyle.StandardPixmap | None = None, tooltip: str | None = None) -> QAction:
        return make_action(self, text, slot, shortcut, checkable, checked, icon, tooltip)

    def _build_actions(self) -> None:
        pixmap = QStyle.StandardPixmap
        self.open_action = self._action("&Open…", self.choose_files, "open", icon=pixmap.SP_DialogOpenButton)
        self.demo_action = self._action("Open &demo session", self.open_demo, "demo")
        self.close_take_action = self._action("&Close take", self.close_current_document, "close_take")
        self.screenshot_action = self._action("Save &screenshot…", self.choose_screenshot, "screenshot")
        self.export_action = self._action("&Export joint angles (CSV)…", self.choose_export, "export_angles")
        quit_action = self._action("&Quit", self.close, "quit")
        # the lambda drops Qt's `checked` argument, which solve() would take as its document
        self.solve_action = self._action("&Solve", lambda: self.solver.solve(),  # noqa: PLW0108
                                         "solve", icon=pixmap.SP_BrowserReload)
        self.cancel_action = self._action("&Cancel", self.cancel_work, "cancel", icon=pixmap.SP_BrowserStop)
        self.labels_action = self._action("Marker &names", self.viewport.set_labels_visible, "marker_names", True,
                                          False)
        self.mesh_action = self._action("Hand &mesh", self.viewport.set_mesh_visible, "hand_mesh", True, True)
        self.effectors_action = self._action("&Effectors and residuals", self.viewport.set_effectors_visible,
                                             "effectors", True, True)
        self.grid_action = self._action("Ground &grid", self.viewport.set_grid_visible, "grid", True, True)
        self.frame_action = self._action("&Frame the hand", self.frame_hand, "frame_hand")

        menus = self.menuBar()
        file_menu = self.file_menu = menus.addMenu("&File")
        self.live_action = self._action("Connect to &live capture…", self.open_live_capture)
        for action in (self.open_action, self.demo_action, None, self.live_action, None, self.export_action,
                       self.screenshot_action, None, quit_action):
            if action is None:
                file_menu.addSeparator()
            else:
                file_menu.addAction(action)
        view_menu = self.view_menu = menus.addMenu("&View")
        for action in (self.labels_action, self.mesh_action, self.effectors_action, self.grid_action):
            view_menu.addAction(action)
        view_menu.addSeparator()
        view_menu.addAction(self.frame_action)
        view_menu.addSeparator()
        view_menu.addAction(self.timeline_dock.toggleViewAction())
        view_menu.addAction(self.markers_dock.toggleViewAction())
        playback_menu = menus.addMenu("&Playback")
        for action in self.timeline.transport_actions:
            playback_menu.addAction(action)
        loop_action = QAction("&Loop", self)
        loop_action.setCheckable(True)
        loop_action.setChecked(self.timeline.loop_box.isChecked())
        loop_action.toggled.connect(self.timeline.loop_box.setChecked)
        self.timeline.loop_box.toggled.connect(loop_action.setChecked)
        playback_menu.addSeparator()
        playback_menu.addAction(loop_action)
        tools_menu = self.tools_menu = menus.addMenu("&Tools")
        tools_menu.addAction(self._action("&Calibrate a hand scan…", self.open_calibration, "calibrate_scan"))
        tools_menu.addAction(self._action("Marker &layouts…", self.open_layout_tools, "marker_layouts"))
        tools_menu.addAction(self._action("Learn a labelling &template…", self.open_learn_template))
        tools_menu.addAction(self._action("Fit a hand to a &depth frame…", self.open_depth_fit))
        solve_menu = self.solve_menu = menus.addMenu("&Solve")
        solve_menu.addAction(self.solve_action)
        solve_menu.addAction(self.cancel_action)
        self.help_menu = menus.addMenu("&Help")
        self.shortcuts_action = self._action("&Keyboard shortcuts", self.show_shortcuts, "shortcuts")
        self.help_menu.addAction(self.shortcuts_action)

    def _build_toolbar(self) -> None:
        toolbar = QToolBar("Main", self)
        toolbar.setObjectName("main-toolbar")
        toolbar.setMovable(False)
        toolbar.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        self.addToolBar(toolbar)
        toolbar.addAction(self.open_action)
        toolbar.addSeparator()
        toolbar.addWidget(QLabel(" Take "))
        self.take_box = ElidedComboBox(self, "Open takes: switch between them; each keeps its solve and frame")
        self.take_box.setMinimumContentsLength(TAKE_NAME_CHARACTERS)
        self.take_box.currentIndexChanged.connect(self._take_chosen)
        toolbar.addWidget(self.take_box)
        toolbar.addSeparator()
        toolbar.addWidget(QLabel(" Layout "))
        self.layout_box = QComboBox(self)
        self.layout_box.addItems(layout_names())
        self.layout_box.setToolTip("Marker layout of the hand model; markers are matched to it by name")
        self.layout_box.currentTextChanged.connect(self._layout_chosen)
        toolbar.addWidget(self.layout_box)
        self.side_box = QComboBox(self)
        self.side_box.addItems(list(HAND_SIDES))
        self.side_box.setToolTip("Which hand the model fits (the left hand mirrors the right template); both: "
                                 "each hand of a two-hand take (R_/L_, a lab template's or a vendor's names)")
        self.side_box.currentTextChanged.connect(self._side_chosen)
        toolbar.addWidget(QLabel(" Hand "))
        toolbar.addWidget(self.side_box)
        toolbar.addWidget(QLabel(" Method "))
        self.method_box = QComboBox(self)
        self.method_box.addItems(list(METHODS))
        self.method_box.setToolTip("layered: PCA subspace, then all 26 parameters with the soft prior;\n"
                                   "subspace: PCA subspace only; full: all 26 parameters")
        toolbar.addWidget(self.method_box)
        toolbar.addAction(self.solve_action)
        toolbar.addAction(self.cancel_action)

    def _build_status_bar(self) -> None:
        status = self.statusBar()
        self.info_label = QLabel("No take open — File ▸ Open… or File ▸ Open demo session", self)
        self.info_label.setContentsMargins(6, 0, 6, 0)
        status.addPermanentWidget(self.info_label)
        self.opening_label = QLabel("Opening…", self)
        status.addPermanentWidget(self.opening_label)
        self.progress_bar = ProgressBar(self)
        self.progress_bar.setRange(0, 100)
        self.progress_bar.setFixedWidth(220)
        self.progress_bar.setFormat("Solving… %p %")
        status.addPermanentWidget(self.progress_bar)
        self.cancel_button = QToolButton(self)
        self.cancel_button.setDefaultAction(self.cancel_action)
        self.cancel_button.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        status.addPermanentWidget(self.cancel_button)
        for widget in (self.opening_label, self.progress_bar, self.cancel_button):
            widget.hide()

    def _place_review(self) -> None:
        """The review's docks (Labels and Gaps beside Markers, Tracks under the timeline), menus, toolbar."""
        review, area = self.review, Qt.DockWidgetArea
        self.labels_dock = self._add_dock("Labels", review.table, area.RightDockWidgetArea)
        self.tabifyDockWidget(self.markers_dock, self.labels_dock)
        self.tracks_dock = self._add_dock("Tracks", review.lanes, area.BottomDockWidgetArea)
        self.splitDockWidget(self.timeline_dock, self.tracks_dock, Qt.Orientation.Vertical)
        self.gaps_dock = self._add_dock("Gaps", review.gaps_panel, area.RightDockWidgetArea)
        self.tabifyDockWidget(self.labels_dock, self.gaps_dock)
        self.labels_dock.raise_()
        menus = self.menuBar()
        menus.insertMenu(menus.actions()[1], review.edit_menu)       # after File
        menus.insertMenu(menus.actions()[-1], review.review_menu)    # before Solve
        for dock in (self.labels_dock, self.tracks_dock, self.gaps_dock):
            self.view_menu.addAction(dock.toggleViewAction())
        self.addToolBarBreak()                   # a line of its own: at 1366 px both do not fit in one
        self.addToolBar(review.toolbar)
        self.file_menu.insertAction(self.export_action, self.close_take_action)
        self.file_menu.insertMenu(self.export_action, review.export_menu)
        self.export_dialog_action = export_action(self, review)
        self.file_menu.insertAction(review.export_menu.menuAction(), self.export_dialog_action)

    def _place_sessions(self) -> None:
        """The session browser dock (shown while a session is open) and the session actions."""
        sessions = self.sessions
        self.session_dock = self._add_dock("Session", sessions.browser, Qt.DockWidgetArea.LeftDockWidgetArea)
        self.session_dock.hide()
        first = self.file_menu.actions()[0]
        for action in (sessions.new_action, sessions.open_action, sessions.add_action, sessions.process_action,
                       sessions.close_action):
            self.file_menu.insertAction(first, action)
        self.file_menu.insertSeparator(first)
        self.view_menu.addAction(self.session_dock.toggleViewAction())

    def _place_cameras(self) -> None:
        """The camera dock under the marker tabs (shown when the shown take has a camera), File ▸ Add camera…,
        Tools ▸ Camera calibration… and the sync nudge shortcuts."""
        cameras = self.cameras
        self.camera_dock = self._add_dock("Camera", cameras.view, Qt.DockWidgetArea.RightDockWidgetArea)
        self.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, self.camera_dock, Qt.Orientation.Vertical)
        self.camera_dock.hide()

        def show_dock(count: int) -> None:
            """The camera dock for a take with cameras; hidden for one without (the tabs above get the room)."""
            if count and not self.camera_dock.isVisible():
                self.camera_dock.show()
                self.resizeDocks([self.markers_dock, self.camera_dock], [300, 520], Qt.Orientation.Vertical)
            elif not count and self.camera_dock.isVisible():
                self.camera_dock.hide()

        cameras.cameras_loaded.connect(show_dock)
        self.file_menu.insertAction(self.sessions.close_action, cameras.add_action)
        self.tools_menu.addAction(cameras.wizard_action)
        self.addActions(cameras.nudge_actions)
        self.view_menu.addAction(self.camera_dock.toggleViewAction())
        cameras.status_message.connect(self.statusBar().showMessage)
        cameras.error_raised.connect(self.show_error)

    def _place_plots(self) -> None:
        """The trajectory plots dock (View ▸ Plots), hidden at first, tabbed with the tracks under the timeline."""
        self.plots_dock = self._add_dock("Plots", self.plots.plots, Qt.DockWidgetArea.BottomDockWidgetArea)
        self.tabifyDockWidget(self.tracks_dock, self.plots_dock)
        self.plots_dock.hide()
        bind(self.plots_dock.toggleViewAction(), "plots", "Trajectory plots of the selected labels")
        self.view_menu.addAction(self.plots_dock.toggleViewAction())

    def _place_messages(self) -> None:
        """The message panel (View ▸ Messages), tabbed with the tracks: warnings of reading and labelling takes
        land there (logging and Python warnings while the window is open), counted in the status bar."""
        self.message_panel = MessagePanel(self)
        self.messages_dock = self._add_dock("Messages", self.message_panel, Qt.DockWidgetArea.BottomDockWidgetArea)
        self.tabifyDockWidget(self.tracks_dock, self.messages_dock)
        self.tracks_dock.raise_()
        self.view_menu.addAction(self.messages_dock.toggleViewAction())
        self.messages_button = QToolButton(self)
        self.messages_button.setAutoRaise(True)
        self.messages_button.setToolTip("Warnings of reading and labelling the takes: show the message panel")

        def show_messages() -> None:
            self.messages_dock.show()
            self.messages_dock.raise_()
        self.messages_button.clicked.connect(show_messages)
        self.messages_button.hide()
        self.statusBar().insertPermanentWidget(0, self.messages_button)
        self.message_panel.count_changed.connect(self._messages_counted)
        self.log_handler = PanelLogHandler(self.message_panel)
        self.log_handler.install()

    def _messages_counted(self, count: int) -> None:
        self.messages_dock.setWindowTitle(f"Messages ({count})" if count else "Messages")
        self.messages_button.setText(f"⚠ {count}")
        self.messages_button.setVisible(count > 0)

    def _connect_controllers(self) -> None:
        """Show what the controllers tell, and pass on what one asks of the other."""
        review, sessions = self.review, self.sessions
        self.solve_menu.insertAction(self.cancel_action, self.fusion.fuse_action)
        for controller in (review, self.solver, sessions, self.fusion):
            controller.status_message.connect(self.statusBar().showMessage)
            controller.error_raised.connect(self.show_error)
        for worker in (review, self.solver, self.fusion):
            worker.progress_started.connect(self.show_progress)
            worker.progressed.connect(self.set_progress)
            worker.progress_ended.connect(self.hide_progress)
        review.auto_label_applied.connect(sessions.keep_labelling)
        review.exported.connect(sessions.export_done)
        sessions.auto_label_requested.connect(review.start_auto_label)
        self.frame_drawn.connect(review.draw_frame)

    # ---------------------------------------------------------------------------------- documents
    def choose_files(self) -> None:
        """Ask for take files and open them."""
        paths, _ = QFileDialog.getOpenFileNames(self, "Open takes", "", TAKE_FILTER)
        if paths:
            self.open_files(paths)

    def open_files(self, paths: Sequence[str | Path], solve: bool = False, frame_rate: float | None = None) -> None:
        """Open take files on the loader thread; each good one becomes a take in the take list (solved
        at once when ``solve``), reviewed in an automatic session of its own (:mod:`app.gui.loose_takes`),
        each bad one a one-line message; what is open stays open (a file open already is shown).
        ``frame_rate`` (Hz, ``handmocap gui --rate``) is every file's rate; without it, the rate of a file
        that states none is asked."""
        files = []
        for path in map(Path, paths):
            document = self.app.document_of_file(path)
            if document is None:
                files.append(path)
            else:
                self.app.show(document)
        if not files:
            return
        title = files[0].name if len(files) == 1 else f"{len(files)} takes"
        rates = dict.fromkeys(files, frame_rate) if frame_rate is not None else None
        self.loader.queue(f"Opening {title}…", _open_files_task(files, solve, rates), self._apply_opened)

    def open_demo(self) -> None:
        """Open the demo session (made on the loader thread the first time): the labelled takes are
        solved with IK and the raw take is auto-labelled, one after the other."""
        from handmocap.app.gui.demo import prepare_demo_session

        self.loader.queue("Preparing the demo session…", lambda progress, cancelled: prepare_demo_session(),
                          self._demo_ready)

    def _demo_ready(self, folder: Path) -> None:
        if self.sessions.open_session(folder) and self.sessions.session is not None:
            for entry in self.sessions.session.takes:
                self.sessions.open_take(entry.id, automatic=True)

    def _apply_opened(self, opened: OpenedTakes) -> None:
        if opened.documents:
            first = len(self.app.documents)
            for document in opened.documents:
                self.app.open_document(document)
            self.app.show(self.app.documents[first])
        self.solver.solve_next_pending()
        if opened.errors:
            self.show_error("Cannot open", "\n".join(opened.errors))
        if opened.rate_needed:
            QTimer.singleShot(0, lambda: self._open_at_asked_rates(opened.rate_needed, opened.solve))

    def _open_at_asked_rates(self, paths: list[Path], solve: bool) -> None:
        """Ask the frame rate of each file in ``paths`` (they state none), then open those given one."""
        rates = {}
        for path in paths:
            rate = self.rate_prompt.ask(path)
            if rate is None:
                self.statusBar().showMessage(f"{path.name} not opened: it states no frame rate", 15000)
            else:
                rates[path] = rate
        if rates:
            title = next(iter(rates)).name if len(rates) == 1 else f"{len(rates)} takes"
            self.loader.queue(f"Opening {title}…", _open_files_task(list(rates), solve, rates), self._apply_opened)

    def add_document(self, document: TakeDocument) -> None:
        """Add an open take to the take list and show it."""
        self.app.open_document(document)
        self.app.show(document)

    def _take_chosen(self, index: int) -> None:
        if 0 <= index < len(self.app.documents) and self.app.documents[index] is not self.document:
            self.app.show(self.app.documents[index])

    # ----------------------------------------------------------------------------- following the app
    def _set_up_views(self, event: object) -> None:
        """The window's part before the controllers': the take list, a shown take's markers, table and
        timeline, the session dock, the actions."""
        if isinstance(event, DocumentOpened):
            document = event.document
            self.take_box.blockSignals(True)
            self.take_box.addItem(document.title)
            self.take_box.setItemData(self.take_box.count() - 1, str(document.take.source_path or document.title),
                                      Qt.ItemDataRole.ToolTipRole)
            self.take_box.blockSignals(False)
        elif isinstance(event, DocumentClosed):
            self.take_box.blockSignals(True)
            self.take_box.removeItem(event.index)
            self.take_box.blockSignals(False)
            self._update_enabled()
        elif isinstance(event, CurrentDocumentChanged):
            if event.document is None:
                self._show_no_take()
            else:
                self._set_up_take(event.document)
        elif isinstance(event, FrameChanged):
            if self.timeline.frame != event.frame:     # not when the timeline itself moved (playback goes on)
                self.timeline.set_frame(event.frame)
            self.show_frame(event.frame)
        elif isinstance(event, SessionChanged):
            self.session_dock.setVisible(event.session is not None)
            if event.session is not None:
                self.session_dock.raise_()
            self.refresh_layout_names()
        elif isinstance(event, SessionFolderChanged) and event.what & SessionPart.LAYOUTS:
            self.refresh_layout_names()
        elif isinstance(event, JobsChanged):
            self._update_enabled()

    def _draw_views(self, event: object) -> None:
        """The window's part after the controllers': draw the frame of a newly shown take (and point the
        camera at its hand), or the frame again after a change of its review or a solve of it."""
        document = self.document
        if document is None:
            return
        if isinstance(event, CurrentDocumentChanged):
            self._show_review_residuals()
            self._show_result_geometry()
            self.show_frame(self.app.frame)
            self.frame_hand()
            self._update_enabled()
        elif isinstance(event, ReviewChanged) and event.operation != "clean":
            self._show_review_residuals()
            self.show_frame(self.app.frame)
            self._update_enabled()
        elif isinstance(event, SolveApplied):
            if event.document is document:
                self._show_result_geometry()
                self.timeline.set_residuals(document.mean_residual_per_frame())
                self.show_frame(self.app.frame)
            self._update_enabled()

    def _set_up_take(self, document: TakeDocument) -> None:
        """Show ``document``'s markers, table and timeline at the frame it was left at, and its IK result."""
        take = document.take
        self.take_box.blockSignals(True)
        self.take_box.setCurrentIndex(self.app.documents.index(document))
        self.take_box.blockSignals(False)
        if document.layout_name:
            self.layout_box.blockSignals(True)
            if self.layout_box.findText(document.layout_name) < 0:   # a template file outside the layout folders
                self.layout_box.addItem(document.layout_name)
            self.layout_box.setCurrentText(document.layout_name)
            self.layout_box.blockSignals(False)
        self.side_box.blockSignals(True)
        self.side_box.setCurrentText(document.side)
        self.side_box.blockSignals(False)
        colours = self._marker_colours(document)
        self.viewport.set_markers(take.marker_names, take.marker_positions[0], colours)
        self.marker_panel.set_markers(take.marker_names, document.observed_fraction, colours)
        self._show_result_geometry()
        self.timeline.blockSignals(True)
        self.timeline.set_take(take.n_frames, take.first_frame, take.frame_rate, document.markers_seen)
        self.timeline.set_frame(self.app.frame)
        self.timeline.blockSignals(False)
        self.timeline.set_residuals(document.mean_residual_per_frame())
        self.info_label.setText(self._take_summary(take))
        self.setWindowTitle(f"{document.title} — {APP_NAME}")

    def _show_no_take(self) -> None:
        self.viewport.set_markers([], np.zeros((0, 3)))
        self.viewport.set_hand_mesh(None)
        self.viewport.set_effectors(None)
        self.marker_panel.set_markers([], np.zeros(0), np.zeros((0, 3)))
        self.info_label.setText("No take open — File ▸ Open… or File ▸ Open demo session")
        self.setWindowTitle(APP_NAME)
        self.viewport.request_render()
        self._update_enabled()

    def _show_review_residuals(self) -> None:
        """The timeline's residual curve from the review's solved hands, when it has some."""
        document = self.document
        if document is not None and document.has_solved_hands():
            self.timeline.set_residuals(document.review_residual_per_frame())

    def _marker_colours(self, document: TakeDocument) -> np.ndarray:
        colours = np.tile(OTHER_MARKER_COLOUR, (document.take.n_markers, 1))
        colours[document.hand_columns()] = HAND_MARKER_COLOUR
        return colours

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
        current = hand[self.app.frame]
        current = current[np.isfinite(current).all(axis=1)]
        if len(current) >= 3:
            self.viewport.frame_bounds(current, min_radius=FRAMING_RADIUS_MM * 1.3)
        else:
            self.viewport.frame_bounds(everything)
        self.viewport.request_render()

    # --------------------------------------------------------------------------------------- frame
    def show_frame(self, frame: int) -> None:
        """Show ``frame`` (0-based): markers, table values, the review's drawing (:attr:`frame_drawn`), and
        the IK result's hand when the review has no solved hand. The 3D view redraws once the events
        waiting now are handled, so fast scrubbing skips frames."""
        document = self.document
        if document is None or not 0 <= frame < document.take.n_frames:
            return
        positions = document.take.marker_positions[frame]
        self.viewport.update_markers(positions)
        self.marker_panel.set_frame_values(positions, document.residuals_per_take_marker(frame))
        self.frame_drawn.emit(frame)
        if document.result is not None and not document.has_solved_hands():
            theta = document.result.joint_angles[frame]
            if np.isfinite(theta).all():
                self.viewport.update_hand_vertices(skin_vertices(document.model_for(document.result.hand_side), theta))
            targets = document.effector_targets(frame)
            assert targets is not None, "a solve has effectors"     # (document.result: it has results)
            self.viewport.set_effectors(*targets)
        self.viewport.request_render()

    def _show_result_geometry(self) -> None:
        """The IK result's hand surface, unless the review's solved hands are drawn (by the review)."""
        document = self.document
        if document is not None and document.has_solved_hands():
            return
        if document is None or document.result is None:
            self.viewport.set_hand_mesh(None)
            self.viewport.set_effectors(None)
            return
        model = document.model_for(document.result.hand_side)
        self.viewport.set_hand_mesh(model.vertices, model.faces)

    def _marker_selected(self, row: int) -> None:
        self.viewport.set_selected_marker(None if row < 0 else row)
        self.viewport.request_render()

    def _marker_clicked(self, index: int) -> None:
        self.marker_panel.select_marker(index)

    def _side_chosen(self, side: str) -> None:
        if self.document is not None and side:
            self.document.side = side

    def _layout_chosen(self, name: str) -> None:
        if self.document is not None and name:
            self.document.layout_name = name
            colours = self._marker_colours(self.document)
            self.viewport.set_marker_colours(colours)
            self.marker_panel.set_markers(self.document.take.marker_names, self.document.observed_fraction,
                                          colours)
            self.show_frame(self.app.frame)

    # --------------------------------------------------------------------------------------- solve
    def _solve_choice(self) -> SolveChoice:
        """The toolbar's layout, hand and method, for the solve of the shown take."""
        return SolveChoice(self.layout_box.currentText(), self.side_box.currentText(), self.method_box.currentText())

    def cancel_work(self) -> None:
        """Stop what the progress bar shows: the IK solve, or the review job (auto-label, fill, re-solve)."""
        job = self.app.jobs.get(SOLVE_JOB) or next(iter(self.app.jobs.values()), None)
        if job is not None:
            job.cancel()

    def _loader_busy_changed(self, busy: bool) -> None:
        self.opening_label.setVisible(busy)
        self._update_enabled()

    def _update_enabled(self) -> None:
        document = self.document
        self.solve_action.setEnabled(document is not None and self.solver.solving() is not document)
        self.cancel_action.setEnabled(self.app.is_busy())
        self.export_action.setEnabled(document is not None and document.result is not None)
        self.frame_action.setEnabled(document is not None)
        self.close_take_action.setEnabled(document is not None)

    def is_busy(self) -> bool:
        """Whether takes are being opened or solved."""
        return self.loader.is_busy() or self.app.is_busy()

    # ------------------------------------------------------------------------------ review jobs
    def show_progress(self, text: str) -> None:
        """Show the status-bar progress bar for a review job (its Cancel stops it)."""
        self.progress_bar.setFormat(text)
        self.progress_bar.setValue(0)
        self.progress_bar.show()
        self.cancel_button.show()
        self.cancel_action.setEnabled(True)

    def set_progress(self, fraction: float) -> None:
        self.progress_bar.setValue(int(round(100 * fraction)))

    def hide_progress(self) -> None:
        if not self.solver.is_busy():
            self.progress_bar.hide()
            self.cancel_button.hide()
            self.progress_bar.setFormat("Solving… %p %")
        self._update_enabled()

    def refresh_layout_names(self) -> None:
        """List the shipped layouts and those of the open session in the layout choice."""
        current = self.layout_box.currentText()
        self.layout_box.blockSignals(True)
        self.layout_box.clear()
        self.layout_box.addItems(layout_names())
        self.layout_box.setCurrentText(current)
        self.layout_box.blockSignals(False)

    def open_layout_tools(self) -> None:
        """The marker layout window: optimise, compare, save into the session, print a placement sheet."""
        from handmocap.app.gui.layout_view import open_layout_view

        session = self.sessions.session
        self._layout_window = open_layout_view(self, session=session,
                                               save_to_session=self.sessions.save_layout if session else None)

    def open_live_capture(self) -> None:
        """Connect to QTM or Motive and supervise a capture live; the take enters the open session."""
        from handmocap.app.gui.live_window import open_live_capture
        from handmocap.core.model import layout_names

        session = self.app.session
        folder = session.folder if session is not None else None
        self._live_window = open_live_capture(self, folder, layout_names())

    def open_learn_template(self) -> None:
        """Learn a lab's labelling template from labelled takes; it is saved into the session's layouts."""
        from handmocap.app.gui.learn_template import open_learn_template

        self._learn_template_dialog = open_learn_template(self, self.app, self.sessions.browser.selected_take())

    def open_depth_fit(self) -> None:
        """The single depth-frame fit (``handmocap depth fit``): the fitted hand drawn on the depth, trusted or not."""
        from handmocap.app.gui.depth_fit_dialog import open_depth_fit

        self._depth_fit_dialog = open_depth_fit(self)

    def open_calibration(self) -> None:
        """The scan calibration wizard; the subject model it saves goes into the open session."""
        from handmocap.app.gui.calibration_wizard import open_calibration_wizard

        session = self.app.session
        self._calibration_wizard = open_calibration_wizard(
            self, session, save_subject=self.app.save_subject_model if session is not None else None)

    def show_shortcuts(self) -> None:
        """Help ▸ Keyboard shortcuts: every key of the one shortcut table (:mod:`widgets.shortcuts`)."""
        if getattr(self, "_shortcuts_dialog", None) is None:
            self._shortcuts_dialog = ShortcutsDialog(self)
        self._shortcuts_dialog.show()
        self._shortcuts_dialog.raise_()

    def close_current_document(self) -> None:
        if self.document is not None:
            self.close_document(self.document)

    def close_document(self, document: TakeDocument) -> None:
        """Close an open take (a session take is saved first); another open take is shown."""
        problem = self.app.close_document(document)
        if problem:
            self.show_error("Cannot save", problem)

    # -------------------------------------------------------------------------------------- output
    def choose_screenshot(self) -> None:
        """Ask for a PNG path and save the window there."""
        path, _ = QFileDialog.getSaveFileName(self, "Save screenshot", "handmocap.png", "PNG images (*.png)")
        if path:
            self.save_screenshot(path)

    def window_image(self) -> QImage:
        """The whole window as an image, with the 3D view drawn in (it renders through OpenGL)."""
        return window_image(self, [self.viewport])

    def save_screenshot(self, path: str | Path) -> bool:
        """Save the whole window as a PNG; shows the reason and returns False when it cannot."""
        return save_screenshot(self.window_image(), path, self.show_error)

    def choose_export(self) -> None:
        """Ask for a CSV path and write the current take's joint angles there."""
        if self.document is None or self.document.result is None:
            return
        default = default_export_path(self.document.ensure_review(), self.document.title, "_angles", ".csv")
        path, _ = QFileDialog.getSaveFileName(self, "Export joint angles", str(default), "CSV (*.csv)")
        if path:
            try:
                self.document.result.save_csv(path)
            except OSError as error:
                self.show_error("Cannot export", f"{path}: {error.strerror or error}")

    def show_error(self, title: str, message: str) -> None:
        """Tell the operator what went wrong (message box and status bar)."""
        self.statusBar().showMessage(message.splitlines()[0] if message else title, 15000)
        QMessageBox.warning(self, title, message)

    # -------------------------------------------------------------------------------------- events
    def dragEnterEvent(self, event: QDragEnterEvent) -> None:
        """Accept take files dragged onto the window."""
        if any(url.toLocalFile().lower().endswith(TAKE_SUFFIXES) for url in event.mimeData().urls()):
            event.acceptProposedAction()

    def dropEvent(self, event: QDropEvent) -> None:
        """Open the take files dropped onto the window."""
        paths = [url.toLocalFile() for url in event.mimeData().urls()
                 if url.toLocalFile().lower().endswith(TAKE_SUFFIXES)]
        if paths:
            self.open_files(paths)
            event.acceptProposedAction()

    def closeEvent(self, event: QCloseEvent) -> None:
        """Cancel and wait for the workers, release the render window."""
        self.log_handler.remove()
        self.timeline.pause()
        self.sessions.close()
        self.solver.stop()
        self.loader.stop()
        self.review.stop()
        self.fusion.close()
        self.viewport.close_viewport()
        super().closeEvent(event)
