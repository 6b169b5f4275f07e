"""Session browser: the takes of a session with their state (raw / labelled / reviewed / exported) as a
coloured badge, subject, layout and frame count; flat or grouped by subject, sortable, filterable.

Adding takes (the Add button's file dialog, or files dropped on the widget) emits
:attr:`SessionBrowser.add_requested`; double-click or Enter emits :attr:`SessionBrowser.open_requested`;
the context menu sets a take's state or removes it (by signal: the widget changes nothing itself).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from PySide6.QtCore import QEvent, QModelIndex, QObject, QPersistentModelIndex, QPoint, QRect, QSize, Qt, Signal
from PySide6.QtGui import (
    QAction,
    QBrush,
    QColor,
    QDragEnterEvent,
    QDragMoveEvent,
    QDropEvent,
    QFont,
    QFontMetrics,
    QIcon,
    QKeyEvent,
    QPainter,
    QPalette,
    QPixmap,
)
from PySide6.QtWidgets import (
    QAbstractItemView,
    QCheckBox,
    QComboBox,
    QFileDialog,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QMenu,
    QStackedWidget,
    QStyle,
    QStyledItemDelegate,
    QStyleOptionViewItem,
    QToolButton,
    QTreeWidget,
    QTreeWidgetItem,
    QVBoxLayout,
    QWidget,
)

from handmocap.core.io import READ_SUFFIXES, TAKE_FILE_FILTER, recognised_format
from handmocap.core.session import TAKE_STATES
from handmocap.widgets.marker_lanes import css

#: files the session can take in (the readers of ``core.io.load_take``)
TAKE_SUFFIXES = READ_SUFFIXES
TAKE_FILTER = TAKE_FILE_FILTER
STATE_COLOURS: dict[str, tuple[int, int, int]] = {
    "raw": (118, 124, 134),
    "labelled": (62, 132, 226),
    "reviewed": (52, 164, 96),
    "exported": (146, 100, 214),
}
STATE_TIPS = {
    "raw": "Raw: not labelled yet",
    "labelled": "Labelled: automatic labelling done, not reviewed",
    "reviewed": "Reviewed: labels checked and gaps handled by an operator",
    "exported": "Exported: labelled C3D / joint angles written",
}
COLUMNS = ("Take", "State", "Subject", "Layout", "Frames")
TAKE_COLUMN, STATE_COLUMN, SUBJECT_COLUMN, LAYOUT_COLUMN, FRAMES_COLUMN = range(len(COLUMNS))
ID_ROLE = Qt.ItemDataRole.UserRole + 1
SORT_ROLE = Qt.ItemDataRole.UserRole + 2
NO_SUBJECT = "(no subject)"


class TakeEntryLike(Protocol):
    """What :meth:`TakeRow.from_entry` reads of a :class:`core.session.TakeEntry` (``subject``, ``layout``,
    ``frames`` and ``source`` are read when present)."""

    @property
    def id(self) -> str: ...

    @property
    def name(self) -> str: ...

    @property
    def state(self) -> str: ...


@dataclass(frozen=True)
class TakeRow:
    """One take as the browser shows it: ``id`` (session take id), ``name``, ``state`` (one of
    :data:`core.session.TAKE_STATES`), ``subject`` and ``layout`` (None: not set), ``frames``;
    ``source``: the file it came from (tooltip)."""

    id: str
    name: str
    state: str = "raw"
    subject: str | None = None
    layout: str | None = None
    frames: int = 0
    source: str = ""

    @classmethod
    def from_entry(cls, entry: TakeEntryLike) -> TakeRow:
        """A row from a :class:`core.session.TakeEntry` (or anything with the same attributes)."""
        return cls(str(entry.id), str(entry.name), str(entry.state), getattr(entry, "subject", None),
                   getattr(entry, "layout", None), int(getattr(entry, "frames", 0) or 0),
                   str(getattr(entry, "source", "") or ""))


def take_files(paths: list[str], by_content: bool = False) -> list[str]:
    """The paths among ``paths`` with a take file suffix (case-insensitive); ``by_content``: a .csv or .txt
    file only when a take format recognises its first lines (notes and other tables are left out)."""
    return [path for path in paths if Path(path).suffix.lower() in TAKE_SUFFIXES
            and (not by_content or _recognised(path))]


def _recognised(path: str) -> bool:
    try:
        return recognised_format(path) is not None
    except OSError:
        return False


def _top_items(tree: QTreeWidget) -> list[QTreeWidgetItem]:
    """The top-level items of ``tree``, in order."""
    return [item for index in range(tree.topLevelItemCount()) if (item := tree.topLevelItem(index)) is not None]


def _children(item: QTreeWidgetItem) -> list[QTreeWidgetItem]:
    """The child items of ``item``, in order."""
    return [child for index in range(item.childCount()) if (child := item.child(index)) is not None]


def _shared_prefix(first: str, second: str) -> int:
    """Characters ``first`` shares with ``second`` from its start, to a word boundary of ``first``."""
    count = 0
    for mine, theirs in zip(first, second, strict=False):
        if mine != theirs:
            break
        count += 1
    while count and count < len(first) and first[count - 1] not in " _-(.,":
        count -= 1
    return count


def distinct_elided(text: str, others: list[str], metrics: QFontMetrics, width: int) -> str:
    """``text`` shortened to ``width`` pixels so that it stays told apart from ``others`` (the names listed
    with it): what it shares with them at its start goes first ("…grasps (dense, labelled)"), then the part it
    shares at its end is cut at the right; a name sharing nothing is shortened in the middle."""
    if metrics.horizontalAdvance(text) <= width:
        return text
    rivals = [other for other in others if other != text]
    start = max((_shared_prefix(text, other) for other in rivals), default=0)
    if start < 4:
        return metrics.elidedText(text, Qt.TextElideMode.ElideMiddle, width)
    return "…" + metrics.elidedText(text[start:], Qt.TextElideMode.ElideRight,
                                    max(width - metrics.horizontalAdvance("…"), 0))


class DistinctNameDelegate(QStyledItemDelegate):
    """Paints take names shortened so that they stay told apart (:func:`distinct_elided`): "(dense, labelled)"
    and "(dense, unlabelled)" never both become "simulated …labelled)"."""

    def __init__(self, tree: QTreeWidget) -> None:
        super().__init__(tree)
        self.tree = tree

    def _names(self) -> list[str]:
        names, stack = [], _top_items(self.tree)
        while stack:
            item = stack.pop()
            names.append(item.text(TAKE_COLUMN))
            stack += _children(item)
        return names

    def paint(self, painter: QPainter, option: QStyleOptionViewItem,
              index: QModelIndex | QPersistentModelIndex) -> None:
        self.initStyleOption(option, index)
        text = option.text
        style = option.widget.style() if option.widget else None
        if style is None or not text:
            super().paint(painter, option, index)
            return
        available = style.subElementRect(QStyle.SubElement.SE_ItemViewItemText, option, option.widget).width() - 6
        option.text = distinct_elided(text, self._names(), option.fontMetrics, available)
        style.drawControl(QStyle.ControlElement.CE_ItemViewItem, option, painter, option.widget)


class StateBadgeDelegate(QStyledItemDelegate):
    """Paints a take's state as a rounded coloured badge."""

    def paint(self, painter: QPainter, option: QStyleOptionViewItem,
              index: QModelIndex | QPersistentModelIndex) -> None:
        state = index.data(Qt.ItemDataRole.DisplayRole)
        if state not in STATE_COLOURS:
            super().paint(painter, option, index)
            return
        self.initStyleOption(option, index)
        option.text = ""
        style = option.widget.style() if option.widget else None
        if style is not None:
            style.drawControl(QStyle.ControlElement.CE_ItemViewItem, option, painter, option.widget)
        painter.save()
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        font = QFont(option.font)
        font.setPointSizeF(max(7.0, font.pointSizeF() - 1.0))
        font.setBold(True)
        painter.setFont(font)
        metrics = painter.fontMetrics()
        width = metrics.horizontalAdvance(state) + 14
        height = min(option.rect.height() - 4, metrics.height() + 4)
        rect = QRect(option.rect.left() + 4, option.rect.center().y() - height // 2 + 1, width, height)
        painter.setPen(Qt.PenStyle.NoPen)
        painter.setBrush(QColor(*STATE_COLOURS[state]))
        painter.drawRoundedRect(rect, height / 2, height / 2)
        painter.setPen(QColor(255, 255, 255))
        painter.drawText(rect, Qt.AlignmentFlag.AlignCenter, state)
        painter.restore()

    def sizeHint(self, option: QStyleOptionViewItem, index: QModelIndex | QPersistentModelIndex) -> QSize:
        size = super().sizeHint(option, index)
        return QSize(max(size.width(), 96), max(size.height(), 22))


class _TakeItem(QTreeWidgetItem):
    """Sorts by :data:`SORT_ROLE` (state by workflow order, frames by number)."""

    def __lt__(self, other: QTreeWidgetItem) -> bool:
        column = self.treeWidget().sortColumn() if self.treeWidget() else 0
        mine, theirs = self.data(column, SORT_ROLE), other.data(column, SORT_ROLE)
        if mine is None or theirs is None:
            return self.text(column).lower() < other.text(column).lower()
        return mine < theirs


class SessionBrowser(QWidget):
    """The takes of one session. Signals carry take ids (and a state name)."""

    add_requested = Signal(list)
    open_requested = Signal(str)
    take_selected = Signal(str)
    state_change_requested = Signal(str, str)
    remove_requested = Signal(str)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self._rows: list[TakeRow] = []
        self._current = ""
        self._quiet = False
        self.setAcceptDrops(True)
        self._build()
        self.set_takes([])

    # ------------------------------------------------------------------------------------ building
    def _build(self) -> None:
        self.add_action = QAction(self.style().standardIcon(QStyle.StandardPixmap.SP_FileDialogNewFolder),
                                  "Add takes…", self)
        self.add_action.setToolTip("Add C3D, Qualisys TSV, TRC or CSV takes to the session "
                                   "(or drop the files here)")
        self.add_action.triggered.connect(self.choose_files)
        add_button = QToolButton(self)
        add_button.setDefaultAction(self.add_action)
        add_button.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
        add_button.setAutoRaise(True)
        self.filter_edit = QLineEdit(self)
        self.filter_edit.setPlaceholderText("Filter takes…")
        self.filter_edit.setClearButtonEnabled(True)
        self.filter_edit.setToolTip("Show takes whose name, subject or layout holds this text")
        self.filter_edit.textChanged.connect(self._apply_filter)
        self.state_box = QComboBox(self)
        self.state_box.addItem("All states", "")
        for state in TAKE_STATES:
            self.state_box.addItem(state.capitalize(), state)
        self.state_box.currentIndexChanged.connect(self._apply_filter)
        self.group_box = QCheckBox("By subject", self)
        self.group_box.setToolTip("Group the takes by subject")
        self.group_box.toggled.connect(lambda _on: self._rebuild())
        tools = QHBoxLayout()
        tools.setContentsMargins(0, 0, 0, 0)
        tools.addWidget(add_button)
        tools.addWidget(self.filter_edit, 1)
        tools.addWidget(self.state_box)
        tools.addWidget(self.group_box)

        self.tree = QTreeWidget(self)
        self.tree.setColumnCount(len(COLUMNS))
        self.tree.setHeaderLabels(list(COLUMNS))
        self.tree.setRootIsDecorated(False)
        self.tree.setUniformRowHeights(True)
        self.tree.setAlternatingRowColors(True)
        self.tree.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.tree.setSortingEnabled(True)
        self.tree.sortByColumn(TAKE_COLUMN, Qt.SortOrder.AscendingOrder)
        self.tree.setContextMenuPolicy(Qt.ContextMenuPolicy.CustomContextMenu)
        self.tree.customContextMenuRequested.connect(self._context_menu)
        self.tree.itemActivated.connect(self._activated)
        self.tree.installEventFilter(self)        # Delete asks to remove the selected take
        self.tree.itemSelectionChanged.connect(self._selection_changed)
        self.tree.setItemDelegateForColumn(STATE_COLUMN, StateBadgeDelegate(self.tree))
        self.tree.setAcceptDrops(False)            # drops go to the browser itself
        self.tree.viewport().setAcceptDrops(False)
        self.tree.setTextElideMode(Qt.TextElideMode.ElideMiddle)
        self.tree.setItemDelegateForColumn(TAKE_COLUMN, DistinctNameDelegate(self.tree))
        header = self.tree.header()
        header.setStretchLastSection(False)
        header.setSectionResizeMode(QHeaderView.ResizeMode.Interactive)
        self.tree.viewport().installEventFilter(self)   # a resize fits the columns again (_fit_columns)
        for column, tip in enumerate(("Take name (tooltip: its source file)", "raw → labelled → reviewed → exported",
                                      "Subject whose hand the take shows", "Marker layout of the take",
                                      "Number of frames")):
            self.tree.headerItem().setToolTip(column, tip)
        self.tree.headerItem().setTextAlignment(FRAMES_COLUMN, Qt.AlignmentFlag.AlignRight)

        self.empty_label = QLabel("No takes in this session yet.\n\nAdd takes… or drop C3D, TSV, TRC or CSV "
                                  "files here.", self)
        self.empty_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.empty_label.setWordWrap(True)
        palette = self.empty_label.palette()
        palette.setColor(QPalette.ColorRole.WindowText, QColor(130, 134, 140))
        self.empty_label.setPalette(palette)
        self.stack = QStackedWidget(self)
        self.stack.addWidget(self.tree)
        self.stack.addWidget(self.empty_label)
        self.summary_label = QLabel(self)
        self.summary_label.setTextFormat(Qt.TextFormat.RichText)
        self.summary_label.setContentsMargins(4, 0, 4, 0)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(2, 2, 2, 2)
        layout.addLayout(tools)
        layout.addWidget(self.stack, 1)
        layout.addWidget(self.summary_label)

    # ------------------------------------------------------------------------------------- public
    def set_takes(self, rows: list[TakeRow]) -> None:
        """Show the session's takes; keeps the selection and the current take when they still exist,
        without emitting."""
        for row in rows:
            if row.state not in TAKE_STATES:
                raise ValueError(f"take '{row.name}' has unknown state '{row.state}'")
        self._rows = list(rows)
        self._rebuild()

    def rows(self) -> list[TakeRow]:
        """The rows shown, as given."""
        return list(self._rows)

    def update_take(self, row: TakeRow) -> None:
        """Replace the row with ``row.id`` (its state, frames… changed) or append it."""
        rows = [row if existing.id == row.id else existing for existing in self._rows]
        if not any(existing.id == row.id for existing in self._rows):
            rows.append(row)
        self.set_takes(rows)

    def set_current(self, take_id: str) -> None:
        """Show ``take_id`` as the open take (bold); "" for none."""
        self._current = take_id
        for item in self._take_items():
            font = item.font(TAKE_COLUMN)
            font.setBold(item.data(TAKE_COLUMN, ID_ROLE) == take_id)
            item.setFont(TAKE_COLUMN, font)

    def select_take(self, take_id: str) -> None:
        """Select ``take_id`` ("" clears) without emitting :attr:`take_selected`."""
        self._quiet = True
        try:
            self.tree.clearSelection()
            item = self._item(take_id)
            if item is not None:
                item.setSelected(True)
                self.tree.scrollToItem(item)
        finally:
            self._quiet = False

    def selected_take(self) -> str:
        """Id of the selected take, "" when none."""
        items = [item for item in self.tree.selectedItems() if item.data(TAKE_COLUMN, ID_ROLE)]
        return str(items[0].data(TAKE_COLUMN, ID_ROLE)) if items else ""

    def visible_takes(self) -> list[str]:
        """Ids of the takes shown (after filter, grouping and sort), top to bottom."""
        ids = []
        for top in _top_items(self.tree):
            children = _children(top) or [top]
            ids += [str(item.data(TAKE_COLUMN, ID_ROLE)) for item in children
                    if not item.isHidden() and not top.isHidden() and item.data(TAKE_COLUMN, ID_ROLE)]
        return ids

    def choose_files(self) -> None:
        """Ask for take files and emit :attr:`add_requested` with them."""
        paths, _ = QFileDialog.getOpenFileNames(self, "Add takes to the session", "", TAKE_FILTER)
        if paths:
            self.add_requested.emit(list(paths))

    def state_menu(self, take_id: str) -> QMenu:
        """The context menu of ``take_id`` (Open, Set state ▸, Remove from session…)."""
        row = next(row for row in self._rows if row.id == take_id)
        menu = QMenu(self)
        open_action = menu.addAction("Open")
        open_action.triggered.connect(lambda: self.open_requested.emit(take_id))
        states = menu.addMenu("Set state")
        for state in TAKE_STATES:
            action = states.addAction(state.capitalize())
            action.setCheckable(True)
            action.setChecked(state == row.state)
            action.setIcon(_badge_icon(state))
            action.setToolTip(STATE_TIPS[state])
            action.triggered.connect(lambda _checked=False, s=state: self._request_state(take_id, s))
        menu.addSeparator()
        remove = menu.addAction("Remove from session…")
        remove.setShortcut(Qt.Key.Key_Delete)
        remove.setToolTip("Remove the take from the session (its source file stays where it is)")
        remove.triggered.connect(lambda: self.remove_requested.emit(take_id))
        return menu

    # -------------------------------------------------------------------------------------- events
    def dragEnterEvent(self, event: QDragEnterEvent) -> None:
        """Accept dragged take files."""
        if take_files([url.toLocalFile() for url in event.mimeData().urls()]):
            event.acceptProposedAction()

    def dragMoveEvent(self, event: QDragMoveEvent) -> None:
        """Keep accepting dragged take files over every child."""
        if take_files([url.toLocalFile() for url in event.mimeData().urls()]):
            event.acceptProposedAction()

    def dropEvent(self, event: QDropEvent) -> None:
        """Ask to add the dropped take files (other files are ignored)."""
        paths = take_files([url.toLocalFile() for url in event.mimeData().urls()], by_content=True)
        if paths:
            event.acceptProposedAction()
            self.add_requested.emit(paths)

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        """Delete (or Backspace) on the take list asks to remove the selected take; a resized list fits its
        columns again."""
        if watched is self.tree.viewport() and event.type() == QEvent.Type.Resize:
            self._fit_columns()
        if (watched is self.tree and isinstance(event, QKeyEvent) and event.type() == QEvent.Type.KeyPress
                and event.key() in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace) and self.selected_take()):
            self._remove_selected()
            return True
        return super().eventFilter(watched, event)

    # ------------------------------------------------------------------------------------ private
    def _take_items(self) -> list[QTreeWidgetItem]:
        items: list[QTreeWidgetItem] = []
        for top in _top_items(self.tree):
            items += _children(top) or [top]
        return [item for item in items if item.data(TAKE_COLUMN, ID_ROLE)]

    def _item(self, take_id: str) -> QTreeWidgetItem | None:
        return next((item for item in self._take_items() if item.data(TAKE_COLUMN, ID_ROLE) == take_id), None)

    def _make_item(self, row: TakeRow) -> QTreeWidgetItem:
        item = _TakeItem()
        item.setText(TAKE_COLUMN, row.name)
        item.setData(TAKE_COLUMN, ID_ROLE, row.id)
        item.setData(TAKE_COLUMN, SORT_ROLE, row.name.lower())
        item.setToolTip(TAKE_COLUMN, f"{row.name}\n{row.source}" if row.source else row.name)
        item.setText(STATE_COLUMN, row.state)
        item.setData(STATE_COLUMN, SORT_ROLE, TAKE_STATES.index(row.state))
        item.setToolTip(STATE_COLUMN, STATE_TIPS[row.state])
        item.setText(SUBJECT_COLUMN, row.subject or "—")
        item.setData(SUBJECT_COLUMN, SORT_ROLE, (row.subject or "\uffff").lower())
        item.setText(LAYOUT_COLUMN, row.layout or "—")
        item.setData(LAYOUT_COLUMN, SORT_ROLE, (row.layout or "\uffff").lower())
        item.setText(FRAMES_COLUMN, f"{row.frames:,}".replace(",", " ") if row.frames else "—")
        item.setData(FRAMES_COLUMN, SORT_ROLE, int(row.frames))
        item.setTextAlignment(FRAMES_COLUMN, Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        for column in (SUBJECT_COLUMN, LAYOUT_COLUMN, FRAMES_COLUMN):
            if item.text(column) == "—":
                item.setForeground(column, QBrush(QColor(140, 140, 140)))
        return item

    def _rebuild(self) -> None:
        selected = self.selected_take()
        self._quiet = True
        try:
            self.tree.setSortingEnabled(False)
            self.tree.clear()
            grouped = self.group_box.isChecked()
            self.tree.setRootIsDecorated(grouped)
            if grouped:
                groups: dict[str, _TakeItem] = {}
                for row in self._rows:
                    subject = row.subject or NO_SUBJECT
                    if subject not in groups:
                        group = _TakeItem([subject])
                        group.setData(TAKE_COLUMN, SORT_ROLE, "\uffff" if subject == NO_SUBJECT else subject.lower())
                        group.setFlags(Qt.ItemFlag.ItemIsEnabled)
                        font = group.font(TAKE_COLUMN)
                        font.setBold(True)
                        group.setFont(TAKE_COLUMN, font)
                        groups[subject] = group
                        self.tree.addTopLevelItem(group)
                    groups[subject].addChild(self._make_item(row))
                for group in groups.values():
                    count = group.childCount()
                    group.setText(FRAMES_COLUMN, f"{count} take{'s' if count != 1 else ''}")
                    group.setTextAlignment(FRAMES_COLUMN, Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
                    group.setExpanded(True)
                    group.setFirstColumnSpanned(False)
            else:
                self.tree.addTopLevelItems([self._make_item(row) for row in self._rows])
            self.tree.setSortingEnabled(True)
            self._apply_filter()
        finally:
            self._quiet = False
        self.set_current(self._current)
        if selected:
            self.select_take(selected)
        self.stack.setCurrentWidget(self.tree if self._rows else self.empty_label)
        self._fit_columns()
        self._update_summary()

    def _fit_columns(self) -> None:
        """Take names get what the other columns leave, and at least half of a narrow list; the state badge
        and the frame count keep their width, subject and layout share the rest (elided when it is too little)."""
        header = self.tree.header()
        width = self.tree.viewport().width()
        wanted = {column: max(self.tree.sizeHintForColumn(column), header.sectionSizeHint(column))
                  for column in range(len(COLUMNS)) if column != TAKE_COLUMN}
        fixed = (STATE_COLUMN, FRAMES_COLUMN)
        take = max(width - sum(wanted.values()), min(width // 2, width - sum(wanted[column] for column in fixed)))
        header.resizeSection(TAKE_COLUMN, take)
        for column in fixed:
            header.resizeSection(column, wanted[column])
        shared = (SUBJECT_COLUMN, LAYOUT_COLUMN)
        spare = max(width - take - sum(wanted[column] for column in fixed), 0)
        total = max(sum(wanted[column] for column in shared), 1)
        for column in shared:
            header.resizeSection(column, wanted[column] if total <= spare else wanted[column] * spare // total)

    def _apply_filter(self) -> None:
        text = self.filter_edit.text().strip().lower()
        state = self.state_box.currentData() or ""
        by_id = {row.id: row for row in self._rows}
        for top in _top_items(self.tree):
            children = _children(top)
            for item in children or [top]:
                row = by_id.get(item.data(TAKE_COLUMN, ID_ROLE))
                if row is None:
                    continue
                haystack = " ".join((row.name, row.subject or "", row.layout or "")).lower()
                item.setHidden(bool(text and text not in haystack) or bool(state and row.state != state))
            if children:
                top.setHidden(all(child.isHidden() for child in children))
        self._update_summary()

    def _update_summary(self) -> None:
        counts = {state: sum(row.state == state for row in self._rows) for state in TAKE_STATES}
        shown = len(self.visible_takes())
        total = len(self._rows)
        head = f"{total} take{'s' if total != 1 else ''}" if shown == total else f"{shown} of {total} takes"
        parts = [head] + [f'<span style="color:{css(STATE_COLOURS[s])}">●</span> {counts[s]} {s}'
                          for s in TAKE_STATES if counts[s]]
        self.summary_label.setText(" &nbsp;·&nbsp; ".join(parts))

    def _activated(self, item: QTreeWidgetItem, _column: int) -> None:
        take_id = item.data(TAKE_COLUMN, ID_ROLE)
        if take_id:
            self.open_requested.emit(str(take_id))

    def _selection_changed(self) -> None:
        if not self._quiet:
            self.take_selected.emit(self.selected_take())

    def _context_menu(self, position: QPoint) -> None:
        item = self.tree.itemAt(position)
        take_id = item.data(TAKE_COLUMN, ID_ROLE) if item is not None else None
        if take_id:
            menu = self.state_menu(str(take_id))
        else:
            menu = QMenu(self)
            menu.addAction(self.add_action)
        menu.exec(self.tree.viewport().mapToGlobal(position))

    def _remove_selected(self) -> None:
        take_id = self.selected_take()
        if take_id:
            self.remove_requested.emit(take_id)

    def _request_state(self, take_id: str, state: str) -> None:
        row = next((row for row in self._rows if row.id == take_id), None)
        if row is not None and row.state != state:
            self.state_change_requested.emit(take_id, state)


def _badge_icon(state: str) -> QIcon:
    """A round chip in the state's colour."""
    pixmap = QPixmap(12, 12)
    pixmap.fill(QColor(0, 0, 0, 0))
    painter = QPainter(pixmap)
    painter.setRenderHint(QPainter.RenderHint.Antialiasing)
    painter.setPen(Qt.PenStyle.NoPen)
    painter.setBrush(QColor(*STATE_COLOURS[state]))
    painter.drawEllipse(1, 1, 10, 10)
    painter.end()
    return QIcon(pixmap)
