"""Trajectory plots: X, Y, Z, speed and acceleration of chosen labels over the take's frames (pyqtgraph),
like the graph panes of Nexus, QTM and Motive, linked to the timeline.

A :class:`Trace` is one label's pre-computed curves (:func:`make_trace`): its positions ``(F, 3)`` mm
(measured points and accepted fills), speed ``(F,)`` mm/s and acceleration magnitude ``(F,)`` mm/s² from
central differences at the take's frame rate, the runs of unfilled gaps, of each fill method and of
swap suspects, and its acceleration spikes (:func:`acceleration_spikes`). Several traces overlay in
their own colours; fills are drawn as a halo in their fill method's colour and gaps as bands in the
gap colour (the colours of :mod:`widgets.marker_lanes`); swap suspects are hatched bands, spikes ×.

The x axis shows the file's frame numbers, like :class:`widgets.timeline.TimelineWidget`; signals carry
0-based frames. A click emits :attr:`TrajectoryPlots.frame_clicked`; a left-button drag marks a frame
range (:attr:`range_selected`, inclusive); the wheel zooms time, the middle button pans. The current
frame is a line moved by :meth:`set_frame` (nothing is redrawn).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QBrush, QColor, QShowEvent
from PySide6.QtWidgets import QCheckBox, QGraphicsItem, QHBoxLayout, QLabel, QPushButton, QVBoxLayout, QWidget

from handmocap.core.gaps import fill_method, fill_methods
from handmocap.core.review.take import runs
from handmocap.widgets.cached_drawing import paint_from_cache
from handmocap.widgets.marker_lanes import BACKGROUND, CURSOR_PEN, GAP_COLOUR, SELECTION_COLOUR, css

#: spike threshold: median + SPIKE_MADS × (1.4826 × MAD) of a label's |acceleration|. 1.4826 × MAD is the
#: standard deviation for Gaussian noise; on a simulated 3000-frame take with 0.3 mm noise and grasping
#: motion no sample exceeds 4.4 of them, so 10 leaves room for fast smooth motion. On the real glove
#: recording (100 Hz) what it marks are steps: e.g. 5.85 mm between two frames where the marker moves
#: 0.1 mm a frame before and after
SPIKE_MADS = 10.0
MAD_TO_SIGMA = 1.4826
QUANTITIES = (("x", "X", "mm"), ("y", "Y", "mm"), ("z", "Z", "mm"), ("speed", "speed", "mm/s"),
              ("acceleration", "acceleration", "mm/s²"))
SPIKE_COLOUR = (255, 64, 160)       # acceleration spikes (×): a colour no lane state uses
SWAP_COLOUR = (240, 240, 250)       # swap suspects: hatched bands, told apart by the hatching
BAND_ALPHA = 60                     # gap and range bands are see-through
ROW_MIN_PX = 36                     # a plot never gets lower: its unit and values stay readable
AXIS_WIDTH = 70                     # px: room for accelerations in mm/s² (e.g. 120000)


@dataclass
class Trace:
    """One label's curves (module docstring): ``positions (F, 3)`` mm, ``speed (F,)`` mm/s,
    ``acceleration (F,)`` mm/s² (NaN where a neighbour is missing), ``gaps`` and ``swaps`` as
    ``(start, stop)`` 0-based runs (stop exclusive), ``fills`` {method: runs}, ``spikes`` 0-based frames
    (the peak of each run above ``spike_threshold`` mm/s²)."""

    name: str
    colour: tuple[int, int, int]
    positions: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray
    gaps: list[tuple[int, int]] = field(default_factory=list)
    fills: dict[str, list[tuple[int, int]]] = field(default_factory=dict)
    swaps: list[tuple[int, int]] = field(default_factory=list)
    spikes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    spike_threshold: float = float("nan")

    def values(self, quantity: str) -> np.ndarray:
        """The ``(F,)`` values of ``quantity`` ("x", "y", "z", "speed", "acceleration")."""
        if quantity in ("x", "y", "z"):
            return self.positions[:, "xyz".index(quantity)]
        return self.speed if quantity == "speed" else self.acceleration


def kinematics(positions: np.ndarray, frame_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Speed ``(F,)`` mm/s and acceleration magnitude ``(F,)`` mm/s² of ``positions (F, 3)`` mm by central
    differences at ``frame_rate`` Hz; NaN at the ends and where a neighbouring sample is missing."""
    speed = np.full(len(positions), np.nan)
    acceleration = np.full(len(positions), np.nan)
    if len(positions) >= 3:
        before, here, after = positions[:-2], positions[1:-1], positions[2:]
        speed[1:-1] = np.linalg.norm(after - before, axis=1) * (frame_rate / 2.0)
        acceleration[1:-1] = np.linalg.norm(after - 2.0 * here + before, axis=1) * frame_rate**2
    return speed, acceleration


def acceleration_spikes(acceleration: np.ndarray, k: float = SPIKE_MADS) -> tuple[np.ndarray, float]:
    """Frames of spikes in ``acceleration (F,)`` mm/s² and the threshold (mm/s²): median + k × 1.4826 ×
    MAD of the label's own finite values (see :data:`SPIKE_MADS`); one frame per run above it, its peak.
    No spikes (threshold NaN) with fewer than 10 values or no spread."""
    finite = acceleration[np.isfinite(acceleration)]
    if len(finite) < 10:
        return np.zeros(0, dtype=np.int64), float("nan")
    median = float(np.median(finite))
    spread = MAD_TO_SIGMA * float(np.median(np.abs(finite - median)))
    if spread <= 0.0:
        return np.zeros(0, dtype=np.int64), float("nan")
    threshold = median + k * spread
    with np.errstate(invalid="ignore"):
        _, starts, stops = runs(acceleration > threshold)
    peaks = [start + int(np.argmax(acceleration[start:stop])) for start, stop in zip(starts, stops, strict=True)]
    return np.asarray(peaks, dtype=np.int64), threshold


def make_trace(name: str, colour: tuple[int, int, int], positions: np.ndarray, provenance: np.ndarray,
               gaps: np.ndarray, swaps: list[tuple[int, int]], frame_rate: float) -> Trace:
    """The curves of one label: ``positions (F, 3)`` mm (measured and filled, NaN elsewhere),
    ``provenance (F,)`` codes of :mod:`core.model.provenance`, ``gaps (F,)`` bool (unfilled gaps),
    ``swaps`` its swap suspects (0-based runs), ``frame_rate`` Hz."""
    speed, acceleration = kinematics(positions, frame_rate)
    spikes, threshold = acceleration_spikes(acceleration)
    fills = {}
    for method in fill_methods():
        _, starts, stops = runs(provenance == method.code)
        if len(starts):
            fills[method.name] = list(zip(starts.tolist(), stops.tolist(), strict=True))
    _, starts, stops = runs(gaps)
    return Trace(name, colour, positions, speed, acceleration, list(zip(starts.tolist(), stops.tolist(), strict=True)),
                 fills, list(swaps), spikes, threshold)


def _bands(spans: list[tuple[int, int]], first_frame: int) -> tuple[np.ndarray, np.ndarray]:
    """Left edges and widths (file frame numbers) of bands covering frame runs."""
    spans_array = np.asarray(spans, dtype=float).reshape(-1, 2)
    return first_frame + spans_array[:, 0] - 0.5, spans_array[:, 1] - spans_array[:, 0]


def _masked(values: np.ndarray, spans: list[tuple[int, int]]) -> np.ndarray:
    """``values`` inside the runs ``spans`` (widened by one frame to join the curve), NaN elsewhere."""
    keep = np.zeros(len(values), dtype=bool)
    for start, stop in spans:
        keep[max(start - 1, 0):stop + 1] = True
    return np.where(keep, values, np.nan)


class _FrameBox(pg.ViewBox):
    """Left click: a frame; left drag: a frame range; wheel: zoom time; middle drag: pan."""

    def __init__(self, plots: TrajectoryPlots) -> None:
        super().__init__(enableMenu=False)
        self._plots = plots
        self.setMouseEnabled(x=True, y=False)

    def mouseClickEvent(self, ev) -> None:  # noqa: ANN001 - pyqtgraph signature
        if ev.button() == Qt.MouseButton.LeftButton:
            ev.accept()
            self._plots.click_at(self.mapSceneToView(ev.scenePos()).x())
        else:
            super().mouseClickEvent(ev)

    def mouseDragEvent(self, ev, axis=None) -> None:  # noqa: ANN001 - pyqtgraph signature
        if ev.button() != Qt.MouseButton.LeftButton:
            super().mouseDragEvent(ev, axis)
            return
        ev.accept()
        start = self.mapSceneToView(ev.buttonDownScenePos()).x()
        self._plots.drag_to(start, self.mapSceneToView(ev.scenePos()).x(), ev.isFinish())


class TrajectoryPlots(QWidget):
    """The plots of the module docstring. Feed it with :meth:`set_take`, :meth:`set_traces`,
    :meth:`set_frame` and :meth:`set_range`; it emits :attr:`frame_clicked` (0-based frame),
    :attr:`range_selected` (first, last; 0-based, inclusive), :attr:`pin_clicked` (the Pin button)
    and :attr:`shown` (it became visible: a view that skipped updates while hidden catches up)."""

    frame_clicked = Signal(int)
    range_selected = Signal(int, int)
    pin_clicked = Signal()
    clear_pins_clicked = Signal()
    shown = Signal()

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._first_frame = 1
        self._n_frames = 0
        self._frame_rate = 100.0
        self._traces: list[Trace] = []
        self._items: list[tuple[pg.PlotItem, pg.GraphicsObject]] = []   # what set_traces drew
        self._frame = 0
        self._range: tuple[int | None, int | None] = (None, None)
        self._build()

    # ------------------------------------------------------------------------------------ building
    def _build(self) -> None:
        header = QHBoxLayout()
        header.setContentsMargins(6, 2, 6, 2)
        self.names_label = QLabel("Select a label to plot its trajectory", self)
        header.addWidget(self.names_label, 1)
        self.quantity_boxes: dict[str, QCheckBox] = {}
        for key, title, unit in QUANTITIES:
            box = QCheckBox(title if len(title) < 6 else title[:5] + ".", self)
            box.setChecked(True)
            box.setToolTip(f"Show {title} ({unit})")
            box.toggled.connect(self._show_rows)
            self.quantity_boxes[key] = box
            header.addWidget(box)
        self.pin_button = QPushButton("Pin", self)
        self.pin_button.setToolTip("Keep the selected label in the plots when another is selected (or unpin it)")
        self.pin_button.clicked.connect(self.pin_clicked)
        header.addWidget(self.pin_button)
        self.clear_button = QPushButton("Clear pins", self)
        self.clear_button.clicked.connect(self.clear_pins_clicked)
        header.addWidget(self.clear_button)
        self.legend_label = QLabel(self._legend(), self)
        self.legend_label.setContentsMargins(6, 0, 6, 2)
        self.legend_label.setToolTip(f"Spikes: |acceleration| above the label's median + {SPIKE_MADS:g} × "
                                     f"{MAD_TO_SIGMA} × MAD (its own data).\nSwap suspects: the review's problem "
                                     "list. Click: go to the frame; drag: mark the range (like I and O).")

        self.canvas: pg.GraphicsLayoutWidget | None = None     # the plots: built when first shown or drawn to
        self.plots: dict[str, pg.PlotItem] = {}
        self.cursors: dict[str, pg.InfiniteLine] = {}
        self.regions: dict[str, pg.LinearRegionItem] = {}
        self._layout = QVBoxLayout(self)
        self._layout.setContentsMargins(0, 0, 0, 0)
        self._layout.setSpacing(0)
        self._layout.addLayout(header)
        self._layout.addWidget(self.legend_label)

    def _build_canvas(self) -> None:
        """The plots (pyqtgraph: a tenth of a second or more), built when first shown or drawn to; they take
        the take, frame and range set before."""
        if self.canvas is not None:
            return
        self.canvas = pg.GraphicsLayoutWidget(self)
        self.canvas.setBackground(BACKGROUND)
        self.canvas.ci.layout.setVerticalSpacing(2)
        for row, (key, title, unit) in enumerate(QUANTITIES):
            plot = self.canvas.addPlot(row=row, col=0, viewBox=_FrameBox(self))
            plot.hideButtons()
            plot.setMenuEnabled(False)
            plot.showGrid(x=True, y=True, alpha=0.2)
            plot.setDownsampling(auto=True, mode="peak")    # long takes: a min and max per pixel, spikes kept
            plot.setClipToView(True)
            left = plot.getAxis("left")
            left.setWidth(AXIS_WIDTH)
            left.enableAutoSIPrefix(False)
            left.setLabel(unit)                          # the unit on the axis, the quantity inside the plot
            name = pg.TextItem(title, color=(200, 204, 212), anchor=(0, 0))
            name.setParentItem(plot.getViewBox())        # in the box's pixels: stays at its corner when zooming
            name.setPos(4, 0)
            plot.getAxis("bottom").enableAutoSIPrefix(False)
            for axis in ("left", "bottom"):               # the axes draw the grid: cached, as the curves
                plot.getAxis(axis).setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
            plot.getViewBox().enableAutoRange(y=True)
            plot.getViewBox().setAutoVisible(y=True)
            if self.plots:
                plot.setXLink(self.plots["x"])
            cursor = pg.InfiniteLine(angle=90, movable=False, pen=pg.mkPen(CURSOR_PEN, width=1.5))
            cursor.setZValue(20)
            plot.addItem(cursor, ignoreBounds=True)
            region = pg.LinearRegionItem(movable=False, brush=QBrush(QColor(*SELECTION_COLOUR, 40)),
                                         pen=pg.mkPen(SELECTION_COLOUR, width=1))
            region.setZValue(-5)
            region.hide()
            plot.addItem(region, ignoreBounds=True)
            self.plots[key], self.cursors[key], self.regions[key] = plot, cursor, region
        self._show_rows()
        self._layout.addWidget(self.canvas, 1)
        self._show_take()
        self.set_frame(self._frame)
        self.set_range(*self._range)

    @staticmethod
    def _legend() -> str:
        fills = "".join(f'<span style="color:{css(method.colour)}">━</span>&nbsp;{method.name} '
                        for method in fill_methods())
        return (f'<span style="color:{css(GAP_COLOUR)}">■</span>&nbsp;gap &nbsp; fill: {fills}&nbsp; '
                f'<span style="color:{css(SWAP_COLOUR)}">▨</span>&nbsp;swap suspect &nbsp; '
                f'<span style="color:{css(SPIKE_COLOUR)}">×</span>&nbsp;acceleration spike')

    def _show_rows(self) -> None:
        """Show the plots of the checked quantities; frame numbers under the lowest one shown."""
        if self.canvas is None:
            return
        shown = [key for key, box in self.quantity_boxes.items() if box.isChecked()]
        self.canvas.setMinimumHeight(ROW_MIN_PX * max(len(shown), 1) + 30)
        for key, plot in self.plots.items():
            plot.setVisible(key in shown)
            plot.getAxis("bottom").setStyle(showValues=bool(shown) and key == shown[-1])
            plot.setLabel("bottom", "frame" if shown and key == shown[-1] else None)

    # ------------------------------------------------------------------------------------- public
    @property
    def traces(self) -> list[Trace]:
        """The traces drawn, in order."""
        return list(self._traces)

    def set_take(self, n_frames: int, first_frame: int, frame_rate: float) -> None:
        """A new take: its frame count, the file's number of frame 0 and its rate (Hz); no traces yet."""
        self._n_frames, self._first_frame, self._frame_rate = n_frames, first_frame, frame_rate
        self.set_traces([])
        self.set_range(None, None)
        self._show_take()

    def _show_take(self) -> None:
        if self.canvas is not None:
            self.plots["x"].setXRange(self._first_frame - 0.5, self._first_frame + max(self._n_frames, 1) - 0.5,
                                      padding=0.01)

    def set_traces(self, traces: list[Trace]) -> None:
        """Draw ``traces`` (replacing those drawn); the frame range in view stays."""
        if traces:
            self._build_canvas()
        for plot, item in self._items:
            plot.removeItem(item)
        self._items = []
        self._traces = list(traces)
        frames = self._first_frame + np.arange(self._n_frames, dtype=float)
        for key, plot in self.plots.items():
            self._add_bands(plot, [span for trace in traces for span in trace.gaps], GAP_COLOUR, None)
            self._add_bands(plot, [span for trace in traces for span in trace.swaps], SWAP_COLOUR,
                            Qt.BrushStyle.BDiagPattern)
            for trace in traces:
                values = trace.values(key)
                for method, spans in trace.fills.items():
                    self._add(plot, pg.PlotDataItem(frames, _masked(values, spans), connect="finite",
                                                    pen=pg.mkPen(fill_method(method).colour, width=5)), z=1)
                self._add(plot, pg.PlotDataItem(frames, values, connect="finite",
                                                pen=pg.mkPen(trace.colour, width=1.5)), z=2)
                if len(trace.spikes):
                    self._add(plot, pg.ScatterPlotItem(frames[trace.spikes], values[trace.spikes], symbol="x",
                                                       size=11, pen=pg.mkPen(SPIKE_COLOUR, width=2),
                                                       brush=pg.mkBrush(SPIKE_COLOUR)), z=3)
            if key == "acceleration":
                for trace in traces:
                    if np.isfinite(trace.spike_threshold):
                        line = pg.InfiniteLine(trace.spike_threshold, angle=0, movable=False,
                                               pen=pg.mkPen(SPIKE_COLOUR, width=1, style=Qt.PenStyle.DashLine))
                        self._add(plot, line, z=0, ignore_bounds=True)
        self._show_names()

    def set_frame(self, frame: int) -> None:
        """Move the cursor to 0-based ``frame`` (a line moves; nothing else is redrawn)."""
        self._frame = frame
        for cursor in self.cursors.values():
            cursor.setValue(self._first_frame + frame)

    def set_range(self, first: int | None, last: int | None) -> None:
        """Show the marked frame range (0-based, inclusive; hidden unless both ends are marked)."""
        self._range = (first, last)
        for region in self.regions.values():
            if first is None or last is None:
                region.hide()
            else:
                low, high = sorted((first, last))
                region.setRegion((self._first_frame + low - 0.5, self._first_frame + high + 0.5))
                region.show()

    def frame_at(self, x: float) -> int:
        """The 0-based frame at file frame number ``x``, clamped to the take."""
        return int(min(max(round(x - self._first_frame), 0), max(self._n_frames - 1, 0)))

    def x_of(self, frame: int) -> float:
        """File frame number (x coordinate) of 0-based ``frame``."""
        return float(self._first_frame + frame)

    # ------------------------------------------------------------------------------------- mouse
    def click_at(self, x: float) -> None:
        if self._n_frames:
            self.frame_clicked.emit(self.frame_at(x))

    def drag_to(self, start: float, now: float, finished: bool) -> None:
        """A left-button drag from ``start`` to ``now`` (file frame numbers): the range follows; at the end
        it is emitted (a drag within one frame is a click)."""
        if not self._n_frames:
            return
        first, last = sorted((self.frame_at(start), self.frame_at(now)))
        self.set_range(first, last)
        if finished:
            if first == last:
                self.frame_clicked.emit(first)
            else:
                self.range_selected.emit(first, last)

    # ------------------------------------------------------------------------------------ helpers
    def _add(self, plot: pg.PlotItem, item: pg.GraphicsObject, z: float, ignore_bounds: bool = False) -> None:
        """Add a drawn item; it and its parts (a PlotDataItem's curve) paint from a cached pixmap, so
        moving the cursor over them repaints no curve."""
        paint_from_cache(item)
        item.setZValue(z)
        plot.addItem(item, ignoreBounds=ignore_bounds)
        self._items.append((plot, item))

    def _add_bands(self, plot: pg.PlotItem, spans: list[tuple[int, int]], colour: tuple[int, int, int],
                   pattern: Qt.BrushStyle | None) -> None:
        """Bands over whole frame runs, as high as the view (they do not change its range)."""
        if not spans:
            return
        lefts, widths = _bands(spans, self._first_frame)
        brush = QBrush(QColor(*colour, BAND_ALPHA if pattern is None else 160), pattern or Qt.BrushStyle.SolidPattern)
        bars = pg.BarGraphItem(x0=lefts, width=widths, y0=-1e9, height=2e9, brush=brush, pen=pg.mkPen(None))
        self._add(plot, bars, z=-10, ignore_bounds=True)

    def _show_names(self) -> None:
        if not self._traces:
            self.names_label.setText("Select a label to plot its trajectory")
            return
        self.names_label.setText("  ".join(f'<span style="color:{css(trace.colour)}">━</span>&nbsp;{trace.name}'
                                           for trace in self._traces))

    def showEvent(self, event: QShowEvent) -> None:
        self._build_canvas()
        super().showEvent(event)
        self.shown.emit()
