"""Starting the application: QApplication, main window, files or the demo session, screenshot mode."""

from __future__ import annotations

import sys
from pathlib import Path

SCREENSHOT_TIMEOUT_MS = 120_000


def run_gui(files: list[str], screenshot: str | None = None, frame: int | None = None, solve: bool = False) -> int:
    """Open the main window on ``files`` (the demo session when empty; ``solve``: solve them at once).
    With ``screenshot``, wait for the solves, go to ``frame`` (default: a third into the take), save
    a PNG and quit."""
    from PySide6.QtCore import QElapsedTimer, QTimer
    from PySide6.QtWidgets import QApplication

    from app.main_window import MainWindow

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("Hand Mocap Studio")
    app.setStyle("Fusion")
    _apply_dark_palette(app)
    window = MainWindow()
    window.show()
    app.processEvents()
    if files:
        for path in files:
            window.open_file(path, solve=solve)
    else:
        window.open_demo()
    if screenshot is None:
        return app.exec()

    clock = QElapsedTimer()
    clock.start()

    def take_screenshot_when_ready() -> None:
        if window.runner.is_busy() and clock.elapsed() < SCREENSHOT_TIMEOUT_MS:
            return
        timer.stop()
        if window.document is not None:
            window.timeline.set_frame(frame if frame is not None else window.document.take.n_frames // 3)
            window.frame_hand()
        app.processEvents()
        window.save_screenshot(Path(screenshot))
        window.close()
        app.quit()

    timer = QTimer()
    timer.timeout.connect(take_screenshot_when_ready)
    timer.start(200)
    return app.exec()


def _apply_dark_palette(app) -> None:
    """A dark theme like the mocap tools operators know."""
    from PySide6.QtGui import QColor, QPalette

    palette = QPalette()
    colors = {
        QPalette.ColorRole.Window: QColor(45, 47, 52), QPalette.ColorRole.WindowText: QColor(225, 225, 225),
        QPalette.ColorRole.Base: QColor(32, 34, 38), QPalette.ColorRole.AlternateBase: QColor(40, 42, 47),
        QPalette.ColorRole.Text: QColor(225, 225, 225), QPalette.ColorRole.Button: QColor(55, 58, 64),
        QPalette.ColorRole.ButtonText: QColor(225, 225, 225), QPalette.ColorRole.Highlight: QColor(60, 120, 200),
        QPalette.ColorRole.HighlightedText: QColor(255, 255, 255), QPalette.ColorRole.ToolTipBase: QColor(55, 58, 64),
        QPalette.ColorRole.ToolTipText: QColor(225, 225, 225),
        QPalette.ColorRole.PlaceholderText: QColor(140, 140, 140),
    }
    for role, color in colors.items():
        palette.setColor(role, color)
    app.setPalette(palette)
