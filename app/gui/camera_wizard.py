"""The camera calibration wizard: intrinsics from board images, extrinsics from the take's markers, the
clock offset (sync); each step on a :class:`~app.gui.workers.TaskRunner` with progress and Cancel.

Steps are tabs: 1 Intrinsics (ChArUco or chessboard images: every view's corners and RMS error, which views
were rejected, the coverage hint), 2 Extrinsics (the shown camera's video registered against the shown take's
markers: pose and clock, :func:`core.camera.registration.register_take`; or from a marked board filmed in the
video, :func:`core.camera.extrinsics.register_from_board`), 3 Offset (the clock offset of a
registered camera searched around the current one, :func:`core.camera.sync.sync_markers`). The worker
reads its own copies (images, its own video reader); a step's result replaces the wizard's camera only on
the GUI thread. Save writes the camera: into the session with the take (the shown camera), else to a
camera file chosen by the operator; both are durable writes.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol, TypeVar

import numpy as np
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.workers import TaskRunner
from handmocap.core.camera.extrinsics import Blobs, Registration, detect_blobs, register_from_board
from handmocap.core.camera.files import save_camera
from handmocap.core.camera.frames import open_frames
from handmocap.core.camera.intrinsics import (
    BOARD_KINDS,
    BoardSpec,
    IntrinsicCalibration,
    calibrate_intrinsics,
    detect_board,
    detect_board_in_files,
)
from handmocap.core.camera.model import Camera
from handmocap.core.camera.overlay import markers_at
from handmocap.core.camera.registration import TakeRegistration, register_take
from handmocap.core.camera.sync import SyncResult, sync_markers
from handmocap.core.errors import CancelledError, HandMocapError, InputError
from handmocap.core.io import Take
from handmocap.core.io.documents import read_document
from handmocap.core.io.input_schemas import BOARD_MARKERS
from handmocap.core.session.cameras import TakeCamera
from handmocap.widgets.file_row import browse_row
from handmocap.widgets.progress_bar import ProgressBar


class CameraHost(Protocol):
    """What the wizard needs of the window's camera controller (``CameraController``): the shown take and
    camera, and where a calibrated camera is kept."""

    @property
    def document(self) -> TakeDocument | None: ...

    @property
    def camera(self) -> TakeCamera | None: ...

    def set_camera(self, camera: Camera) -> None: ...


IMAGE_FILTER = "Board images (*.png *.jpg *.jpeg)"
#: video frames searched for the marked board (evenly spread over the video)
BOARD_FRAMES = 60
METHODS = ("the take's markers", "a marked board")
T = TypeVar("T")


@dataclass
class Intrinsics:
    """An intrinsic calibration and the corners found in each image (0: the board was not found)."""

    calibration: IntrinsicCalibration
    corners: list[int]


def intrinsics_task(paths: list[Path], spec: BoardSpec, name: str) -> Callable:
    """Worker task: detect the board in every image, then calibrate (:class:`Intrinsics`)."""

    def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> Intrinsics:
        def before(index: int) -> None:
            if cancelled():
                raise CancelledError("intrinsic calibration cancelled")
            progress(0.9 * index / len(paths))

        detections, size = detect_board_in_files(paths, spec, before)
        result = calibrate_intrinsics(detections, size, name=name)
        progress(1.0)
        return Intrinsics(result, [0 if detection is None else len(detection.ids) for detection in detections])

    return task


@dataclass
class VideoBlobs:
    """The marker blobs of every frame of a video and the frames' times (s)."""

    blobs: list[Blobs]
    times: np.ndarray


def _video_blobs(camera: Camera, media: Path, progress: Callable[[float], None], cancelled: Callable[[], bool],
                 share: float) -> VideoBlobs:
    """Blobs of every frame of ``media`` (its own reader: the dock's is the GUI thread's); progress to ``share``."""
    blobs = []
    with open_frames(media) as video:
        if video.size != camera.size:
            raise InputError(f"{media.name} is {video.size[0]}×{video.size[1]} px but the camera is "
                             f"{camera.width}×{camera.height}")
        for index in range(video.count):
            if cancelled():
                raise CancelledError("cancelled")
            blobs.append(detect_blobs(camera, video.frame(index)))
            progress(share * (index + 1) / video.count)
        return VideoBlobs(blobs, video.timestamps.copy())


def registration_task(camera: Camera, media: Path, positions: np.ndarray, mocap_rate: float,
                      window_s: float) -> Callable:
    """Worker task: pose and clock of ``camera`` from its video ``media`` against the take's ``positions
    (F,M,3)`` mm (:class:`TakeRegistration`)."""

    return _blobs_then(camera, media, 0.7, lambda found: register_take(camera, found.blobs, found.times, positions,
                                                                      mocap_rate, window_s))


def _blobs_then(camera: Camera, media: Path, share: float, solve: Callable[[VideoBlobs], T]) -> Callable:
    """Worker task: the blobs of every frame of ``media`` (progress up to ``share``), then ``solve(blobs)``."""

    def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> T:
        result = solve(_video_blobs(camera, media, progress, cancelled, share))
        progress(1.0)
        return result

    return task


def read_board_markers(path: str | Path, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The marked board's file ``{"markers": {"<take marker name>": [x, y, z], ...}}`` (board frame, mm):
    ``(columns (B,) of those markers in the take's ``names``, points (B,3) mm)``; InputError (one line)."""
    path = Path(path)
    markers = read_document(path, "board marker file", BOARD_MARKERS)["markers"]
    points = np.array([markers[name] for name in markers], dtype=float)
    missing = [name for name in markers if name not in names]
    if missing:
        raise InputError(f"{path.name}: the take has no marker {', '.join(missing[:5])}")
    if len(points) < 3 or points.shape[1:] != (3,) or not np.isfinite(points).all():
        raise InputError(f"{path.name}: the board needs at least 3 markers with 3 finite coordinates (mm)")
    return np.array([names.index(name) for name in markers]), points


def board_task(camera: Camera, media: Path, spec: BoardSpec, columns: np.ndarray, board_points: np.ndarray,
               positions: np.ndarray, mocap_rate: float) -> Callable:
    """Worker task: pose of ``camera`` from its video's views of a board carrying the markers ``columns`` of the
    take's ``positions (F,M,3)`` mm at ``board_points (B,3)`` mm on the board, paired through the camera's clock
    (:class:`Registration`)."""

    def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> Registration:
        detections, markers = [], []
        with open_frames(media) as video:
            if video.size != camera.size:
                raise InputError(f"{media.name} is {video.size[0]}×{video.size[1]} px but the camera is "
                                 f"{camera.width}×{camera.height}")
            chosen = np.unique(np.linspace(0, video.count - 1, min(BOARD_FRAMES, video.count)).astype(int))
            for number, index in enumerate(chosen):
                if cancelled():
                    raise CancelledError("cancelled")
                detections.append(detect_board(video.frame(index), spec))
                frame = float(camera.clock.mocap_frame(video.time(index), mocap_rate))
                markers.append(markers_at(positions, frame)[columns])
                progress(0.9 * (number + 1) / len(chosen))
        result = register_from_board(camera, detections, board_points, np.array(markers))
        progress(1.0)
        return result

    return task


def offset_task(camera: Camera, media: Path, positions: np.ndarray, mocap_rate: float, window_s: float) -> Callable:
    """Worker task: the clock of the registered ``camera`` searched within ±``window_s`` (:class:`SyncResult`)."""

    return _blobs_then(camera, media, 0.9, lambda found: sync_markers(camera, found.blobs, found.times, positions,
                                                                     mocap_rate, window_s))


class CameraWizard(QDialog):
    """The wizard (module docstring); ``controller`` gives the shown take and camera and keeps the result."""

    progress_bar: ProgressBar     # (made with the pages, after the worker that reports to it)

    def __init__(self, parent: QWidget, controller: CameraHost) -> None:
        super().__init__(parent)
        self.controller = controller
        taken = controller.camera
        self.camera: Camera | None = None if taken is None else taken.camera
        self.media = None if taken is None else taken.media
        self.image_paths: list[Path] = []
        self.setWindowTitle("Camera calibration" + ("" if taken is None else f" — {taken.name}"))
        self.resize(760, 620)
        self.runner = TaskRunner(self)
        self.runner.progressed.connect(lambda _request, fraction: self.progress_bar.setValue(round(100 * fraction)))
        self.runner.succeeded.connect(self._succeeded)
        self.runner.failed.connect(self._failed)
        self.runner.cancelled.connect(lambda _request: self._ended("cancelled: nothing changed"))
        self.runner.busy_changed.connect(self._busy_changed)
        self._step = ""

        self.tabs = QTabWidget(self)
        self.tabs.addTab(self._intrinsics_page(), "1 Intrinsics")
        self.tabs.addTab(self._extrinsics_page(), "2 Extrinsics")
        self.tabs.addTab(self._offset_page(), "3 Offset")
        self.camera_label = QLabel(self)
        self.camera_label.setWordWrap(True)
        self.status_label = QLabel("", self)
        self.status_label.setWordWrap(True)
        self.progress_bar = ProgressBar(self)
        self.progress_bar.setRange(0, 100)
        self.cancel_button = QPushButton("Cancel", self)
        self.cancel_button.clicked.connect(self.runner.cancel)
        self.save_button = QPushButton("Save camera", self)
        self.save_button.clicked.connect(lambda: self.save())  # noqa: PLW0108 (drops Qt's `checked`, not a path)
        close_button = QPushButton("Close", self)
        close_button.clicked.connect(self.close)
        bottom = QHBoxLayout()
        bottom.addWidget(self.progress_bar, 1)
        bottom.addWidget(self.cancel_button)
        bottom.addStretch(0)
        bottom.addWidget(self.save_button)
        bottom.addWidget(close_button)
        layout = QVBoxLayout(self)
        layout.addWidget(self.tabs, 1)
        layout.addWidget(self.camera_label)
        layout.addWidget(self.status_label)
        layout.addLayout(bottom)
        self._busy_changed(False)
        self._show_camera()

    # ------------------------------------------------------------------------------------ pages
    def _intrinsics_page(self) -> QWidget:
        page = QWidget(self)
        form = QFormLayout()
        self.board_box = QComboBox(page)
        self.board_box.addItems(list(BOARD_KINDS))
        self.columns_box, self.rows_box = QSpinBox(page), QSpinBox(page)
        for box, value in ((self.columns_box, 7), (self.rows_box, 5)):
            box.setRange(3, 40)
            box.setValue(value)
        squares = QHBoxLayout()
        squares.addWidget(self.columns_box)
        squares.addWidget(QLabel("×"))
        squares.addWidget(self.rows_box)
        squares.addStretch(1)
        self.square_box, self.marker_box = QDoubleSpinBox(page), QDoubleSpinBox(page)
        for length_box, length in ((self.square_box, 30.0), (self.marker_box, 22.0)):
            length_box.setRange(0.1, 1000.0)
            length_box.setValue(length)
            length_box.setSuffix(" mm")
        self.dictionary_edit = QLineEdit("DICT_4X4_50", page)
        self.images_button = QPushButton("Choose board images…", page)
        self.images_button.clicked.connect(self.choose_images)
        self.images_label = QLabel("no images chosen", page)
        form.addRow("Board", self.board_box)
        form.addRow("Squares", squares)
        form.addRow("Square side", self.square_box)
        form.addRow("ArUco marker side", self.marker_box)
        form.addRow("ArUco dictionary", self.dictionary_edit)
        images = QHBoxLayout()
        images.addWidget(self.images_button)
        images.addWidget(self.images_label, 1)
        form.addRow("Images", images)
        self.calibrate_button = QPushButton("Calibrate intrinsics", page)
        self.calibrate_button.clicked.connect(self.start_intrinsics)
        form.addRow(self.calibrate_button)
        self.views_table = QTableWidget(0, 4, page)
        self.views_table.setHorizontalHeaderLabels(["Image", "Corners", "Error (px)", "Used"])
        self.views_table.horizontalHeader().setStretchLastSection(True)
        self.views_table.setColumnWidth(0, 260)
        self.views_table.verticalHeader().setVisible(False)
        self.coverage_label = QLabel("", page)
        self.coverage_label.setWordWrap(True)
        layout = QVBoxLayout(page)
        layout.addLayout(form)
        layout.addWidget(self.views_table, 1)
        layout.addWidget(self.coverage_label)
        return page

    def _extrinsics_page(self) -> QWidget:
        form = QFormLayout()
        self.method_box = QComboBox(self)
        self.method_box.addItems(list(METHODS))
        self.method_box.setToolTip("A marked board: a ChArUco board (step 1's board) carrying markers the mocap "
                                   "measures, filmed by the camera; its marker file gives their board positions")
        form.addRow("From", self.method_box)
        self.register_window_box = self._window_box(self, 1.0)
        form.addRow("Offset search (± s)", self.register_window_box)
        self.board_file_edit = QLineEdit(self)
        self.board_file_edit.setPlaceholderText('{"markers": {"<take marker name>": [x, y, z] mm on the board}}')
        form.addRow("Board marker file", browse_row(self.board_file_edit, self.choose_board_file, self))
        page, self.register_button, self.register_label = self._step_page(
            "Registers the camera to the mocap space. From the take's markers: the bright marker blobs "
            "of every video frame are matched to the projected markers (P3P hypotheses, then PnP) and the "
            "clock offset is found with the pose; a registered camera is refined from its pose, an "
            "unregistered one is searched for around its current clock offset (nudge it close in the "
            "camera dock first). From a marked board: the board (step 1's) is found in the video frames, "
            "its markers' mocap positions at those frames (through the clock) place it in the mocap "
            "space, and one PnP over all its corners gives the pose.", form, "Register", self.start_registration)
        return page

    def _offset_page(self) -> QWidget:
        form = QFormLayout()
        self.offset_window_box = self._window_box(self, 0.5)
        form.addRow("Search (± s)", self.offset_window_box)
        page, self.offset_button, self.offset_label = self._step_page(
            "Searches the clock offset of a registered camera around the current one: the projected "
            "markers against the detected blobs of every video frame. The dock's nudge buttons move it by "
            "hand.", form, "Estimate the offset", self.start_offset)
        return page

    def _step_page(self, intro: str, form: QFormLayout, action: str, start: Callable[[], None]
                   ) -> tuple[QWidget, QPushButton, QLabel]:
        """A step's tab: the ``intro`` text, the step's ``form``, its button (``action`` runs ``start``) and the
        label its result is shown in."""
        page = QWidget(self)
        layout = QVBoxLayout(page)
        text = QLabel(intro, page)
        text.setWordWrap(True)
        layout.addWidget(text)
        layout.addLayout(form)
        button = QPushButton(action, page)
        button.clicked.connect(start)
        layout.addWidget(button)
        label = QLabel("", page)
        label.setWordWrap(True)
        layout.addWidget(label)
        layout.addStretch(1)
        return page, button, label

    @staticmethod
    def _window_box(parent: QWidget, value: float) -> QDoubleSpinBox:
        box = QDoubleSpinBox(parent)
        box.setRange(0.05, 10.0)
        box.setSingleStep(0.1)
        box.setValue(value)
        box.setSuffix(" s")
        return box

    # ------------------------------------------------------------------------------------ steps
    def choose_images(self) -> None:
        paths, _ = QFileDialog.getOpenFileNames(self, "Board images", "", IMAGE_FILTER)
        if paths:
            self.set_images(paths)

    def set_images(self, paths: Sequence[str | Path]) -> None:
        self.image_paths = [Path(path) for path in paths]
        self.images_label.setText(f"{len(paths)} images" + (f" ({self.image_paths[0].parent})" if paths else ""))

    def board_spec(self) -> BoardSpec:
        return BoardSpec(self.board_box.currentText(), (self.columns_box.value(), self.rows_box.value()),
                         self.square_box.value(), self.marker_box.value(), self.dictionary_edit.text().strip())

    def start_intrinsics(self) -> None:
        try:
            if not self.image_paths:
                raise InputError("choose the board images first")
            spec = self.board_spec()
        except InputError as error:
            self.status_label.setText(str(error))
            return
        name = self.camera.name if self.camera is not None else "camera"
        self._start("intrinsics", intrinsics_task(list(self.image_paths), spec, name), "Calibrating intrinsics")

    def _take_inputs(self) -> tuple[Camera, Path, Take, tuple[np.ndarray, float]] | None:
        """The camera, its video, the shown take and what a registration task reads of it (marker positions,
        frame rate); None (and why, in the status line) when one is missing."""
        document = self.controller.document
        if document is None or self.camera is None or self.media is None:
            self.status_label.setText("the shown take needs a camera with a video (File ▸ Add camera…)")
            return None
        return self.camera, self.media, document.take, (document.take.marker_positions.copy(), document.take.frame_rate)

    def choose_board_file(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Board marker file", "", "Board markers (*.json)")
        if path:
            self.board_file_edit.setText(path)

    def start_registration(self) -> None:
        taken = self._take_inputs()
        if taken is None:
            return
        camera, media, take, inputs = taken
        if self.method_box.currentText() == METHODS[0]:
            self._start("extrinsics", registration_task(camera, media, *inputs,
                                                        self.register_window_box.value()), "Registering")
            return
        try:
            spec = self.board_spec()
            columns, points = read_board_markers(self.board_file_edit.text().strip(),
                                                 take.marker_names)
        except InputError as error:
            self.status_label.setText(str(error))
            return
        self._start("extrinsics", board_task(camera, media, spec, columns, points, *inputs),
                    "Registering from the board")

    def start_offset(self) -> None:
        taken = self._take_inputs()
        if taken is None:
            return
        camera, media, _take, inputs = taken
        if not camera.registered:
            self.status_label.setText("register the camera first (step 2)")
            return
        self._start("offset", offset_task(camera, media, *inputs, self.offset_window_box.value()),
                    "Estimating the offset")

    def _start(self, step: str, task: Callable, text: str) -> None:
        self._step = step
        self.status_label.setText(f"{text}…")
        self.progress_bar.setValue(0)
        self.runner.start(task)

    def _succeeded(self, _request: int, result: object) -> None:
        if isinstance(result, Intrinsics):
            self._show_intrinsics(result)
            result, previous = result.calibration, self.camera
            camera = result.camera
            if previous is not None:
                camera = replace(camera, name=previous.name, clock=previous.clock)
            self.camera = camera
            self._ended(f"intrinsics from {int(result.used.sum())} of {len(result.used)} images: RMS "
                        f"{result.reprojection_px:.3f} px (the camera is not registered until step 2)", done=True)
        elif isinstance(result, TakeRegistration):
            report = result.report()
            self.camera = result.camera
            self.register_label.setText(
                f"reprojection {report['reprojection_px']:.3f} px over {report['matches']} matches "
                f"({100 * report['matched_share']:.0f} % of the blobs); offset {report['offset_s']:+.4f} s, "
                f"rate ratio {report['rate_ratio']:.5f}, sync quality {report['quality']:.2f}")
            self._ended("registered: Save camera keeps it", done=True)
        elif isinstance(result, Registration):
            report = result.report()
            self.camera = result.camera
            self.register_label.setText(f"reprojection {report['reprojection_px']:.3f} px over {report['matches']} "
                                        f"board corners; board markers fit to {report['residual_mm']:.2f} mm RMS")
            self._ended("registered from the board: Save camera keeps it", done=True)
        elif isinstance(result, SyncResult):
            assert self.camera is not None, "the offset task had a camera"
            self.camera = self.camera.with_clock(result.clock)
            self.offset_label.setText(f"offset {result.offset_s:+.4f} s = {result.offset_frames:+.2f} mocap frames, "
                                      f"rate ratio {result.rate_ratio:.5f}, quality {result.quality:.2f}")
            self._ended("offset estimated: Save camera keeps it", done=True)
        self._show_camera()

    def _show_intrinsics(self, intrinsics: Intrinsics) -> None:
        """Every view's corners, RMS error and whether it was used; the coverage hint."""
        result, table = intrinsics.calibration, self.views_table
        table.setRowCount(len(self.image_paths))
        for row, path in enumerate(self.image_paths):
            error = result.view_errors[row]
            found = intrinsics.corners[row] > 0
            if not found:
                shown = "board not found"
            elif np.isfinite(error):
                shown = f"{error:.3f}"
            else:
                shown = "—"                          # no error known: never in a fit
            cells = (path.name, str(intrinsics.corners[row]), shown,
                     "yes" if result.used[row] else (f"left out (above {result.threshold_px:.2f} px)" if found
                                                     else "—"))
            for column, text in enumerate(cells):
                table.setItem(row, column, QTableWidgetItem(text))
        table.resizeRowsToContents()
        self.coverage_label.setText(f"Coverage: {result.report()['coverage_hint']} · rejection threshold "
                                    f"{result.threshold_px:.3f} px")

    def _failed(self, _request: int, message: str) -> None:
        self._ended(f"failed: {message}")

    def _ended(self, text: str, done: bool = False) -> None:
        """A step ended: its outcome in words; the bar full when it was done, empty when it failed or was
        cancelled."""
        self.status_label.setText(text)
        self.progress_bar.setValue(100 if done else 0)

    def _busy_changed(self, busy: bool) -> None:
        self.cancel_button.setEnabled(busy)
        for button in (self.calibrate_button, self.register_button, self.offset_button, self.save_button):
            button.setEnabled(not busy)
        self.save_button.setEnabled(not busy and self.camera is not None)

    def _show_camera(self) -> None:
        camera = self.camera
        if camera is None:
            self.camera_label.setText("No camera yet: calibrate the intrinsics (step 1).")
        else:
            (fx, fy), (cx, cy) = camera.focal, camera.principal_point
            pose = f"at {np.array2string(camera.centre, precision=0)} mm" if camera.registered else "not registered"
            self.camera_label.setText(f"Camera '{camera.name}': {camera.width}×{camera.height} px, f {fx:.1f}, "
                                      f"{fy:.1f} px, principal point {cx:.1f}, {cy:.1f} px, {pose}, offset "
                                      f"{camera.clock.offset_s:+.4f} s")
        self.save_button.setEnabled(camera is not None and not self.runner.is_busy())

    def save(self, path: str | Path | None = None) -> bool:
        """Keep the camera: the shown take's camera in the session, else a camera file (``path`` or asked)."""
        if self.camera is None:
            return False
        try:
            if self.controller.camera is not None:
                self.controller.set_camera(self.camera)
                self.status_label.setText(f"saved camera '{self.controller.camera.name}' with the take")
                return True
            if not path:
                path, _ = QFileDialog.getSaveFileName(self, "Save camera", "camera.json", "Camera (*.json)")
            if not path:
                return False
            save_camera(self.camera, path)
            self.status_label.setText(f"saved {path}: File ▸ Add camera… adds it to a take with its video")
        except HandMocapError as error:
            self.status_label.setText(f"cannot save: {error}")
            return False
        return True

    def closeEvent(self, event) -> None:
        self.runner.stop()
        super().closeEvent(event)
