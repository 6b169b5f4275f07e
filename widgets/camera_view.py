"""The camera dock's view: one camera frame with the markers drawn over it, and the sync nudges.

The widget knows nothing about takes or cameras: it shows an image array (BGR colour ``(H,W,3) uint8``
or depth ``(H,W)`` mm, 0 = none) and an overlay in image pixels: points ``(N,2)`` with colours, one
selected point ringed, skeleton segments, and outlines (closed polygons, e.g. the rendered silhouette of the
solved hand). Under the frame, an :class:`~widgets.energy_strip.EnergyStrip` shows a fusion's energy terms
(hidden until there is one). The image becomes a :class:`QImage` over the array's own
memory (no copy for colour), and the overlay is painted with :class:`QPainter` on top, scaled with the
image to fit the widget; so a new frame costs a conversion and a paint, nothing more.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QImage, QMouseEvent, QPainter, QPaintEvent, QPen, QPolygonF
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QSizePolicy,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from handmocap.widgets.energy_strip import EnergyStrip
from handmocap.widgets.shortcuts import SHORTCUTS, key_text

POINT_RADIUS_PX = 5.0          # marker circle radius on screen
SELECTED_RADIUS_PX = 9.0       # ring around the selected marker
CLICK_RADIUS_PX = 12.0         # a click this close to a point (on screen) picks it
SELECTED_COLOUR = QColor(255, 220, 50)
SKELETON_COLOUR = QColor(255, 255, 255, 200)
OUTLINE_COLOUR = QColor(60, 255, 200)     # the solved hand's silhouette: a colour no marker state uses
BACKGROUND = QColor(24, 26, 30)


def depth_to_grey(depth_mm: np.ndarray) -> np.ndarray:
    """A depth image ``(H,W)`` mm (0 = none) as grey ``(H,W) uint8``: near is bright, far dark (scaled to the
    frame's 99th percentile), no depth black."""
    valid = depth_mm > 0
    far = float(np.percentile(depth_mm[valid], 99)) if valid.any() else 1.0
    grey = np.clip(255.0 * (1.0 - depth_mm / max(far * 1.05, 1e-6)), 0, 255)
    return np.where(valid, grey, 0).astype(np.uint8)


class ArrayImage(QImage):
    """A QImage that reads a numpy array's memory and keeps that array alive (``array``)."""

    array: np.ndarray


def to_qimage(image: np.ndarray) -> ArrayImage:
    """A QImage over ``image`` (BGR uint8 colour, grey uint8, or depth float mm); the QImage keeps the array
    it reads alive (attribute ``array``)."""
    if image.ndim == 2 and image.dtype != np.uint8:
        image = depth_to_grey(image)
    image = np.ascontiguousarray(image)
    height, width = image.shape[:2]
    if image.ndim == 3:
        qimage = ArrayImage(image.data, width, height, image.strides[0], QImage.Format.Format_BGR888)
    else:
        qimage = ArrayImage(image.data, width, height, image.strides[0], QImage.Format.Format_Grayscale8)
    qimage.array = image
    return qimage


class FrameCanvas(QWidget):
    """The image, fitted to the widget with its aspect ratio, and the overlay (module docstring)."""

    point_clicked = Signal(int)    # index of the overlay point clicked (-1: none near the click)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Expanding)
        self.setMinimumSize(160, 60)    # the dock shares the right column with the tables, even at 1366×768
        self._image: ArrayImage | None = None
        self._pixels = np.zeros((0, 2))
        self._colours = np.zeros((0, 3), dtype=np.uint8)
        self._selected = -1
        self._skeleton = np.zeros((0, 2, 2))
        self._outlines: list[np.ndarray] = []
        self._message = ""
        self.paint_count = 0

    def set_content(self, image: np.ndarray | None, pixels: np.ndarray, colours: np.ndarray, selected: int = -1,
                    skeleton: np.ndarray | None = None, message: str = "") -> None:
        """Show ``image`` (None: ``message`` instead) with ``pixels (N,2)`` image px coloured ``colours (N,3)``
        in [0, 1] (NaN pixels are not drawn), point ``selected`` ringed, ``skeleton (B,2,2)`` px lines."""
        self._image = None if image is None else to_qimage(image)
        self._pixels = np.asarray(pixels, dtype=float).reshape(-1, 2)
        self._colours = np.clip(np.round(np.asarray(colours, dtype=float) * 255), 0, 255).astype(np.uint8)
        self._selected = selected
        self._skeleton = np.zeros((0, 2, 2)) if skeleton is None else np.asarray(skeleton, dtype=float)
        self._message = message
        self._outlines = []
        self.update()

    def set_outlines(self, outlines: list[np.ndarray]) -> None:
        """Draw closed polygons ``(N,2)`` image px over the image (cleared by :meth:`set_content`)."""
        self._outlines = [np.asarray(outline, dtype=float).reshape(-1, 2) for outline in outlines]
        self.update()

    @property
    def outlines(self) -> list[np.ndarray]:
        return self._outlines

    def image_rect(self) -> QRectF:
        """Where the image is drawn in the widget (fitted, centred)."""
        if self._image is None:
            return QRectF()
        width, height = self._image.width(), self._image.height()
        scale = min(self.width() / width, self.height() / height)
        return QRectF((self.width() - width * scale) / 2, (self.height() - height * scale) / 2,
                      width * scale, height * scale)

    def widget_point(self, pixel: np.ndarray) -> QPointF:
        """Widget coordinates of image pixel ``(x, y)`` (OpenCV convention: pixel centres at integers)."""
        if self._image is None:
            raise ValueError("no image is shown: an image pixel has no place in the widget")
        rect = self.image_rect()
        scale = rect.width() / self._image.width()
        return QPointF(rect.left() + (pixel[0] + 0.5) * scale, rect.top() + (pixel[1] + 0.5) * scale)

    def point_at(self, x: float, y: float) -> int:
        """Index of the overlay point nearest widget position (x, y) within :data:`CLICK_RADIUS_PX`, else -1."""
        if self._image is None or not len(self._pixels):
            return -1
        rect = self.image_rect()
        scale = rect.width() / self._image.width()
        screen = np.column_stack([rect.left() + (self._pixels[:, 0] + 0.5) * scale,
                                  rect.top() + (self._pixels[:, 1] + 0.5) * scale])
        distances = np.hypot(screen[:, 0] - x, screen[:, 1] - y)
        distances[~np.isfinite(distances)] = np.inf
        best = int(np.argmin(distances))
        return best if distances[best] <= CLICK_RADIUS_PX else -1

    def mousePressEvent(self, event: QMouseEvent) -> None:
        if event.button() == Qt.MouseButton.LeftButton:
            self.point_clicked.emit(self.point_at(event.position().x(), event.position().y()))
        super().mousePressEvent(event)

    def paintEvent(self, _event: QPaintEvent) -> None:
        self.paint_count += 1
        painter = QPainter(self)
        painter.fillRect(self.rect(), BACKGROUND)
        if self._image is None:
            painter.setPen(QColor(190, 190, 190))
            painter.drawText(self.rect(), Qt.AlignmentFlag.AlignCenter | Qt.TextFlag.TextWordWrap, self._message)
            return
        painter.drawImage(self.image_rect(), self._image)
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        painter.setBrush(Qt.BrushStyle.NoBrush)
        painter.setPen(QPen(OUTLINE_COLOUR, 2.0))
        for outline in self._outlines:
            painter.drawPolygon(QPolygonF([self.widget_point(pixel) for pixel in outline]))
        painter.setPen(QPen(SKELETON_COLOUR, 2.0))
        for start, end in self._skeleton:
            if np.isfinite(start).all() and np.isfinite(end).all():
                painter.drawLine(self.widget_point(start), self.widget_point(end))
        painter.setBrush(Qt.BrushStyle.NoBrush)
        for index in np.flatnonzero(np.isfinite(self._pixels).all(axis=1)):
            centre = self.widget_point(self._pixels[index])
            red, green, blue = (int(v) for v in self._colours[index])
            painter.setPen(QPen(QColor(red, green, blue), 2.0))
            painter.drawEllipse(centre, POINT_RADIUS_PX, POINT_RADIUS_PX)
            if index == self._selected:
                painter.setPen(QPen(SELECTED_COLOUR, 2.5))
                painter.drawEllipse(centre, SELECTED_RADIUS_PX, SELECTED_RADIUS_PX)
        if self._message:
            painter.setPen(QColor(235, 235, 235))
            painter.drawText(self.rect().adjusted(6, 4, -6, -4), Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop,
                             self._message)


class CameraView(QWidget):
    """A camera choice, colour/depth toggle, sync nudges (± one camera frame, ± one mocap frame) and the
    :class:`FrameCanvas`. It asks; the controller decides: :attr:`nudged` (camera frames, mocap frames),
    :attr:`stream_changed`, :attr:`camera_chosen`, :attr:`point_clicked`."""

    point_clicked = Signal(int)
    nudged = Signal(int, int)          # camera frames, mocap frames to add to the clock offset
    stream_changed = Signal(str)       # "colour" or "depth"
    camera_chosen = Signal(int)        # index in the camera choice
    silhouette_toggled = Signal(bool)  # draw the solved hand's rendered silhouette

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.canvas = FrameCanvas(self)
        self.canvas.point_clicked.connect(self.point_clicked)
        self.camera_box = QComboBox(self)
        self.camera_box.setToolTip("Cameras of the shown take (File ▸ Add camera…)")
        self.camera_box.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToContents)
        self.camera_box.setMinimumContentsLength(6)
        self.camera_box.currentIndexChanged.connect(self.camera_chosen)
        self.stream_box = QComboBox(self)
        self.stream_box.addItems(["colour", "depth"])
        self.stream_box.setToolTip("Colour or depth frames of an RGB-D camera")
        self.stream_box.currentTextChanged.connect(self.stream_changed)
        self.nudge_buttons: dict[tuple[int, int], QToolButton] = {}
        bar = QHBoxLayout()
        bar.setContentsMargins(4, 2, 4, 2)
        bar.addWidget(self.camera_box)
        bar.addWidget(self.stream_box)
        sync = QLabel(" Shift video ", self)
        sync.setToolTip("When the video and the markers are out of step: move the video against the markers "
                        "(the camera clock's offset, saved with the camera)")
        bar.addWidget(sync)
        for text, step, name in (("◀◀", (-1, 0), "camera_earlier"), ("◀", (0, -1), "camera_earlier_fine"),
                                 ("▶", (0, 1), "camera_later_fine"), ("▶▶", (1, 0), "camera_later")):
            button = QToolButton(self)
            button.setText(text)
            unit = "camera frame" if step[0] else "mocap frame"
            button.setToolTip(f"{SHORTCUTS[name].what} ({key_text(name)}): the clock offset "
                              f"{'+' if sum(step) > 0 else '−'} one {unit}; saved with the camera")
            button.clicked.connect(lambda _checked=False, step=step: self.nudged.emit(*step))
            bar.addWidget(button)
            self.nudge_buttons[step] = button
        self.offset_label = QLabel("", self)
        # the offset text gives way on a narrow window (the full text stays in its tooltip)
        self.offset_label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        bar.addWidget(self.offset_label, 1)
        self.silhouette_box = QCheckBox("Silhouette", self)
        self.silhouette_box.setToolTip("Outline the solved hand as the camera sees it (rendered from the model)")
        self.silhouette_box.toggled.connect(self.silhouette_toggled)
        bar.addWidget(self.silhouette_box)
        self.energy_strip = EnergyStrip(self)
        self.energy_strip.hide()
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(0)
        layout.addLayout(bar)
        layout.addWidget(self.canvas, 1)
        layout.addWidget(self.energy_strip)
        self.set_cameras([], False)

    def set_cameras(self, names: list[str], has_depth: bool) -> None:
        """List the take's cameras (none: the canvas says how to add one); ``has_depth``: the depth toggle is
        offered."""
        self.camera_box.blockSignals(True)
        self.camera_box.clear()
        self.camera_box.addItems(names)
        self.camera_box.blockSignals(False)
        self.set_has_depth(has_depth)
        for widget in (self.camera_box, *self.nudge_buttons.values()):
            widget.setEnabled(bool(names))
        if not names:
            self.offset_label.setText("")
            self.canvas.set_content(None, np.zeros((0, 2)), np.zeros((0, 3)),
                                    message="No camera for this take.\nFile ▸ Add camera… adds a video and its "
                                            "calibration (JSON or OpenCV YAML).")

    def set_has_depth(self, has_depth: bool) -> None:
        self.stream_box.setEnabled(has_depth)
        if not has_depth:
            self.stream_box.blockSignals(True)
            self.stream_box.setCurrentText("colour")
            self.stream_box.blockSignals(False)

    @property
    def stream(self) -> str:
        return self.stream_box.currentText()

    def set_offset_text(self, text: str) -> None:
        self.offset_label.setText(text)
        self.offset_label.setToolTip(text)
