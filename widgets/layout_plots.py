"""Plots and the metrics table of the layout tools: best energy per optimiser iteration (live), the
reconstruction error against the number of markers, and a side-by-side table of layout metrics."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QHeaderView, QTableWidget, QTableWidgetItem, QWidget

from handmocap.core.layout import LayoutMetrics

RUN_PENS = ((110, 180, 255), (255, 160, 70), (120, 220, 120), (230, 120, 220), (200, 200, 200))
SPECIFIC_PEN = (255, 160, 70)
GENERIC_PEN = (110, 180, 255)


def _style(plot: pg.PlotWidget, left: str, bottom: str) -> None:
    plot.setBackground((32, 34, 38))
    plot.showGrid(x=True, y=True, alpha=0.25)
    plot.setLabel("left", left)
    plot.setLabel("bottom", bottom)
    plot.addLegend(offset=(-10, 10))


class EnergyPlot(pg.PlotWidget):
    """The best layout energy after each iteration of one or more optimisation runs (one curve per run,
    the last :data:`MAX_RUNS` kept), updated live."""

    MAX_RUNS = 4

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        _style(self, "score (lower is better)", "iteration")
        self.setToolTip("The best layout's score after each iteration of the optimiser: its energy\n"
                        "E = 0.1 E_cond + 100 E_dist (how badly the markers pin the pose, plus how close they come\n"
                        "to each other); lower is better")
        self._runs: list[tuple[pg.PlotDataItem, list[float]]] = []

    def start_run(self, label: str) -> None:
        """Begin a new curve called ``label`` (dropping the oldest beyond :data:`MAX_RUNS`)."""
        if len(self._runs) >= self.MAX_RUNS:
            curve, _ = self._runs.pop(0)
            self.removeItem(curve)
        pen = pg.mkPen(RUN_PENS[len(self._runs) % len(RUN_PENS)], width=2)
        curve = self.plot([], [], pen=pen, name=label)
        self._runs.append((curve, []))

    def add_energy(self, energy: float) -> None:
        """Append the best energy after the next iteration to the current curve."""
        if not self._runs:
            self.start_run("run")
        curve, values = self._runs[-1]
        values.append(float(energy))
        curve.setData(np.arange(len(values)), np.array(values))
        # the first iterations fall steeply: keep the converging tail readable
        finite = [value for _, run in self._runs for value in run[min(3, len(run) - 1):] if np.isfinite(value)]
        if finite:
            low, high = min(finite), max(finite)
            margin = max(0.05 * (high - low), 1e-3 * max(abs(high), 1.0))
            self.setYRange(low - margin, high + margin, padding=0)

    def current_values(self) -> list[float]:
        """The energies of the current run (a copy)."""
        return list(self._runs[-1][1]) if self._runs else []


class ErrorPlot(pg.PlotWidget):
    """Held-out reconstruction error (mean, mm) against the number of markers: one curve for the layouts
    optimised for the specific motions, one for the generic ones (the journal's Fig. 11)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        _style(self, "mean vertex error (mm)", "markers")
        self._specific = self.plot([], [], pen=pg.mkPen(SPECIFIC_PEN, width=2), symbol="o", symbolSize=7,
                                   symbolBrush=SPECIFIC_PEN, name="specific")
        self._generic = self.plot([], [], pen=pg.mkPen(GENERIC_PEN, width=2), symbol="s", symbolSize=7,
                                  symbolBrush=GENERIC_PEN, name="generic")
        self.rows: list = []

    def set_names(self, specific: str, generic: str) -> None:
        """Legend names of the two curves (the motion sets)."""
        self.plotItem.legend.clear()
        self.plotItem.legend.addItem(self._specific, f"optimised for {specific}")
        self.plotItem.legend.addItem(self._generic, f"optimised for {generic}")

    def clear_rows(self) -> None:
        self.rows = []
        self._specific.setData([], [])
        self._generic.setData([], [])

    def add_row(self, row) -> None:  # noqa: ANN001 - core.layout.workflow.ErrorRow
        """Add one marker count's result (an ``ErrorRow``)."""
        self.rows.append(row)
        rows = sorted(self.rows, key=lambda item: item.markers)
        counts = np.array([item.markers for item in rows], dtype=float)
        self._specific.setData(counts, np.array([item.specific_mean_mm for item in rows]))
        self._generic.setData(counts, np.array([item.generic_mean_mm for item in rows]))


#: plain words in the rows, the precise term in each row's tooltip (:data:`METRIC_TIPS`)
METRIC_ROWS = (
    ("Markers", lambda m, k: f"{k}"),
    ("Pose ambiguity (lower is better)", lambda m, k: _number(m.mean_condition)),
    ("… with its worst marker hidden",
     lambda m, k: f"{_number(m.worst_occluded_condition)} ({m.worst_occluded_marker})"),
    ("Min marker distance (mm)", lambda m, k: f"{m.min_distance_mm:.1f}"),
    ("Closest pair (labelling risk)", lambda m, k: f"{m.closest_pair[0]}–{m.closest_pair[1]} @ {m.closest_frame + 1}"),
    ("Frames with a pair < 20 mm", lambda m, k: f"{100.0 * m.risk_fraction:.0f} %"),
    ("Reconstruction mean (mm)", lambda m, k: _number(m.reconstruction_mean_mm, 2)),
    ("Reconstruction max (mm)", lambda m, k: _number(m.reconstruction_max_mm, 2)),
)


METRIC_TIPS = (
    "Markers in the layout",
    "Mean condition number κ(JᵀJ) of the markers' Jacobian over the motion: how unevenly the markers pin the\n"
    "hand's joints (1 = perfectly even; large = some joints barely move any marker)",
    "The mean κ(JᵀJ) with the one marker hidden that makes it worst (that marker in brackets)",
    "Smallest distance between two markers over the motion (mm)",
    "The two markers that come closest, and the frame where they do: where labelling may confuse them",
    "Share of the motion's frames where two markers are closer than 20 mm",
    "Mean per-vertex error of the hand rebuilt from the layout's markers by layered IK (mm)",
    "Largest per-vertex error of that rebuilt hand (mm)",
)


def _number(value: float, digits: int = 1) -> str:
    if not np.isfinite(value):
        return "—" if np.isnan(value) else "∞ (singular)"
    return f"{value:,.{digits}f}"


class LayoutMetricsTable(QTableWidget):
    """One column per layout, one row per metric (:data:`METRIC_ROWS`); the best value of the numeric
    rows is shown in bold."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(len(METRIC_ROWS), 0, parent)
        self.setVerticalHeaderLabels([name for name, _ in METRIC_ROWS])
        for row, tip in enumerate(METRIC_TIPS):
            self.verticalHeaderItem(row).setToolTip(tip)
        self.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        self.setAlternatingRowColors(True)

    def set_metrics(self, columns: Sequence[tuple[str, int, LayoutMetrics]]) -> None:
        """Show ``(layout name, marker count, metrics)`` per column."""
        self.setColumnCount(len(columns))
        self.setHorizontalHeaderLabels([name for name, _, _ in columns])
        better = {1: min, 2: min, 3: max, 5: min, 6: min, 7: min}     # row -> which value is best
        keys = {1: "mean_condition", 2: "worst_occluded_condition", 3: "min_distance_mm", 5: "risk_fraction",
                6: "reconstruction_mean_mm", 7: "reconstruction_max_mm"}
        for column, (_name, count, metrics) in enumerate(columns):
            for row, (_label, text) in enumerate(METRIC_ROWS):
                item = QTableWidgetItem(text(metrics, count))
                item.setTextAlignment(Qt.AlignmentFlag.AlignCenter)
                if row in keys and len(columns) > 1:
                    values = [getattr(other, keys[row]) for _, _, other in columns]
                    finite = [value for value in values if np.isfinite(value)]
                    if finite and getattr(metrics, keys[row]) == better[row](finite):
                        font = item.font()
                        font.setBold(True)
                        item.setFont(font)
                self.setItem(row, column, item)

    def text_at(self, row: int, column: int) -> str:
        """The text of a cell ('' when empty)."""
        item = self.item(row, column)
        return item.text() if item is not None else ""
