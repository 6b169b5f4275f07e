"""3D viewport of a hand take: skinned hand mesh, markers, model effectors, ground grid (Z up, mm).

The widget knows nothing about takes or solvers: it draws numpy arrays. Every scene object is built
once; per-frame updates write into the existing VTK arrays and call ``Modified()``, so scrubbing and
playback never create actors.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyvista as pv
from PySide6.QtCore import QEvent, QObject, QPointF, Qt, Signal
from PySide6.QtGui import QMouseEvent
from PySide6.QtWidgets import QVBoxLayout, QWidget
from pyvistaqt import QtInteractor
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkStringArray
from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
from vtkmodules.vtkRenderingCore import vtkActor2D, vtkGlyph3DMapper, vtkPolyDataMapper
from vtkmodules.vtkRenderingLabel import vtkLabeledDataMapper

SKIN_COLOR = (0.91, 0.73, 0.62)
MARKER_COLOR = (0.55, 0.80, 1.00)
SELECTED_MARKER_COLOR = (1.00, 0.86, 0.20)
EFFECTOR_COLOR = (1.00, 0.55, 0.10)
BACKGROUND_TOP = (0.24, 0.26, 0.30)
BACKGROUND_BOTTOM = (0.07, 0.08, 0.09)
GRID_COLOR = (0.42, 0.45, 0.50)

MARKER_RADIUS_MM = 3.2
EFFECTOR_RADIUS_MM = 2.2
SELECTED_SCALE = 1.7
PICK_RADIUS_PX = 12.0      # a click this close to a marker's centre selects it
CLICK_SLOP_PX = 4.0        # a press and release further apart than this is a camera drag, not a click


def _as_rgb_bytes(colors: np.ndarray) -> np.ndarray:
    """``(N,3)`` floats in [0, 1] to ``(N,3)`` uint8."""
    return np.clip(np.round(np.asarray(colors, dtype=float) * 255.0), 0, 255).astype(np.uint8)


def _grid_lines(center_xy: np.ndarray, half_extent: float, spacing: float, height: float) -> pv.PolyData:
    """Square grid of lines in the plane ``z = height`` centred (snapped to ``spacing``) on ``center_xy``."""
    center = np.round(np.asarray(center_xy, dtype=float) / spacing) * spacing
    count = int(np.ceil(half_extent / spacing))
    ticks = np.arange(-count, count + 1) * spacing
    low, high = -count * spacing, count * spacing
    starts, ends = [], []
    for tick in ticks:
        starts += [(center[0] + tick, center[1] + low), (center[0] + low, center[1] + tick)]
        ends += [(center[0] + tick, center[1] + high), (center[0] + high, center[1] + tick)]
    n_lines = len(starts)
    points = np.empty((2 * n_lines, 3))
    points[0::2, :2] = starts
    points[1::2, :2] = ends
    points[:, 2] = height
    cells = np.column_stack([np.full(n_lines, 2), np.arange(0, 2 * n_lines, 2), np.arange(1, 2 * n_lines, 2)])
    return pv.PolyData(points, lines=cells.ravel())


def _nice_spacing(extent: float) -> float:
    """A 1-2-5 grid spacing (mm) giving roughly ten cells over ``extent``."""
    raw = max(extent, 1.0) / 10.0
    magnitude = 10.0 ** np.floor(np.log10(raw))
    for step in (1.0, 2.0, 5.0, 10.0):
        if raw <= step * magnitude:
            return float(step * magnitude)
    return float(10.0 * magnitude)


class HandViewport(QWidget):
    """Interactive Z-up 3D view of one hand: mesh, markers, effectors and residual lines.

    Mouse: left drag orbits about Z, middle drag pans, wheel zooms; a left click on a marker emits
    :attr:`marker_clicked` with its index (-1 for a click on empty space). Keys are left to the
    application (VTK's one-letter commands, such as ``w`` for wireframe, are switched off).
    """

    marker_clicked = Signal(int)

    def __init__(self, parent: QWidget | None = None, off_screen: bool | None = None) -> None:
        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self._plotter = QtInteractor(self, off_screen=off_screen, auto_update=False, multi_samples=4)
        self._plotter.setAcceptDrops(False)       # files dropped on the view go to the window
        self._plotter.installEventFilter(self)
        self._press_position: QPointF | None = None
        layout.addWidget(self._plotter)
        self.setMinimumSize(320, 240)

        plotter = self._plotter
        plotter.set_background(BACKGROUND_BOTTOM, top=BACKGROUND_TOP)
        plotter.enable_lightkit()
        if plotter.iren is not None:
            plotter.enable_terrain_style(mouse_wheel_zooms=True)
        plotter.add_axes(interactive=False, line_width=2, color="white",
                         xlabel="X", ylabel="Y", zlabel="Z")

        self._marker_names: list[str] = []
        self._marker_positions = np.zeros((0, 3))
        self._marker_colors = np.zeros((0, 3))
        self._selected: int | None = None
        self._labels_visible = False
        self._effectors_visible = True
        self._mesh_visible = True
        self._has_mesh = False

        self._build_grid()
        self._build_mesh()
        self._build_markers()
        self._build_effectors()
        self._build_labels()
        self.frame_bounds(np.array([[-100.0, -100.0, 0.0], [100.0, 100.0, 200.0]]))

    # ----------------------------------------------------------------------------------- scene setup
    def _build_grid(self) -> None:
        self._grid = _grid_lines(np.zeros(2), 500.0, 50.0, 0.0)
        self._grid_actor = self._plotter.add_mesh(self._grid, color=GRID_COLOR, opacity=0.55,
                                                  line_width=1, lighting=False, pickable=False,
                                                  name="ground-grid")

    def _build_mesh(self) -> None:
        self._mesh = pv.PolyData()
        self._normals = vtkPolyDataNormals()
        self._normals.SetInputData(self._mesh)
        self._normals.ComputePointNormalsOn()
        self._normals.ComputeCellNormalsOff()
        self._normals.SplittingOff()
        self._normals.ConsistencyOff()
        self._normals.AutoOrientNormalsOff()
        mapper = vtkPolyDataMapper()
        mapper.SetInputConnection(self._normals.GetOutputPort())
        mapper.ScalarVisibilityOff()
        self._mesh_actor = pv.Actor(mapper=mapper)
        prop = self._mesh_actor.prop
        prop.color = SKIN_COLOR
        prop.interpolation = "phong"
        prop.ambient = 0.12
        prop.diffuse = 0.85
        prop.specular = 0.18
        prop.specular_power = 18.0
        self._mesh_actor.visibility = False
        self._plotter.add_actor(self._mesh_actor, name="hand-mesh", reset_camera=False)

    def _glyph_actor(self, data: pv.PolyData, radius: float, name: str) -> pv.Actor:
        sphere = pv.Sphere(radius=radius, theta_resolution=20, phi_resolution=14)
        mapper = vtkGlyph3DMapper()
        mapper.SetInputData(data)
        mapper.SetSourceData(sphere)
        mapper.ScalingOn()
        mapper.SetScaleModeToScaleByMagnitude()
        mapper.SetScaleArray("scale")
        mapper.SetScaleFactor(1.0)
        mapper.OrientOff()
        mapper.SetColorModeToDirectScalars()
        mapper.SetScalarModeToUsePointFieldData()
        mapper.SelectColorArray("colors")
        mapper.ScalarVisibilityOn()
        actor = pv.Actor(mapper=mapper)
        actor.prop.ambient = 0.25
        actor.prop.specular = 0.4
        actor.prop.specular_power = 30.0
        self._plotter.add_actor(actor, name=name, reset_camera=False)
        return actor

    @staticmethod
    def _resize_points(data: pv.PolyData, count: int, color: tuple[float, float, float]) -> None:
        """Give ``data`` ``count`` points with a zero ``scale`` array and a ``colors`` array."""
        data.SetPoints(pv.vtk_points(np.zeros((count, 3))))
        for name, values in (("scale", np.zeros(count)),
                             ("colors", np.tile(_as_rgb_bytes(color), (count, 1)))):
            array = numpy_to_vtk(values, deep=True)
            array.SetName(name)
            data.GetPointData().AddArray(array)
        data.Modified()

    @staticmethod
    def _point_array(data: pv.PolyData, name: str) -> np.ndarray:
        """Writable numpy view of a point-data array of ``data`` (call ``_modified`` after writing)."""
        return vtk_to_numpy(data.GetPointData().GetArray(name))

    @staticmethod
    def _modified(data: pv.PolyData) -> None:
        data.GetPoints().Modified()
        for name in ("scale", "colors"):
            data.GetPointData().GetArray(name).Modified()
        data.Modified()

    def _build_markers(self) -> None:
        self._marker_data = pv.PolyData()
        self._resize_points(self._marker_data, 0, MARKER_COLOR)
        self._marker_actor = self._glyph_actor(self._marker_data, MARKER_RADIUS_MM, "markers")

    def _build_effectors(self) -> None:
        self._effector_data = pv.PolyData()
        self._resize_points(self._effector_data, 0, EFFECTOR_COLOR)
        self._effector_actor = self._glyph_actor(self._effector_data, EFFECTOR_RADIUS_MM, "effectors")
        self._residual_lines = pv.PolyData()
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(self._residual_lines)
        mapper.ScalarVisibilityOff()
        self._residual_actor = pv.Actor(mapper=mapper)
        self._residual_actor.prop.color = EFFECTOR_COLOR
        self._residual_actor.prop.line_width = 2.0
        self._residual_actor.prop.lighting = False
        self._plotter.add_actor(self._residual_actor, name="residual-lines", reset_camera=False)

    def _build_labels(self) -> None:
        self._label_data = pv.PolyData()
        self._label_mapper = vtkLabeledDataMapper()
        self._label_mapper.SetInputData(self._label_data)
        self._label_mapper.SetLabelModeToLabelFieldData()
        self._label_mapper.SetFieldDataName("names")
        text = self._label_mapper.GetLabelTextProperty()
        text.SetFontSize(13)
        text.SetColor(0.92, 0.94, 0.97)
        text.SetShadow(True)
        text.SetBold(False)
        text.SetJustificationToLeft()
        text.SetVerticalJustificationToBottom()
        self._label_actor = vtkActor2D()
        self._label_actor.SetMapper(self._label_mapper)
        self._label_actor.SetVisibility(False)
        self._plotter.renderer.AddViewProp(self._label_actor)

    # ------------------------------------------------------------------------------------- events
    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        """Keep key presses from VTK; turn a left click (press and release in place) into a pick."""
        if watched is not self._plotter:
            return False
        kind = event.type()
        if kind in (QEvent.Type.KeyPress, QEvent.Type.KeyRelease):
            event.ignore()
            return True
        if isinstance(event, QMouseEvent) and event.button() == Qt.MouseButton.LeftButton:
            if kind == QEvent.Type.MouseButtonPress:
                self._press_position = event.position()
            elif kind == QEvent.Type.MouseButtonRelease and self._press_position is not None:
                moved = event.position() - self._press_position
                self._press_position = None
                if abs(moved.x()) + abs(moved.y()) <= CLICK_SLOP_PX:
                    self.marker_clicked.emit(self.marker_at(event.position().x(), event.position().y()))
        return False

    def marker_at(self, x: float, y: float) -> int:
        """Index of the shown marker nearest to widget position ``(x, y)`` (logical pixels) within
        :data:`PICK_RADIUS_PX`, or -1."""
        visible = np.flatnonzero(np.isfinite(self._marker_positions).all(axis=1))
        if not len(visible):
            return -1
        renderer = self._plotter.renderer
        ratio = self._plotter.devicePixelRatioF()
        height = self._plotter.height() * ratio
        best, best_distance = -1, PICK_RADIUS_PX * ratio
        for index in visible:
            renderer.SetWorldPoint(*self._marker_positions[index], 1.0)
            renderer.WorldToDisplay()
            display_x, display_y, depth = renderer.GetDisplayPoint()
            if not 0.0 <= depth <= 1.0:
                continue
            distance = float(np.hypot(display_x - x * ratio, (height - display_y) - y * ratio))
            if distance < best_distance:
                best, best_distance = int(index), distance
        return best

    # --------------------------------------------------------------------------------------- access
    @property
    def plotter(self) -> QtInteractor:
        """The underlying pyvista Qt interactor (for camera access and screenshots)."""
        return self._plotter

    def marker_points(self) -> np.ndarray:
        """The marker positions currently shown, ``(M,3)`` mm, NaN where hidden (a copy)."""
        return self._marker_positions.copy()

    def vertex_points(self) -> np.ndarray:
        """The hand mesh vertices currently shown, ``(V,3)`` mm (empty without a mesh)."""
        return np.array(self._mesh.points) if self._has_mesh else np.zeros((0, 3))

    def selected_marker(self) -> int | None:
        """Index of the highlighted marker, or None."""
        return self._selected

    # -------------------------------------------------------------------------------------- markers
    def set_markers(self, names: Sequence[str], positions: np.ndarray,
                    colors: np.ndarray | None = None) -> None:
        """Show a new marker set: ``names (M,)``, ``positions (M,3)`` mm (NaN = missing),
        ``colors (M,3)`` in [0, 1] (default light blue)."""
        count = len(names)
        self._marker_names = list(names)
        self._marker_colors = (np.tile(MARKER_COLOR, (count, 1)) if colors is None
                               else np.asarray(colors, dtype=float).reshape(count, 3))
        self._selected = None
        self._resize_points(self._marker_data, count, MARKER_COLOR)
        self._marker_positions = np.full((count, 3), np.nan)
        self.update_markers(positions)

    def set_marker_colors(self, colors: np.ndarray) -> None:
        """Base colours ``(M,3)`` in [0, 1] of the current markers."""
        self._marker_colors = np.asarray(colors, dtype=float).reshape(len(self._marker_names), 3)
        self._refresh_marker_style()

    def update_markers(self, positions: np.ndarray) -> None:
        """Move the current markers to ``positions (M,3)`` mm; NaN rows are hidden."""
        positions = np.asarray(positions, dtype=float).reshape(len(self._marker_names), 3)
        self._marker_positions = positions.copy()
        visible = np.isfinite(positions).all(axis=1)
        vtk_to_numpy(self._marker_data.GetPoints().GetData())[visible] = positions[visible]
        self._refresh_marker_style()
        if self._labels_visible:
            self._refresh_labels()

    def set_selected_marker(self, index: int | None) -> None:
        """Highlight marker ``index`` (bigger, yellow, labelled) or clear the highlight with None."""
        if index is not None and not 0 <= index < len(self._marker_names):
            index = None
        self._selected = index
        self._refresh_marker_style()
        self._refresh_labels()

    def _refresh_marker_style(self) -> None:
        count = len(self._marker_names)
        visible = np.isfinite(self._marker_positions).all(axis=1) if count else np.zeros(0, dtype=bool)
        scale = visible.astype(float)
        colors = self._marker_colors.copy()
        if self._selected is not None:
            scale[self._selected] *= SELECTED_SCALE
            colors[self._selected] = SELECTED_MARKER_COLOR
        self._point_array(self._marker_data, "scale")[:] = scale
        self._point_array(self._marker_data, "colors")[:] = _as_rgb_bytes(colors)
        self._modified(self._marker_data)

    # --------------------------------------------------------------------------------------- labels
    def set_labels_visible(self, visible: bool) -> None:
        """Show or hide the name labels of all markers (the selected marker is always labelled)."""
        self._labels_visible = bool(visible)
        self._refresh_labels()

    def labels_visible(self) -> bool:
        """Whether all marker names are shown."""
        return self._labels_visible

    def _refresh_labels(self) -> None:
        visible = np.isfinite(self._marker_positions).all(axis=1)
        if not self._labels_visible:
            only_selected = np.zeros_like(visible)
            if self._selected is not None:
                only_selected[self._selected] = True
            visible &= only_selected
        indices = np.flatnonzero(visible)
        names = vtkStringArray()
        names.SetName("names")
        for index in indices:
            names.InsertNextValue(f"  {self._marker_names[index]}")
        label_data = pv.PolyData(self._marker_positions[indices]) if len(indices) else pv.PolyData()
        label_data.GetPointData().AddArray(names)
        self._label_data.ShallowCopy(label_data)
        self._label_actor.SetVisibility(bool(len(indices)))

    # ---------------------------------------------------------------------------------- hand mesh
    def set_hand_mesh(self, vertices: np.ndarray | None, faces: np.ndarray | None = None) -> None:
        """Show the hand surface ``vertices (V,3)`` mm with triangles ``faces (T,3)``; None hides it."""
        if vertices is None or faces is None:
            self._has_mesh = False
            self._mesh_actor.visibility = False
            return
        # copies: the widget updates these points in place, the caller's arrays must stay untouched
        surface = pv.PolyData.from_regular_faces(np.array(vertices, dtype=float),
                                                 np.array(faces, dtype=np.int64))
        self._mesh.ShallowCopy(surface)
        self._has_mesh = True
        self._mesh_actor.visibility = self._mesh_visible

    def update_hand_vertices(self, vertices: np.ndarray) -> None:
        """Move the shown hand mesh to ``vertices (V,3)`` mm, in place."""
        if not self._has_mesh:
            return
        vtk_to_numpy(self._mesh.GetPoints().GetData())[:] = vertices
        self._mesh.GetPoints().Modified()
        self._mesh.Modified()

    def set_mesh_visible(self, visible: bool) -> None:
        """Show or hide the hand mesh (if one is set)."""
        self._mesh_visible = bool(visible)
        self._mesh_actor.visibility = self._mesh_visible and self._has_mesh

    # ------------------------------------------------------------------------------------ effectors
    def set_effectors(self, effectors: np.ndarray | None, targets: np.ndarray | None = None) -> None:
        """Show the model's effectors ``(K,3)`` mm and a line from each to its measured marker
        ``targets (K,3)`` (NaN rows: no line; NaN effector: hidden). None clears them."""
        if effectors is None:
            effectors = np.zeros((0, 3))
        effectors = np.asarray(effectors, dtype=float).reshape(-1, 3)
        count = len(effectors)
        if self._effector_data.GetNumberOfPoints() != count:
            self._resize_points(self._effector_data, count, EFFECTOR_COLOR)
        shown = np.isfinite(effectors).all(axis=1)
        vtk_to_numpy(self._effector_data.GetPoints().GetData())[shown] = effectors[shown]
        self._point_array(self._effector_data, "scale")[:] = shown.astype(float)
        self._modified(self._effector_data)

        if targets is None or not count:
            paired = np.zeros(count, dtype=bool)
            targets = np.zeros((count, 3))
        else:
            targets = np.asarray(targets, dtype=float).reshape(count, 3)
            paired = shown & np.isfinite(targets).all(axis=1)
        starts, ends = effectors[paired], targets[paired]
        n_lines = len(starts)
        if n_lines:
            points = np.empty((2 * n_lines, 3))
            points[0::2], points[1::2] = starts, ends
            cells = np.column_stack([np.full(n_lines, 2), np.arange(0, 2 * n_lines, 2),
                                     np.arange(1, 2 * n_lines, 2)]).ravel()
            self._residual_lines.ShallowCopy(pv.PolyData(points, lines=cells))
        else:
            self._residual_lines.ShallowCopy(pv.PolyData())
        self._residual_lines.Modified()

    def set_effectors_visible(self, visible: bool) -> None:
        """Show or hide effectors and residual lines."""
        self._effectors_visible = bool(visible)
        self._effector_actor.visibility = self._effectors_visible
        self._residual_actor.visibility = self._effectors_visible

    def set_grid_visible(self, visible: bool) -> None:
        """Show or hide the ground grid."""
        self._grid_actor.visibility = bool(visible)

    # --------------------------------------------------------------------------------------- camera
    def set_ground(self, points: np.ndarray, height: float = 0.0) -> None:
        """Size the ground grid (plane ``z = height`` mm) to cover the XY extent of ``points (N,3)``."""
        finite = np.asarray(points, dtype=float).reshape(-1, 3)
        finite = finite[np.isfinite(finite).all(axis=1)]
        if not len(finite):
            return
        low, high = finite.min(axis=0), finite.max(axis=0)
        extent = float(max(high[0] - low[0], high[1] - low[1], 200.0))
        half = 1.5 * extent
        grid = _grid_lines((low[:2] + high[:2]) / 2.0, half, _nice_spacing(2.0 * half), height)
        self._grid.ShallowCopy(grid)
        self._grid.Modified()

    def frame_bounds(self, points: np.ndarray, min_radius: float = 60.0) -> None:
        """Point the Z-up camera at ``points (N,3)`` mm so that a sphere of at least ``min_radius`` mm
        around them fills the view. The camera looks across the points' longest horizontal extent
        (a hand is seen side-on along its length), from the -Y side and 35° above."""
        finite = np.asarray(points, dtype=float).reshape(-1, 3)
        finite = finite[np.isfinite(finite).all(axis=1)]
        if not len(finite):
            return
        low, high = np.percentile(finite, 1, axis=0), np.percentile(finite, 99, axis=0)
        center = (low + high) / 2.0
        radius = max(float(np.linalg.norm(high - low)) / 2.0, min_radius)
        horizontal = np.array([-0.5, -0.866])
        if len(finite) >= 3:
            spread = finite[:, :2] - finite[:, :2].mean(axis=0)
            eigenvalues, eigenvectors = np.linalg.eigh(spread.T @ spread)
            if eigenvalues[1] > 2.0 * max(eigenvalues[0], 1e-9):       # clearly elongated in XY
                long_axis = eigenvectors[:, 1]
                across = np.array([-long_axis[1], long_axis[0]])
                horizontal = across if across @ horizontal >= 0 else -across
        elevation = np.radians(35.0)
        direction = np.array([*(np.cos(elevation) * horizontal), np.sin(elevation)])
        camera = self._plotter.camera
        camera.focal_point = tuple(center)
        camera.up = (0.0, 0.0, 1.0)
        distance = radius / np.sin(np.radians(float(camera.view_angle)) / 2.0) * 1.05
        camera.position = tuple(center + direction * distance)
        self._plotter.renderer.ResetCameraClippingRange()

    # ------------------------------------------------------------------------------------- output
    def render(self) -> None:
        """Redraw now."""
        self._plotter.render()

    def save_screenshot(self, path: str | Path) -> None:
        """Write the current 3D view to an image file (PNG/JPEG by extension)."""
        self._plotter.screenshot(str(path))

    def close_viewport(self) -> None:
        """Release the render window (call when the owning window closes)."""
        self._plotter.close()
