"""Help ▸ Keyboard shortcuts: the table of :mod:`widgets.shortcuts`, section by section, with a filter."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QAbstractItemView,
    QDialog,
    QDialogButtonBox,
    QHeaderView,
    QLineEdit,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from handmocap.widgets.shortcuts import rows


class ShortcutsDialog(QDialog):
    """Every keyboard shortcut (section, keys, what it does); typing in the filter keeps the rows that hold it."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Keyboard shortcuts")
        self.filter_edit = QLineEdit(self)
        self.filter_edit.setPlaceholderText("Type to find a command or a key…")
        self.filter_edit.setClearButtonEnabled(True)
        self.filter_edit.textChanged.connect(self.filter)
        self.table = QTableWidget(0, 3, self)
        self.table.setHorizontalHeaderLabels(["Where", "Keys", "What it does"])
        self.table.verticalHeader().hide()
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
        header.setSectionResizeMode(1, QHeaderView.ResizeMode.ResizeToContents)
        header.setSectionResizeMode(2, QHeaderView.ResizeMode.Stretch)
        entries = rows()
        self.table.setRowCount(len(entries))
        for row, entry in enumerate(entries):
            for column, text in enumerate(entry):
                item = QTableWidgetItem(text)
                if column == 1:
                    font = item.font()
                    font.setBold(True)
                    item.setFont(font)
                self.table.setItem(row, column, item)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close, self)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addWidget(self.filter_edit)
        layout.addWidget(self.table, 1)
        layout.addWidget(buttons)
        self.resize(640, 620)
        self.filter_edit.setFocus(Qt.FocusReason.OtherFocusReason)

    def filter(self, text: str) -> None:
        """Show only the rows whose section, keys or words hold ``text`` (case-insensitive)."""
        wanted = text.strip().lower()
        for row in range(self.table.rowCount()):
            cells = " ".join(self._cells(row)).lower()
            self.table.setRowHidden(row, bool(wanted) and wanted not in cells)

    def visible_rows(self) -> list[tuple[str, str, str]]:
        """The rows shown now."""
        return [self._cells(row) for row in range(self.table.rowCount()) if not self.table.isRowHidden(row)]

    def _cells(self, row: int) -> tuple[str, str, str]:
        """The section, keys and words of ``row`` (every cell is filled when the table is built; an empty
        one would read "")."""
        where, keys, what = (item.text() if (item := self.table.item(row, column)) is not None else ""
                             for column in range(3))
        return where, keys, what
