"""Events and trim in the window (issue 23 item 7): Ctrl+M names the current frame, the timeline marks it,
Ctrl+Right/Left and Review ▸ Go to event jump to it; I, O and Ctrl+T trim the take (shown, played and exported
within the range); each is one undoable step."""

from __future__ import annotations

import pytest
from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import QApplication

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.dialogs import EventDialog
from handmocap.core.review import review_from_labelled_c3d
from handmocap.core.simulate import simulate_take

pytestmark = pytest.mark.gui
FRAMES = 300


@pytest.fixture
def shown(window, qtbot):
    take = simulate_take(layout="dense", n_frames=FRAMES, seed=9, noise_mm=0.3).take
    window.add_document(TakeDocument(take, "events"))
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=2_000)
    return window


def test_ctrl_m_names_the_frame_and_the_timeline_jumps_to_it(shown, qtbot):
    window, controller = shown, shown.review
    review = window.document.review
    window.app.set_frame(120)

    def name_it() -> None:
        dialog = QApplication.activeModalWidget()
        assert isinstance(dialog, EventDialog)
        dialog.name_box.setCurrentText("grasp on")
        dialog.context_box.setCurrentText("Right")
        dialog.accept()

    QTimer.singleShot(200, name_it)
    qtbot.keyClick(window.viewport, Qt.Key.Key_M, Qt.KeyboardModifier.ControlModifier)
    assert [(event.name, event.frame_number, event.context) for event in review.events] == [("grasp on", 121, "Right")]
    assert window.timeline.event_marks() == [(120, "grasp on")]
    assert [action.text() for action in controller.events_menu.actions()] == ["grasp on — frame 121 (Right)"]
    window.app.set_frame(10)
    window.activateWindow()                                  # the dialog had the keyboard
    qtbot.waitUntil(window.isActiveWindow, timeout=2_000)
    qtbot.keyClick(window.viewport, Qt.Key.Key_Right, Qt.KeyboardModifier.ControlModifier)
    assert window.app.frame == 120 and "grasp on" in window.statusBar().currentMessage()
    window.app.set_frame(200)
    controller.events_menu.actions()[0].trigger()
    assert window.app.frame == 120
    controller.undo()
    assert review.events == [] and window.timeline.event_marks() == []
    controller.redo()
    assert window.timeline.event_marks() == [(120, "grasp on")]
    assert not window.messages, window.messages


def test_i_o_and_ctrl_t_trim_the_take_shown_played_and_exported(shown, qtbot, tmp_path):
    window, controller = shown, shown.review
    review = window.document.review
    window.app.set_frame(50)
    qtbot.keyClick(window.viewport, Qt.Key.Key_I)
    window.app.set_frame(249)
    qtbot.keyClick(window.viewport, Qt.Key.Key_O)
    controller.add_event("grasp off")
    qtbot.keyClick(window.viewport, Qt.Key.Key_T, Qt.KeyboardModifier.ControlModifier)
    assert review.trim == (50, 250) and window.timeline.trim_range() == (50, 250)
    assert controller.undo_action.text() == "&Undo trim the take to frames 51-250"
    window.app.set_frame(0)
    assert window.app.frame == 50 and window.timeline.frame == 50            # the frames outside are not shown
    assert window.timeline.frame_box.minimum() == 51 and window.timeline.frame_box.maximum() == 250
    qtbot.keyClick(window.viewport, Qt.Key.Key_End)
    assert window.app.frame == 249
    out = tmp_path / "trimmed.c3d"
    controller.export_c3d(str(out))
    exported = review_from_labelled_c3d(out)
    assert exported.n_frames == 200 and exported.take.first_frame == 51
    assert [(event.name, event.frame_number) for event in exported.events] == [("grasp off", 250)]
    controller.undo()                                                        # the trim goes, the frames come back
    assert review.trim is None and window.timeline.trim_range() == (0, FRAMES)
    window.app.set_frame(0)
    assert window.app.frame == 0
    assert not window.messages, window.messages
