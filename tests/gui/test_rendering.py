"""The 3D view keeps up with scrubbing: many frame changes before a paint give one render of the latest
frame, drawn without anti-aliasing and redrawn anti-aliased once still; frames move the existing VTK
points (no new actors or point arrays); marker names only for the selection, the marker under the mouse,
or all when asked."""

import numpy as np
import pytest

from handmocap.app.gui.document import TakeDocument
from handmocap.core.simulate import simulate_take
from handmocap.widgets.viewport import IDLE_MS

pytestmark = pytest.mark.gui


@pytest.fixture
def shown(window, qtbot):
    """The window showing a labelled simulated take (its labels are the review's), settled."""
    take = simulate_take(layout="dense", n_frames=200, seed=3).take
    window.add_document(TakeDocument(take, "simulated.c3d"))
    qtbot.wait(IDLE_MS + 200)
    return window


def test_many_frame_changes_give_one_render_of_the_last_frame(shown, qtbot):
    view = shown.viewport.view()
    view._idle_timer.setInterval(60_000)        # only the render of the frame changes is counted here
    before = view.render_count
    for frame in range(10, 30):
        shown.app.set_frame(frame)
    assert view.render_count == before          # nothing is rendered while the changes come in
    qtbot.waitUntil(lambda: view.render_count > before, timeout=5_000)
    qtbot.wait(100)
    assert view.render_count == before + 1
    expected = shown.document.take.marker_positions[29]
    visible = np.isfinite(expected).all(axis=1)
    np.testing.assert_allclose(view.marker_points()[visible], expected[visible])
    assert not view.is_anti_aliased()


def test_the_still_view_is_redrawn_anti_aliased(shown, qtbot):
    view = shown.viewport
    shown.app.set_frame(40)
    qtbot.waitUntil(lambda: not view.is_anti_aliased(), timeout=5_000)
    rendered = view.render_count
    qtbot.waitUntil(lambda: view.is_anti_aliased() and view.render_count > rendered, timeout=5_000)


def test_frames_move_the_existing_points_and_actors(shown, qtbot):
    view = shown.viewport.view()
    shown.review.select_label(0)
    renderer = view.plotter.renderer
    actors = renderer.GetActors().GetNumberOfItems()
    shown.app.set_frame(100)
    markers, trail = view._marker_data.GetPoints(), view._trail_data.GetPoints()
    first = view.marker_points()
    shown.app.set_frame(101)
    qtbot.wait(50)
    assert renderer.GetActors().GetNumberOfItems() == actors
    assert view._marker_data.GetPoints() is markers and view._trail_data.GetPoints() is trail
    assert not np.allclose(np.nan_to_num(first), np.nan_to_num(view.marker_points()))


def test_names_only_for_the_selection_and_the_hovered_marker(shown, qtbot):
    view, review = shown.viewport, shown.review
    assert view.labelled_markers() == []                  # nothing selected: no names piled on the fingers
    review.select_label(3)
    column = shown.app.selection.column
    assert column >= 0 and view.labelled_markers() == [column]
    shown.app.set_frame(shown.app.frame + 1)              # the name follows its marker
    assert view.labelled_markers() == [shown.app.selection.column]
    other = next(index for index in range(len(view.marker_names()))
                 if index != shown.app.selection.column and np.isfinite(view.marker_points()[index]).all())
    view.set_hovered_marker(other)
    assert sorted(view.labelled_markers()) == sorted([shown.app.selection.column, other])
    view.set_hovered_marker(-1)
    assert view.labelled_markers() == [shown.app.selection.column]
    shown.labels_action.trigger()                         # Marker names: all of them, when asked
    visible = np.flatnonzero(np.isfinite(view.marker_points()).all(axis=1))
    assert view.labelled_markers() == list(visible)


def test_hovering_a_marker_in_the_view_names_it(shown, qtbot):
    from PySide6.QtCore import QPointF, Qt
    from PySide6.QtGui import QMouseEvent
    from PySide6.QtWidgets import QApplication

    view = shown.viewport
    positions = view.marker_points()
    plotter = view.plotter
    matrix = plotter.renderer.GetActiveCamera().GetCompositeProjectionTransformMatrix(
        plotter.width() / plotter.height(), -1, 1)
    projection = np.array([[matrix.GetElement(row, column) for column in range(4)] for row in range(4)])
    index = int(np.flatnonzero(np.isfinite(positions).all(axis=1))[0])
    clip = projection @ np.r_[positions[index], 1.0]
    point = QPointF((clip[0] / clip[3] + 1.0) * 0.5 * plotter.width(),
                    (1.0 - (clip[1] / clip[3] + 1.0) * 0.5) * plotter.height())
    under = view.marker_at(point.x(), point.y())          # this marker, or one drawn over it
    assert under >= 0
    move = QMouseEvent(QMouseEvent.Type.MouseMove, point, plotter.mapToGlobal(point), Qt.MouseButton.NoButton,
                       Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier)
    QApplication.sendEvent(plotter, move)
    assert view.labelled_markers() == [under]
    QApplication.sendEvent(plotter, QMouseEvent(QMouseEvent.Type.MouseMove, QPointF(1, 1), plotter.mapToGlobal(
        QPointF(1, 1)), Qt.MouseButton.NoButton, Qt.MouseButton.NoButton, Qt.KeyboardModifier.NoModifier))
    assert view.labelled_markers() == []


def test_orbiting_draws_without_anti_aliasing_until_released(shown, qtbot):
    from PySide6.QtCore import QPointF, Qt
    from PySide6.QtGui import QMouseEvent
    from PySide6.QtWidgets import QApplication

    view = shown.viewport
    plotter = view.plotter
    qtbot.waitUntil(view.is_anti_aliased, timeout=5_000)

    def send(kind, x, button, buttons):
        point = QPointF(x, 200)
        QApplication.sendEvent(plotter, QMouseEvent(kind, point, plotter.mapToGlobal(point), button, buttons,
                                                    Qt.KeyboardModifier.NoModifier))

    left, none = Qt.MouseButton.LeftButton, Qt.MouseButton.NoButton
    send(QMouseEvent.Type.MouseButtonPress, 200, left, left)
    send(QMouseEvent.Type.MouseMove, 230, none, left)
    assert not view.is_anti_aliased()
    send(QMouseEvent.Type.MouseButtonRelease, 240, left, none)
    qtbot.waitUntil(view.is_anti_aliased, timeout=5_000)
