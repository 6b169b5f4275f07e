"""A take file opened outside a session (File ▸ Open) never loses an edit: it is reviewed in an automatic
session in the user data folder, every edit journalled at once, and reopening the file brings the review
back; when that folder cannot be written the review works in memory and says its edits will not survive."""

import os

import numpy as np
import pytest
import shiboken6
from conftest import release
from PySide6.QtWidgets import QMessageBox

from handmocap.app.gui.loose_takes import LOOSE_FOLDER, loose_folder
from handmocap.app.gui.main_window import MainWindow
from handmocap.app.gui.review.dialogs import AutoLabelSettings
from handmocap.core.io import save_take
from handmocap.core.simulate import simulate_take

pytestmark = pytest.mark.gui


@pytest.fixture
def take_file(tmp_path):
    path = tmp_path / "files" / "grasps.trc"
    path.parent.mkdir()
    save_take(simulate_take(layout="dense", n_frames=120, seed=4, noise_mm=0.3).take, path)
    return path


@pytest.fixture
def new_window(qtbot, monkeypatch):
    """Makes main windows (message boxes captured in ``window.messages``); closes what is left open."""
    windows = []
    monkeypatch.setattr(QMessageBox, "warning", lambda parent, title, text: parent.messages.append(text))

    def make():
        window = MainWindow()
        window.messages = []
        qtbot.addWidget(window)
        window.show()
        windows.append(window)
        return window

    yield make
    for window in windows:
        if shiboken6.isValid(window):      # a closed main window deletes itself
            window.close()
            release(window)


def open_and_wait(window, qtbot, path):
    with qtbot.waitSignal(window.loader.succeeded, timeout=20_000):
        window.open_files([path])
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=5_000)


def assign_other_label(window, frame=60, label=3, other=5):
    """Click the point of ``label`` at ``frame`` and give it label ``other`` to the end of its fragment."""
    review, controller = window.document.review, window.review
    window.timeline.set_frame(frame)
    column = int(review.assignment[frame, label])
    window.viewport.marker_clicked.emit(column)
    assert window.app.selection.label == label
    controller.scope_box.setCurrentIndex(controller.scope_box.findData("fragment"))
    controller.assign_label(review.label_names[other])
    assert review.assignment[frame, other] == column
    return column


def test_an_edit_survives_closing_the_window_without_saving(new_window, qtbot, take_file, data_folder):
    files_before = sorted(os.listdir(take_file.parent))
    window = new_window()
    open_and_wait(window, qtbot, take_file)
    column = assign_other_label(window)
    qtbot.waitUntil(lambda: not window.review.jobs.is_busy(), timeout=60_000)
    journal = loose_folder(take_file) / "takes" / "t0001" / "journal.jsonl"
    assert journal.exists() and journal.stat().st_size > 0       # journalled at once, before any save
    window.close()                                                # no prompt, no save asked
    again = new_window()
    open_and_wait(again, qtbot, take_file)
    review = again.document.review
    assert review.assignment[60, 5] == column and review.edited[60, 5]
    assert "restored" in again.statusBar().currentMessage()
    assert again.windowTitle().startswith("grasps.trc —")
    assert again.review.undo_action.isEnabled()                  # the edit can still be undone
    assert sorted(os.listdir(take_file.parent)) == files_before  # nothing written next to the file
    assert loose_folder(take_file).parent == data_folder / LOOSE_FOLDER
    assert not again.messages, again.messages


def test_closing_the_take_keeps_the_auto_labelling(new_window, qtbot, tmp_path):
    simulated = simulate_take(layout="dense", n_frames=150, seed=1, noise_mm=0.3, ghost_rate=0.05,
                              unlabelled=True)
    path = tmp_path / "raw.c3d"
    save_take(simulated.take, path)
    window = new_window()
    open_and_wait(window, qtbot, path)
    assert window.document.is_raw and window.document.review.n_labels == 0
    window.review.start_auto_label(AutoLabelSettings(layout="dense", hands="right"))
    qtbot.waitUntil(lambda: not window.review.jobs.is_busy(), timeout=120_000)
    labelled = window.document.review.assignment.copy()
    assert window.document.review.n_labels == 24
    window.close_take_action.trigger()                           # File ▸ Close take
    assert window.document is None
    open_and_wait(window, qtbot, path)
    document = window.document
    np.testing.assert_array_equal(document.review.assignment, labelled)
    assert "right" in document.hand_models                        # the hand auto-label calibrated came back
    assert not window.messages, window.messages


def test_opening_the_open_file_again_shows_it(new_window, qtbot, take_file):
    window = new_window()
    open_and_wait(window, qtbot, take_file)
    first = window.document
    window.open_files([take_file])
    assert window.document is first and len(window.app.documents) == 1
    assert not first.open_take.read_only


def test_another_window_opens_it_read_only(new_window, qtbot, take_file):
    first = new_window()
    open_and_wait(first, qtbot, take_file)
    second = new_window()
    open_and_wait(second, qtbot, take_file)
    assert second.document.open_take.read_only and second.document.title.endswith("(read-only)")
    column = int(second.document.review.assignment[60, 3])
    second.viewport.marker_clicked.emit(column)
    assert second.review.assign_label(second.document.review.label_names[5]) is None
    assert second.messages and "is editing it" in second.messages[-1]


def test_a_changed_file_starts_a_new_review(new_window, qtbot, take_file):
    window = new_window()
    open_and_wait(window, qtbot, take_file)
    assign_other_label(window)
    qtbot.waitUntil(lambda: not window.review.jobs.is_busy(), timeout=60_000)
    window.close()
    save_take(simulate_take(layout="dense", n_frames=120, seed=9, noise_mm=0.3).take, take_file)
    again = new_window()
    open_and_wait(again, qtbot, take_file)
    assert not again.document.review.edited.any()                 # the edits were made on other data
    assert "changed on disk" in again.statusBar().currentMessage()
    assert list(loose_folder(take_file).parent.glob("*.replaced-*"))   # the old review is kept aside


def test_unwritable_data_folder_reviews_in_memory_with_a_warning(new_window, qtbot, take_file, tmp_path,
                                                                 monkeypatch):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the data folder should be")
    monkeypatch.setenv("HANDMOCAP_DATA", str(blocker / "handmocap"))   # cannot be made, even by root
    window = new_window()
    open_and_wait(window, qtbot, take_file)
    document = window.document
    assert document.open_take is None and document.title == "grasps.trc (edits not kept)"
    assert window.messages and "edits will not survive" in window.messages[0]
    assert "edits will not survive" in window.statusBar().currentMessage()
    column = assign_other_label(window)                           # the review still works, in memory
    window.review.undo()
    assert document.review.assignment[60, 5] != column
    assert blocker.read_text().startswith("a file")
