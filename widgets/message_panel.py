"""Message panel: the warnings of reading and labelling takes (and any other warning the application logs),
newest last, with their time and level, instead of on the terminal the operator does not see.

:class:`PanelLogHandler` is a :class:`logging.Handler` for the root logger; records may come from any
thread (files are read on workers) and reach the panel on the GUI thread through a queued signal.
Python ``warnings`` reach it through :func:`logging.captureWarnings`. The command line keeps its own
logging to stderr: only the window installs the handler.
"""

from __future__ import annotations

import logging
import time

from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QHBoxLayout, QLabel, QListWidget, QListWidgetItem, QPushButton, QVBoxLayout, QWidget

LEVEL_COLOURS = {logging.WARNING: QColor(250, 190, 80), logging.ERROR: QColor(255, 110, 90),
                 logging.CRITICAL: QColor(255, 110, 90)}
MAX_MESSAGES = 2000          # older messages are dropped (a take with a warning per frame must not eat memory)


class MessagePanel(QWidget):
    """A list of messages (time, level, text) with a count and a Clear button; :attr:`count_changed` tells
    how many there are (the window shows the number on the dock and the status bar)."""

    count_changed = Signal(int)

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.list = QListWidget(self)
        self.list.setWordWrap(True)
        self.list.setTextElideMode(Qt.TextElideMode.ElideMiddle)
        self.list.setAlternatingRowColors(True)
        self.summary_label = QLabel("No messages", self)
        clear = QPushButton("Clear", self)
        clear.setToolTip("Remove all messages")
        clear.clicked.connect(self.clear)
        header = QHBoxLayout()
        header.setContentsMargins(6, 2, 6, 2)
        header.addWidget(self.summary_label, 1)
        header.addWidget(clear)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(0)
        layout.addLayout(header)
        layout.addWidget(self.list, 1)

    def add_message(self, level: int, text: str, when: float | None = None) -> None:
        """Add a message of logging ``level`` (e.g. ``logging.WARNING``) at ``when`` (seconds since the epoch;
        default now)."""
        stamp = time.strftime("%H:%M:%S", time.localtime(time.time() if when is None else when))
        item = QListWidgetItem(f"{stamp}  {logging.getLevelName(level).capitalize()}: {text}")
        item.setToolTip(text)
        if level in LEVEL_COLOURS:
            item.setForeground(LEVEL_COLOURS[level])
        self.list.addItem(item)
        while self.list.count() > MAX_MESSAGES:
            self.list.takeItem(0)
        self.list.scrollToBottom()
        self._counted()

    def messages(self) -> list[str]:
        """The texts shown, oldest first."""
        return [self.list.item(row).toolTip() for row in range(self.list.count())]

    def clear(self) -> None:
        self.list.clear()
        self._counted()

    def _counted(self) -> None:
        count = self.list.count()
        self.summary_label.setText(f"{count} message{'s' * (count != 1)}" if count else "No messages")
        self.count_changed.emit(count)


class _Bridge(QObject):
    """Carries records from any thread to the panel's (queued signal)."""

    record = Signal(int, str, float)


class PanelLogHandler(logging.Handler):
    """Logging handler writing WARNING and worse records into a :class:`MessagePanel` (see the module
    docstring). :meth:`install` adds it to the root logger and captures Python warnings; :meth:`remove`
    undoes both."""

    def __init__(self, panel: MessagePanel, level: int = logging.WARNING) -> None:
        super().__init__(level)
        self._bridge = _Bridge()
        self._bridge.record.connect(panel.add_message, Qt.ConnectionType.QueuedConnection)

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
            if record.name == "py.warnings":          # "file:line: Category: text\n  source line"
                text = text.strip().splitlines()[0].split(": ", 1)[-1]
            self._bridge.record.emit(record.levelno, text, record.created)
        except Exception:  # noqa: BLE001 - a handler must never raise into the code that logs
            self.handleError(record)

    def install(self) -> None:
        logging.getLogger().addHandler(self)
        logging.captureWarnings(True)

    def remove(self) -> None:
        root = logging.getLogger()
        root.removeHandler(self)
        if not any(isinstance(handler, PanelLogHandler) for handler in root.handlers):
            logging.captureWarnings(False)       # the last window closed: warnings go where they went before
