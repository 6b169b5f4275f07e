"""A strip of the fusion's per-frame energy terms over the take's frames (under the camera dock's video).

Each term (marker, silhouette, depth, edge; unweighted, as :class:`core.fusion.FusionResult` holds them at
its RGB-D frames) is drawn as a line through its RGB-D frames, scaled to its own largest value so that
terms of different units share the strip; the legend gives each term's value at the RGB-D frame nearest the
current frame. Frames are 0-based mocap frames (fractional for RGB-D frames); a click emits
:attr:`EnergyStrip.frame_clicked`.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QMouseEvent, QPainter, QPaintEvent, QPen, QPolygonF
from PySide6.QtWidgets import QSizePolicy, QWidget

STRIP_HEIGHT_PX = 84
LEGEND_WIDTH_PX = 150
BACKGROUND = QColor(24, 26, 30)
CURSOR_COLOUR = QColor(255, 220, 50)
TERM_COLOURS = {"marker": QColor(90, 200, 255), "silhouette": QColor(120, 230, 120),
                "depth": QColor(255, 150, 80), "edge": QColor(230, 120, 230), "smoothness": QColor(170, 170, 170)}
#: the terms drawn (the smoothness term only ties a frame to the previous one)
SHOWN_TERMS = ("marker", "silhouette", "depth", "edge")
#: units of the terms (:mod:`core.fusion.energy`): marker distance and depth difference mm, edge distance image
#: px, the silhouette term a sum of two shares of area
UNITS = {"marker": " mm", "silhouette": "", "depth": " mm", "edge": " px"}


class EnergyStrip(QWidget):
    """The energy terms ``values (K, T)`` at mocap frames ``frames (K,)`` of a take of ``n_frames``."""

    frame_clicked = Signal(int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setFixedHeight(STRIP_HEIGHT_PX)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
        self.setToolTip("Fusion energy terms per RGB-D frame (each scaled to its largest value); click: go there")
        self.names: tuple[str, ...] = ()
        self.frames = np.zeros(0)
        self.values = np.zeros((0, 0))
        self.n_frames = 1
        self.frame = 0

    def set_terms(self, names: tuple[str, ...], frames: np.ndarray, values: np.ndarray, n_frames: int) -> None:
        """Show ``values (K, len(names))`` at mocap ``frames (K,)`` over a take of ``n_frames``."""
        self.names = tuple(names)
        self.frames = np.asarray(frames, dtype=float)
        self.values = np.asarray(values, dtype=float).reshape(len(self.frames), len(self.names))
        self.n_frames = max(int(n_frames), 1)
        self.update()

    def set_frame(self, frame: int) -> None:
        self.frame = int(frame)
        self.update()

    def shown_terms(self) -> list[int]:
        """Columns of :attr:`values` drawn."""
        return [index for index, name in enumerate(self.names) if name in SHOWN_TERMS]

    def values_at(self, frame: int) -> dict[str, float]:
        """The drawn terms at the RGB-D frame nearest mocap ``frame`` (empty without frames)."""
        if not len(self.frames):
            return {}
        nearest = int(np.argmin(np.abs(self.frames - frame)))
        return {self.names[index]: float(self.values[nearest, index]) for index in self.shown_terms()}

    def plot_rect(self) -> QRectF:
        return QRectF(LEGEND_WIDTH_PX, 4, max(self.width() - LEGEND_WIDTH_PX - 6, 1), self.height() - 8)

    def x_of(self, frame: float) -> float:
        rect = self.plot_rect()
        return rect.left() + rect.width() * frame / max(self.n_frames - 1, 1)

    def mousePressEvent(self, event: QMouseEvent) -> None:
        rect = self.plot_rect()
        if event.button() == Qt.MouseButton.LeftButton and event.position().x() >= rect.left():
            fraction = (event.position().x() - rect.left()) / rect.width()
            self.frame_clicked.emit(int(round(np.clip(fraction, 0, 1) * (self.n_frames - 1))))
        super().mousePressEvent(event)

    def paintEvent(self, _event: QPaintEvent) -> None:
        painter = QPainter(self)
        painter.fillRect(self.rect(), BACKGROUND)
        rect = self.plot_rect()
        painter.setPen(QColor(70, 74, 82))
        painter.drawRect(rect)
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        current = self.values_at(self.frame)
        line_height = max((self.height() - 8) / max(len(SHOWN_TERMS), 1), 10)
        for row, index in enumerate(self.shown_terms()):
            name = self.names[index]
            colour = TERM_COLOURS.get(name, QColor(200, 200, 200))
            column = self.values[:, index]
            top = np.nanmax(column) if np.isfinite(column).any() else 0.0
            scale = top if top > 0 else 1.0
            points = [QPointF(self.x_of(frame), rect.bottom() - rect.height() * value / scale)
                      for frame, value in zip(self.frames, column, strict=True) if np.isfinite(value)]
            painter.setPen(QPen(colour, 1.5))
            painter.drawPolyline(QPolygonF(points))
            painter.drawText(QRectF(4, 4 + row * line_height, LEGEND_WIDTH_PX - 8, line_height),
                             Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter,
                             f"{name} {current[name]:.3g}{UNITS.get(name, '')}" if name in current else name)
        painter.setPen(QPen(CURSOR_COLOUR, 1.0))
        x = self.x_of(self.frame)
        painter.drawLine(QPointF(x, rect.top()), QPointF(x, rect.bottom()))
