"""The main window driven like an operator: open, scrub, solve, cancel, bad files, close, screenshot."""

import numpy as np
import pytest

from core.io import Take, save_take
from core.simulate import simulate_take

pytestmark = pytest.mark.gui


@pytest.fixture(scope="module")
def take_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("takes") / "grasps.trc"
    save_take(simulate_take(layout="dense", n_frames=240, seed=2, noise_mm=0.3).take, path)
    return path


def test_open_take_fills_table_timeline_and_viewport(window, take_file):
    assert window.open_file(take_file)
    take = window.document.take
    assert window.marker_panel.model.rowCount() == take.n_markers == 24
    assert window.timeline.n_frames == 240
    assert window.layout_box.currentText() == "dense"
    before = window.viewport.marker_points().copy()
    window.timeline.step(10)
    assert window.timeline.frame == 10
    after = window.viewport.marker_points()
    assert not np.allclose(before, after)
    np.testing.assert_allclose(after, take.marker_positions[10], atol=1e-4)
    assert window.timeline.frame_box.value() == take.first_frame + 10


def test_solve_on_worker_then_hand_follows_the_scrubbing(window, qtbot, take_file):
    window.open_file(take_file)
    with qtbot.waitSignal(window.runner.succeeded, timeout=60_000):
        window.solve_action.trigger()
    result = window.document.result
    assert result is not None and result.mean_residual_mm < 1.0
    window.timeline.set_frame(0)
    first = window.viewport.vertex_points().copy()
    window.timeline.set_frame(120)
    moved = window.viewport.vertex_points()
    assert np.linalg.norm(moved - first, axis=1).max() > 5.0
    residual_column = window.marker_panel.model.index(0, 5).data()
    assert residual_column not in (None, "—")
    assert window.export_action.isEnabled()


def test_cancel_leaves_the_take_unsolved(window, qtbot):
    long_take = simulate_take(layout="dense", n_frames=20_000, seed=5).take
    from app.document import TakeDocument

    window.add_document(TakeDocument(long_take, "long"))
    with qtbot.waitSignal(window.runner.cancelled, timeout=60_000):
        window.solve()
        qtbot.wait(50)
        window.cancel_button.click()
    assert window.document.result is None
    assert not window.runner.is_busy()


def test_bad_file_shows_a_message_and_keeps_the_open_take(window, take_file, tmp_path):
    window.open_file(take_file)
    current = window.document
    bad = tmp_path / "broken.c3d"
    bad.write_text("this is not a c3d file")
    assert not window.open_file(bad)
    assert window.document is current
    assert len(window.messages) == 1 and "broken.c3d" in window.messages[0]
    assert "\n" not in window.messages[0]


def test_take_without_layout_markers_reports_instead_of_crashing(window, qtbot):
    from app.document import TakeDocument

    take = Take(["a", "b", "c"], np.random.default_rng(0).normal(size=(30, 3, 3)) * 100, 100.0)
    window.add_document(TakeDocument(take, "foreign"))
    with qtbot.waitSignal(window.runner.failed, timeout=30_000):
        window.solve()
    assert window.messages and "no marker of layout" in window.messages[-1]


def test_closing_while_solving_stops_the_worker(qtbot, monkeypatch):
    from app.document import TakeDocument
    from app.main_window import MainWindow

    window = MainWindow()
    qtbot.addWidget(window)
    window.show()
    window.add_document(TakeDocument(simulate_take(layout="dense", n_frames=20_000, seed=6).take, "long"))
    window.solve()
    assert window.runner.is_busy()
    window.close()
    assert not window.runner.is_busy()


def test_screenshot_writes_a_png(window, take_file, tmp_path):
    window.open_file(take_file)
    path = tmp_path / "shot.png"
    window.save_screenshot(path)
    assert path.exists() and path.stat().st_size > 10_000
