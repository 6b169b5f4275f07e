"""Cameras in the review: the camera dock (:class:`widgets.camera_view.CameraView`), File ▸ Add camera…,
the camera calibration wizard, the camera's frustum in the 3D view and the sync nudges.

The dock follows the application: the shown take's cameras are read from the session its review lives in
(the open session, or a file's automatic one; :mod:`core.session.cameras`); at every
:class:`~app.gui.application.FrameChanged` the camera frame at the mocap frame's time (through the camera
clock) is shown with the raw points of the take at that camera frame's own time projected over it,
coloured as in the 3D view (by label, unlabelled grey, ghosts dark red), the selected point ringed, the
solved hands' skeletons drawn, and with the dock's Silhouette toggle the outlines
:attr:`CameraController.outline_provider` gives (the fusion controller's rendered silhouette of the solved
hand). Drawing waits for the events queued now (a burst of frames during playback or scrubbing draws the
latest only), and a frame that shows the same camera frame with the same overlay is not drawn again, so
the video never makes playback lag: it drops frames instead.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtWidgets import (
    QDialog,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLineEdit,
    QPushButton,
    QWidget,
)

from handmocap.app.gui.actions import make_action
from handmocap.app.gui.application import (
    Application,
    CurrentDocumentChanged,
    DocumentClosing,
    FrameChanged,
    SelectionChanged,
)
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.colours import point_colours
from handmocap.core.camera.files import load_camera
from handmocap.core.camera.frames import FrameSource, open_frames
from handmocap.core.camera.model import Camera, CameraClock
from handmocap.core.camera.overlay import markers_at
from handmocap.core.errors import HandMocapError, InputError
from handmocap.core.model.skeleton import JOINT_PARENTS
from handmocap.core.review.events import ReviewChanged
from handmocap.core.session import Session
from handmocap.core.session.cameras import TakeCamera, add_camera, save_take_camera, take_cameras
from handmocap.widgets.camera_view import CameraView
from handmocap.widgets.deferred_viewport import DeferredViewport
from handmocap.widgets.dialog_buttons import ok_cancel_buttons

RAW_COLOUR = (0.55, 0.80, 1.00)          # points of a take without labels (the 3D view's marker colour)
FRUSTUM_DEPTH_MM = 150.0                 # how far the frustum reaches when the take has no markers in front
DIGIT_LAST_JOINTS = (3, 6, 9, 12, 15)    # the last joint of each digit (its tip hangs off it)


def frustum_segments(camera: Camera, depth_mm: float = FRUSTUM_DEPTH_MM) -> np.ndarray:
    """Line segments ``(8,2,3)`` mocap mm of ``camera``'s viewing pyramid: the centre to the four image corners
    at ``depth_mm`` and the rectangle joining them."""
    corners = np.array([[0, 0], [camera.width - 1, 0], [camera.width - 1, camera.height - 1],
                        [0, camera.height - 1]], dtype=float)
    far = camera.to_mocap(camera.rays(corners) * depth_mm)
    centre = np.repeat(camera.centre[None], 4, axis=0)
    return np.concatenate([np.stack([centre, far], axis=1), np.stack([far, np.roll(far, -1, axis=0)], axis=1)])


def skeleton_points(document: TakeDocument, frame: int) -> list[np.ndarray]:
    """Bone segments ``(20,2,3)`` mm of each hand solved at ``frame`` (the review's hands, else the IK result)."""
    hands = []
    review = document.review
    if review is not None and document.has_solved_hands():
        hands = [(hand.side, hand.joint_angles[frame]) for hand in review.hands]
    elif document.result is not None:
        hands = [(document.result.hand_side, document.result.joint_angles[frame])]
    bones = []
    for side, theta in hands:
        if not np.isfinite(theta).all():
            continue
        model = document.model_for(side)
        _, positions = model.chain.joint_transforms(theta)
        linear, translation = model.chain.skinning_matrices(theta)
        tips = np.einsum("dab,db->da", linear[list(DIGIT_LAST_JOINTS)], model.skeleton.tip_positions) \
            + translation[list(DIGIT_LAST_JOINTS)]
        starts = np.concatenate([positions[JOINT_PARENTS[1:]], positions[list(DIGIT_LAST_JOINTS)]])
        ends = np.concatenate([positions[1:], tips])
        bones.append(np.stack([starts, ends], axis=1))
    return bones


class AddCameraDialog(QDialog):
    """The frames (a video, a folder of colour frames and/or a folder of 16-bit depth frames with their unit)
    and the camera file (our JSON, or OpenCV's YAML/XML)."""

    def __init__(self, parent: QWidget) -> None:
        super().__init__(parent)
        self.setWindowTitle("Add camera")
        form = QFormLayout(self)
        self.media_edit, self.depth_edit, self.camera_edit = QLineEdit(self), QLineEdit(self), QLineEdit(self)
        form.addRow("Video or frame folder", self._row(self.media_edit, [
            ("Video…", lambda: self._file(self.media_edit, "Videos (*.mp4 *.avi *.mov *.mkv);;All files (*)")),
            ("Folder…", lambda: self._folder(self.media_edit))]))
        form.addRow("Depth folder (RGB-D)", self._row(self.depth_edit, [("Folder…", lambda: self._folder(
            self.depth_edit))]))
        self.unit_box = QDoubleSpinBox(self)
        self.unit_box.setRange(0.001, 100.0)
        self.unit_box.setDecimals(3)
        self.unit_box.setValue(1.0)
        self.unit_box.setSuffix(" mm")
        self.unit_box.setToolTip("Depth of one unit of the 16-bit depth images (e.g. 1 mm, or 0.125 mm)")
        form.addRow("Depth unit", self.unit_box)
        form.addRow("Camera file", self._row(self.camera_edit, [
            ("Browse…", lambda: self._file(self.camera_edit, "Cameras (*.json *.yaml *.yml *.xml)"))]))
        form.addRow(ok_cancel_buttons(self))

    def _row(self, edit: QLineEdit, buttons: list) -> QWidget:
        row = QWidget(self)
        layout = QHBoxLayout(row)
        layout.setContentsMargins(0, 0, 0, 0)
        edit.setMinimumWidth(320)
        layout.addWidget(edit, 1)
        for text, slot in buttons:
            button = QPushButton(text, row)
            button.clicked.connect(slot)
            layout.addWidget(button)
        return row

    def _file(self, edit: QLineEdit, filter_text: str) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Choose a file", edit.text(), filter_text)
        if path:
            edit.setText(path)

    def _folder(self, edit: QLineEdit) -> None:
        path = QFileDialog.getExistingDirectory(self, "Choose a folder", edit.text())
        if path:
            edit.setText(path)

    def choice(self) -> tuple[str | None, str | None, float | None, str]:
        """(media or None, depth folder or None, depth unit mm or None, camera file)."""
        media, depth = self.media_edit.text().strip() or None, self.depth_edit.text().strip() or None
        return media, depth, self.unit_box.value() if depth else None, self.camera_edit.text().strip()


class CameraController(QObject):
    """The shown take's cameras (module docstring). Builds :attr:`view`, :attr:`add_action`,
    :attr:`wizard_action` and the nudge actions; the window places them."""

    status_message = Signal(str, int)
    error_raised = Signal(str, str)
    cameras_loaded = Signal(int)           # the shown take's cameras were read: how many it has

    def __init__(self, app: Application, host: QWidget, viewport: DeferredViewport) -> None:
        super().__init__(host)
        self.app, self.host, self.viewport = app, host, viewport
        self.view = CameraView(host)
        self.view.point_clicked.connect(self.point_clicked)
        self.view.nudged.connect(self.nudge)
        self.view.stream_changed.connect(lambda _stream: self.redraw())
        self.view.camera_chosen.connect(self.choose_camera)
        self.view.silhouette_toggled.connect(lambda _on: self.redraw())
        #: outlines (image px) of the document's solved hands at a mocap frame seen by a camera (None: none drawn)
        self.outline_provider: Callable[[TakeDocument, Camera, int], list[np.ndarray]] | None = None
        self.cameras: list[TakeCamera] = []
        self.index = -1
        self._sources: dict[tuple[str, str], FrameSource] = {}
        self._shown_key: tuple | None = None
        self._draw_timer = QTimer(self)
        self._draw_timer.setSingleShot(True)
        self._draw_timer.setInterval(1)        # not 0: an idle timer never fires while playback keeps Qt busy
        self._draw_timer.timeout.connect(self.draw_now)
        self.add_action = make_action(host, "Add &camera…", self.choose_camera_files)
        self.add_action.setToolTip("Add a camera (video or frames and its calibration) to the shown session take")
        self.wizard_action = make_action(host, "Camera ca&libration…", self.open_wizard)
        self.nudge_actions = [
            make_action(host, text, lambda _checked=False, step=step: self.nudge(*step), shortcut)
            for text, step, shortcut in (("Camera offset − one camera frame", (-1, 0), "camera_earlier"),
                                         ("Camera offset + one camera frame", (1, 0), "camera_later"),
                                         ("Camera offset − one mocap frame", (0, -1), "camera_earlier_fine"),
                                         ("Camera offset + one mocap frame", (0, 1), "camera_later_fine"))]
        app.add_listener(self._follow)
        self.update_enabled()

    # ------------------------------------------------------------------------------ following
    @property
    def document(self) -> TakeDocument | None:
        return self.app.document

    @property
    def camera(self) -> TakeCamera | None:
        """The camera shown in the dock."""
        return self.cameras[self.index] if 0 <= self.index < len(self.cameras) else None

    def _follow(self, event: object) -> None:
        if isinstance(event, CurrentDocumentChanged):
            self.load_cameras()
        elif isinstance(event, DocumentClosing) and event.document is self.document:
            self._close_sources()
        elif isinstance(event, FrameChanged | SelectionChanged) or (
                isinstance(event, ReviewChanged) and event.operation != "clean"):
            self.redraw()

    def session_take(self) -> tuple[Session | None, str | None]:
        """The session the shown take's review lives in and its take id there (None, None: in memory only)."""
        document = self.document
        if document is None or document.open_take is None or document.open_take.closed:
            return None, None
        return document.open_take.session, document.open_take.entry.id

    def load_cameras(self, select: str | None = None) -> None:
        """Read the shown take's cameras again and show the one named ``select`` (default: the first)."""
        self._close_sources()
        session, take_id = self.session_take()
        self.cameras = []
        if session is not None and take_id is not None:
            try:
                self.cameras = take_cameras(session, take_id)
            except HandMocapError as error:
                self.status_message.emit(str(error), 15000)
        names = [camera.name for camera in self.cameras]
        self.index = names.index(select) if select in names else (0 if names else -1)
        self.view.set_cameras(names, False)
        self.view.camera_box.blockSignals(True)
        self.view.camera_box.setCurrentIndex(self.index)
        self.view.camera_box.blockSignals(False)
        self._camera_changed()
        self.cameras_loaded.emit(len(self.cameras))

    def choose_camera(self, index: int) -> None:
        self.index = index
        self._camera_changed()

    def _camera_changed(self) -> None:
        camera = self.camera
        self.view.set_has_depth(camera is not None and camera.depth is not None and camera.depth_unit_mm is not None)
        self._show_frustum()
        self._shown_key = None
        self._show_offset()
        self.update_enabled()
        self.draw_now()

    def _show_frustum(self) -> None:
        """The shown camera's frustum in the 3D view, reaching to the take's markers (hidden when unregistered)."""
        taken, document = self.camera, self.document
        if taken is None or document is None or not taken.camera.registered:
            self.viewport.set_camera_frustum(None)
        else:
            positions = document.take.marker_positions[:: max(1, document.take.n_frames // 50)].reshape(-1, 3)
            depths = taken.camera.to_camera(positions[np.isfinite(positions).all(axis=1)])[:, 2]
            depths = depths[depths > 0]
            self.viewport.set_camera_frustum(frustum_segments(taken.camera, float(np.median(depths)) if len(depths)
                                                              else FRUSTUM_DEPTH_MM))
        self.viewport.request_render()

    def update_enabled(self) -> None:
        session, _ = self.session_take()
        self.add_action.setEnabled(session is not None and not session.read_only)
        for action in self.nudge_actions:
            action.setEnabled(self.camera is not None)

    # ----------------------------------------------------------------------------------- frames
    def source(self) -> FrameSource | None:
        """The colour or depth frames of the shown camera (opened once; None when it has none)."""
        camera = self.camera
        if camera is None:
            return None
        stream = "depth" if self.view.stream == "depth" and camera.depth is not None else "colour"
        key = (camera.name, stream)
        if key not in self._sources:
            path = camera.depth if stream == "depth" else camera.media
            if path is None:
                return None
            source = open_frames(path, depth_unit_mm=camera.depth_unit_mm if stream == "depth" else None)
            if source.size != camera.camera.size:
                source.close()
                raise InputError(f"{path.name} is {source.size[0]}×{source.size[1]} px but camera "
                                 f"'{camera.name}' is {camera.camera.width}×{camera.camera.height}")
            self._sources[key] = source
        return self._sources[key]

    def _close_sources(self) -> None:
        for source in self._sources.values():
            source.close()
        self._sources = {}
        self._shown_key = None

    def redraw(self) -> None:
        """Draw once the events queued now are handled (a burst of frames draws the latest only)."""
        if self.camera is not None and not self._draw_timer.isActive():     # restarting it would starve it
            self._draw_timer.start()

    def camera_frame_at(self, frame: int) -> int:
        """The shown camera's frame index at mocap ``frame`` (0-based) of the shown take."""
        source, taken, document = self.source(), self.camera, self.document
        assert source is not None and taken is not None and document is not None, "no camera frames are shown"
        return source.index_at(float(taken.camera.clock.camera_time(frame / document.take.frame_rate)))

    def draw_now(self) -> None:
        """Show the camera frame at the current mocap frame with its overlay (nothing when unchanged)."""
        self._draw_timer.stop()
        document, taken = self.document, self.camera
        if document is None or taken is None:
            return
        try:
            source = self.source()
            if source is None:
                self.view.canvas.set_content(None, np.zeros((0, 2)), np.zeros((0, 3)),
                                             message=f"Camera '{taken.name}' has no {self.view.stream} frames")
                return
            frame = self.app.frame
            index = self.camera_frame_at(frame)
            key = (taken.name, self.view.stream, index, frame, self.app.selection.column,
                   None if document.review is None else document.review.version, self.view.silhouette_box.isChecked())
            if key == self._shown_key:
                return
            self._shown_key = key
            image = source.frame(index)
        except HandMocapError as error:
            self._shown_key = None
            self.view.canvas.set_content(None, np.zeros((0, 2)), np.zeros((0, 3)), message=str(error))
            return
        camera, take = taken.camera, document.take
        mocap_frame = float(camera.clock.mocap_frame(source.time(index), take.frame_rate))
        skeleton = None
        if camera.registered:
            pixels = camera.project(markers_at(take.marker_positions, mocap_frame))
            bones = skeleton_points(document, min(max(int(round(mocap_frame)), 0), take.n_frames - 1))
            if bones:
                segments = np.concatenate(bones)
                skeleton = camera.project(segments.reshape(-1, 3)).reshape(-1, 2, 2)
        else:
            pixels = np.full((take.n_markers, 2), np.nan)
        text = (f"frame {take.first_frame + frame} · camera image {index + 1} of {len(source)} at "
                f"{source.time(index):.3f} s")
        if not camera.registered:
            text += " · not registered: Tools ▸ Camera calibration… to overlay the markers"
        self.view.canvas.set_content(image, pixels, self.point_colours(frame), self.app.selection.column,
                                     skeleton, text)
        if camera.registered and self.outline_provider is not None and self.view.silhouette_box.isChecked():
            solved_frame = min(max(int(round(mocap_frame)), 0), take.n_frames - 1)
            self.view.canvas.set_outlines(self.outline_provider(document, camera, solved_frame))

    def point_colours(self, frame: int) -> np.ndarray:
        """``(P,3)`` colours of the take's raw points at ``frame``, as the 3D view draws them."""
        document = self.document
        assert document is not None, "no take is shown"     # (draw_now checked)
        review = document.review
        if review is None or not (document.has_labels() or document.is_raw):
            return np.tile(np.array(RAW_COLOUR), (document.take.n_markers, 1))
        return point_colours(review, frame)

    def point_clicked(self, column: int) -> None:
        """Select the raw point ``column`` clicked in the video (-1: nothing near the click clears it)."""
        document = self.document
        if document is None:
            return
        label = document.review.label_of_point(self.app.frame, column) if column >= 0 and document.review else -1
        self.app.select(label, column)

    # ------------------------------------------------------------------------------------- sync
    def nudge(self, camera_frames: int, mocap_frames: int) -> None:
        """Add whole camera and mocap frame periods to the shown camera's clock offset and save the camera."""
        taken, document = self.camera, self.document
        if taken is None or document is None:
            return
        try:
            source = self.source()
            rate = source.frame_rate if source is not None else 30.0
            clock = taken.camera.clock
            offset = clock.offset_s + camera_frames * clock.rate_ratio / rate + mocap_frames / document.take.frame_rate
            self.set_camera(taken.camera.with_clock(CameraClock(offset, clock.rate_ratio)))
        except HandMocapError as error:
            self.error_raised.emit("Cannot change the camera offset", str(error))

    def set_camera(self, camera: Camera) -> None:
        """Replace the shown camera (same name) by ``camera``, saved in the session, and show it."""
        session, take_id = self.session_take()
        if session is None or take_id is None or self.camera is None:
            raise InputError("the shown take is not kept in a session; its camera cannot be saved")
        camera = replace(camera, name=self.camera.name)
        save_take_camera(session, take_id, camera)
        self.cameras[self.index] = replace(self.cameras[self.index], camera=camera)
        self._shown_key = None
        self._show_frustum()
        self._show_offset()
        self.draw_now()

    def _show_offset(self) -> None:
        camera = self.camera
        if camera is None or self.document is None:
            self.view.set_offset_text("")
            return
        offset = camera.camera.clock.offset_s
        self.view.set_offset_text(f" offset {offset:+.4f} s = {offset * self.document.take.frame_rate:+.1f} "
                                  "mocap frames ")

    # ------------------------------------------------------------------------------ add camera
    def choose_camera_files(self) -> None:
        dialog = AddCameraDialog(self.host)
        if dialog.exec() == QDialog.DialogCode.Accepted:
            self.add(*dialog.choice())

    def add(self, media: str | None, depth: str | None, depth_unit_mm: float | None, camera_file: str) -> bool:
        """Add a camera to the shown session take: ``media`` and/or ``depth`` (with its unit), calibration read
        from ``camera_file``; the frames are opened first to check they decode at the camera's size."""
        session, take_id = self.session_take()
        try:
            if session is None or take_id is None:
                raise InputError("open a take first (cameras are kept with a take in its session)")
            if not camera_file:
                raise InputError("choose the camera file (JSON, or OpenCV YAML/XML)")
            camera = load_camera(camera_file)
            for path, unit in ((media, None), (depth, depth_unit_mm)):
                if path:
                    with open_frames(path, depth_unit_mm=unit) as frames:
                        if frames.size != camera.size:
                            raise InputError(f"{Path(path).name} is {frames.size[0]}×{frames.size[1]} px but the "
                                             f"camera is {camera.width}×{camera.height}")
            stored = add_camera(session, take_id, camera, media, depth, depth_unit_mm)
        except HandMocapError as error:
            self.error_raised.emit("Cannot add the camera", str(error))
            return False
        self.load_cameras(select=stored.name)
        document = self.document
        title = document.title if document is not None else "the take"     # (a session take is shown)
        self.status_message.emit(f"camera '{stored.name}' added to {title}", 8000)
        return True

    # ------------------------------------------------------------------------------------ wizard
    def open_wizard(self) -> None:
        """The camera calibration wizard for the shown camera (or a new camera file when there is none)."""
        from handmocap.app.gui.camera_wizard import CameraWizard

        self._wizard = CameraWizard(self.host, self)
        self._wizard.show()

    def close(self) -> None:
        self._draw_timer.stop()
        self._close_sources()
