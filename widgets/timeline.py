"""Timeline: transport controls (play/pause, step, speed, loop), frame box and a scrubbable plot of how
many markers are observed per frame and, after a solve, the mean IK residual (pyqtgraph). Emits
:attr:`TimelineWidget.frame_changed` with the 0-based frame index; shows the file's own frame numbers.
The transport is also offered as :class:`QAction` objects (with the usual keys) for a Playback menu."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pyqtgraph as pg
from pyqtgraph.GraphicsScene.mouseEvents import MouseClickEvent
from PySide6.QtCore import QElapsedTimer, Qt, QTimer, Signal
from PySide6.QtGui import QAction
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

from handmocap.widgets.cached_drawing import paint_from_cache
from handmocap.widgets.shortcuts import bind

SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0)
TICK_MS = 15
OBSERVED_PEN = (120, 190, 255)
EVENT_PEN = (120, 230, 160)          # event lines and names
TRIM_PEN = (200, 120, 60)            # the edges of the trim range
RESIDUAL_PEN = (255, 150, 60)


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
        self._low, self._high = 0, 0                 # the frames shown and played: the trim range
        self._event_items: list = []
        self._trim_items: list = []
        self._play_origin_frame = 0
        self._clock = QElapsedTimer()
        self._timer = QTimer(self)
        self._timer.setInterval(TICK_MS)
        self._timer.timeout.connect(self._advance)
        self._build()
        self.set_take(0, 1, 100.0, np.zeros(0))

    # ------------------------------------------------------------------------------------ building
    def _action(self, text: str, icon: QStyle.StandardPixmap, key: str, slot: Callable[[], None]) -> QAction:
        action = QAction(self.style().standardIcon(icon), text, self)
        bind(action, key)                  # the keys of the one shortcut table (widgets.shortcuts)
        action.triggered.connect(slot)
        self.addAction(action)
        return action

    def _button(self, action: QAction) -> QToolButton:
        button = QToolButton(self)
        button.setDefaultAction(action)
        button.setAutoRaise(True)
        return button

    def _build(self) -> None:
        pixmap = QStyle.StandardPixmap
        self.first_action = self._action("First frame", pixmap.SP_MediaSkipBackward, "first_frame",
                                         lambda: self.set_frame(0))
        self.step_back_action = self._action("Previous frame", pixmap.SP_MediaSeekBackward, "previous_frame",
                                             lambda: self.step(-1))
        self.play_action = self._action("Play", pixmap.SP_MediaPlay, "play", self.toggle_playing)
        self.step_forward_action = self._action("Next frame", pixmap.SP_MediaSeekForward, "next_frame",
                                                lambda: self.step(1))
        self.last_action = self._action("Last frame", pixmap.SP_MediaSkipForward, "last_frame",
                                        lambda: self.set_frame(self._n_frames - 1))
        self.transport_actions = (self.first_action, self.step_back_action, self.play_action,
                                  self.step_forward_action, self.last_action)
        controls = QHBoxLayout()
        controls.setContentsMargins(4, 2, 4, 0)
        for action in self.transport_actions:
            controls.addWidget(self._button(action))
        controls.addSpacing(8)
        controls.addWidget(QLabel("Frame"))
        self.frame_box = QSpinBox(self)
        self.frame_box.setKeyboardTracking(False)
        self.frame_box.setMinimumWidth(90)
        self.frame_box.setAlignment(Qt.AlignmentFlag.AlignRight)
        self.frame_box.valueChanged.connect(lambda value: self.set_frame(value - self._first_frame))
        controls.addWidget(self.frame_box)
        self.time_label = QLabel(self)
        # a fixed size: a label whose text changes every frame would otherwise lay the window out again and
        # make Qt compose it once more per frame
        self.time_label.setFixedSize(self.time_label.fontMetrics().horizontalAdvance("0000.000 s  / 0000.00 s") + 12,
                                     self.time_label.sizeHint().height())
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
        controls.addSpacing(10)
        self.legend_label = QLabel(self)
        controls.addWidget(self.legend_label)

        self.plot = pg.PlotWidget(self)
        self.plot.setBackground((30, 32, 36))
        self.plot.setMouseEnabled(x=True, y=False)
        self.plot.setMenuEnabled(False)
        self.plot.hideButtons()
        item = self.plot.getPlotItem()
        item.getAxis("left").setWidth(44)
        item.getAxis("left").setLabel("markers", color=_css(OBSERVED_PEN))
        item.showGrid(x=True, y=False, alpha=0.25)
        self.plot.setMinimumHeight(90)
        self.plot.setMaximumHeight(150)
        self._observed_curve = self.plot.plot(pen=pg.mkPen(OBSERVED_PEN, width=1.5),
                                              fillLevel=0, brush=(70, 120, 180, 70))
        # the residual curve lives in its own view box on the right axis, sharing the frame axis
        self._residual_box = pg.ViewBox(enableMouse=False, enableMenu=False)
        item.showAxis("right")
        item.getAxis("right").setWidth(44)
        item.getAxis("right").setLabel("mm", color=_css(RESIDUAL_PEN))
        item.getAxis("right").enableAutoSIPrefix(False)
        item.scene().addItem(self._residual_box)
        item.getAxis("right").linkToView(self._residual_box)
        self._residual_box.setXLink(item.vb)
        item.vb.sigResized.connect(lambda: self._residual_box.setGeometry(item.vb.sceneBoundingRect()))
        self._residual_curve = pg.PlotDataItem(pen=pg.mkPen(RESIDUAL_PEN, width=1.2))
        self._residual_box.addItem(self._residual_curve)
        paint_from_cache(self._observed_curve, self._residual_curve)
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

    # ------------------------------------------------------------------------------------- public
    @property
    def frame(self) -> int:
        """Current 0-based frame index."""
        return self._frame

    @property
    def n_frames(self) -> int:
        """Number of frames of the shown take."""
        return self._n_frames

    @property
    def first_frame(self) -> int:
        """The file's number of frame 0."""
        return self._first_frame

    @property
    def speed(self) -> float:
        """Playback speed factor (1 = real time)."""
        return float(self.speed_box.currentData())

    def set_speed(self, speed: float) -> None:
        """Choose the preset playback speed closest to ``speed``."""
        index = int(np.argmin(np.abs(np.log(np.asarray(SPEEDS) / max(speed, 1e-6)))))
        self.speed_box.setCurrentIndex(index)

    def is_playing(self) -> bool:
        """Whether playback is running."""
        return self._timer.isActive()

    def set_residuals(self, residuals: np.ndarray | None) -> None:
        """Per-frame mean IK residual ``(F,)`` mm (NaN: none) drawn on the right axis; None hides it."""
        item = self.plot.getPlotItem()
        if residuals is None or not np.isfinite(residuals).any():
            self._residual_curve.setData([], [])
            self._residual_box.setYRange(0, 1, padding=0)
            item.getAxis("right").setStyle(showValues=False)
            item.getAxis("right").setLabel("")
            self._update_legend(False)
            return
        item.getAxis("right").setStyle(showValues=True)
        item.getAxis("right").setLabel("mm", color=_css(RESIDUAL_PEN))
        residuals = np.asarray(residuals, dtype=float)
        self._residual_curve.setData(self._first_frame + np.arange(len(residuals)), residuals, connect="finite")
        top = float(np.nanpercentile(residuals, 99.5))
        self._residual_box.setYRange(0, max(top, 0.5) * 1.15, padding=0)
        self._update_legend(True)

    def _update_legend(self, with_residuals: bool) -> None:
        text = f'<span style="color:{_css(OBSERVED_PEN)}">■</span> markers seen'
        if with_residuals:
            text += f'&nbsp;&nbsp;<span style="color:{_css(RESIDUAL_PEN)}">■</span> mean residual (mm)'
        self.legend_label.setText(text)

    def set_events(self, events: list[tuple[int, str]]) -> None:
        """Mark the take's events: ``(0-based frame, name)`` each, a dashed line named at its top."""
        for item in self._event_items:
            self.plot.removeItem(item)
        self._event_items = []
        for frame, name in events:
            line = pg.InfiniteLine(self._first_frame + frame, angle=90, movable=False,
                                   pen=pg.mkPen(EVENT_PEN, width=1.5, style=Qt.PenStyle.DashLine),
                                   label=name, labelOpts={"position": 0.97, "color": EVENT_PEN,
                                                          "anchors": [(0, 0), (0, 0)], "fill": (30, 32, 36, 200)})
            line.setToolTip(f"{name} (frame {self._first_frame + frame})")
            self.plot.addItem(line)
            self._event_items.append(line)

    def event_marks(self) -> list[tuple[int, str]]:
        """The events marked now: ``(0-based frame, name)``."""
        return [(int(round(item.value())) - self._first_frame, item.label.format) for item in self._event_items]

    def set_trim(self, start: int | None, stop: int | None) -> None:
        """Show and play only frames ``start .. stop - 1`` (0-based; None: the whole take): the frames outside
        are shaded, the frame box and playback keep within the range."""
        for item in self._trim_items:
            self.plot.removeItem(item)
        self._trim_items = []
        self._low, self._high = (0, self._n_frames) if start is None or stop is None else (int(start), int(stop))
        first = self._first_frame
        for left, right in ((first - 1, first + self._low - 0.5), (first + self._high - 0.5, first + self._n_frames)):
            if right > left + 0.5:
                region = pg.LinearRegionItem((left, right), movable=False, brush=pg.mkBrush(0, 0, 0, 150),
                                             pen=pg.mkPen(TRIM_PEN, width=1))
                region.setZValue(5)
                self.plot.addItem(region)
                self._trim_items.append(region)
        self.frame_box.blockSignals(True)
        self.frame_box.setRange(first + self._low, first + max(self._high - 1, self._low))
        self.frame_box.blockSignals(False)
        if self._n_frames and not self._low <= self._frame < self._high:
            self.set_frame(self._frame)

    def trim_range(self) -> tuple[int, int]:
        """The frames shown and played, ``start, stop`` (0-based, stop exclusive)."""
        return self._low, self._high

    def set_take(self, n_frames: int, first_frame: int, frame_rate: float, markers_seen: np.ndarray) -> None:
        """Show a take of ``n_frames`` at ``frame_rate`` Hz whose first frame is numbered ``first_frame``;
        ``markers_seen (F,)``: observed marker count per frame for the overview plot."""
        self.pause()
        self._n_frames, self._first_frame, self._frame_rate = n_frames, first_frame, frame_rate
        self._low, self._high = 0, n_frames
        self.set_events([])
        for item in self._trim_items:
            self.plot.removeItem(item)
        self._trim_items = []
        self.frame_box.blockSignals(True)
        self.frame_box.setRange(first_frame, first_frame + max(n_frames - 1, 0))
        self.frame_box.blockSignals(False)
        # the plot's x axis shows the file's frame numbers, like the frame box
        frames = first_frame + np.arange(len(markers_seen))
        self._observed_curve.setData(frames, np.asarray(markers_seen, dtype=float))
        self.plot.setLimits(xMin=first_frame - 1, xMax=first_frame + max(n_frames, 2))
        self.plot.setXRange(first_frame, first_frame + max(n_frames - 1, 1), padding=0.01)
        self.plot.setYRange(0, max(float(np.max(markers_seen, initial=0)), 1.0) * 1.1, padding=0)
        for action in self.transport_actions:
            action.setEnabled(n_frames > 0)
        self.frame_box.setEnabled(n_frames > 0)
        self._cursor.setMovable(n_frames > 0)
        self.set_residuals(None)
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
        frame = int(np.clip(frame, self._low, max(self._high - 1, self._low)))
        if frame == self._frame:
            return
        self._frame = frame
        self.frame_box.blockSignals(True)
        self.frame_box.setValue(frame + self._first_frame)
        self.frame_box.blockSignals(False)
        self._cursor.blockSignals(True)
        self._cursor.setValue(frame + self._first_frame)
        self._cursor.blockSignals(False)
        self.time_label.setText(f"{frame / self._frame_rate:8.3f} s  / {self._n_frames / self._frame_rate:.2f} s")
        self.frame_changed.emit(frame)

    def step(self, frames: int) -> None:
        """Move by ``frames`` (negative: back); stops playback."""
        self.pause()
        self.set_frame(self._frame + frames)

    def play(self) -> None:
        """Start playback from the current frame (from the start when at the end)."""
        if self._high - self._low < 2 or self.is_playing():
            return
        if self._frame >= self._high - 1:
            self.set_frame(self._low)
        self._restart_clock()
        self._timer.start()
        self.play_action.setIcon(self.style().standardIcon(QStyle.StandardPixmap.SP_MediaPause))
        self.play_action.setText("Pause")
        self.playing_changed.emit(True)

    def pause(self) -> None:
        """Stop playback at the current frame."""
        if not self.is_playing():
            return
        self._timer.stop()
        self.play_action.setIcon(self.style().standardIcon(QStyle.StandardPixmap.SP_MediaPlay))
        self.play_action.setText("Play")
        self.playing_changed.emit(False)

    def toggle_playing(self) -> None:
        """Play when paused, pause when playing."""
        if self.is_playing():
            self.pause()
        else:
            self.play()

    # ------------------------------------------------------------------------------------ private
    def _restart_clock(self) -> None:
        self._play_origin_frame = self._frame
        self._clock.restart()

    def _advance(self) -> None:
        elapsed_s = self._clock.elapsed() / 1000.0
        target = self._play_origin_frame + int(elapsed_s * self._frame_rate * self.speed)
        if target >= self._high:
            if not self.loop_box.isChecked():
                self._show(self._high - 1)
                self.pause()
                return
            target = self._low + (target - self._low) % max(self._high - self._low, 1)
            self._play_origin_frame = target
            self._clock.restart()
        self._show(target)

    def _cursor_moved(self) -> None:
        self.pause()
        self.set_frame(int(round(self._cursor.value())) - self._first_frame)

    def _plot_clicked(self, event: MouseClickEvent) -> None:
        if self._n_frames == 0:
            return
        position = self.plot.getPlotItem().vb.mapSceneToView(event.scenePos())
        self.pause()
        self.set_frame(int(round(position.x())) - self._first_frame)


def _css(colour: tuple[int, int, int]) -> str:
    """``#rrggbb`` of an RGB byte triple."""
    return "#{:02x}{:02x}{:02x}".format(*colour)
