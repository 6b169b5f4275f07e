"""Timeline: transport controls (play/pause, step, speed, loop), frame box and a scrubbable plot of how
many markers are observed per frame (pyqtgraph). Emits :attr:`TimelineWidget.frame_changed` with the
0-based frame index; shows the file's own frame numbers."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QElapsedTimer, Qt, QTimer, Signal
from PySide6.QtGui import QKeySequence, QShortcut
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QHBoxLayout,
    QLabel,
    QSpinBox,
    QStyle,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0)
TICK_MS = 15


class TimelineWidget(QWidget):
    """Frame navigation for one take; playback follows real time at ``frame_rate × speed`` and skips
    frames when drawing is slower than the take."""

    frame_changed = Signal(int)
    playing_changed = Signal(bool)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._n_frames = 0
        self._first_frame = 1
        self._frame_rate = 100.0
        self._frame = 0
        self._play_origin_frame = 0
        self._clock = QElapsedTimer()
        self._timer = QTimer(self)
        self._timer.setInterval(TICK_MS)
        self._timer.timeout.connect(self._advance)
        self._build()
        self.set_take(0, 1, 100.0, np.zeros(0))

    # ------------------------------------------------------------------------------------ building
    def _button(self, icon: QStyle.StandardPixmap, tip: str, slot) -> QToolButton:
        button = QToolButton(self)
        button.setIcon(self.style().standardIcon(icon))
        button.setToolTip(tip)
        button.setAutoRaise(True)
        button.clicked.connect(slot)
        return button

    def _build(self) -> None:
        controls = QHBoxLayout()
        controls.setContentsMargins(4, 2, 4, 0)
        self.first_button = self._button(QStyle.StandardPixmap.SP_MediaSkipBackward, "First frame (Home)",
                                         lambda: self.set_frame(0))
        self.back_button = self._button(QStyle.StandardPixmap.SP_MediaSeekBackward, "Previous frame (←)",
                                        lambda: self.step(-1))
        self.play_button = self._button(QStyle.StandardPixmap.SP_MediaPlay, "Play / pause (Space)",
                                        self.toggle_playing)
        self.forward_button = self._button(QStyle.StandardPixmap.SP_MediaSeekForward, "Next frame (→)",
                                           lambda: self.step(1))
        self.last_button = self._button(QStyle.StandardPixmap.SP_MediaSkipForward, "Last frame (End)",
                                        lambda: self.set_frame(self._n_frames - 1))
        for button in (self.first_button, self.back_button, self.play_button, self.forward_button,
                       self.last_button):
            controls.addWidget(button)
        controls.addSpacing(8)
        controls.addWidget(QLabel("Frame"))
        self.frame_box = QSpinBox(self)
        self.frame_box.setKeyboardTracking(False)
        self.frame_box.valueChanged.connect(lambda value: self.set_frame(value - self._first_frame))
        controls.addWidget(self.frame_box)
        self.time_label = QLabel(self)
        self.time_label.setMinimumWidth(150)
        controls.addWidget(self.time_label)
        controls.addStretch(1)
        controls.addWidget(QLabel("Speed"))
        self.speed_box = QComboBox(self)
        for speed in SPEEDS:
            self.speed_box.addItem(f"{speed:g}×", speed)
        self.speed_box.setCurrentIndex(SPEEDS.index(1.0))
        self.speed_box.currentIndexChanged.connect(self._restart_clock)
        controls.addWidget(self.speed_box)
        self.loop_box = QCheckBox("Loop", self)
        self.loop_box.setChecked(True)
        controls.addWidget(self.loop_box)

        self.plot = pg.PlotWidget(self)
        self.plot.setBackground((30, 32, 36))
        self.plot.setMouseEnabled(x=True, y=False)
        self.plot.setMenuEnabled(False)
        self.plot.hideButtons()
        self.plot.setLabel("left", "markers seen")
        self.plot.showGrid(x=True, y=False, alpha=0.25)
        self.plot.setMaximumHeight(120)
        self._observed_curve = self.plot.plot(pen=pg.mkPen((120, 190, 255), width=1.5),
                                              fillLevel=0, brush=(70, 120, 180, 70))
        self._cursor = pg.InfiniteLine(angle=90, movable=True, pen=pg.mkPen((255, 200, 60), width=2),
                                       hoverPen=pg.mkPen((255, 230, 120), width=3))
        self._cursor.sigPositionChanged.connect(self._cursor_moved)
        self.plot.addItem(self._cursor)
        self.plot.scene().sigMouseClicked.connect(self._plot_clicked)

        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(0)
        layout.addLayout(controls)
        layout.addWidget(self.plot)

        for key, slot in ((Qt.Key.Key_Left, lambda: self.step(-1)), (Qt.Key.Key_Right, lambda: self.step(1)),
                          (Qt.Key.Key_Space, self.toggle_playing), (Qt.Key.Key_Home, lambda: self.set_frame(0)),
                          (Qt.Key.Key_End, lambda: self.set_frame(self._n_frames - 1))):
            shortcut = QShortcut(QKeySequence(key), self.window() or self)
            shortcut.setContext(Qt.ShortcutContext.ApplicationShortcut)
            shortcut.activated.connect(slot)

    # ------------------------------------------------------------------------------------- public
    @property
    def frame(self) -> int:
        """Current 0-based frame index."""
        return self._frame

    @property
    def n_frames(self) -> int:
        return self._n_frames

    @property
    def speed(self) -> float:
        return float(self.speed_box.currentData())

    def is_playing(self) -> bool:
        return self._timer.isActive()

    def set_take(self, n_frames: int, first_frame: int, frame_rate: float, markers_seen: np.ndarray) -> None:
        """Show a take of ``n_frames`` at ``frame_rate`` Hz whose first frame is numbered ``first_frame``;
        ``markers_seen (F,)``: observed marker count per frame for the overview plot."""
        self.pause()
        self._n_frames, self._first_frame, self._frame_rate = n_frames, first_frame, frame_rate
        self.frame_box.blockSignals(True)
        self.frame_box.setRange(first_frame, first_frame + max(n_frames - 1, 0))
        self.frame_box.blockSignals(False)
        frames = np.arange(len(markers_seen))
        self._observed_curve.setData(frames, np.asarray(markers_seen, dtype=float))
        self.plot.setLimits(xMin=-1, xMax=max(n_frames, 2))
        self.plot.setXRange(0, max(n_frames - 1, 1), padding=0.01)
        self.plot.setYRange(0, max(float(np.max(markers_seen, initial=0)), 1.0) * 1.1, padding=0)
        for widget in (self.first_button, self.back_button, self.play_button, self.forward_button,
                       self.last_button, self.frame_box, self._cursor):
            widget.setEnabled(n_frames > 0)
        self._frame = -1
        self.set_frame(0)

    def set_frame(self, frame: int) -> None:
        """Go to 0-based ``frame`` (clamped); emits :attr:`frame_changed` when it changes. During
        playback, playback continues from there."""
        self._show(frame)
        if self.is_playing():
            self._restart_clock()

    def _show(self, frame: int) -> None:
        if self._n_frames == 0:
            return
        frame = int(np.clip(frame, 0, self._n_frames - 1))
        if frame == self._frame:
            return
        self._frame = frame
        self.frame_box.blockSignals(True)
        self.frame_box.setValue(frame + self._first_frame)
        self.frame_box.blockSignals(False)
        self._cursor.blockSignals(True)
        self._cursor.setValue(frame)
        self._cursor.blockSignals(False)
        self.time_label.setText(f"{frame / self._frame_rate:8.3f} s  / {self._n_frames / self._frame_rate:.2f} s")
        self.frame_changed.emit(frame)

    def step(self, frames: int) -> None:
        """Move by ``frames`` (negative: back); stops playback."""
        self.pause()
        self.set_frame(self._frame + frames)

    def play(self) -> None:
        if self._n_frames < 2 or self.is_playing():
            return
        if self._frame >= self._n_frames - 1:
            self.set_frame(0)
        self._restart_clock()
        self._timer.start()
        self.play_button.setIcon(self.style().standardIcon(QStyle.StandardPixmap.SP_MediaPause))
        self.playing_changed.emit(True)

    def pause(self) -> None:
        if not self.is_playing():
            return
        self._timer.stop()
        self.play_button.setIcon(self.style().standardIcon(QStyle.StandardPixmap.SP_MediaPlay))
        self.playing_changed.emit(False)

    def toggle_playing(self) -> None:
        self.pause() if self.is_playing() else self.play()

    # ------------------------------------------------------------------------------------ private
    def _restart_clock(self) -> None:
        self._play_origin_frame = self._frame
        self._clock.restart()

    def _advance(self) -> None:
        elapsed_s = self._clock.elapsed() / 1000.0
        target = self._play_origin_frame + int(elapsed_s * self._frame_rate * self.speed)
        if target >= self._n_frames:
            if not self.loop_box.isChecked():
                self._show(self._n_frames - 1)
                self.pause()
                return
            target %= self._n_frames
            self._play_origin_frame = target
            self._clock.restart()
        self._show(target)

    def _cursor_moved(self) -> None:
        self.pause()
        self.set_frame(int(round(self._cursor.value())))

    def _plot_clicked(self, event) -> None:
        position = self.plot.getPlotItem().vb.mapSceneToView(event.scenePos())
        self.pause()
        self.set_frame(int(round(position.x())))
