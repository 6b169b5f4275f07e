"""Two-hand takes and other programs' names in the application: a take labelled by ``label --hands both``, by a
lab template or by Vicon opens with its layout and both hands shown, Solve solves both, the gap dock offers the
model fill for either hand; a left-hand take opens as left."""

import numpy as np
import pytest
from two_hand_takes import LAYOUT, named_take, write_lab_template

from handmocap.core.gaps import fill_codes
from handmocap.core.io import save_take
from handmocap.core.model import add_layout_folder, remove_layout_folder

pytestmark = pytest.mark.gui


def open_and_wait(window, qtbot, path):
    with qtbot.waitSignal(window.loader.succeeded, timeout=20_000):
        window.open_files([path])
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=5_000)


def solve_and_wait(window, qtbot):
    with qtbot.waitSignal(window.solver.runner.succeeded, timeout=60_000):
        window.solve_action.trigger()


@pytest.fixture
def lab_layouts(tmp_path):
    """A lab template in a layout folder, as in an open session's ``layouts``."""
    folder = tmp_path / "layouts"
    folder.mkdir()
    write_lab_template(folder)
    add_layout_folder(folder)
    yield folder
    remove_layout_folder(folder)


@pytest.mark.parametrize("style, layout", [("label", LAYOUT), ("vicon", LAYOUT), ("template", "guitar-lab")])
def test_a_two_hand_take_shows_both_hands_and_solve_solves_both(window, qtbot, tmp_path, lab_layouts, style, layout):
    window.refresh_layout_names()
    path = tmp_path / f"{style}.c3d"
    save_take(named_take(style), path)
    open_and_wait(window, qtbot, path)
    assert window.layout_box.currentText() == layout
    assert window.side_box.currentText() == "both"
    review = window.document.review
    assert [(hand.side, len(hand.labels)) for hand in review.hands] == [("right", 13), ("left", 13)]
    solve_and_wait(window, qtbot)
    assert [result.hand_side for result in window.document.results] == ["right", "left"]
    assert all(np.isfinite(hand.joint_angles).all() for hand in review.hands) and len(review.hands) == 2
    assert np.nanmean(review.residuals_mm) < 1.0
    assert window.viewport.hand_count() == 2
    assert "right and left hands" in window.review.undo_action.text()
    assert "right" in window.statusBar().currentMessage() and "left" in window.statusBar().currentMessage()
    window.review.undo()
    assert len(review.hands) == 2 and all(np.isnan(hand.joint_angles).all() for hand in review.hands)
    assert not window.messages, window.messages


def test_the_hand_choice_solves_one_hand_of_two(window, qtbot, tmp_path):
    path = tmp_path / "both.c3d"
    save_take(named_take("label"), path)
    open_and_wait(window, qtbot, path)
    window.side_box.setCurrentText("left")
    solve_and_wait(window, qtbot)
    assert [result.hand_side for result in window.document.results] == ["left"]
    review = window.document.review
    assert np.isnan(review.hands[0].joint_angles).all() and np.isfinite(review.hands[1].joint_angles).all()


def test_a_left_hand_take_opens_as_left(window, qtbot, tmp_path):
    path = tmp_path / "left.trc"
    save_take(named_take("dash", hands="left"), path)
    open_and_wait(window, qtbot, path)
    assert window.layout_box.currentText() == LAYOUT and window.side_box.currentText() == "left"
    solve_and_wait(window, qtbot)
    assert window.document.result.hand_side == "left" and window.document.result.mean_residual_mm < 1.0
    assert [hand.side for hand in window.document.review.hands] == ["left"]


def test_the_gap_dock_fills_either_hand_with_the_model(window, qtbot, tmp_path):
    path = tmp_path / "both.c3d"
    save_take(named_take("vicon"), path)
    open_and_wait(window, qtbot, path)
    controller, review = window.review, window.document.review
    rows = controller.gap_list.rows()
    names = {review.label_names[row.marker].split(":")[0] for row in rows}
    assert names == {"RightHand", "LeftHand"}, names               # gaps of both hands are listed
    index = next(number for number, row in enumerate(rows) if review.label_names[row.marker].startswith("Left")
                 and row.length <= 30)
    controller.gap_list.table.selectRow(index)
    qtbot.waitUntil(lambda: controller.gap_list.rows()[index].checked, timeout=60_000)
    assert "model" in controller.gap_list.rows()[index].errors_mm   # the left hand's model fill applies
    gap = controller.gap_list.rows()[index]
    assert controller.accept_fill(index, "model") is not None
    assert (review.provenance[gap.start:gap.start + gap.length, gap.marker] == fill_codes()["model"]).all()
    qtbot.waitUntil(lambda: not controller.jobs.is_busy(), timeout=60_000)
    assert not window.messages, window.messages


def test_the_export_dialog_writes_a_bvh_per_hand_and_one_gltf(qtbot, tmp_path):
    from handmocap.app.gui.export_dialog import ExportDialog
    from handmocap.core.model import load_template
    from handmocap.core.model.bvh import read_bvh
    from handmocap.core.review import ReviewTake

    review = ReviewTake.from_labelled_take(named_take("label", frames=30))
    for number, hand in enumerate(review.hands):
        hand.joint_angles[:] = 0.0
        hand.joint_angles[:, 0] = 100.0 * number
    review.take.source_path = str(tmp_path / "take.c3d")        # exports are proposed next to the raw take
    dialog = ExportDialog(None, review, load_template, None, "take")
    qtbot.addWidget(dialog)
    assert dialog.hand_box.currentData() is None and dialog.hand_box.count() == 3
    written: list[str] = []
    dialog.exported.connect(lambda name, path: written.append(path))
    dialog.format_box.setCurrentIndex(dialog.format_box.findData("bvh"))
    assert dialog.export()
    assert written == [str(tmp_path / "take_angles_right.bvh"), str(tmp_path / "take_angles_left.bvh")]
    assert read_bvh(tmp_path / "take_angles_left.bvh").joint_names[0] == "L_wrist"
