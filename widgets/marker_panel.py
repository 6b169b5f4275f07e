"""Marker panel: a sortable table of the take's markers (name, % observed, current position, IK
residual). Selecting a row emits :attr:`MarkerPanel.marker_selected` with the marker's index."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import (
    QAbstractTableModel,
    QModelIndex,
    QObject,
    QPersistentModelIndex,
    QSortFilterProxyModel,
    Qt,
    Signal,
)
from PySide6.QtGui import QBrush, QColor, QIcon, QPainter, QPixmap
from PySide6.QtWidgets import QAbstractItemView, QHeaderView, QLineEdit, QTableView, QVBoxLayout, QWidget

COLUMNS = ("Marker", "Seen %", "X", "Y", "Z", "Resid.")
COLUMN_TIPS = (
    "Marker name (chip: colour in the 3D view, hollow when missing in this frame)",
    "Share of the take's frames in which the marker is observed",
    "X position in this frame (mm)", "Y position in this frame (mm)", "Z position in this frame (mm)",
    "IK residual in this frame: distance between the model's effector and the marker (mm)",
)
SORT_ROLE = Qt.ItemDataRole.UserRole + 1
MISSING_TEXT = "—"
SWATCH_PX = 10


def swatch(colour: np.ndarray, filled: bool) -> QIcon:
    """A small round colour chip: filled when the marker is observed in the current frame."""
    pixmap = QPixmap(SWATCH_PX + 2, SWATCH_PX + 2)
    pixmap.fill(QColor(0, 0, 0, 0))
    painter = QPainter(pixmap)
    painter.setRenderHint(QPainter.RenderHint.Antialiasing)
    qcolour = QColor.fromRgbF(*(float(c) for c in colour))
    painter.setPen(qcolour)
    painter.setBrush(qcolour if filled else QColor(0, 0, 0, 0))
    painter.drawEllipse(1, 1, SWATCH_PX - 1, SWATCH_PX - 1)
    painter.end()
    return QIcon(pixmap)


def filtered_table(parent: QWidget, model: QAbstractTableModel, minimum_section: int
                   ) -> tuple[QSortFilterProxyModel, QLineEdit, QTableView]:
    """A marker table view over ``model`` sorted by :data:`SORT_ROLE` (unsorted at first), one row
    selectable, first column fitted to the names and the others stretched, and a name filter box
    (connect its ``textChanged``). Returns the proxy, the filter box and the view."""
    proxy = QSortFilterProxyModel(parent)
    proxy.setSourceModel(model)
    proxy.setSortRole(SORT_ROLE)
    proxy.setFilterKeyColumn(0)
    proxy.setFilterCaseSensitivity(Qt.CaseSensitivity.CaseInsensitive)
    filter_edit = QLineEdit(parent)
    filter_edit.setPlaceholderText("Filter markers…")
    filter_edit.setClearButtonEnabled(True)
    table = QTableView(parent)
    table.setModel(proxy)
    table.setSortingEnabled(True)
    table.sortByColumn(-1, Qt.SortOrder.AscendingOrder)
    table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
    table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
    table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
    table.setAlternatingRowColors(True)
    table.verticalHeader().setVisible(False)
    table.verticalHeader().setDefaultSectionSize(22)
    header = table.horizontalHeader()
    header.setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
    for column in range(1, model.columnCount()):
        header.setSectionResizeMode(column, QHeaderView.ResizeMode.Stretch)
    header.setMinimumSectionSize(minimum_section)
    return proxy, filter_edit, table


class ColumnTableModel(QAbstractTableModel):
    """A flat table model with fixed named columns (``columns``) and their header tooltips
    (``column_tips``); subclasses give the rows (``rowCount``) and the cells (``data``)."""

    columns: tuple[str, ...] = ()
    column_tips: tuple[str, ...] = ()

    def columnCount(self, parent: QModelIndex | QPersistentModelIndex = QModelIndex()) -> int:  # noqa: B008 - Qt signature
        return 0 if parent.isValid() else len(self.columns)

    def headerData(self, section: int, orientation: Qt.Orientation,
                   role: int = Qt.ItemDataRole.DisplayRole) -> str | None:
        if orientation == Qt.Orientation.Horizontal and role == Qt.ItemDataRole.DisplayRole:
            return self.columns[section]
        if orientation == Qt.Orientation.Horizontal and role == Qt.ItemDataRole.ToolTipRole:
            return self.column_tips[section]
        return None


class MarkerTableModel(ColumnTableModel):
    """Rows = markers; the per-frame columns are replaced with :meth:`set_frame_values`."""

    columns, column_tips = COLUMNS, COLUMN_TIPS

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self._names: list[str] = []
        self._observed = np.zeros(0)
        self._positions = np.zeros((0, 3))
        self._residuals = np.zeros(0)
        self._icons: list[tuple[QIcon, QIcon]] = []

    def set_markers(self, names: list[str], observed_fraction: np.ndarray,
                    colours: np.ndarray | None = None) -> None:
        """New marker list: ``names (M,)``, the share of frames each is observed in ``(M,)`` and the
        colour ``(M,3)`` in [0, 1] it has in the 3D view (shown as a chip, hollow when missing)."""
        self.beginResetModel()
        self._names = list(names)
        self._observed = np.asarray(observed_fraction, dtype=float)
        colours = np.full((len(names), 3), 0.7) if colours is None else np.asarray(colours, dtype=float)
        self._icons = [(swatch(colour, True), swatch(colour, False)) for colour in colours]
        self._positions = np.full((len(names), 3), np.nan)
        self._residuals = np.full(len(names), np.nan)
        self.endResetModel()

    def set_frame_values(self, positions: np.ndarray, residuals: np.ndarray | None) -> None:
        """Current frame: ``positions (M,3)`` mm (NaN missing), ``residuals (M,)`` mm or None. Only the chips
        of the markers that appeared or vanished are redrawn."""
        was_observed = np.asarray(np.isfinite(self._positions).all(axis=1))
        self._positions = np.asarray(positions, dtype=float)
        self._residuals = (np.full(len(self._names), np.nan) if residuals is None
                           else np.asarray(residuals, dtype=float))
        if self._names:
            last = len(self._names) - 1
            observed = np.asarray(np.isfinite(self._positions).all(axis=1))
            changed = (np.flatnonzero(was_observed != observed) if len(was_observed) == len(observed)
                       else np.arange(len(observed)))
            if len(changed):
                self.dataChanged.emit(self.index(int(changed[0]), 0), self.index(int(changed[-1]), 0),
                                      [Qt.ItemDataRole.DecorationRole])
            self.dataChanged.emit(self.index(0, 2), self.index(last, len(COLUMNS) - 1))

    def rowCount(self, parent: QModelIndex | QPersistentModelIndex = QModelIndex()) -> int:  # noqa: B008 - Qt signature
        return 0 if parent.isValid() else len(self._names)

    def _value(self, row: int, column: int) -> float | str:
        if column == 0:
            return self._names[row]
        if column == 1:
            return 100.0 * float(self._observed[row])
        if column <= 4:
            return float(self._positions[row, column - 2])
        return float(self._residuals[row])

    def data(self, index: QModelIndex | QPersistentModelIndex, role: int = Qt.ItemDataRole.DisplayRole) -> object:
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
        if role == Qt.ItemDataRole.DecorationRole and column == 0 and self._icons:
            observed = bool(np.isfinite(self._positions[row]).all())
            return self._icons[row][0 if observed else 1]
        if role == Qt.ItemDataRole.TextAlignmentRole and column > 0:
            return int(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        if role == Qt.ItemDataRole.ForegroundRole and isinstance(value, float):    # the numbers' columns
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
        self.proxy, self.filter_edit, self.table = filtered_table(self, self.model, minimum_section=48)
        # the names column is sized when the markers change, not measured again with every frame's values
        self.table.horizontalHeader().setSectionResizeMode(0, QHeaderView.ResizeMode.Interactive)
        self.filter_edit.textChanged.connect(self.proxy.setFilterFixedString)
        self.table.selectionModel().selectionChanged.connect(self._selection_changed)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.filter_edit)
        layout.addWidget(self.table)

    def set_markers(self, names: list[str], observed_fraction: np.ndarray,
                    colours: np.ndarray | None = None) -> None:
        """Show a new marker list (see :meth:`MarkerTableModel.set_markers`); clears the selection."""
        self.table.clearSelection()
        self.model.set_markers(names, observed_fraction, colours)
        self.table.resizeColumnToContents(0)

    def set_frame_values(self, positions: np.ndarray, residuals: np.ndarray | None) -> None:
        """Current frame's positions ``(M,3)`` mm and residuals ``(M,)`` mm (or None)."""
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
        """Source row of the selected marker, -1 when none."""
        rows = self.table.selectionModel().selectedRows()
        return self.proxy.mapToSource(rows[0]).row() if rows else -1

    def _selection_changed(self) -> None:
        self.marker_selected.emit(self.selected_marker())
