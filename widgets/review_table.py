"""Review marker table: one row per marker of a labelled take with what the operator checks first —
% observed, unfilled gaps, longest gap, mean IK residual, lowest labelling confidence — sortable by
value, filterable by name. Selecting a row emits :attr:`ReviewTable.marker_selected`;
:meth:`ReviewTable.select_marker` selects from outside without emitting (no feedback loops).

The figures come as a :class:`core.session.MarkerStats` (``ReviewTake.marker_stats()``).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QModelIndex, QObject, QPersistentModelIndex, Qt, Signal
from PySide6.QtGui import QBrush, QColor, QIcon
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from handmocap.core.review import MarkerStats, ReviewSettings
from handmocap.widgets.marker_lanes import LOW_CONFIDENCE_COLOUR
from handmocap.widgets.marker_panel import MISSING_TEXT, SORT_ROLE, ColumnTableModel, filtered_table, swatch

#: plain words in the headers, the precise term in each tooltip (:data:`COLUMN_TIPS`)
COLUMNS = ("Marker", "Seen %", "Filled %", "Gaps", "Longest\ngap", "Off model\n(mm)", "Sure by\n(mm)")
#: what each number column shows (MarkerStats field) and how many decimals
FIELDS = (("observed_percent", 1), ("filled_percent", 1), ("gap_count", 0), ("longest_gap", 0),
          ("mean_residual_mm", 2), ("lowest_confidence_mm", 2))
OBSERVED_COLUMN, FILLED_COLUMN, GAPS_COLUMN, LONGEST_COLUMN, RESIDUAL_COLUMN, CONFIDENCE_COLUMN = range(1, 7)
COLUMN_TIPS = (
    "Marker label (chip: its colour in the 3D view)",
    "Share of the take's frames with a measured sample of this marker (filled samples do not count)",
    "Share of the take's frames filled by an accepted gap fill",
    "Number of unfilled gaps (runs of frames without a sample between the marker's first and last sample)",
    "Length of the longest unfilled gap, in frames",
    "How far the solved hand's marker is from the measured one, on average over the take (mm):\n"
    "the mean IK residual (distance from the model's effector to the marker)",
    "How sure the labelling was, at its least sure frame (mm): the lowest labelling confidence, the margin by\n"
    f"which the chosen point beat the next-best option; below {ReviewSettings().low_confidence_mm:g} mm "
    "(orange) a swap is possible",
)
#: thresholds that colour a cell as a warning
LOW_OBSERVED_PERCENT = 90.0
HIGH_RESIDUAL_MM = 5.0
LOW_CONFIDENCE_MM = ReviewSettings().low_confidence_mm
WARNING_COLOUR = QColor(*LOW_CONFIDENCE_COLOUR)
ERROR_COLOUR = QColor(255, 110, 90)
DIM_COLOUR = QColor(140, 140, 140)


class ReviewTableModel(ColumnTableModel):
    """Rows = markers; columns :data:`COLUMNS`. Sorts by :data:`SORT_ROLE` (numbers, missing last)."""

    columns, column_tips = COLUMNS, COLUMN_TIPS

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._names: list[str] = []
        self._values = np.zeros((0, len(COLUMNS) - 1))
        self._icons: list[QIcon] = []

    def set_markers(self, stats: MarkerStats, colours: np.ndarray | None = None) -> None:
        """New rows: one per marker of ``stats`` (its ``names``), with the 3D-view colours ``(M,3)`` in [0, 1]."""
        self.beginResetModel()
        self._names = list(stats.names)
        self._values = self._stack(stats, len(self._names))
        self._icons = [] if colours is None else [swatch(colour, True) for colour in np.asarray(colours, dtype=float)]
        self.endResetModel()

    def set_stats(self, stats: MarkerStats) -> None:
        """New figures for the same markers; the rows stay (a sorted view re-sorts)."""
        if list(stats.names) != self._names:
            raise ValueError("the figures are for other markers than the table shows; use set_markers")
        self._values = self._stack(stats, len(self._names))
        if self._names:
            self.dataChanged.emit(self.index(0, 1), self.index(len(self._names) - 1, len(COLUMNS) - 1))

    @staticmethod
    def _stack(stats: MarkerStats, n_markers: int) -> np.ndarray:
        values = np.zeros((n_markers, len(FIELDS)))
        for column, (name, _decimals) in enumerate(FIELDS):
            field = np.asarray(getattr(stats, name), dtype=float).reshape(-1)
            if len(field) != n_markers:
                raise ValueError(f"{name} has {len(field)} values for {n_markers} markers")
            values[:, column] = field
        if values.shape[0] != n_markers:
            raise ValueError(f"review figures for {values.shape[0]} markers, the table has {n_markers}")
        return values

    def value(self, row: int, column: int) -> float | str:
        """The raw value of a cell (name, or a number; NaN when unknown)."""
        return self._names[row] if column == 0 else float(self._values[row, column - 1])

    def rowCount(self, parent: QModelIndex | QPersistentModelIndex = QModelIndex()) -> int:  # noqa: B008 - Qt signature
        return 0 if parent.isValid() else len(self._names)

    def data(self, index: QModelIndex | QPersistentModelIndex, role: int = Qt.ItemDataRole.DisplayRole) -> object:
        if not index.isValid():
            return None
        row, column = index.row(), index.column()
        value = self.value(row, column)
        if role == SORT_ROLE:
            # unknown values sort after every number in ascending order
            return value if column == 0 else (np.inf if np.isnan(value) else value)
        if role == Qt.ItemDataRole.DisplayRole:
            if column == 0:
                return value
            if np.isnan(value):
                return MISSING_TEXT
            return f"{value:.{FIELDS[column - 1][1]}f}"
        if role == Qt.ItemDataRole.DecorationRole and column == 0 and self._icons:
            return self._icons[row]
        if role == Qt.ItemDataRole.TextAlignmentRole and column > 0:
            return int(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        if not isinstance(value, float):      # the name column
            return None
        if role == Qt.ItemDataRole.ForegroundRole:
            return self._foreground(column, value)
        if role == Qt.ItemDataRole.ToolTipRole and column == LONGEST_COLUMN and value > 0:
            return f"{self._names[row]}: longest unfilled gap {value:.0f} frames"
        return None

    @staticmethod
    def _foreground(column: int, value: float) -> QBrush | None:
        if np.isnan(value):
            return QBrush(DIM_COLOUR)
        if column == OBSERVED_COLUMN and value < LOW_OBSERVED_PERCENT:
            return QBrush(WARNING_COLOUR)
        if column == GAPS_COLUMN and value > 0:
            return QBrush(WARNING_COLOUR)
        if column == RESIDUAL_COLUMN and value > HIGH_RESIDUAL_MM:
            return QBrush(ERROR_COLOUR)
        if column == CONFIDENCE_COLUMN and value < LOW_CONFIDENCE_MM:
            return QBrush(WARNING_COLOUR)
        return None


class ReviewTable(QWidget):
    """Filterable, numerically sortable review table; :attr:`marker_selected` carries the source row
    (take marker column) of the row the operator selects (-1: none)."""

    marker_selected = Signal(int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = ReviewTableModel(self)
        self.proxy, self.filter_edit, self.table = filtered_table(self, self.model, minimum_section=56)
        self.filter_edit.textChanged.connect(self._filter_changed)
        self.table.selectionModel().selectionChanged.connect(self._selection_changed)
        self.count_label = QLabel(self)
        self.count_label.setContentsMargins(4, 0, 4, 0)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.filter_edit)
        layout.addWidget(self.table)
        layout.addWidget(self.count_label)
        self._quiet = False
        self._selected = -1
        self._update_count()

    def set_markers(self, stats: MarkerStats, colours: np.ndarray | None = None) -> None:
        """Show a take's markers (see :meth:`ReviewTableModel.set_markers`); keeps the selected marker
        when it still exists, without emitting."""
        selected = self._selected
        self._quiet = True
        try:
            self.table.clearSelection()
            self.model.set_markers(stats, colours)
        finally:
            self._quiet = False
        self._selected = -1
        self.select_marker(selected if selected < len(stats.names) else -1)
        self._update_count()

    def update_stats(self, stats: MarkerStats) -> None:
        """New figures for the same markers (after an edit or a fill); selection and sorting stay."""
        self.model.set_stats(stats)
        self.select_marker(self._selected)

    def select_marker(self, row: int) -> None:
        """Select the marker at source ``row`` (-1 clears) without emitting :attr:`marker_selected`.
        A marker hidden by the filter is remembered as selected but shows no row."""
        self._quiet = True
        try:
            self.table.clearSelection()
            self._selected = row if 0 <= row < self.model.rowCount() else -1
            if self._selected >= 0:
                index = self.proxy.mapFromSource(self.model.index(self._selected, 0))
                if index.isValid():
                    self.table.selectRow(index.row())
                    self.table.scrollTo(index)
        finally:
            self._quiet = False

    def selected_marker(self) -> int:
        """Source row of the selected marker, -1 when none."""
        return self._selected

    def sort_by(self, column: int, descending: bool = False) -> None:
        """Sort by ``column`` (index in :data:`COLUMNS`), as clicking its header does."""
        self.table.sortByColumn(column, Qt.SortOrder.DescendingOrder if descending else Qt.SortOrder.AscendingOrder)

    def visible_rows(self) -> list[int]:
        """Source rows in the order shown (after filter and sort)."""
        return [self.proxy.mapToSource(self.proxy.index(i, 0)).row() for i in range(self.proxy.rowCount())]

    def _filter_changed(self, text: str) -> None:
        self._quiet = True
        try:
            self.proxy.setFilterFixedString(text)
        finally:
            self._quiet = False
        self.select_marker(self._selected)
        self._update_count()

    def _selection_changed(self) -> None:
        if self._quiet:
            return
        rows = self.table.selectionModel().selectedRows()
        self._selected = self.proxy.mapToSource(rows[0]).row() if rows else -1
        self.marker_selected.emit(self._selected)

    def _update_count(self) -> None:
        shown, total = self.proxy.rowCount(), self.model.rowCount()
        text = f"{total} markers" if shown == total else f"{shown} of {total} markers"
        self.count_label.setText(text)
