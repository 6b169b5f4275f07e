"""Building menu and toolbar actions; their keys come from the one shortcut table (:mod:`widgets.shortcuts`)."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtGui import QAction
from PySide6.QtWidgets import QStyle, QWidget

from handmocap.widgets.shortcuts import bind


def make_action(parent: QWidget, text: str, slot: Callable, shortcut: str | None = None,
                checkable: bool = False, checked: bool = False,
                icon: QStyle.StandardPixmap | None = None, tooltip: str | None = None) -> QAction:
    """An action of ``parent`` calling ``slot`` when triggered (or toggled, when ``checkable``). ``shortcut``:
    the name of its command in :data:`widgets.shortcuts.SHORTCUTS`, which gives its keys, the key its menu
    shows and the one its tooltip (``tooltip``, else the table's words) names."""
    action = QAction(text, parent)
    if icon is not None:
        action.setIcon(parent.style().standardIcon(icon))
    if shortcut is not None:
        bind(action, shortcut, tooltip)
    elif tooltip is not None:
        action.setToolTip(tooltip)
    action.setCheckable(checkable)
    if checkable:
        action.setChecked(checked)
        action.toggled.connect(slot)
    else:
        action.triggered.connect(slot)
    return action
