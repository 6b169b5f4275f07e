"""Fill preview: the x, y and z coordinates of one marker around a gap — the measured samples, the gap
shaded, and the candidate fill of each method drawn through it (the chosen one bold, the others
thin), so the operator sees which fill follows the motion before accepting it (pyqtgraph).
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QEvent, QObject, Qt, QTimer
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from handmocap.core.gaps import fill_method, menu_fill_methods
from handmocap.widgets.marker_lanes import BACKGROUND, GAP_COLOUR, css

AXES = ("X", "Y", "Z")
MEASURED_PEN = (205, 210, 218)
MIN_CONTEXT = 30           # frames shown on each side of the gap, at least
CONTEXT_PER_LENGTH = 1.5   # and this many gap lengths


class FillPreview(QWidget):
    """Three x-linked plots (x, y, z in mm over the file's frame numbers) of one marker around a gap."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._curves: dict[str, list[pg.PlotDataItem]] = {}
        self._selected: str | None = None
        self._errors: dict[str, float] = {}
        self.title_label = QLabel(self)
        self.title_label.setTextFormat(Qt.TextFormat.RichText)
        self.title_label.setWordWrap(True)       # a long marker name must not widen the preview past the list
        self.title_label.setContentsMargins(6, 2, 6, 2)
        self.legend_label = QLabel(self)
        self.legend_label.setTextFormat(Qt.TextFormat.RichText)
        self.legend_label.setWordWrap(True)
        self.legend_label.setContentsMargins(6, 0, 6, 2)
        for label in (self.title_label, self.legend_label):
            label.setStyleSheet(f"background: {css(BACKGROUND)}; color: #cdd2da;")
        self.graphics = pg.GraphicsLayoutWidget(self)
        self.graphics.setBackground(BACKGROUND)
        self.graphics.ci.setSpacing(0)
        self.graphics.setMinimumSize(220, 110)   # beside the gap list in the Gaps dock, even at 1366×768
        self.graphics.viewport().installEventFilter(self)      # its first paint builds the plots
        self.plots: list[pg.PlotItem] = []       # built when first painted or drawn to (_build_plots)
        self._regions: list[pg.LinearRegionItem] = []
        self._measured: list[pg.PlotDataItem] = []
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(0)
        layout.addWidget(self.title_label)
        layout.addWidget(self.legend_label)
        layout.addWidget(self.graphics, 1)
        self.clear()

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        """The plots are built on the event-loop turn after the first paint of their area: a tab behind
        another in its dock counts as shown but is never painted."""
        if event.type() == QEvent.Type.Paint and not self.plots:
            QTimer.singleShot(0, self, self._build_plots)
        return False

    def _build_plots(self) -> None:
        """The three plots (pyqtgraph: a tenth of a second or more)."""
        if self.plots:
            return
        for row, axis in enumerate(AXES):
            # the axis name level, not rotated: three rotated labels overlap when the dock is short
            self.graphics.addLabel(f"{axis}<br>mm", row=row, col=0, color="#cdd2da", size="8pt")
            plot = self.graphics.addPlot(row=row, col=1)
            plot.setMenuEnabled(False)
            plot.hideButtons()
            plot.setMouseEnabled(x=True, y=True)
            plot.showGrid(x=True, y=True, alpha=0.18)
            plot.getAxis("left").setWidth(40)
            plot.getAxis("left").enableAutoSIPrefix(False)
            if row < len(AXES) - 1:
                plot.getAxis("bottom").setStyle(showValues=False)
            if self.plots:
                plot.setXLink(self.plots[0])
            self.plots.append(plot)
        self.plots[-1].setLabel("bottom", "frame")
        self._regions = [pg.LinearRegionItem(movable=False, brush=pg.mkBrush(*GAP_COLOUR, 40),
                                             pen=pg.mkPen(*GAP_COLOUR, 90)) for _ in AXES]
        self._measured = [pg.PlotDataItem(pen=pg.mkPen(MEASURED_PEN, width=1.2), symbol="o", symbolSize=3,
                                          symbolPen=None, symbolBrush=MEASURED_PEN, connect="finite")
                          for _ in AXES]
        for plot, region, measured in zip(self.plots, self._regions, self._measured, strict=True):
            region.hide()                        # until a gap is shown
            plot.addItem(region)
            plot.addItem(measured)

    # ------------------------------------------------------------------------------------- public
    def clear(self) -> None:
        """Show nothing (no gap selected)."""
        self._remove_candidates()
        for measured, region in zip(self._measured, self._regions, strict=True):
            measured.setData([], [])
            region.hide()
        self.title_label.setText("No gap selected")
        self.legend_label.setText("")
        self._window = (0, 0)

    def show_gap(self, trajectory: np.ndarray, start: int, length: int,
                 candidates: dict[str, np.ndarray] | None = None, selected: str | None = None,
                 errors_mm: dict[str, float] | None = None, first_frame: int = 1, name: str = "") -> None:
        """Show marker ``name`` around its gap of ``length`` frames from 0-based ``start``.

        ``trajectory (F,3)`` mm: the marker's measured positions (NaN missing; samples inside the gap
        are ignored); ``candidates``: fill method → ``(length,3)`` mm positions it gives for the gap;
        ``selected``: the method drawn bold; ``errors_mm``: fill-check error per method, shown in the
        legend; ``first_frame``: the file's number of frame 0.
        """
        self._build_plots()
        trajectory = np.asarray(trajectory, dtype=float)
        if trajectory.ndim != 2 or trajectory.shape[1] != 3:
            raise ValueError(f"trajectory must be (frames, 3), got shape {trajectory.shape}")
        n_frames = len(trajectory)
        if not (start >= 0 and length >= 1 and start + length <= n_frames):
            raise ValueError(f"gap {start}+{length} is outside the take's {n_frames} frames")
        context = max(MIN_CONTEXT, int(CONTEXT_PER_LENGTH * length))
        low, high = max(0, start - context), min(n_frames, start + length + context)
        self._window = (low, high)
        self._first_frame = first_frame
        self._start, self._length = start, length
        self._errors = dict(errors_mm or {})
        shown = trajectory[low:high].copy()
        shown[start - low:start - low + length] = np.nan
        frames = first_frame + np.arange(low, high)
        for axis, (measured, region) in enumerate(zip(self._measured, self._regions, strict=True)):
            measured.setData(frames, shown[:, axis])
            region.setRegion((first_frame + start - 0.5, first_frame + start + length - 0.5))
            region.show()
        self._remove_candidates()
        before = trajectory[start - 1] if start > 0 else np.full(3, np.nan)
        after = trajectory[start + length] if start + length < n_frames else np.full(3, np.nan)
        for method in (registered.name for registered in menu_fill_methods()):
            values = (candidates or {}).get(method)
            if values is None:
                continue
            values = np.asarray(values, dtype=float).reshape(length, 3)
            # join the fill to the samples on each side so the eye follows it through the gap
            path = np.vstack([before, values, after])
            path_frames = first_frame + np.arange(start - 1, start + length + 1)
            self._curves[method] = [plot.plot(path_frames, path[:, axis], connect="finite")
                                    for axis, plot in enumerate(self.plots)]
        for plot, axis in zip(self.plots, range(3), strict=True):
            series = [shown[:, axis]] + [np.asarray(c[axis].yData) for c in self._curves.values()]
            finite = np.concatenate([v[np.isfinite(v)] for v in series])
            if finite.size:
                pad = max(1.0, 0.08 * float(finite.max() - finite.min()))
                plot.setYRange(float(finite.min()) - pad, float(finite.max()) + pad, padding=0)
        self.plots[0].setXRange(first_frame + low - 0.5, first_frame + high - 0.5, padding=0)
        last = first_frame + start + length - 1
        self.title_label.setText(f"<b>{name or 'marker'}</b> · gap frames {first_frame + start}–{last} "
                                 f"({length} frames)")
        self.set_selected(selected if selected in self._curves else next(iter(self._curves), None))

    def set_selected(self, method: str | None) -> None:
        """Draw ``method``'s fill bold and on top, the others thin and dashed."""
        self._selected = method if method in self._curves else None
        for name, curves in self._curves.items():
            chosen = name == self._selected
            colour = fill_method(name).colour
            pen = (pg.mkPen(colour, width=2.6) if chosen
                   else pg.mkPen((*colour, 170), width=1.1, style=Qt.PenStyle.DashLine))
            for curve in curves:
                curve.setPen(pen)
                curve.setZValue(20 if chosen else 10)
        self._update_legend()

    def selected(self) -> str | None:
        """The method drawn bold (None: none)."""
        return self._selected

    def methods(self) -> list[str]:
        """Methods with a candidate curve, in the panel's order."""
        return list(self._curves)

    def curve_data(self, method: str, axis: int) -> tuple[np.ndarray, np.ndarray]:
        """Frames (file numbers) and values (mm) drawn for ``method`` on ``axis`` (0 x, 1 y, 2 z)."""
        curve = self._curves[method][axis]
        return np.asarray(curve.xData), np.asarray(curve.yData)

    def frame_window(self) -> tuple[int, int]:
        """0-based frame range ``[first, stop)`` shown."""
        return self._window

    # ------------------------------------------------------------------------------------ private
    def _remove_candidates(self) -> None:
        for curves in self._curves.values():
            for plot, curve in zip(self.plots, curves, strict=True):
                plot.removeItem(curve)
        self._curves = {}
        self._selected = None

    def _update_legend(self) -> None:
        parts = [f'<span style="color:{css(MEASURED_PEN)}">●</span>&nbsp;measured',
                 f'<span style="color:{css(GAP_COLOUR)}">▮</span>&nbsp;gap']
        for method in self._curves:
            error = self._errors.get(method)
            text = fill_method(method).label.replace(" ", "&nbsp;")
            if error is not None:
                text += f"&nbsp;{error:.2f}&nbsp;mm"
            if method == self._selected:
                text = f"<b>{text}</b>"
            parts.append(f'<span style="color:{css(fill_method(method).colour)}">■</span>&nbsp;{text}')
        self.legend_label.setText("&nbsp;&nbsp; ".join(parts))
