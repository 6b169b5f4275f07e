"""Starting the application: QApplication, main window, files or the demo session, screenshot mode."""

from __future__ import annotations

import sys
from pathlib import Path

from PySide6.QtCore import QElapsedTimer, QTimer
from PySide6.QtWidgets import QApplication

from app.gui.palette import apply_dark_palette
from core.errors import InputError

SCREENSHOT_TIMEOUT_MS = 120_000
MIN_SIZE = (640, 480)        # smaller windows cannot hold the 3D view and the docks
MAX_SIDE = 16384             # larger than any screen (and than Qt's widget size limit)


def window_size(text: str) -> tuple[int, int]:
    """``"WxH"`` (pixels, e.g. ``1366x768``) as ``(width, height)``; InputError when it is not one."""
    width, _, height = text.lower().partition("x")
    if not (width.strip().isdigit() and height.strip().isdigit()):
        raise InputError(f"--size {text}: give the window size as WIDTHxHEIGHT in pixels, e.g. 1366x768")
    size = int(width), int(height)
    if not (MIN_SIZE[0] <= size[0] <= MAX_SIDE and MIN_SIZE[1] <= size[1] <= MAX_SIDE):
        raise InputError(f"--size {text}: the window must be {MIN_SIZE[0]}x{MIN_SIZE[1]} to {MAX_SIDE}x{MAX_SIDE} "
                         "pixels")
    return size


def run_gui(files: list[str], screenshot: str | None = None, frame: int | None = None, solve: bool = False,
            demo: bool = False, size: str | None = None) -> int:
    """Open the main window on ``files`` (and the demo session when ``demo`` or when no file is given;
    ``solve``: solve the files at once), ``size`` ``"WxH"`` pixels (default the window's own). With
    ``screenshot``, wait until everything is opened and solved, go to ``frame`` (0-based; default a third
    into the take), save a PNG and quit. Returns the process exit code."""
    from app.gui.main_window import APP_NAME, MainWindow

    requested = window_size(size) if size else None
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName(APP_NAME)
    app.setStyle("Fusion")
    apply_dark_palette(app)
    window = MainWindow()
    window.show()
    app.processEvents()
    if requested is not None:          # after showing: before, the unfinished layout makes Qt grow it
        window.resize(*requested)
        app.processEvents()
    if demo or not files:
        window.open_demo()
    if files:
        window.open_files(files, solve=solve)
    if screenshot is None:
        code = app.exec()
        _release(window, app)
        return code

    clock = QElapsedTimer()
    clock.start()
    outcome = {"code": 1}

    def take_screenshot_when_ready() -> None:
        if window.is_busy() and clock.elapsed() < SCREENSHOT_TIMEOUT_MS:
            return
        timer.stop()
        if window.document is not None:
            window.app.set_frame(frame if frame is not None else window.document.take.n_frames // 3)
            window.frame_hand()
        app.processEvents()
        outcome["code"] = 0 if window.save_screenshot(Path(screenshot)) else 1
        window.close()
        app.quit()

    timer = QTimer()
    timer.timeout.connect(take_screenshot_when_ready)
    timer.start(200)
    app.exec()
    _release(window, app)
    return outcome["code"]


def _release(window, app: QApplication) -> None:
    """Delete the window while Qt still runs: pyqtgraph plots alive at interpreter exit can abort it."""
    window.deleteLater()
    app.processEvents()
