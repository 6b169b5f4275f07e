"""Take review driven like an operator: auto-label a raw take, edit labels with undo/redo, fill gaps,
jump to problems, export a labelled C3D."""

import numpy as np
import pytest
from simulated_files import save_raw_take

from handmocap.app.gui.review.dialogs import AutoLabelSettings
from handmocap.core.io import save_take
from handmocap.core.simulate import simulate_take

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def raw_take(tmp_path_factory):
    """A raw (unlabelled, per-frame shuffled) take with ghosts and occlusion gaps, and its truth."""
    path = tmp_path_factory.mktemp("raw") / "raw.c3d"
    return path, save_raw_take(path, n_frames=300, seed=1).truth


def open_and_wait(window, qtbot, path):
    with qtbot.waitSignal(window.loader.succeeded, timeout=20_000):
        window.open_files([path])
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=5_000)


def wait_jobs(window, qtbot, timeout=120_000):
    qtbot.waitUntil(lambda: not window.review.jobs.is_busy(), timeout=timeout)


def auto_label(window, qtbot):
    window.review.start_auto_label(AutoLabelSettings(layout="dense", hands="right"))
    wait_jobs(window, qtbot)
    assert not window.messages, window.messages


def test_auto_label_fills_lanes_table_and_hand(window, qtbot, raw_take):
    path, truth = raw_take
    open_and_wait(window, qtbot, path)
    document = window.document
    assert document.is_raw and document.review.n_labels == 0
    assert not window.review.assign_action.isEnabled()          # nothing to edit before labelling
    auto_label(window, qtbot)
    review = document.review
    assert review.n_labels == 24 and len(review.hands) == 1
    assert window.review.lanes.n_markers == 24
    assert window.review.table.model.rowCount() == 24
    # the points carry the true labels: compare with the simulator's truth
    point_marker = truth["point_marker"]
    frames, labels = np.nonzero(review.assignment >= 0)
    correct = point_marker[frames, review.assignment[frames, labels]] == labels
    assert correct.mean() > 0.99
    # the hand is drawn and follows the data
    window.timeline.set_frame(50)
    assert window.viewport.hand_count() == 1
    assert window.viewport.vertex_points().shape[0] > 1000
    names = window.viewport.marker_names()
    assert review.label_names[0] in names
    assert window.review.undo_action.isEnabled() and "auto-label" in window.review.undo_action.text()


def test_label_edits_undo_redo(window, qtbot, raw_take):
    path, _ = raw_take
    open_and_wait(window, qtbot, path)
    auto_label(window, qtbot)
    review, controller = window.document.review, window.review
    window.timeline.set_frame(100)
    label = 7
    column = int(review.assignment[100, label])
    assert column >= 0
    before = review.assignment.copy()
    # click the point in the 3D view, then unlabel it over the whole take
    window.viewport.marker_clicked.emit(column)
    assert window.app.selection.label == label
    controller.scope_box.setCurrentIndex(controller.scope_box.findData("take"))
    controller.unlabel()
    assert (review.assignment[:, label] == -1).all()
    wait_jobs(window, qtbot)
    controller.undo_action.trigger()
    np.testing.assert_array_equal(review.assignment, before)
    controller.redo_action.trigger()
    assert (review.assignment[:, label] == -1).all()
    controller.undo_action.trigger()
    # assign another label to the point from here to the end of its fragment; undo restores it exactly
    window.viewport.marker_clicked.emit(column)
    controller.scope_box.setCurrentIndex(controller.scope_box.findData("fragment"))
    other = review.label_names[8]
    controller.assign_label(other)
    assert review.assignment[100, 8] == column and review.assignment[100, label] != column
    assert review.edited[100, 8]
    wait_jobs(window, qtbot)
    controller.undo()
    np.testing.assert_array_equal(review.assignment, before)
    # swap two labels over a marked range
    controller.select_label(label)
    window.timeline.set_frame(120)
    controller.set_range_in()
    window.timeline.set_frame(140)
    controller.set_range_out()
    controller.swap_labels(review.label_names[9])
    np.testing.assert_array_equal(review.assignment[120:141, label], before[120:141, 9])
    np.testing.assert_array_equal(review.assignment[:120, label], before[:120, label])
    wait_jobs(window, qtbot)
    controller.undo()
    np.testing.assert_array_equal(review.assignment, before)
    assert not window.messages, window.messages


def test_edit_without_selection_gives_a_message(window, qtbot, raw_take):
    path, _ = raw_take
    open_and_wait(window, qtbot, path)
    auto_label(window, qtbot)
    window.review.point_clicked(-1)
    assert window.review.unlabel() is None
    assert window.messages and "select a point" in window.messages[-1]


def test_gap_fill_accept_fill_all_and_problems(window, qtbot, raw_take, tmp_path):
    path, _ = raw_take
    open_and_wait(window, qtbot, path)
    auto_label(window, qtbot)
    review, controller = window.document.review, window.review
    rows = controller.gap_list.rows()
    assert rows, "the simulated occlusion leaves gaps"
    table = controller.gap_list.table
    table.selectRow(0)                                      # what a click on the first row does
    gap = controller.gap_list.rows()[controller.gap_list.selected_gap()]
    index = controller.gap_list.selected_gap()
    assert window.timeline.frame == gap.start and window.app.selection.label == gap.marker
    qtbot.waitUntil(lambda: controller.gap_list.rows()[index].checked, timeout=60_000)
    assert controller.gap_list.rows()[index].errors_mm
    assert controller.preview.methods()                     # the fills are drawn in the preview
    span = controller.accept_fill(index, "linear")
    assert span is not None
    assert (review.provenance[gap.start:gap.start + gap.length, gap.marker] == 1).all()
    wait_jobs(window, qtbot)
    controller.undo()
    assert (review.provenance[gap.start:gap.start + gap.length, gap.marker] == -1).all()
    filled_before = int((review.provenance > 0).sum())
    controller.fill_all(60)
    wait_jobs(window, qtbot)
    assert int((review.provenance > 0).sum()) > filled_before
    # next problem moves the current frame and selects the label
    window.timeline.set_frame(0)
    controller.go_to_problem(True)
    problem = review.next_problem(0)
    assert problem is not None and window.timeline.frame == problem.frame
    # export a labelled C3D and read its labels back
    out = tmp_path / "labelled.c3d"
    controller.export_c3d(str(out))
    import ezc3d

    labels = ezc3d.c3d(str(out))["parameters"]["POINT"]["LABELS"]["value"]
    assert labels[:24] == review.label_names
    assert not window.messages, window.messages


def test_two_hands_and_a_rigid_body_from_selected_points(window, qtbot, tmp_path):
    from handmocap.core.simulate.scene import simulate_scene

    scene = simulate_scene(layout="glove-13", n_frames=150, seed=2, hands="both", n_objects=1)
    path = tmp_path / "scene.c3d"
    save_take(scene.take, path)
    open_and_wait(window, qtbot, path)
    controller = window.review
    names = list(scene.truth["marker_names"])
    box = [index for index, name in enumerate(names) if name.startswith("box")]
    frame = next(f for f in range(150) if all((scene.truth["point_marker"][f] == m).any() for m in box))
    window.timeline.set_frame(frame)
    columns = [int(np.flatnonzero(scene.truth["point_marker"][frame] == m)[0]) for m in box]
    for column in columns:
        controller.toggle_rigid_point(column)
    assert controller.rigid_body_action.isEnabled()
    spec = controller.define_rigid_body("box")
    assert spec is not None and spec.exists()
    settings = AutoLabelSettings(layout="glove-13", hands="both", objects=controller.auto_settings.objects)
    controller.start_auto_label(settings)
    wait_jobs(window, qtbot)
    assert not window.messages, window.messages
    review = window.document.review
    assert review.label_names[:2] == ["R_" + names[0][2:], "R_" + names[1][2:]]
    assert {hand.side for hand in review.hands} == {"right", "left"}
    assert [name for name in review.label_names if name.startswith("box")] == ["box1", "box2", "box3", "box4"]
    assert window.viewport.hand_count() == 2
    # the selected points carry the rigid body's labels in the frame they were picked in
    for number, column in enumerate(columns):
        assert review.label_of_point(frame, column) == review.label_names.index(f"box{number + 1}")
    # the box is drawn as lines between its four markers
    assert list(review.rigid_bodies) == ["box"] and len(review.rigid_bodies["box"]) == 4
    window.timeline.set_frame(frame)
    assert window.viewport.rigid_body_segment_count() == 6
    window.review.undo_action.trigger()                                  # undo the auto-label
    assert window.document.review.rigid_bodies == {} and window.viewport.rigid_body_segment_count() == 0


def test_ik_solve_is_kept_in_the_review_and_undoable(window, qtbot, tmp_path):
    take = simulate_take(layout="dense", n_frames=120, seed=3, noise_mm=0.3).take
    path = tmp_path / "labelled.trc"
    save_take(take, path)
    open_and_wait(window, qtbot, path)
    review = window.document.review
    assert review.n_labels == 24                                # a labelled take: its columns are the labels,
    assert [hand.side for hand in review.hands] == ["right"]    # its hand found from their names, unsolved
    assert np.isnan(review.hands[0].joint_angles).all()
    with qtbot.waitSignal(window.solver.runner.succeeded, timeout=60_000):
        window.solve_action.trigger()
    assert len(review.hands) == 1 and np.isfinite(review.hands[0].joint_angles).all()
    assert np.nanmean(review.residuals_mm) < 1.0
    assert "IK solve" in window.review.undo_action.text()
    window.review.undo()
    assert len(review.hands) == 1 and np.isnan(review.hands[0].joint_angles).all()
    window.review.redo()
    assert len(review.hands) == 1 and np.isfinite(review.hands[0].joint_angles).all()
