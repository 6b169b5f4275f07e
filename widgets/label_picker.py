"""The label menus of Assign label (L) and Swap labels (W): a popup list of the take's labels, grouped by hand,
with a search field that has the keyboard from the start: typing keeps the labels whose name holds what was
typed (any part of it, any case), Up/Down move, Enter or a click picks, Esc closes."""

from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, QPoint, Qt
from PySide6.QtGui import QKeyEvent
from PySide6.QtWidgets import QDialog, QLabel, QLineEdit, QListWidget, QListWidgetItem, QVBoxLayout, QWidget

NAME_ROLE = Qt.ItemDataRole.UserRole


class LabelPicker(QDialog):
    """Pick one of ``groups`` ``[(group title, [label name])]`` (titles shown as headers when there are several
    groups or a title is given); :attr:`chosen` holds the pick after :meth:`exec`."""

    def __init__(self, parent: QWidget | None, title: str, groups: list[tuple[str, list[str]]]) -> None:
        super().__init__(parent, Qt.WindowType.Popup)
        self.chosen: str | None = None
        self.title = QLabel(f"<b>{title}</b>", self)
        self.search = QLineEdit(self)
        self.search.setPlaceholderText("Type to find a label…")
        self.search.setClearButtonEnabled(True)
        self.search.textChanged.connect(self.filter)
        self.search.installEventFilter(self)
        self.list = QListWidget(self)
        self.list.itemActivated.connect(self._picked)
        self.list.itemClicked.connect(self._picked)
        headers = len(groups) > 1 or any(name for name, _ in groups)
        for group, names in groups:
            if headers:
                header = QListWidgetItem(group or "other")
                font = header.font()
                font.setBold(True)
                header.setFont(font)
                header.setFlags(Qt.ItemFlag.NoItemFlags)
                self.list.addItem(header)
            for name in names:
                item = QListWidgetItem(f"   {name}" if headers else name)
                item.setData(NAME_ROLE, name)
                self.list.addItem(item)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(6, 6, 6, 6)
        layout.addWidget(self.title)
        layout.addWidget(self.search)
        layout.addWidget(self.list)
        rows = min(self.list.count(), 18)
        self.list.setMinimumHeight(rows * self.list.sizeHintForRow(0) + 8 if rows else 40)
        self.setMinimumWidth(max(240, self.list.sizeHintForColumn(0) + 40))
        self.filter("")
        self.search.setFocus(Qt.FocusReason.PopupFocusReason)

    def names(self) -> list[str]:
        """The labels shown now, in order."""
        return [self.list.item(row).data(NAME_ROLE) for row in range(self.list.count())
                if not self.list.item(row).isHidden() and self.list.item(row).data(NAME_ROLE)]

    def filter(self, text: str) -> None:
        """Keep the labels whose name holds ``text`` (case-insensitive) and the headers of their groups; the
        first one kept is the current one (Enter picks it)."""
        wanted = text.strip().lower()
        header: QListWidgetItem | None = None
        header_shown = False
        first: QListWidgetItem | None = None
        for row in range(self.list.count()):
            item = self.list.item(row)
            name = item.data(NAME_ROLE)
            if not name:
                if header is not None:
                    header.setHidden(not header_shown)
                header, header_shown = item, False
                continue
            shown = wanted in name.lower()
            item.setHidden(not shown)
            header_shown |= shown
            if shown and first is None:
                first = item
        if header is not None:
            header.setHidden(not header_shown)
        if first is None:
            self.list.setCurrentRow(-1)     # no label shown: no current item (what setCurrentItem(None) does)
        else:
            self.list.setCurrentItem(first)

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:  # noqa: N802 - Qt's name
        """Up/Down in the search field move in the list; Enter picks the current label."""
        if watched is self.search and isinstance(event, QKeyEvent) and event.type() == QEvent.Type.KeyPress:
            key = event.key()
            if key in (Qt.Key.Key_Down, Qt.Key.Key_Up):
                self._move(1 if key == Qt.Key.Key_Down else -1)
                return True
            if key in (Qt.Key.Key_Return, Qt.Key.Key_Enter):
                current = self.list.currentItem()
                if current is not None and current.data(NAME_ROLE):
                    self._picked(current)
                return True
        return super().eventFilter(watched, event)

    def _move(self, step: int) -> None:
        rows = [row for row in range(self.list.count())
                if not self.list.item(row).isHidden() and self.list.item(row).data(NAME_ROLE)]
        if not rows:
            return
        current = self.list.currentRow()
        later = [row for row in rows if (row > current if step > 0 else row < current)]
        target = (later[0] if step > 0 else later[-1]) if later else current
        self.list.setCurrentRow(target)

    def _picked(self, item: QListWidgetItem) -> None:
        name = item.data(NAME_ROLE)
        if name:
            self.chosen = name
            self.accept()

    @classmethod
    def choose(cls, parent: QWidget | None, title: str, groups: list[tuple[str, list[str]]],
               position: QPoint) -> str | None:
        """Show the picker at ``position`` (global) until a label is picked (returned) or it is closed (None)."""
        picker = cls(parent, title, groups)
        picker.move(position)
        picker.exec()
        return picker.chosen
