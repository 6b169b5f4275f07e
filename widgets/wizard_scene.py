"""3D view for the calibration wizard: a scan point cloud, a hand surface (optionally coloured by a
per-vertex scalar such as the scan distance), landmark spheres, and click-to-pick on the points.

The widget draws numpy arrays and knows nothing about calibration. Updates of the surface write into
the existing VTK arrays (live display of a running fit).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyvista as pv
from PySide6.QtCore import QEvent, QObject, Signal
from PySide6.QtWidgets import QVBoxLayout, QWidget
from pyvistaqt import QtInteractor
from vtkmodules.util.numpy_support import vtk_to_numpy

from handmocap.widgets.viewport import ClickFilter, aim_camera, close_plotter, finite_points, screen_distances

# pyvista types the Plotter methods it defines through functools.wraps (set_background, enable_terrain_style,
# add_axes, remove_actor, remove_scalar_bar) as unbound functions, so mypy wants ``self`` passed again: the
# ``type: ignore``s marked "pyvista wraps" are that gap in pyvista's typing.

SKIN_COLOUR = (0.91, 0.73, 0.62)
POINT_COLOUR = (0.75, 0.78, 0.82)
LANDMARK_COLOUR = (0.30, 0.75, 1.00)
CURRENT_COLOUR = (1.00, 0.84, 0.15)
BACKGROUND_TOP = (0.24, 0.26, 0.30)
BACKGROUND_BOTTOM = (0.07, 0.08, 0.09)
PICK_RADIUS_PX = 10.0
LANDMARK_RADIUS_MM = 2.5


class CalibrationScene(QWidget):
    """Z-up 3D view of a point cloud, one surface and landmark spheres (mm).

    A left click (press and release in place) emits :attr:`point_picked` with the index of the front-most
    shown point within :data:`PICK_RADIUS_PX` of the cursor (-1 when there is none).
    """

    point_picked = Signal(int)

    def __init__(self, parent: QWidget | None = None, title: str = "") -> None:
        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self._plotter = QtInteractor(self, auto_update=False)
        self._plotter.installEventFilter(self)
        layout.addWidget(self._plotter)
        self.setMinimumSize(280, 220)
        plotter = self._plotter
        plotter.set_background(BACKGROUND_BOTTOM, top=BACKGROUND_TOP)  # type: ignore[arg-type]  # pyvista wraps
        plotter.enable_lightkit()
        if plotter.iren is not None:
            plotter.enable_terrain_style(mouse_wheel_zooms=True)  # type: ignore[call-arg]  # pyvista wraps
        if title:
            plotter.add_text(title, position="upper_left", font_size=10, color="white", name="title")
        self._clicks = ClickFilter()
        self._points = np.zeros((0, 3))
        self._cloud: pv.PolyData | None = None
        self._surface: pv.PolyData | None = None
        self._surface_scalars: str | None = None

    # ------------------------------------------------------------------------------------ content
    def set_points(self, points: np.ndarray | None, colours: np.ndarray | None = None, point_size: float = 2.0) -> None:
        """Show ``points (N,3)`` mm with RGB ``colours (N,3)`` uint8 (grey when None); None removes them."""
        self._plotter.remove_actor("cloud", render=False)  # type: ignore[arg-type]  # pyvista wraps
        if points is None or len(points) == 0:
            self._points, self._cloud = np.zeros((0, 3)), None
            return
        self._points = np.asarray(points, dtype=float)
        self._cloud = pv.PolyData(self._points.copy())
        rgb = (np.tile((np.array(POINT_COLOUR) * 255).astype(np.uint8), (len(points), 1)) if colours is None
               else np.asarray(colours, dtype=np.uint8))
        self._cloud["rgb"] = rgb
        self._plotter.add_mesh(self._cloud, scalars="rgb", rgb=True, point_size=point_size, name="cloud",
                               render_points_as_spheres=False, reset_camera=False, lighting=False)

    def set_point_colours(self, colours: np.ndarray) -> None:
        """Recolour the shown points, ``colours (N,3)`` uint8."""
        if self._cloud is None:
            return
        # pyvista types pyvista_ndarray's index as int or an int array only, not a slice
        self._cloud["rgb"][:] = np.asarray(colours, dtype=np.uint8)  # type: ignore[index]
        self._cloud.Modified()

    def set_surface(self, vertices: np.ndarray | None, faces: np.ndarray | None = None,
                    scalars: np.ndarray | None = None, clim: tuple[float, float] = (0.0, 5.0),
                    scalar_title: str = "distance to scan (mm)", opacity: float = 1.0,
                    colour: tuple[float, float, float] = SKIN_COLOUR) -> None:
        """Show one surface ``vertices (V,3)``, ``faces (T,3)``; with ``scalars (V,)`` coloured by them (a
        colour bar titled ``scalar_title``), else in ``color``; None removes it."""
        self._plotter.remove_actor("surface", render=False)  # type: ignore[arg-type]  # pyvista wraps
        if self._surface_scalars:
            self._plotter.remove_scalar_bar(scalar_title)  # type: ignore[arg-type]  # pyvista wraps
        self._surface, self._surface_scalars = None, None
        if vertices is None or faces is None:
            return
        # pyvista annotates faces as ndarray[dtype[int]], a dtype no numpy array has
        surface = pv.PolyData.from_regular_faces(np.array(vertices, dtype=float),
                                                 np.array(faces, dtype=np.int64))  # type: ignore[arg-type]
        if scalars is not None:
            surface[scalar_title] = np.nan_to_num(np.asarray(scalars, dtype=float), nan=clim[1])
            self._plotter.add_mesh(surface, scalars=scalar_title, clim=clim, cmap="viridis", name="surface",
                                   smooth_shading=True, reset_camera=False, opacity=opacity,
                                   scalar_bar_args={"title": scalar_title, "color": "white"})
            self._surface_scalars = scalar_title
        else:
            self._plotter.add_mesh(surface, color=colour, smooth_shading=True, name="surface", opacity=opacity,
                                   reset_camera=False, specular=0.2)
        self._surface = surface

    def update_surface(self, vertices: np.ndarray) -> None:
        """Move the shown surface to ``vertices (V,3)`` in place."""
        if self._surface is None or len(vertices) != self._surface.n_points:
            return
        vtk_to_numpy(self._surface.GetPoints().GetData())[:] = vertices
        self._surface.GetPoints().Modified()
        self._surface.Modified()

    def surface_points(self) -> np.ndarray:
        """The shown surface's vertices (V,3) (empty when none)."""
        return np.zeros((0, 3)) if self._surface is None else np.asarray(self._surface.points)

    def set_landmarks(self, positions: np.ndarray, current: int | None = None) -> None:
        """Spheres at ``positions (L,3)`` mm (NaN rows are not drawn); ``current`` is highlighted."""
        self._plotter.remove_actor("landmarks", render=False)  # type: ignore[arg-type]  # pyvista wraps
        self._plotter.remove_actor("current-landmark", render=False)  # type: ignore[arg-type]  # pyvista wraps
        positions = np.asarray(positions, dtype=float).reshape(-1, 3)
        shown = np.isfinite(positions).all(axis=1)
        others = shown.copy()
        if current is not None and 0 <= current < len(positions) and shown[current]:
            others[current] = False
            sphere = pv.Sphere(radius=1.5 * LANDMARK_RADIUS_MM, center=positions[current])
            self._plotter.add_mesh(sphere, color=CURRENT_COLOUR, name="current-landmark", reset_camera=False)
        if others.any():
            glyphs = pv.PolyData(positions[others]).glyph(geom=pv.Sphere(radius=LANDMARK_RADIUS_MM), scale=False,
                                                          orient=False)
            self._plotter.add_mesh(glyphs, color=LANDMARK_COLOUR, name="landmarks", reset_camera=False)

    def frame(self, points: np.ndarray) -> None:
        """Look at ``points (N,3)`` from the back of the hand (+Z) and slightly from the wrist."""
        finite = finite_points(points)
        if len(finite):
            direction = np.array([0.0, -0.35, 1.0]) / np.linalg.norm([0.0, -0.35, 1.0])
            aim_camera(self._plotter, finite, 40.0, direction, (0.0, 1.0, 0.0))

    # ------------------------------------------------------------------------------------ picking
    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        """Keep key presses from VTK; turn a left click (press and release in place) into a pick."""
        return watched is self._plotter and self._clicks.filter(
            event, lambda x, y: self.point_picked.emit(self.point_at(x, y)))

    def point_at(self, x: float, y: float) -> int:
        """Index of the front-most shown point within :data:`PICK_RADIUS_PX` of widget position ``(x, y)``
        (logical pixels), or -1."""
        if not len(self._points):
            return -1
        distance, depth = screen_distances(self._plotter, self._points, x, y)
        near = np.flatnonzero(distance <= PICK_RADIUS_PX * self._plotter.devicePixelRatioF())
        if not len(near):
            return -1
        depth = depth[near]
        front = near[depth <= depth.min() + 0.002]          # the nearest surface layer under the cursor
        return int(front[np.argmin(distance[front])])

    # ------------------------------------------------------------------------------------ output
    @property
    def plotter(self) -> QtInteractor:
        return self._plotter

    def render_now(self) -> None:
        """Redraw now. (Not ``render``: that is QWidget's painting into a device.)"""
        self._plotter.render()

    def save_screenshot(self, path: str | Path) -> None:
        self._plotter.screenshot(str(path))

    def close_scene(self) -> None:
        """Release the render window."""
        close_plotter(self._plotter)
