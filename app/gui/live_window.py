"""File ▸ Connect to live capture…: a window that connects to QTM or Motive, labels each frame live and shows
the labelled points and a supervision panel per hand and object.

The capture (:class:`core.live.capture.LiveCapture`) runs on threads of its own: the source's and the
capture worker's, which journal and label every frame. This window never waits for them: a timer reads the
latest labelled frame (:meth:`LiveCapture.snapshot`) :data:`DRAW_HZ` times a second and draws it, so when
drawing is slower than the stream, draws are dropped, never frames. Stop ends the recording: the take is
written and enters the session (the live labels as its first review step) on a worker, and the end summary
("ring tip missing 38 % of the take: retake?") is shown.

On QTM the window offers capture control (Take control, New, Start, Stop, Save NAME). With "record while QTM
captures" the recording follows QTM's own start and stop (until QTM starts, the points streamed are shown in
grey, not recorded); when QTM stops, the take is written as with Stop. The connection to QTM stays open until
the window closes, so that the measurement can still be saved in QTM after its stop.
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import numpy as np
import pyvista as pv
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QColor
from PySide6.QtOpenGLWidgets import QOpenGLWidget
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QMainWindow,
    QMessageBox,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)
from pyvistaqt import QtInteractor

from handmocap.core.errors import InputError
from handmocap.widgets.dialog_buttons import ok_cancel_buttons

# pyvista types the Plotter methods it defines through functools.wraps (set_background, add_axes, reset_camera)
# as unbound functions, so mypy wants ``self`` passed again: the ``type: ignore``s marked "pyvista wraps" are
# that gap in pyvista's typing.

DRAW_HZ = 30
PANEL_HZ = 5
#: Python's thread switch interval while a live window is open (5 ms by default): the window's thread gets the
#: interpreter back sooner from the capture's threads (measured under load 7: 8-10 -> 11-12 drawn frames/s, and
#: the capture's latency p99 lower too)
SWITCH_INTERVAL_S = 0.001
LIGHT_COLOURS = {"green": "#2e9d44", "amber": "#e0a020", "red": "#d03030"}
MODEL_COLOURS = ["#3b7ddd", "#dd6b3b", "#8e44ad", "#16a085", "#c0392b"]
UNLABELLED = "#9a9a9a"


class ConnectDialog(QDialog):
    """The capture system, its address, the layout and hands, the session and the take's name."""

    def __init__(self, parent: QWidget | None, session: Path | None, layouts: list[str]) -> None:
        super().__init__(parent)
        self.setWindowTitle("Connect to live capture")
        form = QFormLayout(self)
        self.system = QComboBox(self)
        self.system.addItem("Qualisys QTM (real-time protocol)", "qtm")
        self.system.addItem("OptiTrack Motive (NatNet, unicast)", "natnet")
        self.address = QLineEdit("127.0.0.1:22223", self)
        self.system.currentIndexChanged.connect(self._default_address)
        self.layout_box = QComboBox(self)
        self.layout_box.setEditable(True)
        self.layout_box.addItems(layouts)
        self.hands = QComboBox(self)
        self.hands.addItems(["auto", "right", "left", "both"])
        self.session = QLineEdit(str(session) if session else str(Path.home() / "handmocap-live"), self)
        browse = QPushButton("…", self)
        browse.clicked.connect(self._browse)
        row = QHBoxLayout()
        row.addWidget(self.session)
        row.addWidget(browse)
        self.name = QLineEdit(time.strftime("live-%Y%m%d-%H%M%S"), self)
        self.follow = QCheckBox("Record while QTM captures (follow its Start and Stop)", self)
        self.password = QLineEdit(self)
        self.password.setEchoMode(QLineEdit.EchoMode.Password)
        self.password.setPlaceholderText("QTM's real-time control password, if it has one")
        form.addRow("System", self.system)
        form.addRow("Address (host:port)", self.address)
        form.addRow("Layout or template", self.layout_box)
        form.addRow("Hands", self.hands)
        form.addRow("Session folder", row)
        form.addRow("Take name", self.name)
        form.addRow("QTM", self.follow)
        form.addRow("QTM password", self.password)
        form.addRow(ok_cancel_buttons(self, "Connect"))

    def _default_address(self) -> None:
        qtm = self.system.currentData() == "qtm"
        host = self.address.text().rpartition(":")[0] or "127.0.0.1"
        self.address.setText(f"{host}:{22223 if qtm else 1510}")
        self.follow.setEnabled(qtm)
        self.password.setEnabled(qtm)

    def _browse(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Session folder", self.session.text())
        if folder:
            self.session.setText(folder)


class LiveWindow(QMainWindow):
    """The live view and supervision panel of one capture (module docstring)."""

    finished = Signal(object)

    def __init__(self, capture, session: Path, name: str, parent: QWidget | None = None, password: str = "") -> None:
        super().__init__(parent)
        self.capture, self.session, self.name, self.password = capture, session, name, password
        self.setWindowTitle(f"Live capture — {capture.source.label} at {capture.source.address}")
        self.drawn = 0
        self.last_frame = -1
        self._last_snapshot = None
        self._panel_at = -1.0
        self._alarms_shown = 0
        self._stopping = False
        self.result = None
        #: QTM's answers to the control buttons, in order (the status bar shows the last)
        self.answers: list[str] = []
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch_interval, SWITCH_INTERVAL_S))
        splitter = QSplitter(Qt.Orientation.Horizontal, self)
        # no multisampling (8x by default: a software-rendered draw took 150-250 ms) and no 5 Hz auto-render
        # beside the draws of the timer (as the main 3D view, widgets.viewport)
        self.view = QtInteractor(splitter, auto_update=False, multi_samples=0)
        #: VTK renders of the view, and those that showed a frame not shown before (``drawn``)
        self.renders = 0
        self._new_frame = False
        self.view.GetRenderWindow().AddObserver("EndEvent", self._rendered)
        self.view.set_background("#20242a")  # type: ignore[arg-type]  # pyvista wraps
        self.view.add_axes()  # type: ignore[call-arg]  # pyvista wraps
        self.cloud = pv.PolyData(np.zeros((1, 3)))
        self.cloud["colour"] = np.zeros((1, 3), dtype=np.uint8)
        self.view.add_mesh(self.cloud, scalars="colour", rgb=True, point_size=8, render_points_as_spheres=False)
        panel = QWidget(splitter)
        column = QVBoxLayout(panel)
        self.status = QLabel("connecting…", panel)
        self.status.setWordWrap(True)
        column.addWidget(self.status)
        self.table = QTableWidget(0, 6, panel)
        self.table.setHorizontalHeaderLabels(["", "Model", "Labelled now", "Missing now", "Swap suspects",
                                              "Noise (mm)"])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.table.verticalHeader().setVisible(False)
        column.addWidget(self.table, 2)
        column.addWidget(QLabel("Alarms", panel))
        self.alarms = QListWidget(panel)
        column.addWidget(self.alarms, 1)
        buttons = QHBoxLayout()
        self.control_buttons: dict[str, QPushButton] = {}
        self.save_name: QLineEdit | None = None
        if capture.source.kind == "qtm":   # QTM's capture: its buttons on one row, Save as and its name below
            column.addWidget(QLabel("QTM capture", panel))
            control, saving = QHBoxLayout(), QHBoxLayout()
            for text, command in (("Take control", "takecontrol"), ("New", "new"), ("Start", "start"),
                                  ("Stop", "stop"), ("Save as", "save")):
                button = QPushButton(text, panel)
                button.setToolTip(f"QTM: {text.lower()}")
                button.clicked.connect(lambda _checked=False, command=command: self._control(command))
                (saving if command == "save" else control).addWidget(button)
                self.control_buttons[command] = button
            self.save_name = QLineEdit(name, panel)
            self.save_name.setToolTip("the name QTM saves its measurement under")
            saving.addWidget(self.save_name, 1)
            column.addLayout(control)
            column.addLayout(saving)
        self.stop_button = QPushButton("Stop and save the take", panel)
        self.stop_button.clicked.connect(self.stop)
        buttons.addWidget(self.stop_button)
        column.addLayout(buttons)
        splitter.addWidget(self.view)
        splitter.addWidget(panel)
        splitter.setSizes([760, 520])
        self.setCentralWidget(splitter)
        self.resize(1320, 760)
        self.timer = QTimer(self)
        self.timer.timeout.connect(self.draw_latest)
        self.timer.start(int(1000 / DRAW_HZ))
        self._framed = False

    # --- drawing at the window's pace ---------------------------------------------------------------------

    def draw_latest(self) -> None:
        """Draw the latest labelled frame (frames between two draws are skipped, never lost). When the recording
        follows QTM and QTM stopped, the take is written (:meth:`stop`)."""
        if self.capture.ended and not self._stopping:
            self.stop()
        snapshot = self.capture.snapshot()
        if snapshot is None or snapshot is self._last_snapshot:
            return
        self._last_snapshot = snapshot
        self.last_frame = snapshot.frame
        points = np.asarray(snapshot.points, dtype=float).reshape(-1, 3)
        colours = np.tile(_rgb(UNLABELLED), (max(len(points), 1), 1))
        owners = snapshot.model_of_marker
        for marker, point in enumerate(snapshot.assignment):
            if 0 <= point < len(points) and marker < len(owners):
                colours[point] = _rgb(MODEL_COLOURS[int(owners[marker]) % len(MODEL_COLOURS)])
        if len(points):
            cloud = pv.PolyData(points)
            cloud["colour"] = colours[:len(points)]
            self.cloud.shallow_copy(cloud)
            if not self._framed:
                self.view.reset_camera()  # type: ignore[call-arg]  # pyvista wraps
                self._framed = True
            self._new_frame = True
            self._paint()
        self._panel(snapshot)

    def _paint(self) -> None:
        """Have the view render once, in its next paint: the OpenGL widget renders there and shows the result
        (rendering first, then painting, would render twice); off screen, render now."""
        if getattr(self.view, "_off_screen", False):
            self.view.render_now()
        else:
            QOpenGLWidget.update(self.view)

    def _rendered(self, *_arguments: object) -> None:
        self.renders += 1
        if self._new_frame:
            self._new_frame = False
            self.drawn += 1

    def _panel(self, snapshot) -> None:
        """The alarms at every draw; the status line and the table at most :data:`PANEL_HZ` times a second, and
        only the cells whose text changed (each repaint of a widget beside the 3D view costs a composition of
        the window, as much as a render of the view without a graphics card)."""
        if len(snapshot.alarms) != self._alarms_shown:
            self._alarms_shown = len(snapshot.alarms)
            self.alarms.clear()
            self.alarms.addItems(snapshot.alarms[-50:])
            self.alarms.scrollToBottom()
        now = time.monotonic()
        if now - self._panel_at < 1.0 / PANEL_HZ:
            return
        self._panel_at = now
        figures = snapshot.figures
        if not snapshot.recording:
            self.status.setText(f"waiting for {self.capture.source.label} to start a capture (not recording) · "
                                f"{len(snapshot.points)} points streamed")
            return
        latency = figures.get("latency_ms_p99")
        system = figures.get("system_labelled_share")
        text = (f"frame {snapshot.frame + 1} · received {figures.get('frames_received', 0)} · dropped "
                f"{figures.get('frames_dropped', 0)}"
                + (f" · latency p99 {latency:.1f} ms" if latency is not None else
                   " · labelling the start-up window…" if snapshot.statuses else " · finding the hands…")
                + (f" · {figures['frame_rate_hz']:g} Hz" if figures.get("frame_rate_hz") else "")
                + (f" · {self.capture.source.label} labels {100 * system:.0f} % itself" if system is not None
                   else ""))
        self.status.setText(text)
        if self.table.rowCount() != len(snapshot.statuses):
            self.table.setRowCount(len(snapshot.statuses))
        for row, status in enumerate(snapshot.statuses):
            missing = ", ".join(f"{name.replace('_', ' ')} {seconds:.1f} s" for name, seconds in
                                sorted(status.missing.items(), key=lambda item: -item[1])[:4]) or "—"
            texts = [status.light, status.name, f"{100 * status.labelled_share:.0f} %", missing,
                     ", ".join(status.swap_suspects) or "—",
                     "—" if status.noise_mm is None else f"{status.noise_mm:.2f}"]
            for column, text in enumerate(texts):
                item = self.table.item(row, column)
                shown = item.toolTip() if column == 0 and item is not None else item.text() if item else None
                if shown == text:
                    continue
                if column == 0:
                    item = QTableWidgetItem("●")
                    item.setForeground(QColor(LIGHT_COLOURS[status.light]))
                    item.setToolTip(status.light)
                else:
                    item = QTableWidgetItem(text)
                self.table.setItem(row, column, item)

    # --- control and the end --------------------------------------------------------------------------------

    def _control(self, command: str) -> None:
        """Send a capture-control command to QTM; its answer in the status bar, a refusal in one line."""
        argument = self.password if command == "takecontrol" else ""
        if command == "save":
            argument = self.save_name.text().strip() if self.save_name is not None else ""
        try:
            answer = self.capture.control(command, argument)
        except InputError as error:
            QMessageBox.warning(self, "QTM", str(error))
            return
        self.answers.append(answer)
        self.statusBar().showMessage(f"QTM: {answer}", 6000)

    def stop(self) -> None:
        """End the recording; the take is written and enters the session on a worker thread. A QTM connection
        stays open for capture control until the window closes."""
        if self._stopping:
            return
        self._stopping = True
        self.stop_button.setEnabled(False)
        self.stop_button.setText("saving…")
        out = self.session / f"{self.name}.c3d"
        result: dict = {}
        keep = bool(self.control_buttons)

        def work() -> None:
            result["value"] = self.capture.stop(out, disconnect=not keep)

        thread = threading.Thread(target=work, name="live-stop", daemon=True)
        thread.start()

        def wait() -> None:
            if thread.is_alive():
                QTimer.singleShot(100, wait)
                return
            self.timer.stop()
            self._show_result(result.get("value"))
        wait()

    def _show_result(self, result) -> None:
        if result is None:
            return
        self.result = result
        lines = list(result.messages) + list(result.summary)
        figures = result.figures
        head = (f"{figures['frames_received']} frames received, {figures['frames_dropped']} dropped, labelled "
                f"{100 * figures.get('labelled_share', 0):.1f} %")
        where = f"take written to {result.out} and entered into the session" if result.out else "no take written"
        self.status.setText(head + "\n" + where)
        self.stop_button.setText("Stopped")
        if lines:
            self.alarms.addItems(["— end of capture —", *lines])
            self.alarms.scrollToBottom()
        self.finished.emit(result)

    def closeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        if not self._stopping:
            self.stop()
        self.capture.close()
        self.timer.stop()
        self.view.close()
        sys.setswitchinterval(self._switch_interval)
        super().closeEvent(event)


def _rgb(colour: str) -> np.ndarray:
    value = QColor(colour)
    return np.array([value.red(), value.green(), value.blue()], dtype=np.uint8)


def open_live_capture(parent: QWidget, session: Path | None, layouts: list[str]) -> LiveWindow | None:
    """Ask where to connect, connect (one line when it cannot) and show the live window."""
    from handmocap.core.live.capture import LiveCapture
    from handmocap.core.live.systems import make_source
    from handmocap.core.model.lab_template import load_lab_template

    dialog = ConnectDialog(parent, session, layouts)
    if dialog.exec() != QDialog.DialogCode.Accepted:
        return None
    try:
        source = make_source(dialog.system.currentData(), dialog.address.text())
        layout_name = dialog.layout_box.currentText().strip() or "dense"
        layout = load_lab_template(layout_name) or layout_name
        folder = Path(dialog.session.text()).expanduser()
        follow = source.kind == "qtm" and dialog.follow.isChecked()
        capture = LiveCapture(source, layout, dialog.hands.currentText(), session=folder, name=dialog.name.text(),
                              follow_system=follow)
        capture.start()
    except InputError as error:
        QMessageBox.warning(parent, "Connect to live capture", str(error))
        return None
    window = LiveWindow(capture, folder, capture.name, parent, password=dialog.password.text())
    window.show()
    return window
