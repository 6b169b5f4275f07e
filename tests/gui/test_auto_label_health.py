"""The auto-label dialog (hands "auto" by default, relabel from scratch), the labels the file already has
kept through auto-label, solve after auto-label with the subject's hand, and the labelling's warnings
in the status bar and the problem list (F3), driven through the real widgets."""


import numpy as np
import pytest
from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import QApplication, QDialogButtonBox

from handmocap.app.gui.review.dialogs import AutoLabelDialog, AutoLabelSettings
from handmocap.core.evaluation.data import REAL_RECORDING
from handmocap.core.io import load_take, save_take
from handmocap.core.io.labelled_c3d import subject_calibrations
from handmocap.core.review import MEASURED
from handmocap.core.session import Session
from handmocap.core.simulate import simulate_take

pytestmark = pytest.mark.gui

OTHER = ["right_elbow", "back_top", "back_left", "back_right", "right_shoulder", "pillow_top", "pillow_left",
         "pillow_right"]
needs_real = pytest.mark.skipif(not REAL_RECORDING.exists(), reason="the real recording is not in ../shared")


def open_and_wait(window, qtbot, path):
    with qtbot.waitSignal(window.loader.succeeded, timeout=30_000):
        window.open_files([path])
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=5_000)


def label_through_dialog(window, qtbot, layout: str, relabel: bool = False) -> None:
    """Open Auto-label from its action, choose ``layout`` (and relabel) in the dialog, press Auto-label."""
    seen = {}

    def fill_dialog():
        dialog = QApplication.activeModalWidget()
        assert isinstance(dialog, AutoLabelDialog)
        seen["hands"] = dialog.hands_box.currentText()
        dialog.layout_box.setCurrentText(layout)
        if relabel:
            qtbot.mouseClick(dialog.relabel_box, Qt.MouseButton.LeftButton)
        ok = dialog.findChild(QDialogButtonBox).button(QDialogButtonBox.StandardButton.Ok)
        qtbot.mouseClick(ok, Qt.MouseButton.LeftButton)

    QTimer.singleShot(200, fill_dialog)
    window.review.auto_label_action.trigger()
    qtbot.waitUntil(lambda: not window.review.jobs.is_busy(), timeout=180_000)
    assert seen["hands"] == "auto"
    assert not window.messages, window.messages


def test_dialog_defaults_to_auto_hands_and_offers_relabel(window, qtbot):
    dialog = AutoLabelDialog(window, AutoLabelSettings())
    qtbot.addWidget(dialog)
    assert [dialog.hands_box.itemText(i) for i in range(dialog.hands_box.count())] == ["auto", "right", "left",
                                                                                        "both"]
    assert dialog.hands_box.currentText() == "auto" and dialog.settings().hands == "auto"
    assert not dialog.relabel_box.isChecked() and dialog.settings().relabel is False
    dialog.show()
    qtbot.mouseClick(dialog.relabel_box, Qt.MouseButton.LeftButton)
    assert dialog.settings().relabel is True


@needs_real
def test_real_take_keeps_its_other_markers_and_solves_with_the_subject(window, qtbot):
    open_and_wait(window, qtbot, REAL_RECORDING)
    document = window.document
    label_through_dialog(window, qtbot, "glove-13")
    review = document.review
    take = review.take
    for name in OTHER:
        label, column = review.label_index(name), take.marker_names.index(name)
        present = np.isfinite(take.marker_positions[:, column]).all(axis=1)
        assert (review.assignment[present, label] == column).all()
        assert (review.provenance[present, label] == MEASURED).all() and not review.ghost[:, column].any()
    assert int(review.ghost.sum()) < 200
    message = window.statusBar().currentMessage()
    assert message.startswith("Auto-label: ") or "kept from the file: 8 labels outside the layout" in message
    assert "right" in document.marker_sets                          # the subject's calibrated markers
    assert window.viewport.hand_count() == 1
    window.solve_action.trigger()
    qtbot.waitUntil(lambda: document.result is not None, timeout=120_000)
    assert document.result.mean_residual_mm < 2.6                   # template: 2.95 mm
    assert not window.messages, window.messages


@needs_real
def test_labelling_warning_in_status_bar_problem_list_and_screenshot(window, qtbot, tmp_path):
    open_and_wait(window, qtbot, REAL_RECORDING)
    label_through_dialog(window, qtbot, "glove-13", relabel=True)    # the arm, back and pillow become ghosts
    review = window.document.review
    assert review.health and any(warning.kind == "many_ghosts" for warning in review.health)
    message = window.statusBar().currentMessage()
    assert message.startswith("Auto-label: ") and "warning" in message and "ghosts" in message
    assert "auto-label warnings" in window.review.problem_label.text()
    warning = next(problem for problem in review.problems() if problem.kind == "labelling")
    window.timeline.set_frame(warning.start + 1)
    window.review.previous_problem_action.trigger()
    assert window.statusBar().currentMessage().startswith("Auto-label: ")
    window.timeline.set_frame(1500)
    window.review.next_problem_action.trigger()
    assert window.timeline.frame > 1500 or window.timeline.frame == review.problems()[0].start
    window.app.show(window.document)                                 # the summary comes back with the take
    window.timeline.set_frame(1200)
    QApplication.processEvents()
    assert window.statusBar().currentMessage().startswith("Auto-label: ")
    screenshot = tmp_path / "auto-label-warning.png"
    assert window.save_screenshot(screenshot) and screenshot.stat().st_size > 10_000


def test_session_take_keeps_the_subject_markers_and_exports_the_calibration(window, qtbot, tmp_path):
    simulated = simulate_take(layout="dense", n_frames=150, seed=4, noise_mm=0.3, unlabelled=True)
    path = tmp_path / "raw.c3d"
    save_take(simulated.take, path)
    folder = tmp_path / "session"
    assert window.sessions.create_session(folder)
    window.sessions.add_takes([str(path)])
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=30_000)
    take_id = window.sessions.session.takes[0].id
    window.sessions.open_take(take_id)
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=30_000)
    window.review.start_auto_label(AutoLabelSettings(layout="dense", hands="right"))
    qtbot.waitUntil(lambda: not window.review.jobs.is_busy(), timeout=120_000)
    assert not window.messages, window.messages
    document = window.document
    markers = document.marker_sets["right"]
    assert (document.open_take.folder / "labelling_markers_right.npz").exists()
    window.sessions.close()
    opened = Session.open(folder).open_take(take_id)
    window.sessions._take_opened(opened)
    reopened = window.document
    assert reopened is not document
    np.testing.assert_array_equal(reopened.marker_sets["right"].local_points, markers.local_points)
    assert reopened.marker_set_for("right", "dense") is reopened.marker_sets["right"]
    assert reopened.subjects["right"].layout == "dense"
    exported = tmp_path / "exported.c3d"
    window.review.export_c3d(str(exported))                         # a CLI solve of it uses the subject
    assert [subject.side for subject in subject_calibrations(load_take(exported).parameters)] == ["right"]
