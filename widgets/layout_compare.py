"""Side-by-side comparison of 2–4 marker layouts: one 3D view per layout, all showing the hand in the
same posture with that layout's markers, one shared camera, one frame slider and a play button.

The widget draws numpy arrays computed by ``core``: the posed mesh is computed once per frame and
given to every view; each view adds its own markers.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QSlider,
    QStyle,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from handmocap.core.model import HandModel, MarkerSet, marker_positions, skin_vertices
from handmocap.widgets.viewport import HandViewport

MAX_VIEWS = 4
PLAYBACK_FPS = 30.0
#: one colour per compared layout (view title chip and marker colour)
LAYOUT_COLOURS = ((0.35, 0.70, 1.00), (1.00, 0.62, 0.25), (0.45, 0.85, 0.45), (0.90, 0.45, 0.85))


class LayoutCompareView(QWidget):
    """Up to :data:`MAX_VIEWS` synchronised hand views. :meth:`set_layouts` chooses what is compared,
    :meth:`set_motion` the posture trajectory ``(F, 26)`` played in every view."""

    frame_changed = Signal(int)

    def __init__(self, model: HandModel, parent: QWidget | None = None, off_screen: bool | None = None) -> None:
        super().__init__(parent)
        self._model = model
        self._off_screen = off_screen
        self._views: list[HandViewport] = []
        self._titles: list[QLabel] = []
        self._cells: list[QWidget] = []
        self._layouts: list[tuple[str, MarkerSet]] = []
        self._motion = np.zeros((1, 26))
        self._frame_rate = 100.0
        self._frame = 0
        self._framed = False

        self._grid = QGridLayout()
        self._grid.setSpacing(4)
        self._placeholder = QLabel("Tick two to four layouts in the list to compare them here.")
        self._placeholder.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self._grid.addWidget(self._placeholder, 0, 0)

        self.play_button = QToolButton()
        self.play_button.setCheckable(True)
        self.play_button.setIcon(self.style().standardIcon(QStyle.StandardPixmap.SP_MediaPlay))
        self.play_button.setToolTip("Play the motion in every view")
        self.play_button.toggled.connect(self._toggle_play)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, 0)
        self.slider.valueChanged.connect(self.set_frame)
        self.frame_label = QLabel("frame 0")
        self.frame_label.setMinimumWidth(110)
        transport = QHBoxLayout()
        transport.addWidget(self.play_button)
        transport.addWidget(self.slider, 1)
        transport.addWidget(self.frame_label)

        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addLayout(self._grid, 1)
        layout.addLayout(transport)
        self._timer = QTimer(self)
        self._timer.setInterval(round(1000.0 / PLAYBACK_FPS))
        self._timer.timeout.connect(self._advance)

    # ---------------------------------------------------------------------------------------- setup
    def _ensure_views(self, count: int) -> None:
        """Create views (once; they are reused) until there are ``count``; share the first's camera."""
        while len(self._views) < count:
            cell = QWidget(self)
            cell_layout = QVBoxLayout(cell)
            cell_layout.setContentsMargins(0, 0, 0, 0)
            cell_layout.setSpacing(2)
            title = QLabel(cell)
            title.setTextFormat(Qt.TextFormat.RichText)
            view = HandViewport(cell, off_screen=self._off_screen)
            view.set_grid_visible(False)
            view.set_effectors_visible(False)
            cell_layout.addWidget(title)
            cell_layout.addWidget(view, 1)
            if self._views:
                view.plotter.renderer.SetActiveCamera(self._views[0].plotter.renderer.GetActiveCamera())
            iren = view.plotter.iren
            if iren is not None:
                iren.add_observer("InteractionEvent", lambda *_args, source=view: self._render_others(source))
                iren.add_observer("EndInteractionEvent", lambda *_args, source=view: self._render_others(source))
            self._views.append(view)
            self._titles.append(title)
            self._cells.append(cell)

    def _render_others(self, source: HandViewport) -> None:
        """The camera is shared: redraw the views the user is not dragging in."""
        for view, cell in zip(self._views, self._cells, strict=True):
            if view is not source and cell.isVisible():
                view.render_now()

    def set_layouts(self, layouts: Sequence[tuple[str, MarkerSet]]) -> None:
        """Compare ``layouts``: ``(title, resolved markers)`` pairs, at most :data:`MAX_VIEWS`."""
        self._layouts = list(layouts)[:MAX_VIEWS]
        count = len(self._layouts)
        self._ensure_views(count)
        while self._grid.count():
            self._grid.takeAt(0)
        self._placeholder.setVisible(count == 0)
        if count == 0:
            self._grid.addWidget(self._placeholder, 0, 0)
        columns = 1 if count <= 1 else 2
        faces = self._model.faces
        rest = skin_vertices(self._model, self._motion[self._frame])
        for index, cell in enumerate(self._cells):
            shown = index < count
            cell.setVisible(shown)
            if not shown:
                continue
            self._grid.addWidget(cell, index // columns, index % columns)
            title, markers = self._layouts[index]
            colour = LAYOUT_COLOURS[index % len(LAYOUT_COLOURS)]
            chip = "#" + "".join(f"{round(255 * c):02x}" for c in colour)
            self._titles[index].setText(f"<span style='color:{chip}'>&#9679;</span> <b>{title}</b> "
                                        f"&nbsp;{len(markers.names)} markers")
            view = self._views[index]
            view.set_hand_mesh(rest, faces)
            view.set_markers(markers.names, marker_positions(self._model, markers, self._motion[self._frame]),
                             np.tile(colour, (len(markers.names), 1)))
            view.set_labels_visible(True)
        self._framed = False
        self.set_frame(self._frame, force=True)

    def set_motion(self, motion: np.ndarray, frame_rate: float = 100.0) -> None:
        """Play the finger postures of ``motion (F, 26)`` (joint angles, mm/rad) at ``frame_rate`` Hz in
        every view, the wrist held in the rest pose (the layouts differ on the fingers, not the wrist)."""
        motion = np.array(motion, dtype=float).reshape(-1, 26)
        motion[:, :6] = 0.0
        self._motion = motion if len(motion) else np.zeros((1, 26))
        self._frame_rate = float(frame_rate)
        self.slider.blockSignals(True)
        self.slider.setRange(0, len(self._motion) - 1)
        self.slider.blockSignals(False)
        self._framed = False
        self.set_frame(min(self._frame, len(self._motion) - 1), force=True)

    # ------------------------------------------------------------------------------------- playing
    def frame(self) -> int:
        """The frame shown (0-based)."""
        return self._frame

    def view_count(self) -> int:
        """How many views are shown."""
        return len(self._layouts)

    def views(self) -> list[HandViewport]:
        """The shown views, in layout order."""
        return self._views[:len(self._layouts)]

    def set_frame(self, frame: int, force: bool = False) -> None:
        """Show ``frame`` in every view."""
        frame = int(np.clip(frame, 0, len(self._motion) - 1))
        if frame == self._frame and not force:
            return
        self._frame = frame
        if self.slider.value() != frame:
            self.slider.blockSignals(True)
            self.slider.setValue(frame)
            self.slider.blockSignals(False)
        self.frame_label.setText(f"frame {frame + 1} / {len(self._motion)}")
        if self._layouts:
            theta = self._motion[frame]
            vertices = skin_vertices(self._model, theta)
            for view, (_title, markers) in zip(self._views, self._layouts, strict=False):
                view.update_hand_vertices(vertices)
                view.update_markers(marker_positions(self._model, markers, theta))
            if not self._framed:
                self._frame_back_view(vertices)
                self._framed = True
            for view in self.views():
                view.render_now()
        self.frame_changed.emit(frame)

    def _frame_back_view(self, vertices: np.ndarray) -> None:
        """Point the shared camera at the back of the hand (markers sit there), fingers up on screen,
        seen a little from the wrist and the thumb side."""
        low, high = vertices.min(axis=0), vertices.max(axis=0)
        centre = (low + high) / 2.0
        radius = max(float(np.linalg.norm(high - low)) / 2.0, 60.0)
        back = np.asarray(self._model.back_direction, dtype=float)
        thumb_side = -1.0 if self._model.side == "right" else 1.0
        direction = back + np.array([0.3 * thumb_side, -0.45, 0.0])
        direction /= np.linalg.norm(direction)
        camera = self._views[0].plotter.camera
        camera.focal_point = tuple(centre)
        camera.up = (0.0, 1.0, 0.0)
        distance = radius / np.sin(np.radians(float(camera.view_angle)) / 2.0) * 0.95
        camera.position = tuple(centre + direction * distance)
        for view in self.views():
            view.plotter.renderer.ResetCameraClippingRange()

    def _toggle_play(self, playing: bool) -> None:
        icon = QStyle.StandardPixmap.SP_MediaPause if playing else QStyle.StandardPixmap.SP_MediaPlay
        self.play_button.setIcon(self.style().standardIcon(icon))
        if playing:
            self._timer.start()
        else:
            self._timer.stop()

    def _advance(self) -> None:
        step = max(1, round(self._frame_rate / PLAYBACK_FPS))
        self.set_frame((self._frame + step) % len(self._motion))

    def close_views(self) -> None:
        """Stop playback and release the render windows (call when the owning window closes)."""
        self._timer.stop()
        for view in self._views:
            view.close_viewport()
