"""The hand-scan calibration wizard (issue 4): Scan, Clean, Landmarks, Align, Fit, Review, Save.

Every long step runs on a :class:`app.gui.workers.TaskRunner` with progress and Cancel; the worker never
touches a widget: live meshes of the alignment and the fit are handed over through a locked slot that a
GUI-thread timer polls. Going Back never loses the picked landmarks; a failed or cancelled step keeps
everything the operator did. Open it with :func:`open_calibration_wizard`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import cast

import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QPushButton,
    QSlider,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
    QWizard,
    QWizardPage,
)

from handmocap.app.gui.actions import make_action
from handmocap.app.gui.workers import TaskRunner
from handmocap.core.calibration.align import Alignment
from handmocap.core.calibration.cleaning import clean_scan, skin_mask
from handmocap.core.calibration.landmarks import MIN_LANDMARKS, load_landmarks, save_landmarks
from handmocap.core.calibration.pipeline import (
    CalibrationInput,
    CalibrationResult,
    finish_calibration,
    load_template_file,
    prepare_calibration,
    prepare_scan,
    run_alignment,
    run_fit,
)
from handmocap.core.calibration.scan import Scan, load_scan
from handmocap.core.errors import HandMocapError, InputError
from handmocap.core.model import HandModel
from handmocap.core.model.template_mesh import LANDMARK_DESCRIPTIONS, LANDMARK_NAMES
from handmocap.widgets.file_row import browse_row
from handmocap.widgets.progress_bar import ProgressBar
from handmocap.widgets.wizard_scene import CalibrationScene

REMOVED_COLOUR = np.array([220, 40, 40], dtype=np.uint8)
LIVE_INTERVAL_MS = 120
TEMPLATE_COLOUR = (0.45, 0.66, 0.95)     # the moving template, distinct from the skin-coloured scan
SCAN_FILTER = "Hand scans (*.ply *.obj)"
TEMPLATE_CHOICES = ("Shipped right hand", "Shipped left hand", "From file (.npz, .gltf, .glb)…")


class _LiveSlot:
    """The latest vertices (V,3) a worker produced, handed to the GUI thread under a lock."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._vertices: np.ndarray | None = None

    def put(self, vertices: np.ndarray) -> None:
        with self._lock:
            self._vertices = vertices

    def take(self) -> np.ndarray | None:
        with self._lock:
            vertices, self._vertices = self._vertices, None
        return vertices


class CalibrationState:
    """What the operator has done so far; pages read and write it, nothing is thrown away on Back."""

    def __init__(self) -> None:
        self.scan_path: Path | None = None
        self.raw_scan: Scan | None = None
        self.scan: Scan | None = None               # cleaned
        self.notes: list[str] = []
        self.strictness = 0.5
        self.template: HandModel | None = None
        self.landmarks: dict[str, np.ndarray | None] = dict.fromkeys(LANDMARK_NAMES)
        self.skipped: set[str] = set()
        self.undo: list[tuple[str, np.ndarray | None, bool]] = []
        self.data: CalibrationInput | None = None
        self.alignment: Alignment | None = None
        self.fitted: np.ndarray | None = None
        self.result: CalibrationResult | None = None

    def picked_count(self) -> int:
        return sum(value is not None for value in self.landmarks.values())


def _message_label() -> QLabel:
    label = QLabel()
    label.setWordWrap(True)
    label.setStyleSheet("color: #d9534f;")
    return label


# --------------------------------------------------------------------------- Scan


class ScanPage(QWizardPage):
    """Choose the scan file and the template."""

    def __init__(self, state: CalibrationState) -> None:
        super().__init__()
        self.state = state
        self.setTitle("Scan")
        self.setSubTitle("A PLY or OBJ point cloud or mesh of the subject's hand (mm or m, with or without "
                         "normals and colours), and the template to fit.")
        form = QFormLayout(self)
        self.path_edit = QLineEdit()
        self.path_edit.setPlaceholderText("hand scan .ply / .obj")
        form.addRow("Scan file", browse_row(self.path_edit, self._browse))
        self.template_combo = QComboBox()
        self.template_combo.addItems(TEMPLATE_CHOICES)
        self.template_edit = QLineEdit()
        self.template_edit.setPlaceholderText("template .npz / .gltf / .glb")
        self.template_edit.setEnabled(False)
        self.template_combo.currentIndexChanged.connect(lambda index: self.template_edit.setEnabled(index == 2))
        form.addRow("Template", self.template_combo)
        form.addRow("", self.template_edit)
        self.info = QLabel()
        self.info.setWordWrap(True)
        form.addRow(self.info)
        self.error = _message_label()
        form.addRow(self.error)
        self.path_edit.textChanged.connect(self.completeChanged)

    def _browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open hand scan", "", SCAN_FILTER)
        if path:
            self.path_edit.setText(path)

    def isComplete(self) -> bool:
        return bool(self.path_edit.text().strip())

    def validatePage(self) -> bool:
        self.error.clear()
        path = Path(self.path_edit.text().strip())
        try:
            if self.state.scan_path != path or self.state.raw_scan is None:
                self.state.raw_scan = load_scan(path)
                self.state.scan_path = path
                self.state.scan = None
            choice = self.template_combo.currentIndex()
            self.state.template = (load_template_file(None, "right") if choice == 0 else
                                   load_template_file(None, "left") if choice == 1 else
                                   load_template_file(self.template_edit.text().strip() or None))
        except HandMocapError as error:
            self.error.setText(str(error))
            return False
        scan = self.state.raw_scan
        self.info.setText(f"{len(scan):,} points" + (", colours" if scan.colors is not None else "")
                          + (", normals" if scan.normals is not None else "") + "".join(f"; {n}" for n in scan.notes))
        if scan.colors is None:
            # no colours: the skin filter cannot run, only the outlier filter (Clean page skipped)
            try:
                self.state.scan, self.state.notes = prepare_scan(scan, clean=True)
            except HandMocapError as error:
                self.error.setText(str(error))
                return False
        return True

    def nextId(self) -> int:
        wizard = cast(CalibrationWizard, self.wizard())     # the calibration wizard's page
        if self.state.raw_scan is not None and self.state.raw_scan.colors is None:
            return wizard.page_ids["landmarks"]
        return wizard.page_ids["clean"]


# --------------------------------------------------------------------------- Clean


class CleanPage(QWizardPage):
    """Skin-colour filter preview with a strictness slider; outliers are removed when leaving."""

    def __init__(self, state: CalibrationState) -> None:
        super().__init__()
        self.state = state
        self.setTitle("Clean")
        self.setSubTitle("Points that are not skin coloured (Kovac et al. 2003) are shown in red and removed; "
                         "isolated outliers are removed too.")
        layout = QVBoxLayout(self)
        self.scene = CalibrationScene(self, "scan: kept (skin) and removed (red)")
        layout.addWidget(self.scene, 1)
        row = QHBoxLayout()
        row.addWidget(QLabel("Strictness"))
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, 100)
        self.slider.setValue(50)
        self.slider.valueChanged.connect(self._preview)
        row.addWidget(self.slider, 1)
        self.counts = QLabel()
        row.addWidget(self.counts)
        layout.addLayout(row)
        self.error = _message_label()
        layout.addWidget(self.error)
        self._display = np.zeros(0, dtype=np.int64)

    def initializePage(self) -> None:
        scan = self.state.raw_scan
        assert scan is not None and scan.colors is not None, "a colour scan was read (the scan page's next)"
        step = max(1, len(scan) // 150_000)
        self._display = np.arange(0, len(scan), step)
        self.scene.set_points(scan.points[self._display], scan.colors[self._display])
        self.scene.frame(scan.points[self._display])
        self.slider.setValue(int(round(self.state.strictness * 100)))
        self._preview()

    def _preview(self) -> None:
        scan = self.state.raw_scan
        if scan is None or scan.colors is None:
            return
        strictness = self.slider.value() / 100.0
        keep = skin_mask(scan.colors, strictness)
        colours = scan.colors[self._display].copy()
        colours[~keep[self._display]] = REMOVED_COLOUR
        self.scene.set_point_colours(colours)
        self.scene.render_now()
        self.counts.setText(f"{int(keep.sum()):,} skin points kept, {int((~keep).sum()):,} removed")

    def validatePage(self) -> bool:
        self.error.clear()
        self.state.strictness = self.slider.value() / 100.0
        assert self.state.raw_scan is not None, "read on the scan page"
        try:
            self.state.scan, report = clean_scan(self.state.raw_scan, strictness=self.state.strictness)
        except HandMocapError as error:
            self.error.setText(f"{error}: lower the strictness")
            return False
        self.state.notes = [f"skin filter removed {report['non_skin_removed']:,} points",
                            f"outlier filter removed {report['outliers_removed']:,} points"]
        return True


# --------------------------------------------------------------------------- Landmarks


class LandmarksPage(QWizardPage):
    """Pick the 20 landmarks on the scan: list, template view showing where each goes, scan view to click."""

    def __init__(self, state: CalibrationState) -> None:
        super().__init__()
        self.state = state
        self.setTitle("Landmarks")
        self.setSubTitle("Select a landmark in the list (the template shows it in yellow) and click the matching "
                         f"point on the scan. At least {MIN_LANDMARKS} are needed; all 20 give the best fit.")
        layout = QHBoxLayout(self)
        left = QVBoxLayout()
        self.list = QListWidget()
        self.list.currentRowChanged.connect(self._current_changed)
        left.addWidget(self.list, 1)
        self.description = QLabel()
        self.description.setWordWrap(True)
        left.addWidget(self.description)
        buttons = QHBoxLayout()
        self.skip_button = QPushButton("Skip")
        self.undo_button = QPushButton("Undo")
        self.clear_button = QPushButton("Re-pick")
        for button, slot in ((self.skip_button, self.skip_current), (self.undo_button, self.undo),
                             (self.clear_button, self.clear_current)):
            button.clicked.connect(slot)
            buttons.addWidget(button)
        left.addLayout(buttons)
        files = QHBoxLayout()
        load_button, save_button = QPushButton("Load JSON…"), QPushButton("Save JSON…")
        load_button.clicked.connect(self._load_dialog)
        save_button.clicked.connect(self._save_dialog)
        files.addWidget(load_button)
        files.addWidget(save_button)
        left.addLayout(files)
        self.error = _message_label()
        left.addWidget(self.error)
        panel = QWidget()
        panel.setLayout(left)
        panel.setMaximumWidth(330)
        layout.addWidget(panel)
        splitter = QSplitter()
        self.template_scene = CalibrationScene(self, "template: where the landmark goes")
        self.scan_scene = CalibrationScene(self, "scan: click to place it")
        self.scan_scene.point_picked.connect(self._picked)
        splitter.addWidget(self.template_scene)
        splitter.addWidget(self.scan_scene)
        layout.addWidget(splitter, 1)
        for name in LANDMARK_NAMES:
            self.list.addItem(QListWidgetItem(name))

    def initializePage(self) -> None:
        template, scan = self.state.template, self.state.scan
        assert template is not None and scan is not None, "read on the scan page"
        self.template_scene.set_surface(template.vertices, template.faces)
        self.template_scene.frame(template.vertices)
        step = max(1, len(scan) // 150_000)
        self._display = np.arange(0, len(scan), step)
        self.scan_scene.set_points(scan.points[self._display],
                                   None if scan.colors is None else scan.colors[self._display])
        self.scan_scene.frame(scan.points[self._display])
        if self.list.currentRow() < 0:
            self.list.setCurrentRow(0)
        self._refresh()

    # ----------------------------------------------------------------------------- operations
    def current_name(self) -> str:
        return LANDMARK_NAMES[max(self.list.currentRow(), 0)]

    def assign(self, name: str, position: np.ndarray | None, skipped: bool = False) -> None:
        """Set a landmark (undoable) and move on to the next one without a position."""
        self.state.undo.append((name, self.state.landmarks[name], name in self.state.skipped))
        self.state.landmarks[name] = None if position is None else np.asarray(position, dtype=float)
        (self.state.skipped.add if skipped else self.state.skipped.discard)(name)
        pending = [n for n in LANDMARK_NAMES if self.state.landmarks[n] is None and n not in self.state.skipped]
        if pending and (position is not None or skipped):
            self.list.setCurrentRow(LANDMARK_NAMES.index(pending[0]))
        self._refresh()

    def pick_point(self, index: int) -> None:
        """Place the current landmark at shown scan point ``index`` (what a click does)."""
        scan = self.state.scan
        if scan is not None and 0 <= index < len(self._display):     # (the shown points are the scan's)
            self.assign(self.current_name(), scan.points[self._display[index]])

    def _picked(self, index: int) -> None:
        if index >= 0:
            self.pick_point(index)

    def skip_current(self) -> None:
        self.assign(self.current_name(), None, skipped=True)

    def clear_current(self) -> None:
        """Forget the current landmark's position so that the next click places it again."""
        self.assign(self.current_name(), None)
        self.list.setCurrentRow(LANDMARK_NAMES.index(self.state.undo[-1][0]))

    def undo(self) -> None:
        if not self.state.undo:
            return
        name, position, skipped = self.state.undo.pop()
        self.state.landmarks[name] = position
        (self.state.skipped.add if skipped else self.state.skipped.discard)(name)
        self.list.setCurrentRow(LANDMARK_NAMES.index(name))
        self._refresh()

    def load(self, path: str | Path) -> None:
        """Read a landmark JSON file (all landmarks replaced; undoable one by one)."""
        landmarks = load_landmarks(path)
        for name in LANDMARK_NAMES:
            self.state.undo.append((name, self.state.landmarks[name], name in self.state.skipped))
            self.state.landmarks[name] = landmarks[name]
            (self.state.skipped.add if landmarks[name] is None else self.state.skipped.discard)(name)
        self._refresh()

    def save(self, path: str | Path) -> None:
        save_landmarks(self.state.landmarks, path)

    def _load_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Load landmarks", "", "Landmarks (*.json)")
        if path:
            self._guarded(lambda: self.load(path))

    def _save_dialog(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Save landmarks", "landmarks.json", "Landmarks (*.json)")
        if path:
            self._guarded(lambda: self.save(path))

    def _guarded(self, action) -> None:
        self.error.clear()
        try:
            action()
        except HandMocapError as error:
            self.error.setText(str(error))

    # ----------------------------------------------------------------------------- display
    def _current_changed(self, row: int) -> None:
        if row < 0:
            return
        name = LANDMARK_NAMES[row]
        self.description.setText(f"<b>{name}</b>: {LANDMARK_DESCRIPTIONS[name]}")
        self._refresh_scenes()

    def _refresh(self) -> None:
        for row, name in enumerate(LANDMARK_NAMES):
            value = self.state.landmarks[name]
            status = "skipped" if name in self.state.skipped else "—" if value is None else "✓ picked"
            self.list.item(row).setText(f"{name:<12}  {status}")
        self.undo_button.setEnabled(bool(self.state.undo))
        self._refresh_scenes()
        self.completeChanged.emit()

    def _refresh_scenes(self) -> None:
        if self.state.template is None or self.state.scan is None:
            return
        current = max(self.list.currentRow(), 0)
        template = self.state.template
        self.template_scene.set_landmarks(template.vertices[[template.landmarks[n] for n in LANDMARK_NAMES]],
                                          current)
        positions = np.array([np.full(3, np.nan) if self.state.landmarks[n] is None else self.state.landmarks[n]
                              for n in LANDMARK_NAMES])
        self.scan_scene.set_landmarks(positions, current)
        self.template_scene.render_now()
        self.scan_scene.render_now()

    def isComplete(self) -> bool:
        return self.state.picked_count() >= MIN_LANDMARKS


# --------------------------------------------------------------------------- Align and Fit


class _RunPage(QWizardPage):
    """A page that runs one long step on the wizard's TaskRunner with progress, Cancel and a live mesh:
    ``task(progress, cancelled)`` runs on the worker, ``apply(result)`` and ``summary()`` on the GUI thread."""

    finished = Signal()

    def __init__(self, state: CalibrationState, runner: TaskRunner, title: str, subtitle: str,
                 task: Callable, apply: Callable[[object], None], summary: Callable[[], str]) -> None:
        super().__init__()
        self.state, self.runner = state, runner
        self.task, self.apply, self.summary = task, apply, summary
        self.setTitle(title)
        self.setSubTitle(subtitle)
        layout = QVBoxLayout(self)
        self.scene = CalibrationScene(self, title.lower())
        layout.addWidget(self.scene, 1)
        row = QHBoxLayout()
        self.progress = ProgressBar()
        self.progress.setRange(0, 1000)
        self.run_button = QPushButton("Run again")
        self.cancel_button = QPushButton("Cancel")
        self.run_button.clicked.connect(self.start)
        self.cancel_button.clicked.connect(self.runner.cancel)
        row.addWidget(self.progress, 1)
        row.addWidget(self.run_button)
        row.addWidget(self.cancel_button)
        layout.addLayout(row)
        self.status = QLabel()
        self.status.setWordWrap(True)
        layout.addWidget(self.status)
        self.live = _LiveSlot()
        self.timer = QTimer(self)
        self.timer.setInterval(LIVE_INTERVAL_MS)
        self.timer.timeout.connect(self._show_live)
        self.request = 0
        self.done = False
        runner.progressed.connect(self._progressed)
        runner.succeeded.connect(self._succeeded)
        runner.failed.connect(self._failed)
        runner.cancelled.connect(self._cancelled)

    def initializePage(self) -> None:
        scan = self.state.scan
        assert scan is not None, "read on the scan page"
        step = max(1, len(scan) // 100_000)
        self.scene.set_points(scan.points[::step], None if scan.colors is None else scan.colors[::step])
        self.scene.frame(scan.points[::step])
        self.start()

    def start(self) -> None:
        self.done = False
        self.completeChanged.emit()
        self.progress.setValue(0)
        self.status.setText("running…")
        self.run_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        self.request = self.runner.start(self.task)
        self.timer.start()

    def _show_live(self) -> None:
        vertices = self.live.take()
        if vertices is not None:
            template = self.state.template
            assert template is not None, "read on the scan page"
            if len(self.scene.surface_points()) != len(vertices):
                self.scene.set_surface(vertices, template.faces, opacity=0.8, colour=TEMPLATE_COLOUR)
            else:
                self.scene.update_surface(vertices)
            self.scene.render_now()

    def _ended(self, text: str) -> None:
        self.timer.stop()
        self._show_live()
        self.status.setText(text)
        self.run_button.setEnabled(True)
        self.cancel_button.setEnabled(False)

    def _progressed(self, request: int, fraction: float) -> None:
        if request == self.request:
            self.progress.setValue(int(fraction * 1000))

    def _succeeded(self, request: int, result) -> None:
        if request != self.request:
            return
        self.progress.setValue(1000)
        self.apply(result)
        self.done = True
        self._ended(self.summary())
        self.completeChanged.emit()
        self.finished.emit()

    def _failed(self, request: int, message: str) -> None:
        if request == self.request:
            self._ended(f"<span style='color:#d9534f'>{message}</span> — go Back to fix it; nothing is lost.")

    def _cancelled(self, request: int) -> None:
        if request == self.request:
            self._ended("cancelled; press Run again to restart this step (landmarks and scan are kept).")

    def isComplete(self) -> bool:
        return self.done

    def cleanupPage(self) -> None:
        if self.runner.is_busy():
            self.runner.stop()
        self.timer.stop()


class AlignPage(_RunPage):
    def __init__(self, state: CalibrationState, runner: TaskRunner) -> None:
        super().__init__(state, runner, "Align", "Rigid ICP with scale and posture IK, alternately: the template "
                         "moves onto the scan.", self.align, self.keep, self.describe)

    def align(self, progress, cancelled):
        state = self.state
        assert state.scan is not None, "read on the scan page"
        data = prepare_calibration(state.scan, dict(state.landmarks), state.template, clean=False)
        data.notes[:0] = state.notes
        data.scan_name = state.scan_path.stem if state.scan_path else "scan"
        alignment = run_alignment(data, progress, cancelled, self.live.put)
        return data, alignment

    def keep(self, result) -> None:
        data, alignment = result
        self.state.data, self.state.alignment = data, alignment
        self.state.fitted = self.state.result = None
        self.live.put(alignment.vertices)

    def describe(self) -> str:
        alignment, data = self.state.alignment, self.state.data
        assert alignment is not None and data is not None, "aligned"      # (described after keep)
        return (f"aligned: scale {alignment.scale:.3f}, landmark RMS {alignment.landmark_rms_mm[-1]:.1f} mm"
                + "".join(f"<br>warning: {w}" for w in data.warnings))


class FitPage(_RunPage):
    def __init__(self, state: CalibrationState, runner: TaskRunner) -> None:
        super().__init__(state, runner, "Fit", "The template bends to the scan: first to the landmarks, then to "
                         "the closest scan points, keeping less and less of its own shape as it goes. The mesh "
                         "updates as it runs.", self.fit, self.keep, lambda: "fitted; Next shows the review")
        self.setToolTip("Non-rigid fit: landmark term, then closest points added, with the Laplacian (ARAP) "
                        "regularisation weight λ_reg halved from 1 to 1e-6, then from 1e-6 to 1e-8")

    def fit(self, progress, cancelled):
        data, alignment = self.state.data, self.state.alignment
        assert data is not None and alignment is not None, "aligned on the align page"
        return run_fit(data, alignment, progress=progress, cancelled=cancelled,
                       on_iteration=self.live.put)

    def keep(self, result) -> None:
        self.state.fitted = result
        self.state.result = None
        self.live.put(result)


# --------------------------------------------------------------------------- Review and Save


class ReviewPage(QWizardPage):
    """Distance map on the fitted model, landmark residuals, scan-to-model statistics and warnings."""

    def __init__(self, state: CalibrationState) -> None:
        super().__init__()
        self.state = state
        self.setTitle("Review")
        self.setSubTitle("Colour: distance of each vertex to the nearest scan point (mm); bright areas had no scan "
                         "data and keep the template's shape.")
        layout = QHBoxLayout(self)
        self.scene = CalibrationScene(self, "fitted model")
        layout.addWidget(self.scene, 1)
        side = QVBoxLayout()
        self.table = QTableWidget(0, 2)
        self.table.setHorizontalHeaderLabels(["landmark", "residual (mm)"])
        self.table.verticalHeader().setVisible(False)
        side.addWidget(self.table, 1)
        self.statistics = QLabel()
        self.statistics.setWordWrap(True)
        side.addWidget(self.statistics)
        self.warnings = QListWidget()
        self.warnings.setWordWrap(True)
        side.addWidget(self.warnings)
        panel = QWidget()
        panel.setLayout(side)
        panel.setMaximumWidth(360)
        layout.addWidget(panel)

    def initializePage(self) -> None:
        state = self.state
        if state.result is None:
            assert state.data is not None and state.alignment is not None and state.fitted is not None, "fitted"
            state.result = finish_calibration(state.data, state.alignment, state.fitted)
        result = state.result
        report = result.report
        self.scene.set_points(None)
        self.scene.set_surface(result.fitted_vertices, result.model.faces, scalars=report.vertex_distance)
        self.scene.frame(result.fitted_vertices)
        self.scene.render_now()
        self.table.setRowCount(len(report.landmark_residuals))
        for row, (name, residual) in enumerate(report.landmark_residuals.items()):
            self.table.setItem(row, 0, QTableWidgetItem(name))
            item = QTableWidgetItem(f"{residual:.2f}")
            item.setTextAlignment(int(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter))
            self.table.setItem(row, 1, item)
        self.table.resizeColumnsToContents()
        stats = report.scan_to_model
        self.statistics.setText(f"scan to model: mean {stats['mean']:.2f} mm, p95 {stats['p95']:.2f} mm, max "
                                f"{stats['max']:.2f} mm; scale {result.alignment.scale:.3f}; hand length "
                                f"{result.model.hand_length:.0f} mm")
        self.warnings.clear()
        for text in report.warnings or ["no warnings"]:
            self.warnings.addItem(text)


class SavePage(QWizardPage):
    """Store the calibrated model (.npz; in the session for a subject) and export glTF."""

    saved = Signal(str)

    def __init__(self, state: CalibrationState, session=None,
                 save_subject: Callable[[str, HandModel], Path] | None = None) -> None:
        super().__init__()
        self.state, self.session = state, session
        if save_subject is None and session is not None:
            save_subject = session.save_subject_model
        self.save_subject = save_subject
        self.setTitle("Save")
        self.setSubTitle("The calibrated model (mesh, skeleton with relocated joints, skin weights; marker layouts "
                         "carry over) is used for this subject's takes.")
        form = QFormLayout(self)
        self.subject = QComboBox()
        self.subject.setEditable(True)
        for entry in getattr(session, "subjects", []) or []:
            self.subject.addItem(entry.name)
        form.addRow("Subject", self.subject)
        self.model_edit = QLineEdit()
        self.gltf_edit = QLineEdit()
        self.gltf_edit.setPlaceholderText("optional .glb / .gltf export")
        form.addRow("Model file (.npz)", self.model_edit)
        form.addRow("glTF export", self.gltf_edit)
        self.save_button = QPushButton("Save")
        self.save_button.clicked.connect(self.save)
        form.addRow(self.save_button)
        self.status = QLabel()
        self.status.setWordWrap(True)
        form.addRow(self.status)
        self.done = False

    def initializePage(self) -> None:
        if not self.model_edit.text() and self.state.scan_path is not None and self.session is None:
            self.model_edit.setText(str(self.state.scan_path.with_name(self.state.scan_path.stem + "_model.npz")))
        if not self.subject.currentText() and self.state.scan_path is not None:
            self.subject.setEditText(self.state.scan_path.stem)

    def save(self) -> bool:
        """Write the model (and glTF); returns whether everything was written."""
        from handmocap.core.model.gltf import save_gltf_hand

        result = self.state.result
        assert result is not None, "calibrated on the review page"
        written = []
        try:
            subject = self.subject.currentText().strip() or "subject"
            model = result.model
            if self.save_subject is not None:
                written.append(str(self.save_subject(subject, model)))
            if self.model_edit.text().strip():
                path = Path(self.model_edit.text().strip())
                model.save(path)
                written.append(str(path))
            if self.gltf_edit.text().strip():
                save_gltf_hand(model, self.gltf_edit.text().strip())
                written.append(self.gltf_edit.text().strip())
            if not written:
                raise InputError("give a model file name (or open the wizard from a session)")
        except (HandMocapError, OSError) as error:
            self.status.setText(f"<span style='color:#d9534f'>{error}</span>")
            return False
        self.status.setText("saved: " + ", ".join(written))
        self.done = True
        for saved_path in written:
            self.saved.emit(saved_path)
        return True

    def validatePage(self) -> bool:
        return self.done or self.save()


# --------------------------------------------------------------------------- the wizard


class CalibrationWizard(QWizard):
    """Scan → Clean → Landmarks → Align → Fit → Review → Save (see the module docstring)."""

    model_saved = Signal(str)

    def __init__(self, parent: QWidget | None = None, session=None,
                 save_subject: Callable[[str, HandModel], Path] | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Hand scan calibration")
        self.setWizardStyle(QWizard.WizardStyle.ModernStyle)
        self.setOption(QWizard.WizardOption.NoBackButtonOnLastPage, False)
        self.resize(1180, 760)
        self.state = CalibrationState()
        self.runner = TaskRunner(self)
        scan, clean, landmarks = ScanPage(self.state), CleanPage(self.state), LandmarksPage(self.state)
        align, fit = AlignPage(self.state, self.runner), FitPage(self.state, self.runner)
        review, save = ReviewPage(self.state), SavePage(self.state, session, save_subject)
        self.pages: dict[str, QWizardPage] = {"scan": scan, "clean": clean, "landmarks": landmarks, "align": align,
                                              "fit": fit, "review": review, "save": save}
        self.page_ids = {name: self.addPage(page) for name, page in self.pages.items()}
        save.saved.connect(self.model_saved)
        # Ctrl+Z anywhere in the wizard undoes the last landmark picked, skipped, re-picked or loaded
        self.undo_action = make_action(self, "Undo landmark", landmarks.undo, "wizard_undo")
        self.addAction(self.undo_action)
        landmarks.undo_button.setToolTip(self.undo_action.toolTip())

    def done(self, result: int) -> None:
        self.runner.stop()
        for page in self.pages.values():
            for scene in page.findChildren(CalibrationScene):
                scene.close_scene()
        super().done(result)


def open_calibration_wizard(parent: QWidget | None = None, session=None,
                            save_subject: Callable[[str, HandModel], Path] | None = None) -> QDialog:
    """Create and show the calibration wizard (non-modal); ``session`` (``core.session.Session``) offers its
    subjects and receives the model through ``save_subject(subject, model)`` (default: its
    ``save_subject_model``). Returns the wizard."""
    wizard = CalibrationWizard(parent, session, save_subject)
    wizard.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose, True)
    wizard.show()
    return wizard


__all__ = ["CalibrationWizard", "open_calibration_wizard"]
