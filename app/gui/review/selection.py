"""What the operator selects in the review: a label or point, points of a new rigid body, the marked range."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QApplication, QInputDialog

from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.errors import HandMocapError
from handmocap.core.model.objects import load_scene_spec, rigid_body_from_points, save_scene_spec


class ReviewSelection(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: selecting, and rigid bodies from picked points."""

    def select_label(self, label: int) -> None:
        """Select ``label`` and the point holding it now."""
        review = self.review
        if review is None:
            return
        label = label if 0 <= label < review.n_labels else -1
        self.app.select(label, int(review.assignment[self.app.frame, label]) if label >= 0 else -1)

    def point_clicked(self, column: int) -> None:
        """The operator clicked raw point ``column`` in the 3D view (-1: empty space); with Ctrl, the point
        is picked for a rigid body."""
        review = self.review
        if review is None:
            return
        if QApplication.keyboardModifiers() & Qt.KeyboardModifier.ControlModifier and column >= 0:
            self.toggle_rigid_point(column)
            return
        self.app.select(review.label_of_point(self.app.frame, column) if column >= 0 else -1, column)

    def toggle_rigid_point(self, column: int) -> None:
        """Add raw point ``column`` to the points of a new rigid body (or take it out again)."""
        self.app.toggle_rigid_point(column)
        self.status_message.emit(f"{len(self.selection.rigid_points)} points selected for a rigid body "
                                 "(Review ▸ Define rigid body…)", 5000)

    def choose_rigid_body_name(self) -> None:
        name, accepted = QInputDialog.getText(self.host, "Rigid body", "Name of the object:", text="object")
        if accepted and name.strip():
            self.define_rigid_body(name.strip())

    def define_rigid_body(self, name: str) -> Path | None:
        """Make a rigid body named ``name`` from the selected points in the current frame and add it to the
        scene spec auto-label uses (in the session folder, or next to the take file). Returns the spec."""
        document, review, points = self.document, self.review, self.selection.rigid_points
        if document is None or review is None:
            return None
        frame = self.app.frame
        try:
            if len(points) < 3:
                raise HandMocapError("Ctrl+click at least 3 points of the object in the 3D view first")
            markers = [f"{name}{number + 1}" for number in range(len(points))]
            spec = rigid_body_from_points(name, markers, review.take.marker_positions[frame, points])
            path = Path(self.auto_settings.objects) if self.auto_settings.objects else self._default_spec_path(document)
            objects = [item for item in (load_scene_spec(path) if path.exists() else []) if item.name != name]
            path.parent.mkdir(parents=True, exist_ok=True)
            save_scene_spec([*objects, spec], path)
        except (HandMocapError, OSError) as error:
            self.error_raised.emit("Cannot define the rigid body", str(error))
            return None
        self.auto_settings.objects = str(path)
        self.app.clear_rigid_points()
        self.status_message.emit(f"Rigid body '{name}' ({len(markers)} markers) added to the scene "
                                 f"{path.name}; the next auto-label tracks it", 8000)
        return path

    def _default_spec_path(self, document: TakeDocument) -> Path:
        if document.open_take is not None:
            return document.open_take.folder / "scene_objects.json"
        source = document.take.source_path
        folder = Path(source).parent if source else Path.home() / ".cache" / "handmocap"
        return folder / f"{Path(document.title).stem}_objects.json"

    def _stretch_clicked(self, marker: int, first: int, last: int) -> None:
        self.select_label(marker)
        if not first <= self.app.frame <= last:
            self.app.set_frame(first)

    def set_range_in(self) -> None:
        self.app.mark_range(self.app.frame, self.selection.range_out)

    def set_range_out(self) -> None:
        self.app.mark_range(self.selection.range_in, self.app.frame)

    def clear_range(self) -> None:
        self.app.mark_range(None, None)
