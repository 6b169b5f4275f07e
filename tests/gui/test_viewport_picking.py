"""Picking in the 3D view: a click on a marker's projection finds it; empty space finds nothing."""

import numpy as np
import pytest

pytestmark = pytest.mark.gui


def test_marker_at_finds_the_clicked_marker(qtbot):
    from widgets.viewport import HandViewport

    view = HandViewport()
    qtbot.addWidget(view)
    view.resize(640, 480)
    view.show()
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
    view.close_viewport()
