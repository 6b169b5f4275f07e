"""The main window's 3D view, built once the window is on screen.

VTK, pyvista and pyvistaqt take about two seconds to import and the window a fraction of that, so the window
shows first with this stand-in in the 3D view's place: a panel paints the view's background with a line
saying the view is being prepared, and the :class:`~handmocap.widgets.viewport.HandViewport` is built
(importing its stack) a moment after that first paint. The panel draws through OpenGL, as the
view does: a window shown without an OpenGL child is re-created when it gets one (it flickers and loses the
keyboard).

The stand-in has the view's interface: what changes the drawing (``set_…``, ``update_…``, ``frame_bounds``,
``request_render``) is kept until the view exists and then done in order; anything that reads from the view
builds it at once.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QColor, QLinearGradient, QPainter
from PySide6.QtOpenGLWidgets import QOpenGLWidget
from PySide6.QtWidgets import QVBoxLayout, QWidget

if TYPE_CHECKING:
    from handmocap.widgets.viewport import HandViewport

# the view's gradient (widgets.viewport BACKGROUND_TOP / _BOTTOM), repeated here so as not to import VTK
BACKGROUND_TOP = QColor.fromRgbF(0.24, 0.26, 0.30)
BACKGROUND_BOTTOM = QColor.fromRgbF(0.07, 0.08, 0.09)
MAX_PENDING = 256        # calls kept at most; a window driven while hidden (scripts, tests) builds its view then
BUILD_DELAY_MS = 100     # after the first paint: the window system shows that frame before the build holds the
                         # event loop (about two seconds)

DRAWING_CALLS = frozenset({
    "set_markers", "set_marker_names", "set_marker_colours", "update_markers", "set_selected_marker",
    "set_labels_visible", "set_hand_mesh", "set_hand_meshes", "update_hand_vertices", "set_mesh_visible",
    "set_trails", "set_loose_points", "set_effectors", "set_rigid_bodies", "set_camera_frustum",
    "set_effectors_visible", "set_grid_visible", "set_ground", "frame_bounds", "request_render",
})


class DeferredViewport(QWidget):
    """Stands in for a :class:`HandViewport` until the window has painted, then holds it (see the module
    docstring). ``marker_clicked`` re-emits the view's clicks."""

    marker_clicked = Signal(int)

    def __init__(self, parent: QWidget | None = None, off_screen: bool | None = None) -> None:
        super().__init__(parent)
        self._off_screen = off_screen
        self._view: HandViewport | None = None
        self._pending: list[tuple[str, tuple[Any, ...], dict[str, Any]]] = []
        self._build_scheduled = False
        self._layout = QVBoxLayout(self)
        self._layout.setContentsMargins(0, 0, 0, 0)
        self._panel: PreparingPanel | None = PreparingPanel(self, self._panel_painted)
        self._layout.addWidget(self._panel)
        self.setMinimumSize(320, 240)

    def is_built(self) -> bool:
        """Whether the 3D view exists yet."""
        return self._view is not None

    def view(self) -> HandViewport:
        """The 3D view, built now if it is not yet (the calls kept until then are done first, in order)."""
        if self._view is None:
            from handmocap.widgets.viewport import HandViewport

            view = HandViewport(self, off_screen=self._off_screen)
            view.marker_clicked.connect(self.marker_clicked)
            self._layout.addWidget(view)
            self._view = view
            if self._panel is not None:        # after the view is in: the window keeps an OpenGL child
                self._layout.removeWidget(self._panel)
                self._panel.deleteLater()
                self._panel = None
            pending, self._pending = self._pending, []
            for name, arguments, keywords in pending:
                getattr(view, name)(*arguments, **keywords)
            view.request_render()
        return self._view

    def close_viewport(self) -> None:
        """Release the 3D view's render window, if it was built (call when the window closes)."""
        self._pending.clear()
        if self._view is not None:
            self._view.close_viewport()

    def __getattr__(self, name: str) -> Any:
        """The view's attribute ``name`` (once built, the view's own: nothing stands between); before, a
        drawing call is kept, anything else builds the view first. (Python asks here only for names this
        widget does not have.)"""
        if name.startswith("_"):
            raise AttributeError(name)
        if self._view is None and name in DRAWING_CALLS:
            return partial(self._keep, name)
        return getattr(self.view(), name)

    def _keep(self, name: str, *arguments: Any, **keywords: Any) -> None:
        """Keep drawing call ``name`` until the view exists (a call bound before it was built, e.g. to an
        action, lands here later too: it is then done at once)."""
        if self._view is None and len(self._pending) < MAX_PENDING:
            self._pending.append((name, arguments, keywords))
        else:
            getattr(self.view(), name)(*arguments, **keywords)

    def _panel_painted(self) -> None:
        if not self._build_scheduled:
            self._build_scheduled = True
            QTimer.singleShot(BUILD_DELAY_MS, self, self.view)


class PreparingPanel(QOpenGLWidget):
    """The 3D view's background and a line saying it is being prepared; ``painted()`` is called after each
    paint."""

    def __init__(self, parent: QWidget, painted: Callable[[], None]) -> None:
        super().__init__(parent)
        self._painted = painted

    def paintGL(self) -> None:
        painter = QPainter(self)
        gradient = QLinearGradient(0, 0, 0, self.height())
        gradient.setColorAt(0.0, BACKGROUND_TOP)
        gradient.setColorAt(1.0, BACKGROUND_BOTTOM)
        painter.fillRect(self.rect(), gradient)
        painter.setPen(QColor(200, 200, 200))
        painter.drawText(self.rect(), Qt.AlignmentFlag.AlignCenter, "Preparing the 3D view…")
        painter.end()
        self._painted()
