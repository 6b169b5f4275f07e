"""File ▸ Export…: the review as C3D, TRC, CSV, BVH or glTF with the options of ``handmocap export``.

One small dialog: the format, where the format takes them the units and up axis (TRC, BVH; glTF is always
metres and Y up, C3D and CSV mm in the lab frame), the hand (BVH, glTF: only solved hands are offered; "both"
for a take with two: a BVH file per hand, one glTF with both), whether fills are included (C3D, TRC, CSV),
and the file. The export itself is :func:`core.review.export.export_review`, the same as the command line's.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import cast

import numpy as np
from PySide6.QtCore import Signal
from PySide6.QtGui import QAction, QStandardItemModel
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QFileDialog,
    QFormLayout,
    QLabel,
    QLineEdit,
    QMessageBox,
    QVBoxLayout,
    QWidget,
)

from handmocap.core.errors import HandMocapError
from handmocap.core.io.labelled_c3d import SubjectCalibration
from handmocap.core.model import HandModel
from handmocap.core.review import ReviewTake
from handmocap.core.review.export import export_review
from handmocap.core.review.export_formats import export_format, export_formats
from handmocap.widgets.file_row import browse_row
from handmocap.widgets.shortcuts import bind

UNITS_HINT = "OpenSim: m, Y up · Blender: m, Y up · MotionBuilder: cm, Y up · as recorded: mm, Z up"


def default_export_path(review: ReviewTake, title: str, ending: str, suffix: str) -> Path:
    """Where an export of ``review`` goes unless the operator says otherwise: next to the raw take file (the
    user's home for a take without one), named after it with ``ending`` and ``suffix`` (``walk_labelled.c3d``),
    never the raw file itself."""
    source = Path(review.take.source_path) if review.take.source_path else None
    folder = source.parent if source is not None and source.parent.is_dir() else Path.home()
    stem = source.stem if source is not None else (title.rsplit(".", 1)[0] or "take")
    path = folder / f"{stem}{ending}{suffix}"
    return path.with_name(f"{stem}{ending}_2{suffix}") if source is not None and path == source else path


class ExportDialog(QDialog):
    """Choose a format, its options and a file; :meth:`export` writes it (errors shown, the dialog stays)."""

    exported = Signal(str, str)   # format, path

    def __init__(self, parent: QWidget | None, review: ReviewTake, model_for: Callable[[str], HandModel],
                 subjects: list[SubjectCalibration] | None = None, stem: str = "take") -> None:
        super().__init__(parent)
        self.setWindowTitle("Export")
        self.review, self.model_for, self.subjects, self.stem = review, model_for, subjects, stem
        self._proposed: str | None = None     # the file name proposed (replaced when the format changes)
        solved = [hand for hand in review.hands if np.isfinite(hand.joint_angles).all(axis=1).any()]
        self.format_box = QComboBox()
        for registered in export_formats():
            self.format_box.addItem(registered.label, registered.name)
            if registered.joint_angles and not solved:
                items = cast(QStandardItemModel, self.format_box.model())    # a combo box's own model
                item = items.item(self.format_box.count() - 1)
                item.setEnabled(False)
                item.setToolTip("needs a solved hand (Solve the take first)")
        self.units_box = QComboBox()
        self.units_box.addItems(["mm", "cm", "m"])
        self.up_box = QComboBox()
        self.up_box.addItem("Z (as recorded)", "z")
        self.up_box.addItem("Y", "y")
        self.hand_box = QComboBox()
        self.sides = list(dict.fromkeys(hand.side for hand in solved))
        if len(self.sides) > 1:   # as handmocap export without --hand: a BVH per hand, one glTF with both
            self.hand_box.addItem("both (BVH: a file per hand)", None)
        for side in self.sides:
            self.hand_box.addItem(side, side)
        self.fills_box = QCheckBox("Include accepted fills")
        self.fills_box.setChecked(True)
        self.path_edit = QLineEdit()
        row = browse_row(self.path_edit, self.choose_path)
        form = QFormLayout()
        form.addRow("Format", self.format_box)
        form.addRow("Units", self.units_box)
        form.addRow("Up axis", self.up_box)
        form.addRow("Hand", self.hand_box)
        form.addRow("", self.fills_box)
        form.addRow("File", row)
        self.hint = QLabel(UNITS_HINT)
        self.hint.setWordWrap(True)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Save | QDialogButtonBox.StandardButton.Cancel)
        buttons.accepted.connect(self.export)
        buttons.rejected.connect(self.reject)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(self.hint)
        layout.addWidget(buttons)
        self.format_box.currentIndexChanged.connect(self._format_changed)
        self._format_changed()

    @property
    def format_name(self) -> str:
        return str(self.format_box.currentData())

    def _format_changed(self) -> None:
        """Enable the options the chosen format takes and give the file the format's suffix."""
        chosen = export_format(self.format_name)
        suffixes = chosen.suffixes
        for widget in (self.units_box, self.up_box):
            widget.setEnabled(chosen.axes)
        if not chosen.axes:
            self.units_box.setCurrentText(chosen.units)
            self.up_box.setCurrentIndex(self.up_box.findData(chosen.up))
        self.hand_box.setEnabled(chosen.joint_angles and self.hand_box.count() > 1)
        self.fills_box.setEnabled(not chosen.joint_angles)
        current = self.path_edit.text().strip()
        if not current or current == self._proposed:   # what the dialog proposed: next to the raw take
            self._proposed = str(default_export_path(self.review, self.stem, chosen.name_tag, suffixes[0]))
            self.path_edit.setText(self._proposed)
        else:                                           # the operator's own file: only its suffix changes
            self.path_edit.setText(str(Path(current).with_suffix("")) + suffixes[0])
        self.path_edit.setToolTip(self.path_edit.text())

    def choose_path(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Export", self.path_edit.text(),
                                              export_format(self.format_name).file_filter)
        if path:
            self.path_edit.setText(path)

    def options(self) -> dict:
        """The keyword options of :func:`export_review` the dialog's fields give."""
        chosen = export_format(self.format_name)
        return {"units": self.units_box.currentText() if chosen.axes else None,
                "up": self.up_box.currentData() if chosen.axes else None,
                "hand": self.hand_box.currentData() if chosen.joint_angles else None,
                "fills": self.fills_box.isChecked() or chosen.joint_angles}

    def export(self) -> bool:
        """Write the file (asking before replacing one); True when written (the dialog then closes)."""
        path = self.path_edit.text().strip()
        if not path:
            QMessageBox.warning(self, "Cannot export", "Choose a file to export to")
            return False
        if Path(path).exists():
            answer = QMessageBox.question(self, "Replace file?", f"{path} exists. Replace it?")
            if answer != QMessageBox.StandardButton.Yes:
                return False
        name, options = self.format_name, self.options()
        try:
            models = {}
            if export_format(name).joint_angles:
                models = {side: self.model_for(side) for side in ([options["hand"]] if options["hand"] else
                                                                  self.sides or [self.review.hands[0].side])}
            written = export_review(self.review, path, name, models=models, subjects=self.subjects, **options)
        except (HandMocapError, OSError) as error:
            QMessageBox.warning(self, "Cannot export", str(error))
            return False
        for target in written:
            self.exported.emit(name, str(target))
        self.accept()
        return True


def export_action(host: QWidget, controller) -> QAction:
    """The File ▸ Export… action of ``host`` for the take ``controller`` (the review controller) shows;
    each written file is announced through ``controller.exported`` (the session records it)."""
    action = QAction("&Export…", host)
    bind(action, "export", "Export the take as " + ", ".join(registered.name for registered in export_formats()))

    def run() -> None:
        document = controller.document
        if document is None or document.review is None:
            return
        dialog = ExportDialog(host, document.review, document.model_for, list(document.subjects.values()),
                              document.title.rsplit(".", 1)[0])
        dialog.exported.connect(lambda name, path: controller.exported.emit(document, name, path))
        dialog.exec()

    action.triggered.connect(run)
    return action
