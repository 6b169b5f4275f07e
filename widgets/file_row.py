"""A path field and its "Browse…" button side by side, as the dialogs that ask for a file show them."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtWidgets import QHBoxLayout, QLineEdit, QPushButton, QWidget


def browse_row(edit: QLineEdit, browse: Callable[[], object], parent: QWidget | None = None) -> QHBoxLayout:
    """``edit`` (stretching) and a "Browse…" button (child of ``parent``) that calls ``browse``, in a row."""
    button = QPushButton("Browse…", parent)
    button.clicked.connect(browse)
    row = QHBoxLayout()
    row.addWidget(edit, 1)
    row.addWidget(button)
    return row
