"""The exports of a review: labelled C3D, joint angles as CSV or BVH."""

from __future__ import annotations

from collections.abc import Callable

from PySide6.QtWidgets import QFileDialog

from handmocap.app.gui.export_dialog import default_export_path
from handmocap.app.gui.review.part import ReviewPart
from handmocap.core.errors import HandMocapError
from handmocap.core.review import export_bvh, export_joint_angles_csv, export_labelled_c3d


class ReviewExports(ReviewPart):
    """Part of :class:`~app.gui.review.controller.ReviewController`: exports."""

    def _export(self, title: str, filter_text: str, suffix: str, write: Callable[[str], None], kind: str) -> None:
        document = self.document
        if document is None or document.review is None:
            return
        ending, extension = suffix.rsplit(".", 1)
        proposed = default_export_path(document.review, document.title, ending, f".{extension}")
        path, _ = QFileDialog.getSaveFileName(self.host, title, str(proposed), filter_text)
        if not path:
            return
        try:
            write(path)
        except (HandMocapError, OSError) as error:
            self.error_raised.emit("Cannot export", str(error))
            return
        self.exported.emit(document, kind, path)
        self.status_message.emit(f"Exported {path}", 5000)

    def export_c3d(self, path: str) -> None:
        """The review as a labelled C3D, with the subject calibrations auto-label made (``HAND_SUBJECT``)."""
        document, review = self.document, self.review
        assert document is not None and review is not None, "no take is shown"
        export_labelled_c3d(review, path, subjects=list(document.subjects.values()))

    def export_csv(self, path: str) -> None:
        review = self.review
        assert review is not None, "no take is shown"
        export_joint_angles_csv(review, path)

    def export_bvh(self, path: str) -> None:
        document, review = self.document, self.review
        assert document is not None and review is not None, "no take is shown"
        hand = review.hands[0]
        export_bvh(review, path, document.model_for(hand.side), 0)

    def choose_export_c3d(self) -> None:
        self._export("Export labelled C3D", "C3D (*.c3d)", "_labelled.c3d", self.export_c3d, "c3d")

    def choose_export_csv(self) -> None:
        self._export("Export joint angles", "CSV (*.csv)", "_angles.csv", self.export_csv, "angles-csv")

    def choose_export_bvh(self) -> None:
        self._export("Export joint angles", "BVH (*.bvh)", ".bvh", self.export_bvh, "bvh")
