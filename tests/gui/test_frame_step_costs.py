"""What a frame step redraws stays small: the hand surface's normals are computed with its vertices (no VTK
normals filter rebuilding the mesh topology per frame) and follow the pose; the marker table redraws only the
chips of markers that appeared or vanished and does not measure its names column again."""

import numpy as np
import pytest
from PySide6.QtCore import Qt

from handmocap.core.model import load_template, skin_vertices
from handmocap.core.model.hand_model import mesh_vertex_normals

pytestmark = pytest.mark.gui


def test_the_hand_surface_normals_follow_the_pose(viewport):
    view = viewport
    model = load_template()
    view.set_hand_mesh(model.vertices, model.faces)
    mesh = view._meshes[0]
    assert view._mesh_actors[0].GetMapper().GetInput() is mesh        # drawn as given: no filter in between
    rest_normals = np.array(mesh.point_data["Normals"])
    np.testing.assert_allclose(rest_normals, mesh_vertex_normals(model.vertices, model.faces))
    theta = np.zeros(26)
    theta[3:6] = [0.0, 0.0, 1.5]       # the hand turned 86° about z
    theta[6:] = 0.4
    posed = skin_vertices(model, theta)
    view.update_hand_vertices(posed)
    np.testing.assert_allclose(view.vertex_points(), posed)
    normals = np.array(mesh.point_data["Normals"])
    np.testing.assert_allclose(normals, mesh_vertex_normals(posed, model.faces), atol=1e-12)
    assert np.abs(normals - rest_normals).max() > 0.5
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-9)


def test_the_marker_table_redraws_only_the_chips_that_changed(qtbot):
    from handmocap.widgets.marker_panel import MISSING_TEXT, MarkerPanel

    panel = MarkerPanel()
    qtbot.addWidget(panel)
    panel.resize(420, 300)
    panel.show()
    names = ["thumb_tip", "index_tip", "a_much_longer_marker_name"]
    panel.set_markers(names, np.array([1.0, 0.5, 0.9]))
    header = panel.table.horizontalHeader()
    width = header.sectionSize(0)
    assert width >= panel.table.fontMetrics().horizontalAdvance(names[2])
    chips: list[tuple[int, int]] = []
    panel.model.dataChanged.connect(
        lambda first, last, roles: chips.append((first.row(), last.row()))
        if Qt.ItemDataRole.DecorationRole in roles else None)
    positions = np.array([[1.0, 2.0, 3.0], [np.nan] * 3, [4.0, 5.0, 6.0]])
    panel.set_frame_values(positions, np.array([0.5, np.nan, 1.25]))
    assert chips == [(0, 2)]                 # rows 0 and 2 appeared
    chips.clear()
    panel.set_frame_values(positions + 1.0, np.array([0.4, np.nan, 1.0]))
    assert chips == []                       # nobody appeared or vanished: no chip redrawn
    positions[1] = [7.0, 8.0, 9.0]
    panel.set_frame_values(positions, None)
    assert chips == [(1, 1)]
    model = panel.model
    assert model.data(model.index(1, 2)) == "7.0"
    assert model.data(model.index(2, 5)) == MISSING_TEXT         # no residuals given for this frame
    assert header.sectionSize(0) == width
