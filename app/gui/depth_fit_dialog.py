"""Tools ▸ Fit a hand to a depth frame…: the single depth-frame fit of ``handmocap depth fit`` in the GUI.

The operator picks a 16-bit PNG depth frame and gives the depth camera's intrinsics (focal lengths, principal
point), the depth unit and the hand; :meth:`core.fusion.depth_fit.DepthFitter.fit` runs on a worker with
progress and Cancel, and the dialog shows the overlay of the fitted hand on the depth (green when the fit can be
trusted, red when not), the verdict with its reasons, the palm centre's pixel and the residuals. Save writes the
same JSON and overlay PNG as the command.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QImage, QPixmap, QResizeEvent
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QMessageBox,
    QPushButton,
    QSizePolicy,
    QVBoxLayout,
    QWidget,
)

from handmocap.app.gui.workers import TaskRunner, one_line
from handmocap.core.errors import HandMocapError
from handmocap.core.fusion.depth_fit import DepthFit
from handmocap.widgets.file_row import browse_row
from handmocap.widgets.progress_bar import ProgressBar

#: the SR305's values (``../shared/data/rgbd``), a starting point the operator edits
DEFAULT_INTRINSICS = (476.007, 476.007, 313.683, 242.755)
DEFAULT_UNIT_MM = 0.125


@dataclass
class DepthFitResult:
    """What the worker hands back: the fit, the overlay (H,W,3) BGR uint8 and the depth frame's path."""

    fit: DepthFit
    overlay: np.ndarray
    frame: Path
    intrinsics: str
    unit_mm: float


def depth_fit_task(frame: Path, intrinsics: str, unit_mm: float, side: str) -> Callable:
    """Worker task: read the frame, fit the hand, draw the overlay (:class:`DepthFitResult`)."""

    def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> DepthFitResult:
        from handmocap.core.fusion.depth_fit import DepthFitter
        from handmocap.core.fusion.depth_overlay import draw_depth_fit
        from handmocap.core.fusion.depth_track import parse_intrinsics, read_depth_image

        depth = read_depth_image(frame, unit_mm)
        camera = parse_intrinsics(intrinsics, (depth.shape[1], depth.shape[0]))
        progress(0.1)
        fitter = DepthFitter(camera, side)
        fit = fitter.fit(depth, cancelled)
        overlay = draw_depth_fit(depth, fitter.renderer_for(fit), fit, frame.name)
        progress(1.0)
        return DepthFitResult(fit, overlay, frame, intrinsics, unit_mm)

    return task


def _pixmap(image: np.ndarray) -> QPixmap:
    rgb = np.ascontiguousarray(image[..., ::-1])
    height, width = rgb.shape[:2]
    return QPixmap.fromImage(QImage(rgb.data, width, height, 3 * width, QImage.Format.Format_RGB888).copy())


def describe(fit: DepthFit) -> str:
    """The verdict, the palm and the residuals in a few lines."""
    if fit.candidate is None:
        return "No hand found: " + "; ".join(fit.reasons)
    verdict = "Trusted." if fit.trusted else "NOT trusted: " + "; ".join(fit.reasons) + "."
    return (f"{verdict}\nPalm centre at ({fit.palm_uv[0]:.0f}, {fit.palm_uv[1]:.0f}) px, {fit.palm_depth_mm:.0f} mm "
            f"from the camera; hand size {fit.scale:.2f}× the template.\nDepth residual {fit.depth_residual_mm:.2f} "
            f"mm; the model leaves {100 * fit.missed:.0f} % of the hand uncovered and {100 * fit.outside:.0f} % of it "
            f"lies outside; {len(fit.starts)} starts, {fit.candidates_tried} object(s) tried, {fit.seconds:.1f} s.")


class DepthFitDialog(QDialog):
    """See the module docstring."""

    def __init__(self, parent: QWidget | None = None, frame: str = "") -> None:
        super().__init__(parent)
        self.setWindowTitle("Fit a hand to a depth frame")
        self.fit_result: DepthFitResult | None = None
        self._overlay: QPixmap | None = None
        self.runner = TaskRunner(self)
        self.runner.progressed.connect(lambda _request, fraction: self.progress_bar.setValue(round(100 * fraction)))
        self.runner.succeeded.connect(self._succeeded)
        self.runner.failed.connect(self._failed)
        self.runner.cancelled.connect(lambda _request: self._ended("Cancelled: nothing fitted"))
        self.runner.busy_changed.connect(self._busy_changed)
        layout = QVBoxLayout(self)
        layout.addLayout(self._form(frame))
        self.image_label = QLabel(self)
        self.image_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.image_label.setMinimumSize(480, 360)
        self.image_label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)
        self.image_label.setText("The fitted hand is drawn on the depth here.")
        self.status_label = QLabel(self)
        self.status_label.setWordWrap(True)
        self.status_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(self.image_label, 1)
        layout.addWidget(self.status_label)
        layout.addLayout(self._buttons())
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close, self)
        buttons.rejected.connect(self.reject)
        layout.addWidget(buttons)
        self._busy_changed(False)

    def _form(self, frame: str) -> QFormLayout:
        """The frame, intrinsics, depth unit and hand fields."""
        self.frame_edit = QLineEdit(frame, self)
        self.frame_edit.setPlaceholderText("a 16-bit PNG depth frame")
        frame_row = browse_row(self.frame_edit, self.browse, self)
        self.intrinsics_boxes = []
        intrinsics_row = QHBoxLayout()
        for label, value in zip(("fx", "fy", "cx", "cy"), DEFAULT_INTRINSICS, strict=True):
            box = QDoubleSpinBox(self)
            box.setRange(0.0, 100_000.0)
            box.setDecimals(3)
            box.setValue(value)
            box.setSuffix(" px")
            box.setToolTip(f"{label} of the depth camera (px)")
            intrinsics_row.addWidget(QLabel(label, self))
            intrinsics_row.addWidget(box)
            self.intrinsics_boxes.append(box)
        self.unit_box = QDoubleSpinBox(self)
        self.unit_box.setRange(0.001, 100.0)
        self.unit_box.setDecimals(4)
        self.unit_box.setValue(DEFAULT_UNIT_MM)
        self.unit_box.setSuffix(" mm")
        self.unit_box.setToolTip("mm per depth value (0.125 for an SR305, 1 for a Kinect)")
        self.hand_box = QComboBox(self)
        self.hand_box.addItems(["right", "left"])
        form = QFormLayout()
        form.addRow("Depth frame", frame_row)
        form.addRow("Intrinsics", intrinsics_row)
        form.addRow("Depth unit", self.unit_box)
        form.addRow("Hand", self.hand_box)
        return form

    def _buttons(self) -> QHBoxLayout:
        """The progress bar and the Fit, Cancel and Save buttons."""
        self.progress_bar = ProgressBar(self)
        self.progress_bar.setRange(0, 100)
        self.progress_bar.setFormat("%p %")
        self.fit_button = QPushButton("Fit", self)
        self.fit_button.setDefault(True)
        self.fit_button.clicked.connect(self.start)
        self.cancel_button = QPushButton("Cancel", self)
        self.cancel_button.clicked.connect(self.runner.cancel)
        self.save_button = QPushButton("Save…", self)
        self.save_button.setToolTip("write the result JSON and the overlay PNG (as handmocap depth fit does)")
        self.save_button.clicked.connect(self._save_clicked)
        self.save_button.setEnabled(False)
        row = QHBoxLayout()
        row.addWidget(self.progress_bar, 1)
        row.addWidget(self.fit_button)
        row.addWidget(self.cancel_button)
        row.addWidget(self.save_button)
        return row

    def intrinsics_text(self) -> str:
        return ",".join(f"{box.value():g}" for box in self.intrinsics_boxes)

    def browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open a depth frame", self.frame_edit.text(),
                                              "16-bit PNG depth frames (*.png)")
        if path:
            self.frame_edit.setText(path)

    def start(self) -> None:
        """Fit the hand on a worker."""
        frame = self.frame_edit.text().strip()
        if not frame:
            self._ended("Choose a depth frame first")
            return
        self.progress_bar.setValue(0)
        self.status_label.setText("Finding the hand and fitting it…")
        self.runner.start(depth_fit_task(Path(frame), self.intrinsics_text(), self.unit_box.value(),
                                         self.hand_box.currentText()))

    def _succeeded(self, _request: int, result: object) -> None:
        assert isinstance(result, DepthFitResult)
        self.fit_result = result
        self.status_label.setText(describe(result.fit))
        self.save_button.setEnabled(True)
        self._overlay = _pixmap(result.overlay)
        self._show_overlay()
        QTimer.singleShot(0, self._show_overlay)        # again once the layout has settled

    def _show_overlay(self) -> None:
        """The overlay scaled into the image area, whole."""
        if self._overlay is not None:
            self.image_label.setPixmap(self._overlay.scaled(self.image_label.contentsRect().size(),
                                                            Qt.AspectRatioMode.KeepAspectRatio,
                                                            Qt.TransformationMode.SmoothTransformation))

    def resizeEvent(self, event: QResizeEvent) -> None:  # noqa: N802 - Qt's name
        super().resizeEvent(event)
        self._show_overlay()

    def _failed(self, _request: int, message: str) -> None:
        self._ended(one_line(message))

    def _ended(self, message: str) -> None:
        self.status_label.setText(message)

    def _busy_changed(self, busy: bool) -> None:
        self.fit_button.setEnabled(not busy)
        self.cancel_button.setEnabled(busy)

    def _save_clicked(self) -> None:
        self.save()

    def save(self, path: str | Path | None = None) -> Path | None:
        """Write the result JSON (and the overlay next to it, ``NAME.png``); asks for the path when not given."""
        if self.fit_result is None:
            return None
        if path is None:
            chosen, _ = QFileDialog.getSaveFileName(self, "Save the fit", f"{self.fit_result.frame.stem}_fit.json",
                                                    "Fit JSON (*.json)")
            if not chosen:
                return None
            path = chosen
        target = Path(path)
        try:
            import cv2

            from handmocap.core.io.durable import write_atomic

            document = {"frame": str(self.fit_result.frame), "intrinsics": self.fit_result.intrinsics,
                        "depth_unit_mm": self.fit_result.unit_mm, **self.fit_result.fit.to_dict()}
            write_atomic(target, (json.dumps(document, indent=1) + "\n").encode())
            ok, data = cv2.imencode(".png", self.fit_result.overlay)
            if ok:
                write_atomic(target.with_suffix(".png"), data.tobytes())
        except (HandMocapError, OSError) as error:
            QMessageBox.warning(self, "Cannot save the fit", one_line(str(error)))
            return None
        self.status_label.setText(f"Saved {target} and {target.with_suffix('.png').name}")
        return target

    def done(self, result: int) -> None:
        """Closing cancels the fit and waits for the worker."""
        self.runner.stop()
        super().done(result)


def open_depth_fit(parent: QWidget) -> DepthFitDialog:
    """Show the dialog (not modal: the main window stays usable)."""
    dialog = DepthFitDialog(parent)
    dialog.show()
    return dialog
