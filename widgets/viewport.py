"""3D viewport of a hand take: skinned hand mesh, markers, model effectors, ground grid (Z up, mm).

The widget knows nothing about takes or solvers: it draws numpy arrays. Every scene object is built
once; per-frame updates write into the existing VTK arrays and call ``Modified()``, so scrubbing and
playback never create actors.

Drawing keeps up with scrubbing: :meth:`HandViewport.request_render` asks for one draw once the events
waiting now are handled (many requests, one render of the latest data), rendered once by the Qt
OpenGL widget's paint and without anti-aliasing; when nothing changed for :data:`IDLE_MS` the view is
drawn again with :data:`MULTI_SAMPLES`× multisampling. Marker names are drawn for the selected marker,
the one under the mouse, or all of them when asked (:meth:`HandViewport.set_labels_visible`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pyvista as pv
from numpy.typing import ArrayLike
from PySide6.QtCore import QEvent, QObject, QPointF, Qt, QTimer, Signal
from PySide6.QtGui import QMouseEvent
from PySide6.QtOpenGLWidgets import QOpenGLWidget
from PySide6.QtWidgets import QVBoxLayout, QWidget
from pyvistaqt import QtInteractor
from vtkmodules.util.numpy_support import numpy_to_vtk, vtk_to_numpy
from vtkmodules.vtkCommonCore import vtkStringArray
from vtkmodules.vtkRenderingCore import vtkActor2D, vtkGlyph3DMapper, vtkPolyDataMapper
from vtkmodules.vtkRenderingLabel import vtkLabeledDataMapper

from handmocap.core.model.hand_model import mesh_vertex_normals

# pyvista types the Plotter methods it defines through functools.wraps (set_background, enable_terrain_style,
# add_axes, remove_actor, remove_scalar_bar) as unbound functions, so mypy wants ``self`` passed again: the
# ``type: ignore``s marked "pyvista wraps" are that gap in pyvista's typing.

SKIN_COLOUR = (0.91, 0.73, 0.62)
MARKER_COLOUR = (0.55, 0.80, 1.00)
SELECTED_MARKER_COLOUR = (1.00, 0.86, 0.20)
EFFECTOR_COLOUR = (1.00, 0.55, 0.10)
RIGID_BODY_COLOUR = (0.55, 0.85, 1.00)   # lines between the markers of one rigid object
BACKGROUND_TOP = (0.24, 0.26, 0.30)
BACKGROUND_BOTTOM = (0.07, 0.08, 0.09)
GRID_COLOUR = (0.25, 0.27, 0.30)         # opaque (a translucent actor costs a transparency pass per render)
LOOSE_POINT_COLOUR = (0.62, 0.62, 0.62)

MARKER_RADIUS_MM = 3.2
EFFECTOR_RADIUS_MM = 2.2
LOOSE_POINT_RADIUS_MM = 2.0
SELECTED_SCALE = 1.7
PICK_RADIUS_PX = 12.0      # a click this close to a marker's centre selects it
CLICK_SLOP_PX = 4.0        # a press and release further apart than this is a camera drag, not a click
MULTI_SAMPLES = 4          # multisampling of the still view (software OpenGL: a render costs ~3× more with it)
IDLE_MS = 200              # the view is redrawn anti-aliased when nothing changed for this long


class ClickFilter:
    """Event filter logic of a 3D view: keeps key presses from VTK (its one-letter commands) and tells a
    left click (press and release in place) from a camera drag."""

    def __init__(self) -> None:
        self._press: QPointF | None = None

    def filter(self, event: QEvent, on_click: Callable[[float, float], None]) -> bool:
        """Feed every event of the view: calls ``on_click(x, y)`` (logical pixels) on a completed click;
        returns True for key events, which the caller's event filter must stop."""
        if event.type() in (QEvent.Type.KeyPress, QEvent.Type.KeyRelease):
            event.ignore()
            return True
        if not isinstance(event, QMouseEvent) or event.button() != Qt.MouseButton.LeftButton:
            return False
        if event.type() == QEvent.Type.MouseButtonPress:
            self._press = event.position()
        elif event.type() == QEvent.Type.MouseButtonRelease and self._press is not None:
            moved = event.position() - self._press
            self._press = None
            if abs(moved.x()) + abs(moved.y()) <= CLICK_SLOP_PX:
                on_click(event.position().x(), event.position().y())
        return False


def screen_distances(plotter: QtInteractor, points: np.ndarray, x: float, y: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """On-screen distance (device pixels) of each of ``points (N,3)`` mm from widget position ``(x, y)``
    (logical pixels), and its depth (normalised, -1 near to 1 far); the distance is inf for points behind
    the camera, outside the depth range or NaN. Returns ``(distance (N,), depth (N,))``."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    ratio = plotter.devicePixelRatioF()
    width, height = plotter.width() * ratio, plotter.height() * ratio
    matrix = plotter.renderer.GetActiveCamera().GetCompositeProjectionTransformMatrix(width / max(height, 1.0), -1, 1)
    projection = np.array([[matrix.GetElement(row, column) for column in range(4)] for row in range(4)])
    clip = np.c_[points, np.ones(len(points))] @ projection.T
    valid = (clip[:, 3] > 1e-9) & np.isfinite(clip).all(axis=1)
    ndc = clip[:, :3] / np.where(valid, clip[:, 3], 1.0)[:, None]
    pixel_x = (ndc[:, 0] + 1.0) * 0.5 * width
    pixel_y = (1.0 - (ndc[:, 1] + 1.0) * 0.5) * height
    distance = np.hypot(pixel_x - x * ratio, pixel_y - y * ratio)
    distance = np.where(valid & (np.abs(ndc[:, 2]) <= 1.0), distance, np.inf)
    return distance, ndc[:, 2]


def finite_points(points: ArrayLike) -> np.ndarray:
    """The rows of ``points`` (anything of N×3 numbers) without a NaN or infinity, ``(n,3)`` float."""
    finite = np.asarray(points, dtype=float).reshape(-1, 3)
    return finite[np.isfinite(finite).all(axis=1)]


def aim_camera(plotter: QtInteractor, points: np.ndarray, min_radius: float, direction: np.ndarray,
               up: tuple[float, float, float]) -> None:
    """Point the ``plotter``'s camera at finite ``points (N,3)`` mm from the unit ``direction`` (from the
    points towards the camera) with ``up``, so that a sphere of at least ``min_radius`` mm around the middle
    98 % of them fills the view."""
    low, high = np.percentile(points, 1, axis=0), np.percentile(points, 99, axis=0)
    centre = (low + high) / 2.0
    radius = max(float(np.linalg.norm(high - low)) / 2.0, min_radius)
    camera = plotter.camera
    camera.focal_point = tuple(centre)
    camera.up = up
    distance = radius / np.sin(np.radians(float(camera.view_angle)) / 2.0) * 1.05
    camera.position = tuple(centre + direction * distance)
    plotter.renderer.ResetCameraClippingRange()


def _as_rgb_bytes(colours: ArrayLike) -> np.ndarray:
    """``(N,3)`` floats in [0, 1] to ``(N,3)`` uint8."""
    return np.clip(np.round(np.asarray(colours, dtype=float) * 255.0), 0, 255).astype(np.uint8)


def _segments(starts: np.ndarray, ends: np.ndarray) -> pv.PolyData:
    """Line segments from ``starts (S,3)`` to ``ends (S,3)`` mm as poly data (empty when S = 0)."""
    count = len(starts)
    if not count:
        return pv.PolyData()
    points = np.empty((2 * count, 3))
    points[0::2], points[1::2] = starts, ends
    cells = np.column_stack([np.full(count, 2), np.arange(0, 2 * count, 2), np.arange(1, 2 * count, 2)])
    return pv.PolyData(points, lines=cells.ravel())


def _set_segments(data: pv.PolyData, starts: np.ndarray, ends: np.ndarray) -> None:
    """Make ``data`` the segments from ``starts (S,3)`` to ``ends (S,3)`` mm: the points move in place
    when ``data`` holds S segments already, else it is rebuilt."""
    count = len(starts)
    if count and data.GetNumberOfCells() == count and data.GetNumberOfPoints() == 2 * count:
        points = vtk_to_numpy(data.GetPoints().GetData())
        points[0::2], points[1::2] = starts, ends
        data.GetPoints().Modified()
    else:
        data.ShallowCopy(_segments(starts, ends))
    data.Modified()


def _grid_lines(center_xy: np.ndarray, half_extent: float, spacing: float, height: float) -> pv.PolyData:
    """Square grid of lines in the plane ``z = height`` centred (snapped to ``spacing``) on ``center_xy``."""
    center = np.round(np.asarray(center_xy, dtype=float) / spacing) * spacing
    count = int(np.ceil(half_extent / spacing))
    ticks = np.arange(-count, count + 1) * spacing
    low, high = -count * spacing, count * spacing
    start_xy: list[tuple[float, float]] = []
    end_xy: list[tuple[float, float]] = []
    for tick in ticks:
        start_xy += [(center[0] + tick, center[1] + low), (center[0] + low, center[1] + tick)]
        end_xy += [(center[0] + tick, center[1] + high), (center[0] + high, center[1] + tick)]
    starts, ends = np.asarray(start_xy, dtype=float), np.asarray(end_xy, dtype=float)
    plane = np.full((len(starts), 1), float(height))
    return _segments(np.hstack([starts, plane]), np.hstack([ends, plane]))


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
        self._off_screen = bool(pv.OFF_SCREEN if off_screen is None else off_screen)
        self._plotter = QtInteractor(self, off_screen=self._off_screen, auto_update=False, multi_samples=0)
        self._plotter.setAcceptDrops(False)       # files dropped on the view go to the window
        self._plotter.installEventFilter(self)
        self._plotter.setMouseTracking(True)      # hovering a marker shows its name
        self._clicks = ClickFilter()
        layout.addWidget(self._plotter)
        self.setMinimumSize(320, 240)
        self.render_count = 0                     # VTK renders of this view so far (benchmarks and tests)
        self._plotter.GetRenderWindow().AddObserver("EndEvent", self._rendered)
        self._render_timer = QTimer(self)            # off screen: there is no paint to render in
        self._render_timer.setSingleShot(True)
        self._render_timer.setInterval(0)
        self._render_timer.timeout.connect(self._plotter.render)
        self._idle_timer = QTimer(self)
        self._idle_timer.setSingleShot(True)
        self._idle_timer.setInterval(IDLE_MS)
        self._idle_timer.timeout.connect(self._draw_still)

        plotter = self._plotter
        plotter.set_background(BACKGROUND_BOTTOM, top=BACKGROUND_TOP)  # type: ignore[arg-type]  # pyvista wraps
        plotter.enable_lightkit()
        if plotter.iren is not None:
            plotter.enable_terrain_style(mouse_wheel_zooms=True)  # type: ignore[call-arg]  # pyvista wraps
            style = plotter.iren.interactor.GetInteractorStyle()      # orbiting: fast renders, smooth once still
            style.AddObserver("StartInteractionEvent", lambda *_: self._set_multi_samples(0))
            style.AddObserver("EndInteractionEvent", lambda *_: self._idle_timer.start())
        plotter.add_axes(interactive=False, line_width=2, color="white",  # type: ignore[call-arg]  # pyvista wraps
                         xlabel="X", ylabel="Y", zlabel="Z")

        self._marker_names: list[str] = []
        self._marker_positions = np.zeros((0, 3))
        self._marker_colours = np.zeros((0, 3))
        self._selected: int | None = None
        self._hovered: int | None = None
        self._labelled = np.zeros(0, dtype=np.int64)   # markers whose names are drawn now
        self._label_texts: list[str] = []
        self._labels_visible = False
        self._effectors_visible = True
        self._mesh_visible = True

        self._build_grid()
        self._build_mesh()
        self._build_markers()
        self._build_effectors()
        self._build_rigid_bodies()
        self._build_labels()
        self._build_trails()
        self.frame_bounds(np.array([[-100.0, -100.0, 0.0], [100.0, 100.0, 200.0]]))

    # ----------------------------------------------------------------------------------- scene setup
    def _build_grid(self) -> None:
        self._grid = _grid_lines(np.zeros(2), 500.0, 50.0, 0.0)
        self._grid_actor = self._plotter.add_mesh(self._grid, color=GRID_COLOUR,
                                                  line_width=1, lighting=False, pickable=False,
                                                  name="ground-grid")

    def _build_mesh(self) -> None:
        self._meshes: list[pv.PolyData] = []
        self._mesh_faces: list[np.ndarray] = []
        self._mesh_actors: list[pv.Actor] = []
        self._mesh_count = 0
        self._add_mesh_slot()

    def _add_mesh_slot(self) -> None:
        """One more hand surface actor (hidden), for scenes with more hands than slots."""
        mesh = pv.PolyData()
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(mesh)
        mapper.ScalarVisibilityOff()
        actor = pv.Actor(mapper=mapper)
        prop = actor.prop
        prop.color = SKIN_COLOUR
        prop.interpolation = "phong"
        prop.ambient = 0.12
        prop.diffuse = 0.85
        prop.specular = 0.18
        prop.specular_power = 18.0
        actor.visibility = False
        actor.SetPickable(False)
        self._plotter.add_actor(actor, name=f"hand-mesh-{len(self._meshes)}", reset_camera=False)
        self._meshes.append(mesh)
        self._mesh_faces.append(np.zeros((0, 3), dtype=np.int64))
        self._mesh_actors.append(actor)

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
    def _resize_points(data: pv.PolyData, count: int, colour: tuple[float, float, float]) -> None:
        """Give ``data`` ``count`` points with a zero ``scale`` array and a ``colors`` array."""
        data.SetPoints(pv.vtk_points(np.zeros((count, 3))))
        for name, values in (("scale", np.zeros(count)),
                             ("colors", np.tile(_as_rgb_bytes(colour), (count, 1)))):
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
        self._resize_points(self._marker_data, 0, MARKER_COLOUR)
        self._marker_actor = self._glyph_actor(self._marker_data, MARKER_RADIUS_MM, "markers")

    def _build_effectors(self) -> None:
        self._effector_data = pv.PolyData()
        self._resize_points(self._effector_data, 0, EFFECTOR_COLOUR)
        self._effector_actor = self._glyph_actor(self._effector_data, EFFECTOR_RADIUS_MM, "effectors")
        self._residual_lines = pv.PolyData()
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(self._residual_lines)
        mapper.ScalarVisibilityOff()
        self._residual_actor = pv.Actor(mapper=mapper)
        self._residual_actor.prop.color = EFFECTOR_COLOUR
        self._residual_actor.prop.line_width = 2.0
        self._residual_actor.prop.lighting = False
        self._plotter.add_actor(self._residual_actor, name="residual-lines", reset_camera=False)

    def _build_rigid_bodies(self) -> None:
        self._rigid_lines = pv.PolyData()
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(self._rigid_lines)
        mapper.ScalarVisibilityOff()
        actor = pv.Actor(mapper=mapper)
        actor.prop.color = RIGID_BODY_COLOUR
        actor.prop.line_width = 2.5
        actor.prop.lighting = False
        self._plotter.add_actor(actor, name="rigid-bodies", reset_camera=False)

    def _build_trails(self) -> None:
        self._trail_data = pv.PolyData()
        self._trail_shape: tuple = ((), b"")        # point count of each polyline and their colours
        mapper = vtkPolyDataMapper()
        mapper.SetInputData(self._trail_data)
        mapper.SetColorModeToDirectScalars()
        mapper.SetScalarModeToUseCellFieldData()
        mapper.SelectColorArray("colors")
        mapper.ScalarVisibilityOn()
        self._trail_actor = pv.Actor(mapper=mapper)
        self._trail_actor.prop.line_width = 2.0
        self._trail_actor.prop.lighting = False
        self._trail_actor.SetPickable(False)
        self._plotter.add_actor(self._trail_actor, name="trails", reset_camera=False)
        self._loose_data = pv.PolyData()
        self._resize_points(self._loose_data, 0, LOOSE_POINT_COLOUR)
        self._loose_actor = self._glyph_actor(self._loose_data, LOOSE_POINT_RADIUS_MM, "loose-points")

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
        """Keep key presses from VTK; turn a left click (press and release in place) into a pick; name the
        marker under the mouse while no button is held."""
        if watched is not self._plotter:
            return False
        if (isinstance(event, QMouseEvent) and event.type() == QEvent.Type.MouseMove
                and event.buttons() == Qt.MouseButton.NoButton):
            self.set_hovered_marker(self.marker_at(event.position().x(), event.position().y()))
        elif event.type() == QEvent.Type.Leave:
            self.set_hovered_marker(-1)
        return self._clicks.filter(event, lambda x, y: self.marker_clicked.emit(self.marker_at(x, y)))

    def marker_at(self, x: float, y: float) -> int:
        """Index of the shown marker nearest to widget position ``(x, y)`` (logical pixels) within
        :data:`PICK_RADIUS_PX`, or -1."""
        if not len(self._marker_positions):
            return -1
        distance, _ = screen_distances(self._plotter, self._marker_positions, x, y)
        nearest = int(np.argmin(distance))
        return nearest if distance[nearest] <= PICK_RADIUS_PX * self._plotter.devicePixelRatioF() else -1

    # --------------------------------------------------------------------------------------- access
    @property
    def plotter(self) -> QtInteractor:
        """The underlying pyvista Qt interactor (for camera access and screenshots)."""
        return self._plotter

    def marker_points(self) -> np.ndarray:
        """The marker positions currently shown, ``(M,3)`` mm, NaN where hidden (a copy)."""
        return self._marker_positions.copy()

    def vertex_points(self, hand: int = 0) -> np.ndarray:
        """The vertices of hand surface ``hand`` currently shown, ``(V,3)`` mm (empty without one)."""
        return np.array(self._meshes[hand].points) if hand < self._mesh_count else np.zeros((0, 3))

    def selected_marker(self) -> int | None:
        """Index of the highlighted marker, or None."""
        return self._selected

    # -------------------------------------------------------------------------------------- markers
    def set_markers(self, names: Sequence[str], positions: np.ndarray,
                    colours: np.ndarray | None = None) -> None:
        """Show a new marker set: ``names (M,)``, ``positions (M,3)`` mm (NaN = missing),
        ``colours (M,3)`` in [0, 1] (default light blue)."""
        count = len(names)
        self._marker_names = list(names)
        self._marker_colours = (np.tile(MARKER_COLOUR, (count, 1)) if colours is None
                               else np.asarray(colours, dtype=float).reshape(count, 3))
        self._selected = self._hovered = None
        self._resize_points(self._marker_data, count, MARKER_COLOUR)
        self._marker_positions = np.full((count, 3), np.nan)
        self.update_markers(positions)

    def set_marker_names(self, names: Sequence[str]) -> None:
        """New names for the current markers (same count), e.g. the labels the points hold this frame."""
        if len(names) != len(self._marker_names):
            raise ValueError(f"{len(names)} names for {len(self._marker_names)} markers")
        self._marker_names = list(names)
        self._refresh_labels()

    def marker_names(self) -> list[str]:
        """Names of the current markers."""
        return list(self._marker_names)

    def set_marker_colours(self, colours: np.ndarray) -> None:
        """Base colours ``(M,3)`` in [0, 1] of the current markers."""
        self._marker_colours = np.asarray(colours, dtype=float).reshape(len(self._marker_names), 3)
        self._refresh_marker_style()

    def update_markers(self, positions: np.ndarray) -> None:
        """Move the current markers to ``positions (M,3)`` mm; NaN rows are hidden."""
        positions = np.asarray(positions, dtype=float).reshape(len(self._marker_names), 3)
        self._marker_positions = positions.copy()
        visible = np.isfinite(positions).all(axis=1)
        vtk_to_numpy(self._marker_data.GetPoints().GetData())[visible] = positions[visible]
        self._refresh_marker_style()
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
        colours = self._marker_colours.copy()
        if self._selected is not None:
            scale[self._selected] *= SELECTED_SCALE
            colours[self._selected] = SELECTED_MARKER_COLOUR
        self._point_array(self._marker_data, "scale")[:] = scale
        self._point_array(self._marker_data, "colors")[:] = _as_rgb_bytes(colours)
        self._modified(self._marker_data)

    # --------------------------------------------------------------------------------------- labels
    def set_labels_visible(self, visible: bool) -> None:
        """Show or hide the names of all markers (the selected marker and the one under the mouse are
        always named)."""
        self._labels_visible = bool(visible)
        self._refresh_labels()
        self.request_render()

    def set_hovered_marker(self, index: int) -> None:
        """Name marker ``index`` while the mouse is over it (-1: none)."""
        hovered = index if 0 <= index < len(self._marker_names) else None
        if hovered != self._hovered:
            self._hovered = hovered
            self._refresh_labels()
            self.request_render()

    def labelled_markers(self) -> list[int]:
        """Indices of the markers whose names are drawn now."""
        return [int(index) for index in self._labelled]

    def _refresh_labels(self) -> None:
        """Name the selected and the hovered marker (all markers when names are switched on); the label
        points move in place while the same markers keep the same names."""
        visible = np.isfinite(self._marker_positions).all(axis=1)
        if not self._labels_visible:
            named = np.zeros_like(visible)
            for index in (self._selected, self._hovered):
                if index is not None:
                    named[index] = True
            visible &= named
        indices = np.flatnonzero(visible)
        texts = [f"  {self._marker_names[index]}" for index in indices]
        if np.array_equal(indices, self._labelled) and texts == self._label_texts and len(indices):
            vtk_to_numpy(self._label_data.GetPoints().GetData())[:] = self._marker_positions[indices]
            self._label_data.GetPoints().Modified()
            self._label_data.Modified()
            return
        names = vtkStringArray()
        names.SetName("names")
        for text in texts:
            names.InsertNextValue(text)
        label_data = pv.PolyData(self._marker_positions[indices]) if len(indices) else pv.PolyData()
        label_data.GetPointData().AddArray(names)
        self._label_data.ShallowCopy(label_data)
        self._label_actor.SetVisibility(bool(len(indices)))
        self._labelled, self._label_texts = indices, texts

    # ---------------------------------------------------------------------------------- hand mesh
    def set_hand_mesh(self, vertices: np.ndarray | None, faces: np.ndarray | None = None) -> None:
        """Show one hand surface ``vertices (V,3)`` mm with triangles ``faces (T,3)``; None hides it."""
        self.set_hand_meshes([] if vertices is None or faces is None else [(vertices, faces)])

    def set_hand_meshes(self, meshes: Sequence[tuple[np.ndarray, np.ndarray]]) -> None:
        """Show one surface per hand: ``meshes`` of ``(vertices (V,3) mm, faces (T,3))``; [] hides all."""
        while len(self._meshes) < len(meshes):
            self._add_mesh_slot()
        for number, (vertices, faces) in enumerate(meshes):
            # copies: the widget updates these points in place, the caller's arrays must stay untouched
            self._mesh_faces[number] = np.array(faces, dtype=np.int64)
            surface = pv.PolyData.from_regular_faces(np.array(vertices, dtype=float), self._mesh_faces[number])
            normals = numpy_to_vtk(mesh_vertex_normals(surface.points, self._mesh_faces[number]), deep=True)
            normals.SetName("Normals")
            surface.GetPointData().SetNormals(normals)
            self._meshes[number].ShallowCopy(surface)
        self._mesh_count = len(meshes)
        self._refresh_mesh_visibility()

    def update_hand_vertices(self, vertices: np.ndarray, hand: int = 0) -> None:
        """Move the shown surface of ``hand`` to ``vertices (V,3)`` mm, in place, with its smooth-shading
        normals (computed here: VTK's normals filter would rebuild the mesh's topology on every frame)."""
        if hand >= self._mesh_count:
            return
        mesh = self._meshes[hand]
        vtk_to_numpy(mesh.GetPoints().GetData())[:] = vertices
        normals = mesh.GetPointData().GetNormals()
        vtk_to_numpy(normals)[:] = mesh_vertex_normals(vertices, self._mesh_faces[hand])
        mesh.GetPoints().Modified()
        normals.Modified()
        mesh.Modified()

    def hand_count(self) -> int:
        """Number of hand surfaces set."""
        return self._mesh_count

    def set_mesh_visible(self, visible: bool) -> None:
        """Show or hide the hand meshes (those that are set)."""
        self._mesh_visible = bool(visible)
        self._refresh_mesh_visibility()

    def _refresh_mesh_visibility(self) -> None:
        for index, actor in enumerate(self._mesh_actors):
            actor.visibility = self._mesh_visible and index < self._mesh_count

    # ------------------------------------------------------------------------ trails and loose points
    def set_trails(self, trails: Sequence[np.ndarray], colours: np.ndarray | None = None) -> None:
        """Draw a polyline per trail ``(T,3)`` mm (NaN rows break the line), coloured ``colours (N,3)``
        in [0, 1] (default the selection colour); an empty list clears them."""
        points, cells, cell_colours = [], [], []
        offset = 0
        palette = (np.tile(SELECTED_MARKER_COLOUR, (len(trails), 1)) if colours is None
                   else np.asarray(colours, dtype=float).reshape(len(trails), 3))
        for given, colour in zip(trails, palette, strict=True):
            trail = np.asarray(given, dtype=float).reshape(-1, 3)
            finite = np.isfinite(trail).all(axis=1)
            bounds = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
            for start, end in zip(bounds[0::2], bounds[1::2], strict=True):
                if end - start < 2:
                    continue
                points.append(trail[start:end])
                cells.append(np.concatenate([[end - start], offset + np.arange(end - start)]))
                cell_colours.append(colour)
                offset += end - start
        shape = (tuple(len(part) for part in points), _as_rgb_bytes(np.array(cell_colours)).tobytes())
        if points and shape == self._trail_shape:        # same polylines, moved: write the points in place
            vtk_to_numpy(self._trail_data.GetPoints().GetData())[:] = np.concatenate(points)
            self._trail_data.GetPoints().Modified()
        elif points:
            lines = pv.PolyData(np.concatenate(points), lines=np.concatenate(cells))
            lines.cell_data["colors"] = _as_rgb_bytes(np.array(cell_colours))
            self._trail_data.ShallowCopy(lines)
        else:
            self._trail_data.ShallowCopy(pv.PolyData())
        self._trail_shape = shape
        self._trail_data.Modified()

    def set_loose_points(self, points: np.ndarray | None, colours: np.ndarray | None = None) -> None:
        """Show small dots that are not pickable markers, e.g. gap fills, ``(K,3)`` mm coloured
        ``colours (K,3)`` in [0, 1] (default grey); None clears them."""
        points = np.zeros((0, 3)) if points is None else np.asarray(points, dtype=float).reshape(-1, 3)
        colours = (np.tile(LOOSE_POINT_COLOUR, (len(points), 1)) if colours is None
                  else np.asarray(colours, dtype=float).reshape(len(points), 3))
        finite = np.isfinite(points).all(axis=1)
        points, colours = points[finite], colours[finite]
        if self._loose_data.GetNumberOfPoints() != len(points):
            self._resize_points(self._loose_data, len(points), LOOSE_POINT_COLOUR)
        vtk_to_numpy(self._loose_data.GetPoints().GetData())[:] = points
        self._point_array(self._loose_data, "scale")[:] = 1.0
        self._point_array(self._loose_data, "colors")[:] = _as_rgb_bytes(colours)
        self._modified(self._loose_data)

    # ------------------------------------------------------------------------------------ effectors
    def set_effectors(self, effectors: np.ndarray | None, targets: np.ndarray | None = None) -> None:
        """Show the model's effectors ``(K,3)`` mm and a line from each to its measured marker
        ``targets (K,3)`` (NaN rows: no line; NaN effector: hidden). None clears them."""
        if effectors is None:
            effectors = np.zeros((0, 3))
        effectors = np.asarray(effectors, dtype=float).reshape(-1, 3)
        count = len(effectors)
        if self._effector_data.GetNumberOfPoints() != count:
            self._resize_points(self._effector_data, count, EFFECTOR_COLOUR)
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
        _set_segments(self._residual_lines, effectors[paired], targets[paired])

    def set_rigid_bodies(self, segments: np.ndarray | None) -> None:
        """Draw rigid objects as lines between their labelled markers: ``segments (S, 2, 3)`` mm (start
        and end of each line); None or empty clears them."""
        segments = np.zeros((0, 2, 3)) if segments is None else np.asarray(segments, dtype=float).reshape(-1, 2, 3)
        _set_segments(self._rigid_lines, segments[:, 0], segments[:, 1])

    def rigid_body_segment_count(self) -> int:
        """Number of rigid-body lines drawn."""
        return self._rigid_lines.GetNumberOfCells()

    def set_camera_frustum(self, segments: np.ndarray | None) -> None:
        """Draw a video camera as its viewing pyramid: ``segments (S,2,3)`` mm (start and end of each line,
        e.g. from the camera's pose and intrinsics); None hides it. Its one actor is made at the first call."""
        segments = np.zeros((0, 2, 3)) if segments is None else np.asarray(segments, dtype=float).reshape(-1, 2, 3)
        if getattr(self, "_frustum_lines", None) is None:
            if not len(segments):
                return
            self._frustum_lines = _segments(segments[:, 0], segments[:, 1])
            self._frustum_actor = self._plotter.add_mesh(
                self._frustum_lines, color=(0.75, 0.78, 0.85), line_width=1.0, opacity=0.6, lighting=False,
                pickable=False, name="camera-frustum", reset_camera=False)
        self._frustum_lines.ShallowCopy(_segments(segments[:, 0], segments[:, 1]))
        self._frustum_lines.Modified()
        self._frustum_actor.visibility = bool(len(segments))

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
        finite = finite_points(points)
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
        finite = finite_points(points)
        if not len(finite):
            return
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
        aim_camera(self._plotter, finite, min_radius, direction, (0.0, 0.0, 1.0))

    # ------------------------------------------------------------------------------------- output
    def render_now(self) -> None:
        """Redraw now, anti-aliased (screenshots). (Not ``render``: that is QWidget's painting into a device.)"""
        self._render_timer.stop()
        self._idle_timer.stop()
        self._set_multi_samples(MULTI_SAMPLES)
        self._plotter.render()

    def request_render(self) -> None:
        """Redraw with the next paint of the window: many requests before it, one render of the latest data
        (fast scrubbing skips frames), without anti-aliasing; anti-aliased once nothing changed for
        :data:`IDLE_MS`. The paint is Qt's, so the view and the widgets that changed with it are composed
        on screen together (a timer of its own would make Qt compose the window once more). Nothing once
        the view is closed (a job that ends after the window closed still announces its result)."""
        if self._plotter.GetRenderWindow() is None:
            return
        self._set_multi_samples(0)
        self._paint()
        self._idle_timer.start()

    def is_anti_aliased(self) -> bool:
        """Whether the view is drawn with multisampling now (it is when still)."""
        return self._plotter.GetRenderWindow().GetMultiSamples() > 0

    def _draw_still(self) -> None:
        if self._plotter.GetRenderWindow() is None:
            return
        self._set_multi_samples(MULTI_SAMPLES)
        self._paint()

    def _set_multi_samples(self, samples: int) -> None:
        window = self._plotter.GetRenderWindow()
        if window.GetMultiSamples() != samples:
            window.SetMultiSamples(samples)

    def _paint(self) -> None:
        """Schedule one render: the OpenGL widget renders in its paint and shows the result (rendering
        first and then painting would render twice); an off-screen view renders once the events waiting
        now are handled."""
        if self._off_screen:
            self._render_timer.start()
        else:
            QOpenGLWidget.update(self._plotter)

    def _rendered(self, *_arguments: object) -> None:
        self.render_count += 1

    def save_screenshot(self, path: str | Path) -> None:
        """Write the current 3D view to an image file (PNG/JPEG by extension)."""
        self._plotter.screenshot(str(path))

    def close_viewport(self) -> None:
        """Release the render window (call when the owning window closes)."""
        self._render_timer.stop()
        self._idle_timer.stop()
        close_plotter(self._plotter)


def close_plotter(plotter: QtInteractor) -> None:
    """Close a Qt 3D view and drop its Python handles on Qt's GL context and surface.

    pyvistaqt keeps wrappers of the widget's QOpenGLContext and QSurface; when Qt destroys them while the
    wrappers live on, a later QObject can get the same address and PySide hands out the stale QSurface
    wrapper for it (seen as "'QSurface' object has no attribute 'children'" when pyqtgraph walks a new
    plot's widgets). pyvistaqt drops them itself when the context announces its end, which Qt does not
    always deliver (e.g. when the parent window goes first); its ``_forget_context`` does the same now.
    """
    plotter.close()
    forget = getattr(plotter, "_forget_context", None)
    if forget is not None:
        forget()
