"""GUI tests run on a virtual screen (Xvfb via installer/test.sh) or, without a display, on Qt's
offscreen platform with pyvista off screen (the 3D view then keeps its data but draws nothing)."""

import os

import pytest

if not os.environ.get("DISPLAY"):
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
if os.environ.get("QT_QPA_PLATFORM") == "offscreen":
    import pyvista

    pyvista.OFF_SCREEN = True


@pytest.fixture(autouse=True)
def data_folder(tmp_path, monkeypatch):
    """Each test's own user data folder: files opened outside a session keep their reviews there, not in
    the user's home (and no test sees another's edits)."""
    folder = tmp_path / "handmocap-data"
    monkeypatch.setenv("HANDMOCAP_DATA", str(folder))
    return folder


@pytest.fixture(autouse=True)
def modifiers_released(qtbot):
    """After each test, release the modifier keys a shortcut test pressed: Qt keeps a modifier in the
    application's state until its own release arrives, and the next test's 3D-view clicks would be Ctrl+clicks."""
    yield
    from PySide6.QtCore import Qt
    from PySide6.QtWidgets import QWidget

    target = QWidget()
    for key in (Qt.Key.Key_Control, Qt.Key.Key_Shift, Qt.Key.Key_Alt, Qt.Key.Key_Meta):
        qtbot.keyRelease(target, key)
    target.deleteLater()


@pytest.fixture
def window(qtbot, monkeypatch):
    """A main window with message boxes captured instead of shown."""
    from PySide6.QtWidgets import QMessageBox

    from handmocap.app.gui.main_window import MainWindow

    messages: list[str] = []
    monkeypatch.setattr(QMessageBox, "warning", lambda parent, title, text: messages.append(text))
    main_window = MainWindow()
    main_window.messages = messages
    qtbot.addWidget(main_window)
    main_window.show()
    yield main_window
    main_window.close()
    release(main_window)


@pytest.fixture
def viewport(qtbot):
    """A 3D view of its own, 640×480, shown; closed after the test."""
    from handmocap.widgets.viewport import HandViewport

    view = HandViewport()
    qtbot.addWidget(view)
    view.resize(640, 480)
    view.show()
    yield view
    view.close_viewport()


def release(widget) -> None:
    """Delete a top-level widget now, while Qt runs: a closed window's 3D views left alive keep the GUI
    thread busy in later tests (a Cancel then arrives too late), and pyqtgraph items left to the
    interpreter's final garbage collection can crash it."""
    import gc

    from PySide6.QtCore import QCoreApplication, QEvent
    from PySide6.QtWidgets import QApplication

    widget.deleteLater()
    QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
    QApplication.processEvents()
    gc.collect()
