"""The start-up splash: a picture with a line of text below, on screen while the program imports and builds
its window.

Qt's ``QSplashScreen`` is not used: its ``show()`` took a second here (under Xvfb) before it returned, longer
than the splash itself needs to be seen. This one is drawn as soon as its window is exposed.
"""

from __future__ import annotations

from PySide6.QtCore import QElapsedTimer, Qt
from PySide6.QtGui import QPainter, QPaintEvent, QPixmap
from PySide6.QtWidgets import QApplication, QWidget

EXPOSE_WAIT_MS = 300     # at most this long for the window system to show the splash before it is painted


class StartSplash(QWidget):
    """A frameless splash window showing ``picture`` and, at its bottom, the latest :meth:`tell`."""

    def __init__(self, picture: QPixmap) -> None:
        super().__init__(None, Qt.WindowType.SplashScreen | Qt.WindowType.FramelessWindowHint)
        self._picture = picture
        self._message = ""
        self.setFixedSize(picture.deviceIndependentSize().toSize())

    def show_now(self) -> None:
        """Show the splash and draw it before returning (the event loop is not running yet)."""
        screen = QApplication.primaryScreen()
        if screen is not None:
            self.move(screen.availableGeometry().center() - self.rect().center())
        self.show()
        clock = QElapsedTimer()
        clock.start()
        while not (self.windowHandle() is not None and self.windowHandle().isExposed()) \
                and clock.elapsed() < EXPOSE_WAIT_MS:
            QApplication.processEvents()
        self.repaint()

    def tell(self, message: str) -> None:
        """Show ``message`` now (the event loop is not running yet)."""
        self._message = message
        self.repaint()
        QApplication.processEvents()

    def message(self) -> str:
        """The line shown now."""
        return self._message

    def paintEvent(self, event: QPaintEvent) -> None:
        painter = QPainter(self)
        painter.drawPixmap(0, 0, self._picture)
        painter.setPen(Qt.GlobalColor.white)
        bottom_centre = Qt.AlignmentFlag.AlignBottom | Qt.AlignmentFlag.AlignHCenter
        painter.drawText(self.rect().adjusted(8, 0, -8, -8), bottom_centre, self._message)
        painter.end()
