"""The main window shows before its 3D view is built (issue 25, start-up): importing the window loads no VTK,
pyvista or matplotlib; the view is built after the window's first paint, in the same native window; drawing
calls made before it exists are done in order once it does."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from handmocap.widgets.deferred_viewport import BACKGROUND_BOTTOM, BACKGROUND_TOP, MAX_PENDING, DeferredViewport

pytestmark = pytest.mark.gui


def test_importing_the_main_window_loads_no_3d_stack():
    probe = ("import sys, handmocap.app.gui.main_window; "
             "print(sorted({name.split('.')[0] for name in sys.modules} & "
             "{'pyvista', 'pyvistaqt', 'vtkmodules', 'vtk', 'matplotlib'}))")
    loaded = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "[]"


def test_the_view_is_built_after_the_window_has_painted_in_the_same_native_window(qtbot):
    from handmocap.app.gui.main_window import MainWindow

    window = MainWindow()
    qtbot.addWidget(window)
    assert not window.viewport.is_built()          # constructing the window builds no 3D view
    window.show()
    qtbot.waitExposed(window)
    native = window.winId()
    qtbot.waitUntil(window.viewport.is_built, timeout=20_000)
    assert window.winId() == native                 # not re-created when its OpenGL view came in
    window.viewport.close_viewport()
    window.close()


def test_drawing_calls_before_the_view_exists_are_done_in_order_once_it_does(qtbot):
    stand_in = DeferredViewport()
    qtbot.addWidget(stand_in)
    stand_in.set_markers(["a", "b"], np.zeros((2, 3)))
    stand_in.update_markers(np.array([[1.0, 2.0, 3.0], [np.nan, np.nan, np.nan]]))
    stand_in.set_selected_marker(0)
    assert not stand_in.is_built()                  # hidden and only drawn to: nothing built yet
    clicks: list[int] = []
    stand_in.marker_clicked.connect(clicks.append)
    np.testing.assert_array_equal(stand_in.marker_points(), [[1.0, 2.0, 3.0], [np.nan, np.nan, np.nan]])
    assert stand_in.is_built() and stand_in.selected_marker() == 0   # a query built it and the calls were done
    stand_in.view().marker_clicked.emit(1)
    assert clicks == [1]
    stand_in.close_viewport()


def test_a_stand_in_driven_while_hidden_keeps_a_bounded_number_of_calls(qtbot):
    stand_in = DeferredViewport()
    qtbot.addWidget(stand_in)
    stand_in.set_markers(["a"], np.zeros((1, 3)))
    for step in range(MAX_PENDING + 10):
        stand_in.update_markers(np.array([[float(step), 0.0, 0.0]]))
    assert stand_in.is_built()
    np.testing.assert_array_equal(stand_in.marker_points(), [[MAX_PENDING + 9.0, 0.0, 0.0]])
    stand_in.close_viewport()


def test_the_panel_paints_the_views_background():
    from handmocap.widgets import viewport

    for painted, drawn in ((BACKGROUND_TOP, viewport.BACKGROUND_TOP), (BACKGROUND_BOTTOM, viewport.BACKGROUND_BOTTOM)):
        np.testing.assert_allclose(painted.getRgbF()[:3], drawn, atol=1e-3)
