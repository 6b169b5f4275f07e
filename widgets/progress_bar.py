"""A progress bar that redraws with its window's next paint.

Qt's ``QProgressBar.setValue`` repaints at once whenever the shown percentage changes; in a window holding an
OpenGL view (the 3D view) each such repaint composes the whole window, 21 ms a step here (software OpenGL),
so a job reporting every percent kept the event loop busy for two seconds.
"""

from __future__ import annotations

from PySide6.QtWidgets import QProgressBar


class ProgressBar(QProgressBar):
    """``QProgressBar`` whose :meth:`setValue` schedules a repaint instead of painting at once."""

    def setValue(self, value: int) -> None:
        self.setUpdatesEnabled(False)    # QProgressBar's own repaint() does nothing now
        super().setValue(value)
        self.setUpdatesEnabled(True)     # and this asks for one update with the next paint
