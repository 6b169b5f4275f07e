"""A take file that states no frame rate (NOKOV CSV) is never refused: File ▸ Open and Add takes ask its rate
(offering the last one given), the automatic or real session keeps it, and opening the take again asks nothing."""

import numpy as np
import pytest
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication, QDialog

from handmocap.core.session import Session
from handmocap.core.simulate import simulate_take
from handmocap.widgets.frame_rate_dialog import DEFAULT_FRAME_RATE_HZ, FrameRateDialog, FrameRatePrompt

pytestmark = pytest.mark.gui


@pytest.fixture
def nokov_file(tmp_path):
    """A NOKOV-shaped export of a simulated take: `<name>-X,<name>-Y,<name>-Z` columns, `nan`, no rate."""
    take = simulate_take(layout="dense", n_frames=60, seed=2, noise_mm=0.3).take
    path = tmp_path / "files" / "arpeggio.csv"
    path.parent.mkdir()
    rows = [",".join(f"{name}-{axis}" for name in take.marker_names for axis in "XYZ")]
    rows += [",".join(f"{value:.6f}" for value in frame.ravel()) for frame in take.marker_positions]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture
def answers(monkeypatch):
    """The rates the dialog is answered with, in order (None: Skip); ``asked`` lists the files asked about."""
    replies: list[float | None] = []
    asked: list[float] = []

    def exec_dialog(dialog: FrameRateDialog) -> int:
        asked.append(dialog.rate_box.value())           # the rate the field offered
        reply = replies.pop(0)
        if reply is None:
            return QDialog.DialogCode.Rejected
        dialog.rate_box.setValue(reply)
        return QDialog.DialogCode.Accepted

    monkeypatch.setattr(FrameRateDialog, "exec", exec_dialog)
    return replies, asked


def wait_loader(window, qtbot):
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=30_000)


def test_the_dialog_has_a_rate_field_in_hz(qtbot):
    dialog = FrameRateDialog("arpeggio.csv")
    qtbot.addWidget(dialog)
    assert dialog.rate_box.value() == DEFAULT_FRAME_RATE_HZ and dialog.rate_box.suffix() == " Hz"
    dialog.rate_box.setValue(0.0)
    assert dialog.rate_hz() > 0                       # the field cannot go to zero
    dialog.rate_box.setValue(120.0)
    assert dialog.rate_hz() == 120.0


def test_the_prompt_asks_with_the_real_dialog_and_remembers_the_rate(qtbot):
    prompt = FrameRatePrompt()

    def answer(rate: float | None) -> None:
        dialog = QApplication.activeModalWidget()
        assert isinstance(dialog, FrameRateDialog)
        if rate is None:
            dialog.reject()
        else:
            dialog.rate_box.setValue(rate)
            dialog.accept()

    QTimer.singleShot(0, lambda: answer(120.0))
    assert prompt.ask("a.csv") == 120.0
    offered = []
    QTimer.singleShot(0, lambda: offered.append(QApplication.activeModalWidget().rate_box.value()) or answer(None))
    assert prompt.ask("b.csv") is None
    assert offered == [120.0] and prompt.last_rate_hz == 120.0


def test_file_open_asks_the_rate_once_and_remembers_it(window, qtbot, nokov_file, answers):
    replies, asked = answers
    replies.append(120.0)
    window.open_files([nokov_file])
    qtbot.waitUntil(lambda: window.document is not None, timeout=30_000)
    wait_loader(window, qtbot)
    assert asked == [DEFAULT_FRAME_RATE_HZ]             # asked once, 100 Hz offered first
    take = window.document.take
    assert take.frame_rate == 120.0 and take.vendor == "NOKOV" and take.n_frames == 60
    assert not window.messages, window.messages
    window.close_take_action.trigger()
    window.open_files([nokov_file])                     # the automatic session kept the rate: nothing asked
    qtbot.waitUntil(lambda: window.document is not None, timeout=30_000)
    wait_loader(window, qtbot)
    assert asked == [DEFAULT_FRAME_RATE_HZ] and window.document.take.frame_rate == 120.0


def test_skipping_the_rate_opens_nothing_and_says_why(window, qtbot, nokov_file, answers):
    replies, asked = answers
    replies.append(None)
    window.open_files([nokov_file])
    qtbot.waitUntil(lambda: len(asked) == 1, timeout=30_000)
    wait_loader(window, qtbot)
    assert window.document is None and not window.messages
    assert "arpeggio.csv not opened: it states no frame rate" in window.statusBar().currentMessage()


def test_add_takes_asks_the_rate_and_the_session_keeps_it(window, qtbot, nokov_file, answers, tmp_path):
    replies, asked = answers
    replies.append(240.0)
    folder = tmp_path / "session"
    assert window.sessions.create_session(folder)
    window.sessions.add_takes([str(nokov_file)])
    qtbot.waitUntil(lambda: bool(window.sessions.session.takes), timeout=30_000)
    wait_loader(window, qtbot)
    entry = window.sessions.session.takes[0]
    assert asked == [DEFAULT_FRAME_RATE_HZ] and entry.frame_rate == 240.0 and entry.frame_rate_given
    window.sessions.open_take(entry.id)                 # read again at the kept rate: nothing asked
    qtbot.waitUntil(lambda: window.document is not None, timeout=30_000)
    wait_loader(window, qtbot)
    assert len(asked) == 1 and window.document.take.frame_rate == 240.0
    assert not window.messages, window.messages
    reopened = Session.open(folder, read_only=True).open_take(entry.id)
    assert reopened.review.take.frame_rate == 240.0
    np.testing.assert_allclose(reopened.review.take.marker_positions, window.document.take.marker_positions)
    reopened.close(save=False)


def test_a_rate_given_on_the_command_line_opens_without_asking(window, qtbot, nokov_file, answers):
    _replies, asked = answers
    window.open_files([nokov_file], frame_rate=90.0)          # handmocap gui FILE --rate 90
    qtbot.waitUntil(lambda: window.document is not None, timeout=30_000)
    wait_loader(window, qtbot)
    assert asked == [] and window.document.take.frame_rate == 90.0
