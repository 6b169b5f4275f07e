"""Picking in the 3D view: a click on a marker's projection finds it; empty space finds nothing."""

import numpy as np
import pytest

pytestmark = pytest.mark.gui


def test_marker_at_finds_the_clicked_marker(viewport):
    view = viewport
    positions = np.array([[0.0, 0.0, 0.0], [60.0, 0.0, 0.0], [0.0, 60.0, 30.0], [np.nan, np.nan, np.nan]])
    view.set_markers(["a", "b", "c", "gone"], positions)
    view.frame_bounds(positions[:3])
    renderer, ratio = view.plotter.renderer, view.plotter.devicePixelRatioF()
    height = view.plotter.height() * ratio
    for index in range(3):
        renderer.SetWorldPoint(*positions[index], 1.0)       # VTK's own projection, to check ours
        renderer.WorldToDisplay()
        display_x, display_y, _ = renderer.GetDisplayPoint()
        assert view.marker_at(display_x / ratio, (height - display_y) / ratio) == index
    assert view.marker_at(2.0, 2.0) == -1


def test_a_click_picks_a_drag_does_not_and_keys_stay_away_from_vtk(viewport, qtbot):
    from PySide6.QtCore import QEvent, QPointF, Qt
    from PySide6.QtGui import QKeyEvent, QMouseEvent

    view = viewport
    positions = np.array([[0.0, 0.0, 0.0], [60.0, 0.0, 0.0]])
    view.set_markers(["a", "b"], positions)
    view.frame_bounds(positions)
    renderer, ratio = view.plotter.renderer, view.plotter.devicePixelRatioF()
    renderer.SetWorldPoint(*positions[1], 1.0)
    renderer.WorldToDisplay()
    display_x, display_y, _ = renderer.GetDisplayPoint()
    at = QPointF(display_x / ratio, (view.plotter.height() * ratio - display_y) / ratio)
    picked = []
    view.marker_clicked.connect(picked.append)

    def mouse(kind, position):
        return QMouseEvent(kind, position, position, Qt.MouseButton.LeftButton, Qt.MouseButton.LeftButton,
                           Qt.KeyboardModifier.NoModifier)

    assert not view.eventFilter(view.plotter, mouse(QEvent.Type.MouseButtonPress, at))
    assert not view.eventFilter(view.plotter, mouse(QEvent.Type.MouseButtonRelease, at + QPointF(1.0, 0.0)))
    assert picked == [1]
    view.eventFilter(view.plotter, mouse(QEvent.Type.MouseButtonPress, at))            # a camera drag
    view.eventFilter(view.plotter, mouse(QEvent.Type.MouseButtonRelease, at + QPointF(40.0, 0.0)))
    assert picked == [1]
    key = QKeyEvent(QEvent.Type.KeyPress, Qt.Key.Key_W, Qt.KeyboardModifier.NoModifier, "w")
    assert view.eventFilter(view.plotter, key) and not key.isAccepted()
    assert not view.eventFilter(view, key)                     # only the 3D view's own events are filtered
