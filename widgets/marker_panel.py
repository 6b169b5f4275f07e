"""Marker panel: a sortable table of the take's markers (name, % observed, current position, IK
residual). Selecting a row emits :attr:`MarkerPanel.marker_selected` with the marker's index."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QAbstractTableModel, QModelIndex, QSortFilterProxyModel, Qt, Signal
from PySide6.QtGui import QBrush, QColor
from PySide6.QtWidgets import QAbstractItemView, QHeaderView, QLineEdit, QTableView, QVBoxLayout, QWidget

COLUMNS = ("Marker", "Seen %", "X mm", "Y mm", "Z mm", "Resid. mm")
SORT_ROLE = Qt.ItemDataRole.UserRole + 1
MISSING_TEXT = "—"


class MarkerTableModel(QAbstractTableModel):
    """Rows = markers; the per-frame columns are replaced with :meth:`set_frame_values`."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self._names: list[str] = []
        self._observed = np.zeros(0)
        self._positions = np.zeros((0, 3))
        self._residuals = np.zeros(0)

    def set_markers(self, names: list[str], observed_fraction: np.ndarray) -> None:
        """New marker list: ``names (M,)`` and the share of frames each is observed in ``(M,)``."""
        self.beginResetModel()
        self._names = list(names)
        self._observed = np.asarray(observed_fraction, dtype=float)
        self._positions = np.full((len(names), 3), np.nan)
        self._residuals = np.full(len(names), np.nan)
        self.endResetModel()

    def set_frame_values(self, positions: np.ndarray, residuals: np.ndarray | None) -> None:
        """Current frame: ``positions (M,3)`` mm (NaN missing), ``residuals (M,)`` mm or None."""
        self._positions = np.asarray(positions, dtype=float)
        self._residuals = (np.full(len(self._names), np.nan) if residuals is None
                           else np.asarray(residuals, dtype=float))
        if self._names:
            self.dataChanged.emit(self.index(0, 2), self.index(len(self._names) - 1, len(COLUMNS) - 1))

    def rowCount(self, parent: QModelIndex = QModelIndex()) -> int:  # noqa: B008 - Qt signature
        return 0 if parent.isValid() else len(self._names)

    def columnCount(self, parent: QModelIndex = QModelIndex()) -> int:  # noqa: B008 - Qt signature
        return 0 if parent.isValid() else len(COLUMNS)

    def headerData(self, section: int, orientation: Qt.Orientation, role: int = Qt.ItemDataRole.DisplayRole):
        if role == Qt.ItemDataRole.DisplayRole and orientation == Qt.Orientation.Horizontal:
            return COLUMNS[section]
        return None

    def _value(self, row: int, column: int) -> float | str:
        if column == 0:
            return self._names[row]
        if column == 1:
            return 100.0 * self._observed[row]
        if column <= 4:
            return float(self._positions[row, column - 2])
        return float(self._residuals[row])

    def data(self, index: QModelIndex, role: int = Qt.ItemDataRole.DisplayRole):
        if not index.isValid():
            return None
        row, column = index.row(), index.column()
        value = self._value(row, column)
        if role == SORT_ROLE:
            return value if column == 0 else (-1e18 if np.isnan(value) else value)
        if role == Qt.ItemDataRole.DisplayRole:
            if column == 0:
                return value
            if np.isnan(value):
                return MISSING_TEXT
            return f"{value:.1f}" if column == 1 else f"{value:.2f}" if column == 5 else f"{value:.1f}"
        if role == Qt.ItemDataRole.TextAlignmentRole and column > 0:
            return int(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        if role == Qt.ItemDataRole.ForegroundRole:
            if column == 1 and value < 90.0:
                return QBrush(QColor(240, 170, 60))
            if column == 5 and not np.isnan(value) and value > 5.0:
                return QBrush(QColor(255, 110, 90))
            if column in (2, 3, 4) and np.isnan(value):
                return QBrush(QColor(140, 140, 140))
        return None


class MarkerPanel(QWidget):
    """Filterable, sortable marker table; emits the source row of the selected marker (-1: none)."""

    marker_selected = Signal(int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.model = MarkerTableModel(self)
        self.proxy = QSortFilterProxyModel(self)
        self.proxy.setSourceModel(self.model)
        self.proxy.setSortRole(SORT_ROLE)
        self.proxy.setFilterKeyColumn(0)
        self.proxy.setFilterCaseSensitivity(Qt.CaseSensitivity.CaseInsensitive)
        self.filter_edit = QLineEdit(self)
        self.filter_edit.setPlaceholderText("Filter markers…")
        self.filter_edit.setClearButtonEnabled(True)
        self.filter_edit.textChanged.connect(self.proxy.setFilterFixedString)
        self.table = QTableView(self)
        self.table.setModel(self.proxy)
        self.table.setSortingEnabled(True)
        self.table.sortByColumn(-1, Qt.SortOrder.AscendingOrder)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.setAlternatingRowColors(True)
        self.table.verticalHeader().setVisible(False)
        self.table.verticalHeader().setDefaultSectionSize(22)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
        for column in range(1, len(COLUMNS)):
            header.setSectionResizeMode(column, QHeaderView.ResizeMode.Stretch)
        header.setMinimumSectionSize(48)
        self.table.selectionModel().selectionChanged.connect(self._selection_changed)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.filter_edit)
        layout.addWidget(self.table)

    def set_markers(self, names: list[str], observed_fraction: np.ndarray) -> None:
        self.model.set_markers(names, observed_fraction)

    def set_frame_values(self, positions: np.ndarray, residuals: np.ndarray | None) -> None:
        self.model.set_frame_values(positions, residuals)

    def select_marker(self, row: int) -> None:
        """Select the marker at source ``row`` (-1 clears the selection)."""
        if row < 0:
            self.table.clearSelection()
            return
        index = self.proxy.mapFromSource(self.model.index(row, 0))
        if index.isValid():
            self.table.selectRow(index.row())
            self.table.scrollTo(index)

    def selected_marker(self) -> int:
        rows = self.table.selectionModel().selectedRows()
        return self.proxy.mapToSource(rows[0]).row() if rows else -1

    def _selection_changed(self) -> None:
        self.marker_selected.emit(self.selected_marker())
