"""The main window driven like an operator: open, scrub, play, select, solve, cancel, bad files, close."""

import numpy as np
import pytest
from conftest import release
from PySide6.QtCore import Qt

from handmocap.app.gui.document import TakeDocument
from handmocap.core.io import Take, save_take
from handmocap.core.model import skin_vertices
from handmocap.core.simulate import simulate_take

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def take_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("takes") / "grasps.trc"
    save_take(simulate_take(layout="dense", n_frames=240, seed=2, noise_mm=0.3).take, path)
    return path


@pytest.fixture(scope="module")
def long_take():
    """A take long enough that its solve is still running when the test cancels it."""
    return simulate_take(layout="dense", n_frames=20_000, seed=5).take


def open_and_wait(window, qtbot, *paths):
    with qtbot.waitSignal(window.loader.succeeded, timeout=20_000):
        window.open_files(list(paths))
    qtbot.waitUntil(lambda: not window.loader.is_busy(), timeout=5_000)


def solve_and_wait(window, qtbot):
    with qtbot.waitSignal(window.solver.runner.succeeded, timeout=60_000):
        window.solve_action.trigger()


def test_open_take_fills_table_timeline_and_viewport(window, qtbot, take_file):
    open_and_wait(window, qtbot, take_file)
    take = window.document.take
    assert window.marker_panel.model.rowCount() == take.n_markers == 24
    assert window.timeline.n_frames == 240
    assert window.layout_box.currentText() == "dense"
    assert "240 frames" in window.info_label.text() and "24 markers" in window.info_label.text()
    assert window.windowTitle().startswith("grasps.trc")
    before = window.viewport.marker_points().copy()
    window.timeline.step(10)
    assert window.timeline.frame == 10
    after = window.viewport.marker_points()
    assert not np.allclose(before, after)
    np.testing.assert_allclose(after, take.marker_positions[10], atol=1e-4)
    assert window.timeline.frame_box.value() == take.first_frame + 10


def test_scrub_by_frame_box_and_cursor_shows_file_numbers(window, qtbot, take_file):
    open_and_wait(window, qtbot, take_file)
    first = window.document.take.first_frame
    window.timeline.frame_box.setValue(first + 100)
    assert window.timeline.frame == 100
    window.timeline._cursor.setValue(first + 42.4)  # what dragging the cursor does (file numbering)
    assert window.timeline.frame == 42
    assert window.timeline.frame_box.value() == first + 42
    np.testing.assert_allclose(window.viewport.marker_points(), window.document.take.marker_positions[42],
                               atol=1e-4)


def test_arrow_keys_step_and_missing_markers_show_a_dash(window, qtbot):
    positions = np.random.default_rng(1).normal(size=(50, 4, 3)) * 50
    positions[7, 2] = np.nan
    window.add_document(TakeDocument(Take(["a", "b", "c", "d"], positions, 100.0, first_frame=1), "gappy"))
    window.activateWindow()
    qtbot.waitUntil(window.isActiveWindow, timeout=2_000)
    window.timeline.set_frame(6)
    qtbot.keyClick(window.viewport, Qt.Key.Key_Right)
    assert window.timeline.frame == 7
    assert window.marker_panel.model.index(2, 2).data() == "—"
    assert np.isnan(window.viewport.marker_points()[2]).all()
    qtbot.keyClick(window.viewport, Qt.Key.Key_Left)
    assert window.timeline.frame == 6
    assert window.marker_panel.model.index(2, 2).data() != "—"


def test_playback_follows_the_clock_and_stops_at_the_end_without_loop(window, qtbot, take_file):
    open_and_wait(window, qtbot, take_file)
    timeline = window.timeline
    timeline.set_speed(4.0)
    assert timeline.speed == 4.0
    timeline.loop_box.setChecked(False)
    timeline.set_frame(200)
    timeline.play()
    assert timeline.is_playing()
    qtbot.waitUntil(lambda: not timeline.is_playing(), timeout=5_000)   # 40 frames at 400 frames/s
    assert timeline.frame == 239
    timeline.loop_box.setChecked(True)
    timeline.play()                                                     # from the end: starts over
    qtbot.waitUntil(lambda: 0 < timeline.frame < 200, timeout=5_000)
    timeline.pause()
    assert not timeline.is_playing()


def test_selecting_a_marker_highlights_it_both_ways(window, qtbot, take_file):
    open_and_wait(window, qtbot, take_file)
    window.marker_panel.select_marker(3)
    assert window.viewport.selected_marker() == 3
    window.viewport.marker_clicked.emit(5)                              # a click on a marker in 3D
    assert window.marker_panel.selected_marker() == 5
    assert window.viewport.selected_marker() == 5
    window.viewport.marker_clicked.emit(-1)                             # a click on empty space
    assert window.viewport.selected_marker() is None


def test_solve_on_worker_then_hand_follows_the_scrubbing(window, qtbot, take_file):
    open_and_wait(window, qtbot, take_file)
    assert window.viewport.vertex_points().shape == (0, 3)              # no hand before a solve
    solve_and_wait(window, qtbot)
    result = window.document.result
    assert result is not None and result.mean_residual_mm < 1.0
    window.timeline.set_frame(0)
    first = window.viewport.vertex_points().copy()
    window.timeline.set_frame(120)
    moved = window.viewport.vertex_points()
    assert np.linalg.norm(moved - first, axis=1).max() > 5.0
    assert window.marker_panel.model.index(0, 5).data() not in (None, "—")
    assert window.export_action.isEnabled()
    assert not window.progress_bar.isVisible()


def test_left_hand_take_is_solved_and_drawn_with_the_mirrored_model(window, qtbot, tmp_path):
    from handmocap.core.model import load_template, skin_vertices

    simulated = simulate_take(layout="dense", n_frames=60, seed=4)
    mirrored = simulated.take.marker_positions * np.array([-1.0, 1.0, 1.0])
    path = tmp_path / "left.trc"
    save_take(Take(simulated.take.marker_names, mirrored, simulated.take.frame_rate), path)
    open_and_wait(window, qtbot, path)
    window.side_box.setCurrentText("left")
    solve_and_wait(window, qtbot)
    result = window.document.result
    assert result.hand_side == "left" and result.mean_residual_mm < 1.0
    window.timeline.set_frame(30)
    expected = skin_vertices(load_template("left"), result.joint_angles[30])
    np.testing.assert_allclose(window.viewport.vertex_points(), expected, atol=1e-3)


def test_each_take_keeps_its_solve_and_frame(window, qtbot, take_file, tmp_path):
    other = tmp_path / "other.csv"
    save_take(simulate_take(layout="dense", n_frames=120, seed=3).take, other)
    open_and_wait(window, qtbot, take_file, other)
    assert window.take_box.count() == 2 and window.document.title == "grasps.trc"
    solve_and_wait(window, qtbot)
    window.timeline.set_frame(77)
    window.take_box.setCurrentIndex(1)
    assert window.document.title == "other.csv" and window.document.result is None
    assert window.timeline.n_frames == 120
    assert window.viewport.vertex_points().shape == (0, 3)
    window.take_box.setCurrentIndex(0)
    assert window.timeline.frame == 77
    assert window.viewport.vertex_points().shape[0] > 1000


def test_cancel_leaves_the_take_unsolved(window, qtbot, long_take):
    window.add_document(TakeDocument(long_take, "long"))
    # the operator presses Cancel once the progress bar moves, however busy the GUI thread was before
    window.solver.runner.progressed.connect(lambda *_: window.cancel_action.trigger())
    with qtbot.waitSignal(window.solver.runner.cancelled, timeout=60_000):
        window.solver.solve()
        assert window.solver.runner.is_busy() and window.cancel_action.isEnabled()
    assert window.document.result is None
    assert not window.solver.runner.is_busy()
    assert window.solve_action.isEnabled()


def test_bad_file_shows_a_message_and_keeps_the_open_take(window, qtbot, take_file, tmp_path):
    open_and_wait(window, qtbot, take_file)
    current = window.document
    bad = tmp_path / "broken.c3d"
    bad.write_text("this is not a c3d file")
    open_and_wait(window, qtbot, bad)
    assert window.document is current and window.take_box.count() == 1
    assert len(window.messages) == 1 and "broken.c3d" in window.messages[0]
    assert "\n" not in window.messages[0]


def test_take_without_layout_markers_reports_instead_of_crashing(window, qtbot):
    take = Take(["a", "b", "c"], np.random.default_rng(0).normal(size=(30, 3, 3)) * 100, 100.0)
    window.add_document(TakeDocument(take, "foreign"))
    window.solver.solve()                                   # refused before any work starts
    assert not window.solver.runner.is_busy()
    assert window.messages and "only 0 of the" in window.messages[-1] and "\n" not in window.messages[-1]
    assert window.solve_action.isEnabled()


def test_closing_while_solving_stops_the_worker(qtbot, long_take):
    from handmocap.app.gui.main_window import MainWindow

    window = MainWindow()
    window.show()
    try:
        window.add_document(TakeDocument(long_take, "long"))
        window.solver.solve()
        assert window.solver.runner.is_busy()
        window.close()
        assert not window.solver.runner.is_busy()
    finally:
        release(window)


def test_screenshot_writes_a_png(window, qtbot, take_file, tmp_path):
    open_and_wait(window, qtbot, take_file)
    path = tmp_path / "shot.png"
    assert window.save_screenshot(path)
    assert path.exists() and path.stat().st_size > 10_000


def test_the_solve_reaches_the_views_through_an_event(window, qtbot, take_file):
    from handmocap.app.gui.application import SolveApplied

    open_and_wait(window, qtbot, take_file)
    heard = []
    window.app.add_listener(lambda event: heard.append(event) if isinstance(event, SolveApplied) else None)
    solve_and_wait(window, qtbot)
    assert [event.document for event in heard] == [window.document]
    results = window.document.results
    # the same result applied through the application alone (no solver, no window call): the views follow
    window.add_document(TakeDocument(window.document.take, "again"))
    assert window.viewport.vertex_points().shape == (0, 3) and not window.export_action.isEnabled()
    window.app.apply_solve(window.document, results)
    assert window.document.result is results[0] and len(heard) == 2
    window.timeline.set_frame(120)
    np.testing.assert_allclose(window.viewport.vertex_points(),
                               skin_vertices(window.document.model_for("right"), results[0].joint_angles[120]),
                               atol=1e-3)
    assert np.isfinite(window.document.review.hands[0].joint_angles).all()    # kept in the review as a step
    assert window.export_action.isEnabled()


def test_cancelling_from_the_solver_leaves_one_state_and_nothing_stale(window, qtbot, long_take):
    window.add_document(TakeDocument(long_take, "long"))
    solver = window.solver
    with qtbot.waitSignal(solver.runner.cancelled, timeout=60_000):
        solver.solve()
        assert solver.solving() is window.document and window.app.jobs["solve"].document is window.document
        assert not window.solve_action.isEnabled()
        solver.cancel()
    assert solver.solving() is None and "solve" not in window.app.jobs and not solver.is_busy()
    assert not any(hasattr(window, name) for name in ("runner", "solve", "_solve_succeeded", "_owner"))
    assert not hasattr(window.document, "solve_request")
    assert window.document.result is None and not window.document.auto_solve
    assert window.solve_action.isEnabled() and not window.cancel_action.isEnabled()
    assert not window.progress_bar.isVisible()
