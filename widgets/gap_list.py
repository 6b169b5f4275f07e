"""Gap list: the gaps of a take (marker, first frame, length, recommended fill, state) and, for the
selected gap, the fill-check error of each method — model (minimum-acceleration joint interpolation),
PCA (marker intercorrelations), linear, spline, pattern (with a donor choice) and rigid body — with
Preview, Accept and Reject, plus "fill all gaps up to N frames with the recommended method".

The widget shows plain :class:`GapRow` data (:meth:`GapRow.from_gap` converts :class:`core.gaps.Gap`
and :class:`core.gaps.FillCheck`) and asks for work by signal; it fills nothing itself. Frames are
0-based inside and in the signals; the table shows the file's frame numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TypedDict, Unpack

import numpy as np
from PySide6.QtCore import QModelIndex, QObject, QPersistentModelIndex, QSortFilterProxyModel, Qt, Signal
from PySide6.QtGui import QBrush, QColor, QFont, QIcon, QPixmap
from PySide6.QtWidgets import (
    QAbstractItemView,
    QButtonGroup,
    QComboBox,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QRadioButton,
    QSpinBox,
    QSplitter,
    QStyle,
    QTableView,
    QVBoxLayout,
    QWidget,
)

from handmocap.core.gaps import FillCheck, Gap, fill_method, fill_method_names, menu_fill_methods, provenance_names
from handmocap.core.gaps.check import DISPLACE_FACTOR, LOCAL_HORIZON_S
from handmocap.widgets.marker_lanes import GAP_COLOUR, css, filled_text
from handmocap.widgets.marker_panel import MISSING_TEXT, SORT_ROLE, ColumnTableModel

GAP_STATES = ("open", "filled", "rejected")
COLUMNS = ("Marker", "First", "Frames", "Best fill", "Error (mm)", "State")
COLUMN_TIPS = (
    "Marker with the gap",
    "First missing frame (the file's frame numbers)",
    "Length of the gap (missing frames)",
    f"Method to use: PCA, unless the gap lasts at most {LOCAL_HORIZON_S:g} s and another method fills\n"
    f"every hidden stretch of the fill check {DISPLACE_FACTOR:g}× better, on the mean and the worst frame",
    "Fill-check error of the recommended method: known stretches of the same length near the gap are\n"
    "hidden and filled, and the mean distance to the measured samples reported (mm)",
    "open: not filled yet; filled (method); rejected: left as a gap on purpose",
)
STATE_FILTERS = ("All gaps", "Open", "Filled", "Rejected")
AUTO_DONOR = -1
DEFAULT_MAX_FILL = 20
REJECTED_COLOUR = QColor(150, 150, 155)


class GapRowFields(TypedDict, total=False):
    """The fields of a :class:`GapRow` that :meth:`GapRow.from_gap` takes as given."""

    state: str
    method: str | None
    donors: tuple[int, ...]


@dataclass
class GapRow:
    """One gap as the list shows it.

    ``marker``: take column; ``start``: first missing frame (0-based); ``length``: frames;
    ``at_take_edge``: observed on one side only (no method fills it); ``state``: one of
    :data:`GAP_STATES`; ``method``: the fill method of a filled gap; ``recommended``: best method of the
    fill check (None: not checked or nothing applies); ``errors_mm``: fill-check error per applicable
    method (None: the check has not run); ``reasons``: why the other methods do not apply;
    ``check_error``: why the check itself could not run; ``donors``: pattern donor candidates (take
    columns, empty: every other marker).
    """

    marker: int
    name: str
    start: int
    length: int
    at_take_edge: bool = False
    state: str = "open"
    method: str | None = None
    recommended: str | None = None
    errors_mm: dict[str, float] | None = None
    reasons: dict[str, str] = field(default_factory=dict)
    check_error: str = ""
    donors: tuple[int, ...] = ()

    @classmethod
    def from_gap(cls, gap: Gap, check: FillCheck | None = None, check_error: str = "",
                 **fields: Unpack[GapRowFields]) -> GapRow:
        """A row for ``gap`` with the result of :func:`core.gaps.check_gap` (``check``) or the message of
        the InputError it raised (``check_error``); ``fields`` set the others (state, method, donors)."""
        errors = None if check is None and not check_error else dict(check.errors_mm) if check else {}
        ranking = check.ranking() if check is not None else []
        return cls(gap.marker, gap.name, gap.start, gap.length, gap.open,
                   recommended=ranking[0] if ranking else None, errors_mm=errors,
                   reasons=dict(check.reasons) if check is not None else {}, check_error=check_error,
                   **fields)

    @property
    def end(self) -> int:
        """First frame after the gap (exclusive, 0-based)."""
        return self.start + self.length

    @property
    def checked(self) -> bool:
        """Whether the fill check has run (or failed with a reason)."""
        return self.errors_mm is not None

    def state_text(self) -> str:
        """"open", "filled (method)" or "rejected"."""
        if self.state == "filled" and self.method:
            return filled_text(self.method)
        return self.state

    def applicable(self, method: str) -> bool:
        """Whether ``method`` can fill this gap as far as is known (unchecked gaps: every method)."""
        if self.at_take_edge:
            return False
        if self.errors_mm is None or self.check_error:     # unknown: the fill itself will tell
            return True
        return method in self.errors_mm or method not in self.reasons


class GapTableModel(ColumnTableModel):
    """Rows = :class:`GapRow`; numeric sort through :data:`SORT_ROLE`."""

    columns, column_tips = COLUMNS, COLUMN_TIPS

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.rows: list[GapRow] = []
        self.first_frame = 1

    def set_rows(self, rows: list[GapRow], first_frame: int) -> None:
        """Show ``rows``; frames are shown as ``first_frame + start``."""
        self.beginResetModel()
        self.rows = list(rows)
        self.first_frame = first_frame
        self.endResetModel()

    def set_row(self, index: int, row: GapRow) -> None:
        """Replace one row (after its check ran, it was filled or rejected)."""
        self.rows[index] = row
        self.dataChanged.emit(self.index(index, 0), self.index(index, len(COLUMNS) - 1))

    def rowCount(self, parent: QModelIndex | QPersistentModelIndex = QModelIndex()) -> int:  # noqa: B008 - Qt signature
        return 0 if parent.isValid() else len(self.rows)

    def _sort_value(self, row: GapRow, column: int) -> object:
        if column == 0:
            return row.name.lower()
        if column == 1:
            return row.start
        if column == 2:
            return row.length
        if column == 3:
            return row.recommended or "~"
        if column == 4:
            error = (row.errors_mm or {}).get(row.recommended or "", np.nan)
            return np.inf if np.isnan(error) else error
        return GAP_STATES.index(row.state) if row.state in GAP_STATES else len(GAP_STATES)

    def data(self, index: QModelIndex | QPersistentModelIndex, role: int = Qt.ItemDataRole.DisplayRole) -> object:
        if not index.isValid():
            return None
        row, column = self.rows[index.row()], index.column()
        if role == SORT_ROLE:
            return self._sort_value(row, column)
        if role == Qt.ItemDataRole.DisplayRole:
            return self._text(row, column)
        if role == Qt.ItemDataRole.TextAlignmentRole and column in (1, 2, 4):
            return int(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        if role == Qt.ItemDataRole.ForegroundRole:
            return self._foreground(row, column)
        if role == Qt.ItemDataRole.ToolTipRole:
            return self._tooltip(row)
        return None

    def _text(self, row: GapRow, column: int) -> str:
        if column == 0:
            return row.name
        if column == 1:
            return str(self.first_frame + row.start)
        if column == 2:
            return f"{row.length}{' ⇤' if row.at_take_edge and row.start == 0 else ' ⇥' if row.at_take_edge else ''}"
        if column == 3:
            if row.at_take_edge:
                return "cannot fill"
            if not row.checked:
                return "…"
            return fill_method(row.recommended).label if row.recommended else "none applies"
        if column == 4:
            error = (row.errors_mm or {}).get(row.recommended or "")
            return MISSING_TEXT if error is None else f"{error:.2f}"
        return row.state_text()

    @staticmethod
    def _foreground(row: GapRow, column: int) -> QBrush | None:
        if column == 3 and row.recommended:
            return QBrush(QColor(*fill_method(row.recommended).colour).darker(115))
        if column == 5:
            if row.state == "open":
                return QBrush(QColor(*GAP_COLOUR))
            if row.state == "filled" and row.method in fill_method_names():
                return QBrush(QColor(*fill_method(row.method).colour).darker(115))
            return QBrush(REJECTED_COLOUR)
        if column == 3 and (row.at_take_edge or row.checked):
            return QBrush(REJECTED_COLOUR)
        return None

    def _tooltip(self, row: GapRow) -> str:
        first = self.first_frame + row.start
        text = f"{row.name}: frames {first}–{first + row.length - 1} ({row.length} frames), {row.state_text()}"
        if row.at_take_edge:
            text += "\nObserved on one side only (the take starts or ends in the gap): no method can fill it"
        elif row.check_error:
            text += f"\nFill check: {row.check_error}"
        return text


class _GapFilter(QSortFilterProxyModel):
    """Rows of ``gaps`` whose marker name holds the filter text and whose state matches the state filter."""

    def __init__(self, gaps: GapTableModel, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.gaps = gaps
        self.setSourceModel(gaps)
        self.text = ""
        self.state = ""

    def set_filter(self, text: str, state: str) -> None:
        self.text, self.state = text.lower(), state
        self.invalidateFilter()

    def filterAcceptsRow(self, source_row: int,  # noqa: N802 - Qt
                         source_parent: QModelIndex | QPersistentModelIndex) -> bool:
        row = self.gaps.rows[source_row]
        return self.text in row.name.lower() and (not self.state or row.state == self.state)


class GapList(QWidget):
    """Gaps of one take with their fill check, and the fill controls. Signals carry the index of the gap
    in the list given to :meth:`set_gaps`, the method name and the pattern donor column (-1: automatic
    donor choice)."""

    gap_selected = Signal(int)
    method_changed = Signal(int, str)
    preview_requested = Signal(int, str, int)
    accept_requested = Signal(int, str, int)
    reject_requested = Signal(int)
    fill_all_requested = Signal(int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._names: list[str] = []
        self._selected = -1
        self._quiet = False
        self._build()
        self.set_gaps([], [], 1)

    # ------------------------------------------------------------------------------------ building
    def _build(self) -> None:
        """The filters, the gap table with Preview / Accept / Reject right under it (in view however short the
        dock is) and the fill-all row; the selected gap's methods below."""
        filters = self._build_filters()
        self._build_table()
        self._build_detail()
        fill_all = self._build_fill_all()
        top = QWidget(self)
        top_layout = QVBoxLayout(top)
        top_layout.setContentsMargins(0, 0, 0, 0)
        top_layout.addLayout(filters)
        self.table.setMinimumHeight(110)     # about four rows, however little room the dock has
        top_layout.addWidget(self.table)
        top_layout.addLayout(self._build_gap_buttons())
        top_layout.addLayout(fill_all)
        self.splitter = QSplitter(Qt.Orientation.Vertical, self)
        self.splitter.addWidget(top)
        self.splitter.addWidget(self.detail)
        self.splitter.setStretchFactor(0, 3)
        self.splitter.setStretchFactor(1, 0)
        self.splitter.setChildrenCollapsible(False)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addWidget(self.splitter)

    def _build_filters(self) -> QHBoxLayout:
        """The table model behind its sort/filter proxy, and the marker filter, state filter and count."""
        self.model = GapTableModel(self)
        self.proxy = _GapFilter(self.model, self)
        self.proxy.setSortRole(SORT_ROLE)
        self.filter_edit = QLineEdit(self)
        self.filter_edit.setPlaceholderText("Filter markers…")
        self.filter_edit.setClearButtonEnabled(True)
        self.state_box = QComboBox(self)
        self.state_box.addItems(list(STATE_FILTERS))
        self.state_box.setToolTip("Show the gaps in one state only")
        self.filter_edit.textChanged.connect(self._filter_changed)
        self.state_box.currentIndexChanged.connect(self._filter_changed)
        self.count_label = QLabel(self)
        filters = QHBoxLayout()
        filters.setContentsMargins(0, 0, 0, 0)
        filters.addWidget(self.filter_edit, 1)
        filters.addWidget(self.state_box)
        filters.addWidget(self.count_label)
        return filters

    def _build_table(self) -> None:
        """The gap table: one row per gap, sortable, one selected at a time."""
        self.table = QTableView(self)
        self.table.setModel(self.proxy)
        self.table.setSortingEnabled(True)
        self.table.sortByColumn(-1, Qt.SortOrder.AscendingOrder)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.setAlternatingRowColors(True)
        self.table.verticalHeader().setVisible(False)
        self.table.verticalHeader().setDefaultSectionSize(22)
        header = self.table.horizontalHeader()
        for column in range(len(COLUMNS)):     # every header readable whole; the last column takes what is left
            header.setSectionResizeMode(column, QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(True)
        header.setMinimumSectionSize(40)
        self.table.selectionModel().selectionChanged.connect(self._selection_changed)

    def _build_detail(self) -> None:
        """The selected gap's box: its title, a row per fill method, a note, and Preview/Accept/Reject."""
        self.detail = QGroupBox("Selected gap", self)
        self.detail_title = QLabel(self.detail)
        self.detail_title.setTextFormat(Qt.TextFormat.RichText)
        self.detail_note = QLabel(self.detail)
        self.detail_note.setWordWrap(True)
        grid = self._build_method_grid()
        detail_layout = QVBoxLayout(self.detail)
        detail_layout.addWidget(self.detail_title)
        detail_layout.addLayout(grid)
        detail_layout.addWidget(self.detail_note)

    def _build_method_grid(self) -> QGridLayout:
        """A row per fill method: its radio button, its check error and a note (the donor choice for the
        pattern fill)."""
        grid = QGridLayout()
        grid.setHorizontalSpacing(10)
        grid.setVerticalSpacing(3)
        heading_font = QFont(self.font())
        heading_font.setBold(True)
        for column, text in enumerate(("Method", "Check error", "")):
            label = QLabel(text, self.detail)
            label.setFont(heading_font)
            grid.addWidget(label, 0, column)
        self.method_group = QButtonGroup(self)
        self.method_buttons: dict[str, QRadioButton] = {}
        self.error_labels: dict[str, QLabel] = {}
        self.note_labels: dict[str, QLabel] = {}
        for row, registered in enumerate(menu_fill_methods(), start=1):
            method = registered.name
            button = QRadioButton(registered.label, self.detail)
            button.setToolTip(registered.description)
            button.setIcon(_chip(registered.colour))
            self.method_group.addButton(button, row)
            self.method_buttons[method] = button
            error = QLabel(MISSING_TEXT, self.detail)
            error.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
            error.setMinimumWidth(70)
            self.error_labels[method] = error
            grid.addWidget(button, row, 0)
            grid.addWidget(error, row, 1)
            if method == "pattern":
                self.donor_box = QComboBox(self.detail)
                self.donor_box.setToolTip("Donor marker whose motion the pattern fill copies")
                self.donor_box.setMinimumContentsLength(14)
                self.donor_box.currentIndexChanged.connect(lambda _i: self._method_clicked())
                grid.addWidget(self.donor_box, row, 2)
            else:
                note = QLabel(self.detail)
                note.setStyleSheet("color: #8a8f98;")
                self.note_labels[method] = note
                grid.addWidget(note, row, 2)
        grid.setColumnStretch(2, 1)
        self.method_group.idClicked.connect(lambda _id: self._method_clicked())
        return grid

    def _build_gap_buttons(self) -> QHBoxLayout:
        """Preview, Accept and Reject of the selected gap (with the method chosen below), right-aligned."""
        pixmap = QStyle.StandardPixmap
        self.preview_button = QPushButton(self.style().standardIcon(pixmap.SP_FileDialogContentsView), "Preview",
                                          self.detail)
        self.preview_button.setToolTip("Show the chosen fill of the selected gap (and the other candidates) around it")
        self.accept_button = QPushButton(self.style().standardIcon(pixmap.SP_DialogApplyButton), "Accept",
                                         self.detail)
        self.accept_button.setToolTip("Fill the selected gap with the method chosen below")
        self.reject_button = QPushButton(self.style().standardIcon(pixmap.SP_DialogCancelButton), "Reject",
                                         self.detail)
        self.reject_button.setToolTip("Leave the selected gap unfilled (Fill all skips it)")
        self.preview_button.clicked.connect(self._preview_clicked)
        self.accept_button.clicked.connect(self._accept_clicked)
        self.reject_button.clicked.connect(self._reject_clicked)
        buttons = QHBoxLayout()
        buttons.setContentsMargins(0, 2, 0, 0)
        buttons.addStretch(1)
        for button in (self.preview_button, self.accept_button, self.reject_button):
            buttons.addWidget(button)
        return buttons

    def _build_fill_all(self) -> QGridLayout:
        """Fill all gaps up to a length with their recommended method, and how many that is."""
        self.max_length_box = QSpinBox(self)
        self.max_length_box.setRange(1, 100_000)
        self.max_length_box.setValue(DEFAULT_MAX_FILL)
        self.max_length_box.setSuffix(" frames")
        self.max_length_box.setToolTip("Longest gap the fill-all fills")
        self.max_length_box.valueChanged.connect(self._update_fill_all)
        self.fill_all_button = QPushButton("Fill all", self)
        self.fill_all_button.setToolTip("Fill every open gap up to this length with its recommended method\n"
                                        "(the method that fills it best in its fill check)")
        self.fill_all_button.clicked.connect(lambda: self.fill_all_requested.emit(self.max_length_box.value()))
        self.fill_all_count = QLabel(self)
        fill_all = QGridLayout()          # narrow enough for the Gaps dock of a 1366×768 screen
        fill_all.setContentsMargins(0, 2, 0, 0)
        fill_all.setHorizontalSpacing(6)
        fill_all.addWidget(self.fill_all_button, 0, 0)
        up_to = QLabel("gaps up to", self)
        up_to.setToolTip("Every open gap up to this length is filled with its recommended method")
        fill_all.addWidget(up_to, 0, 1)
        fill_all.addWidget(self.max_length_box, 0, 2)
        fill_all.addWidget(self.fill_all_count, 0, 3)
        fill_all.setColumnStretch(3, 1)
        return fill_all

    # ------------------------------------------------------------------------------------- public
    def set_gaps(self, rows: list[GapRow], marker_names: list[str], first_frame: int = 1) -> None:
        """Show a take's gaps: ``rows``, the take's ``marker_names`` (for the donor choice) and the file's
        number of frame 0. Clears the selection without emitting."""
        self._names = list(marker_names)
        self._quiet = True
        try:
            self.table.clearSelection()
            self.model.set_rows(rows, first_frame)
        finally:
            self._quiet = False
        self._selected = -1
        self._show_detail()
        self._update_counts()

    def rows(self) -> list[GapRow]:
        """The rows shown, in the order given to :meth:`set_gaps`."""
        return list(self.model.rows)

    def update_gap(self, index: int, row: GapRow) -> None:
        """Replace gap ``index`` (its check finished, it was filled or rejected); the method choice stays
        when it still applies."""
        self._quiet = True             # a row leaving the state filter must not look like a new selection
        try:
            self.model.set_row(index, row)
        finally:
            self._quiet = False
        if index == self._selected:
            self._show_detail(keep_choice=True)
        self._update_counts()

    def select_gap(self, index: int) -> None:
        """Select gap ``index`` (-1 clears) without emitting :attr:`gap_selected`."""
        self._quiet = True
        try:
            self.table.clearSelection()
            self._selected = index if 0 <= index < len(self.model.rows) else -1
            if self._selected >= 0:
                proxy_index = self.proxy.mapFromSource(self.model.index(self._selected, 0))
                if proxy_index.isValid():
                    self.table.selectRow(proxy_index.row())
                    self.table.scrollTo(proxy_index)
        finally:
            self._quiet = False
        self._show_detail()

    def selected_gap(self) -> int:
        """Index of the selected gap, -1 when none."""
        return self._selected

    def chosen_method(self) -> str | None:
        """The method ticked in the detail panel (None: none)."""
        button = self.method_group.checkedButton()
        return next((m for m, b in self.method_buttons.items() if b is button), None)

    def chosen_donor(self) -> int:
        """Pattern donor column chosen, -1 for the automatic choice."""
        data = self.donor_box.currentData()
        return AUTO_DONOR if data is None else int(data)

    def set_donor(self, column: int) -> None:
        """Choose pattern donor ``column`` (-1: automatic)."""
        index = self.donor_box.findData(column)
        if index >= 0:
            self.donor_box.setCurrentIndex(index)

    def fill_all_candidates(self, max_length: int) -> int:
        """Open gaps a fill-all with ``max_length`` would try."""
        return sum(1 for row in self.model.rows
                   if row.state == "open" and not row.at_take_edge and row.length <= max_length)

    def sort_by(self, column: int, descending: bool = False) -> None:
        """Sort by ``column`` (index in :data:`COLUMNS`), as clicking its header does."""
        self.table.sortByColumn(column, Qt.SortOrder.DescendingOrder if descending else Qt.SortOrder.AscendingOrder)

    def visible_rows(self) -> list[int]:
        """Gap indices in the order shown (after filter and sort)."""
        return [self.proxy.mapToSource(self.proxy.index(i, 0)).row() for i in range(self.proxy.rowCount())]

    # ------------------------------------------------------------------------------------ private
    def _filter_changed(self) -> None:
        state = "" if self.state_box.currentIndex() == 0 else GAP_STATES[self.state_box.currentIndex() - 1]
        self._quiet = True
        try:
            self.proxy.set_filter(self.filter_edit.text(), state)
        finally:
            self._quiet = False
        self.select_gap(self._selected)
        self._update_counts()

    def _selection_changed(self) -> None:
        if self._quiet:
            return
        rows = self.table.selectionModel().selectedRows()
        self._selected = self.proxy.mapToSource(rows[0]).row() if rows else -1
        self._show_detail()
        self.gap_selected.emit(self._selected)

    def _show_detail(self, keep_choice: bool = False) -> None:
        row = self.model.rows[self._selected] if self._selected >= 0 else None
        previous = self.chosen_method() if keep_choice else None
        previous_donor = self.chosen_donor() if keep_choice else AUTO_DONOR
        self.detail.setEnabled(row is not None)
        if row is None:
            self.detail_title.setText("No gap selected")
            self.detail_note.setText("")
            self._set_checked(None)
            for method in self.method_buttons:
                self.error_labels[method].setText(MISSING_TEXT)
                if method in self.note_labels:
                    self.note_labels[method].setText("")
            self._fill_donors(None)
            self._update_buttons()
            return
        first = self.model.first_frame + row.start
        self.detail_title.setText(
            f"<b>{row.name}</b> · frames {first}–{first + row.length - 1} · {row.length} frames · "
            f"<span style='color:{self._state_css(row)}'>{row.state_text()}</span>")
        errors = row.errors_mm or {}
        ranking = sorted(errors, key=lambda method: errors[method])
        for method in self.method_buttons:
            button, error_label = self.method_buttons[method], self.error_labels[method]
            button.setEnabled(row.applicable(method))
            error = (row.errors_mm or {}).get(method)
            reason = row.reasons.get(method, "")
            if row.at_take_edge:
                text, tip = "n/a", "observed on one side only"
            elif error is not None:
                text = f"{error:.2f} mm"
                tip = f"{fill_method(method).label}: mean error {error:.2f} mm on the hidden stretches"
            elif not row.checked:
                text, tip = "…", "the fill check has not run yet"
            else:
                text, tip = "n/a", reason or row.check_error or "not applicable"
            if method == row.recommended:
                text = "★ " + text
            error_label.setText(text)
            error_label.setToolTip(tip)
            font = error_label.font()
            font.setBold(method == row.recommended)
            error_label.setFont(font)
            if method in self.note_labels:
                note = "" if error is not None or not row.checked else _short(reason or row.check_error)
                if error is not None and len(ranking) > 1 and method == ranking[-1]:
                    note = "worst"
                self.note_labels[method].setText(note)
                self.note_labels[method].setToolTip(reason)
        self._fill_donors(row)
        if previous_donor != AUTO_DONOR:
            self.set_donor(previous_donor)
        choice = previous if previous and row.applicable(previous) else row.method if row.state == "filled" else None
        choice = choice or row.recommended or next((m for m in self.method_buttons if row.applicable(m)), None)
        self._set_checked(choice)
        if row.at_take_edge:
            note = "The take starts or ends inside this gap: there is nothing to interpolate from on one side."
        elif row.check_error:
            note = f"Fill check: {row.check_error}"
        elif not row.checked:
            note = "Fill check running…"
        else:
            note = ""
        self.detail_note.setText(note)
        self._update_buttons()

    def _fill_donors(self, row: GapRow | None) -> None:
        self.donor_box.blockSignals(True)
        self.donor_box.clear()
        self.donor_box.addItem("Auto (steadiest)", AUTO_DONOR)
        if row is not None:
            donors = row.donors or tuple(i for i in range(len(self._names)) if i != row.marker)
            for column in donors:
                if 0 <= column < len(self._names):
                    self.donor_box.addItem(self._names[column], int(column))
        self.donor_box.blockSignals(False)

    def _set_checked(self, method: str | None) -> None:
        self.method_group.setExclusive(False)
        for name, button in self.method_buttons.items():
            button.setChecked(name == method)
        self.method_group.setExclusive(True)
        self.donor_box.setEnabled(method == "pattern")

    def _update_buttons(self) -> None:
        row = self.model.rows[self._selected] if self._selected >= 0 else None
        method = self.chosen_method()
        can_fill = row is not None and method is not None and row.applicable(method)
        self.preview_button.setEnabled(can_fill)
        self.accept_button.setEnabled(can_fill)
        self.reject_button.setEnabled(row is not None and row.state != "rejected")

    def _method_clicked(self) -> None:
        method = self.chosen_method()
        self.donor_box.setEnabled(method == "pattern")
        self._update_buttons()
        if self._selected >= 0 and method is not None:
            self.method_changed.emit(self._selected, method)

    def _preview_clicked(self) -> None:
        method = self.chosen_method()
        if self._selected >= 0 and method is not None:
            self.preview_requested.emit(self._selected, method, self.chosen_donor() if method == "pattern" else -1)

    def _accept_clicked(self) -> None:
        method = self.chosen_method()
        if self._selected >= 0 and method is not None:
            self.accept_requested.emit(self._selected, method, self.chosen_donor() if method == "pattern" else -1)

    def _reject_clicked(self) -> None:
        if self._selected >= 0:
            self.reject_requested.emit(self._selected)

    def _update_counts(self) -> None:
        rows = self.model.rows
        open_count = sum(row.state == "open" for row in rows)
        shown = self.proxy.rowCount()
        text = f"{len(rows)} gaps · {open_count} open"
        self.count_label.setText(text if shown == len(rows) else f"{shown} shown · {text}")
        self._update_fill_all()

    def _update_fill_all(self) -> None:
        count = self.fill_all_candidates(self.max_length_box.value())
        self.fill_all_count.setText(f"({count} open)")
        self.fill_all_button.setEnabled(count > 0)

    @staticmethod
    def _state_css(row: GapRow) -> str:
        if row.state == "open":
            return css(GAP_COLOUR)
        if row.state == "filled" and row.method in fill_method_names():
            return css(fill_method(row.method).colour)
        return css((150, 150, 155))


def gap_rows(gaps: list[Gap], provenance: np.ndarray | None = None,
             checks: dict[int, FillCheck | str] | None = None, rejected: set[int] | frozenset[int] = frozenset(),
             donors: dict[int, tuple[int, ...]] | None = None) -> list[GapRow]:
    """Rows for ``gaps`` (:func:`core.gaps.find_gaps` of the take without fills, e.g.
    ``ReviewTake.labelled_take(include_fills=False)``). A gap whose every frame has a fill in
    ``provenance (F,M)`` (codes of :mod:`core.model.provenance`) is "filled" with that method; one whose
    index is in ``rejected`` is "rejected"; the others "open". ``checks``: gap index → its
    :class:`FillCheck` or the message of the InputError :func:`core.gaps.check_gap` raised (missing:
    not checked yet); ``donors``: gap index → pattern donor candidates."""
    checks, donors = checks or {}, donors or {}
    rows = []
    for index, gap in enumerate(gaps):
        check = checks.get(index)
        fields: GapRowFields = {"donors": tuple(donors.get(index, ()))}
        codes = None if provenance is None else np.asarray(provenance)[gap.start:gap.end, gap.marker]
        if codes is not None and len(codes) and (codes > 0).all():
            fields["state"] = "filled"
            fields["method"] = provenance_names().get(int(np.bincount(codes).argmax()))
        elif index in rejected:
            fields["state"] = "rejected"
        if isinstance(check, str):
            rows.append(GapRow.from_gap(gap, check_error=check, **fields))
        else:
            rows.append(GapRow.from_gap(gap, check, **fields))
    return rows


def with_state(row: GapRow, state: str, method: str | None = None) -> GapRow:
    """A copy of ``row`` in ``state`` (one of :data:`GAP_STATES`) filled with ``method``."""
    if state not in GAP_STATES:
        raise ValueError(f"unknown gap state '{state}' (use {', '.join(GAP_STATES)})")
    return replace(row, state=state, method=method if state == "filled" else None)


def _short(text: str, limit: int = 60) -> str:
    """``text`` cut to ``limit`` characters with an ellipsis."""
    return text if len(text) <= limit else text[:limit - 1] + "…"


def _chip(colour: tuple[int, int, int]) -> QIcon:
    """A small square colour chip icon."""
    pixmap = QPixmap(10, 10)
    pixmap.fill(QColor(*colour))
    return QIcon(pixmap)
