"""Building menu and toolbar actions."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import QStyle, QWidget


def make_action(parent: QWidget, text: str, slot: Callable, shortcut: QKeySequence | str | None = None,
                checkable: bool = False, checked: bool = False,
                icon: QStyle.StandardPixmap | None = None) -> QAction:
    """An action of ``parent`` calling ``slot`` when triggered (or toggled, when ``checkable``)."""
    action = QAction(text, parent)
    if icon is not None:
        action.setIcon(parent.style().standardIcon(icon))
    if shortcut is not None:
        action.setShortcut(QKeySequence(shortcut))
    action.setCheckable(checkable)
    if checkable:
        action.setChecked(checked)
        action.toggled.connect(slot)
    else:
        action.triggered.connect(slot)
    return action
