"""The progress bar paints with its window's next paint, not at every step (issue 25: a job reporting each
percent composed the main window a hundred times, 21 ms each)."""

from __future__ import annotations

import pytest
from PySide6.QtCore import QEvent, QObject
from PySide6.QtWidgets import QVBoxLayout, QWidget

from handmocap.widgets.progress_bar import ProgressBar

pytestmark = pytest.mark.gui


class PaintCounter(QObject):
    def __init__(self) -> None:
        super().__init__()
        self.paints = 0

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        if event.type() == QEvent.Type.Paint:
            self.paints += 1
        return False


def test_steps_are_painted_once_with_the_next_paint(qtbot):
    window = QWidget()
    qtbot.addWidget(window)
    bar = ProgressBar(window)
    QVBoxLayout(window).addWidget(bar)
    bar.setFormat("Solving… %p %")
    window.show()
    qtbot.waitExposed(window)
    qtbot.wait(50)                                      # its first paint is done
    counter = PaintCounter()
    bar.installEventFilter(counter)
    for percent in range(1, 60):
        bar.setValue(percent)
    assert counter.paints == 0 and bar.value() == 59 and bar.text() == "Solving… 59 %"
    qtbot.waitUntil(lambda: counter.paints >= 1, timeout=2_000)
    assert counter.paints <= 2
