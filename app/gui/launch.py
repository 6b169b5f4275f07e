"""Starting the application: QApplication, main window, files or the demo session, screenshot mode."""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path
from typing import cast

from PySide6.QtCore import QElapsedTimer, QTimer
from PySide6.QtGui import QColor, QIcon, QPainter, QPixmap
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.palette import apply_dark_palette
from handmocap.core.errors import InputError
from handmocap.core.io.resources import resource_path
from handmocap.widgets.start_splash import StartSplash

SCREENSHOT_TIMEOUT_MS = 120_000
ICONS = resource_path("icons")
ICON_SIZES = (16, 32, 48, 64, 128, 256, 512)   # pixels of the shipped PNGs (handmocap-<size>.png)
SPLASH_SIZE = (480, 300)                         # pixels of the start-up splash: the icon, a line of text below
SPLASH_ICON = 200                                # pixels of the icon on it
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
            demo: bool = False, size: str | None = None, frame_rate: float | None = None) -> int:
    """Open the main window on ``files`` (and the demo session when ``demo`` or when no file is given;
    ``solve``: solve the files at once; ``frame_rate``: their rate in Hz, asked for a file that states none
    when not given), ``size`` ``"WxH"`` pixels (default the window's own). With
    ``screenshot``, wait until everything is opened and solved, go to ``frame`` (the file's frame number, as
    the timeline shows it; default a third into the take), save a PNG and quit. Returns the process exit code."""
    requested = window_size(size) if size else None
    app = cast(QApplication, QApplication.instance()) or QApplication(sys.argv[:1])    # (a QApplication if any)
    icon = application_icon()
    app.setWindowIcon(icon)
    splash = StartSplash(_splash_picture(icon))
    splash.show_now()
    splash.tell("Starting Hand Mocap Studio…")

    from handmocap.app.gui.main_window import APP_NAME, MainWindow

    app.setApplicationName(APP_NAME)
    app.setStyle("Fusion")
    apply_dark_palette(app)
    if getattr(sys, "frozen", False):
        _prepare_kernels(splash)
    window = MainWindow()
    window.show()
    splash.close()
    app.processEvents()
    if requested is not None:          # after showing: before, the unfinished layout makes Qt grow it
        window.resize(*requested)
        app.processEvents()
    if demo or not files:
        window.open_demo()
    folders = [session_folder(Path(path)) for path in files]
    sessions = [folder for folder in folders if folder is not None]
    takes = [path for path, folder in zip(files, folders, strict=True) if folder is None]
    if sessions:                       # a session folder or its session.json (the file manager's "Open with")
        window.sessions.open_session(sessions[-1])
    if takes:
        window.open_files(takes, solve=solve, frame_rate=frame_rate)
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
            take = window.document.take
            window.app.set_frame(frame - take.first_frame if frame is not None else take.n_frames // 3)
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


def session_folder(path: Path) -> Path | None:
    """The session folder ``path`` names (the folder or its manifest, ``session.json``), else None."""
    from handmocap.core.session.session import MANIFEST_NAME

    if path.name == MANIFEST_NAME and path.is_file():
        return path.parent
    return path if (path / MANIFEST_NAME).is_file() else None


def application_icon() -> QIcon:
    """The Hand Mocap Studio icon: the PNGs of ``resources/icons`` at every shipped size."""
    icon = QIcon()
    for pixels in ICON_SIZES:
        icon.addFile(str(ICONS / f"handmocap-{pixels}.png"))
    return icon


def _splash_picture(icon: QIcon) -> QPixmap:
    """The splash: the icon centred near the top of a dark card, room for a message line below it."""
    picture = QPixmap(*SPLASH_SIZE)
    picture.fill(QColor(45, 47, 52))   # the dark palette's window colour
    painter = QPainter(picture)
    painter.drawPixmap((SPLASH_SIZE[0] - SPLASH_ICON) // 2, 30, icon.pixmap(SPLASH_ICON, SPLASH_ICON))
    painter.end()
    return picture


def _prepare_kernels(splash: StartSplash) -> None:
    """At the first start of a frozen bundle, compile (or load the bundle's warmed cache of) every numba
    kernel under the splash, so that no operator action waits for the compiler; later starts skip it.

    The stamp file in the user cache folder names the executable and its modification time, so a new or
    moved bundle prepares its kernels once again."""
    from handmocap.core.io.durable import write_text_atomic
    from handmocap.core.workflows.warm_up import warm_up

    executable = Path(sys.executable).resolve()
    key = hashlib.sha1(f"{executable}:{executable.stat().st_mtime_ns}".encode()).hexdigest()[:16]
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "handmocap"
    stamp = cache / f"kernels-ready-{key}"
    if stamp.exists():
        return
    splash.tell("First start: preparing the computing kernels (once, up to a minute)…")
    seconds = warm_up(report=lambda line: splash.tell(f"First start: {line}…"))
    try:
        cache.mkdir(parents=True, exist_ok=True)
        write_text_atomic(stamp, f"{executable}\nkernels ready in {seconds:.1f} s\n")
    except OSError:
        pass  # a cache folder that cannot be written: the kernels are prepared again at the next start


def _release(window, app: QApplication) -> None:
    """Delete the window while Qt still runs: pyqtgraph plots alive at interpreter exit can abort it."""
    window.deleteLater()
    app.processEvents()
