"""The layout view: optimise reduced marker layouts, compare them, save one, print a placement sheet.

Left: what to optimise for (motion set or solved takes, marker count, subspace size, method) with a live
plot of the best energy per iteration and Cancel. Middle: the layouts at hand (shipped, the session's,
opened files and the ones optimised here); tick two to four to compare. Right, in tabs: synchronised 3D
views of the ticked layouts on the same motion, their metrics table, and the reconstruction error
against the number of markers. Every long computation runs on a worker (:class:`TaskRunner`); a
failure or a cancel leaves every layout already there untouched.

Open it with :func:`open_layout_view`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
from PySide6.QtCore import QObject, Qt, Signal
from PySide6.QtGui import QCloseEvent, QImage
from PySide6.QtWidgets import (
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QListWidget,
    QListWidgetItem,
    QMainWindow,
    QMessageBox,
    QPushButton,
    QSpinBox,
    QSplitter,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from handmocap.app.gui.palette import visible_check_boxes
from handmocap.app.gui.workers import TaskRunner
from handmocap.core.errors import HandMocapError, InputError
from handmocap.core.layout import OptimisationResult, PSOSettings, default_subspace_dims, evaluate_layout, motion_set
from handmocap.core.layout.placement_sheet import placement_sheet
from handmocap.core.layout.workflow import GENERIC_MOTIONS, error_against_markers, optimise_layout
from handmocap.core.model import (
    HandModel,
    MarkerLayout,
    layout_names,
    load_layout,
    load_template,
    resolve_layout,
    save_layout,
)
from handmocap.core.session import Session
from handmocap.widgets.layout_compare import MAX_VIEWS, LayoutCompareView
from handmocap.widgets.layout_plots import EnergyPlot, ErrorPlot, LayoutMetricsTable
from handmocap.widgets.placement_sheet import save_placement_sheet
from handmocap.widgets.progress_bar import ProgressBar
from handmocap.widgets.window_image import save_screenshot, window_image

MOTION_CHOICES = (("Grasps (Cutkosky taxonomy)", "grasps"), ("Gestures", "gestures"), ("All motions", "all"),
                  ("Solved takes…", "results"))
METHOD_CHOICES = (("Surface PSO", "pso"), ("PSO + swap polish", "pso-swap"), ("Greedy add-then-swap", "greedy"),
                  ("Subset of a base layout", "subset"))
COMPARE_FRAMES = 1500          # frames of the motion set played and evaluated in the comparison
METRIC_RECONSTRUCTION_FRAMES = 600


@dataclass
class LayoutEntry:
    """A layout in the list: where it came from (``origin``) and, when optimised here, its energy."""

    layout: MarkerLayout
    origin: str
    energy: float | None = None


class _EnergyBridge(QObject):
    """Carries per-iteration energies from the worker thread to the GUI thread (queued signal)."""

    energy = Signal(int, float)          # run id, best energy after an iteration
    row = Signal(int, object)            # run id, ErrorRow


class LayoutWindow(QMainWindow):
    """Top-level window of the layout tools; see the module docstring."""

    layout_saved = Signal(object)        # MarkerLayout saved into the session or to a file

    def __init__(self, parent: QWidget | None = None, session: Session | None = None,
                 save_to_session: Callable[[MarkerLayout], object] | None = None,
                 model: HandModel | None = None, off_screen: bool | None = None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Marker layouts — Hand Mocap Studio")
        self.setWindowFlag(Qt.WindowType.Window, True)
        self.resize(1500, 900)
        self.model = model or load_template()
        self.session = session
        if save_to_session is None and session is not None and hasattr(session, "save_layout"):
            save_to_session = session.save_layout
        self.save_to_session = save_to_session
        self.entries: list[LayoutEntry] = []
        self.result_files: list[str] = []
        self._motion_cache: dict[str, np.ndarray] = {}
        self._bridge = _EnergyBridge(self)
        self._bridge.energy.connect(self._energy_reported)
        self._bridge.row.connect(self._row_reported)

        self.optimiser = TaskRunner(self)
        self.optimiser.progressed.connect(lambda _request, fraction: self._show_progress(fraction))
        self.optimiser.succeeded.connect(self._optimised)
        self.optimiser.failed.connect(lambda _request, message: self._task_failed("Optimisation failed", message))
        self.optimiser.cancelled.connect(lambda _request: self._task_cancelled("Optimisation cancelled"))
        self.optimiser.busy_changed.connect(self._update_enabled)
        self.evaluator = TaskRunner(self)
        self.evaluator.progressed.connect(lambda _request, fraction: self._show_progress(fraction))
        self.evaluator.succeeded.connect(self._evaluated)
        self.evaluator.failed.connect(lambda _request, message: self._task_failed("Evaluation failed", message))
        self.evaluator.cancelled.connect(lambda _request: self._task_cancelled("Evaluation cancelled"))
        self.evaluator.busy_changed.connect(self._update_enabled)
        self._run_id = 0

        splitter = QSplitter(Qt.Orientation.Horizontal, self)
        splitter.addWidget(self._build_optimise_panel())
        splitter.addWidget(self._build_layout_panel())
        self.tabs = QTabWidget(self)
        self.compare = LayoutCompareView(self.model, self, off_screen=off_screen)
        self.metrics_table = LayoutMetricsTable(self)
        self.error_plot = ErrorPlot(self)
        self.tabs.addTab(self.compare, "Compare")
        self.tabs.addTab(self._build_metrics_tab(), "Metrics")
        self.tabs.addTab(self._build_error_tab(), "Error vs markers")
        splitter.addWidget(self.tabs)
        splitter.setSizes([330, 270, 900])
        self.setCentralWidget(splitter)
        self.status = QLabel("Ready", self)
        self.progress = ProgressBar(self)
        self.progress.setRange(0, 1000)
        self.progress.setMaximumWidth(260)
        self.progress.setVisible(False)
        self.statusBar().addWidget(self.status, 1)
        self.statusBar().addPermanentWidget(self.progress)

        for name in layout_names():
            self._add_entry(LayoutEntry(load_layout(name), "shipped"), select=False)
        self._add_session_layouts()
        self._motion_changed()
        self._update_enabled()

    # ----------------------------------------------------------------------------------- building
    def _build_optimise_panel(self) -> QWidget:
        panel = QWidget(self)
        box = QGroupBox("Optimise a layout", panel)
        form = QFormLayout(box)
        self.motion_combo = QComboBox(box)
        for text, key in MOTION_CHOICES:
            self.motion_combo.addItem(text, key)
        self.motion_combo.currentIndexChanged.connect(self._motion_changed)
        form.addRow("Motions", self.motion_combo)
        self.results_label = QLabel("no solved takes chosen", box)
        self.results_label.setWordWrap(True)
        self.results_button = QPushButton("Choose result files…", box)
        self.results_button.clicked.connect(self.choose_result_files)
        form.addRow("", self.results_button)
        form.addRow("", self.results_label)
        self.markers_spin = QSpinBox(box)
        self.markers_spin.setRange(1, 5000)
        self.markers_spin.setValue(6)
        form.addRow("Markers", self.markers_spin)
        self.dims_spin = QSpinBox(box)
        self.dims_spin.setRange(0, 20)
        self.dims_spin.setSpecialValueText("auto (one per marker, 2–6)")
        self.dims_spin.setToolTip("Principal components of the posture subspace the layout must constrain")
        form.addRow("Subspace PCs", self.dims_spin)
        self.method_combo = QComboBox(box)
        for text, key in METHOD_CHOICES:
            self.method_combo.addItem(text, key)
        self.method_combo.currentIndexChanged.connect(self._update_enabled)
        form.addRow("Method", self.method_combo)
        self.base_combo = QComboBox(box)
        self.base_combo.addItems(layout_names())
        self.base_combo.setCurrentText("dense" if "dense" in layout_names() else self.base_combo.currentText())
        form.addRow("Base layout", self.base_combo)
        self.particles_spin = QSpinBox(box)
        self.particles_spin.setRange(10, 20000)
        self.particles_spin.setSingleStep(100)
        self.particles_spin.setValue(1000)
        form.addRow("PSO particles", self.particles_spin)
        self.iterations_spin = QSpinBox(box)
        self.iterations_spin.setRange(1, 2000)
        self.iterations_spin.setValue(100)
        form.addRow("PSO iterations", self.iterations_spin)
        self.keyframes_spin = QSpinBox(box)
        self.keyframes_spin.setRange(3, 10)
        self.keyframes_spin.setValue(10)
        form.addRow("Keyframes", self.keyframes_spin)
        self.seed_spin = QSpinBox(box)
        self.seed_spin.setRange(0, 1_000_000)
        form.addRow("Seed", self.seed_spin)
        buttons = QHBoxLayout()
        self.optimise_button = QPushButton("Optimise", box)
        self.optimise_button.setDefault(True)
        self.optimise_button.clicked.connect(self.start_optimisation)
        self.cancel_button = QPushButton("Cancel", box)
        self.cancel_button.clicked.connect(self.cancel)
        buttons.addWidget(self.optimise_button)
        buttons.addWidget(self.cancel_button)
        form.addRow(buttons)
        self.energy_plot = EnergyPlot(panel)
        self.energy_label = QLabel("", panel)
        layout = QVBoxLayout(panel)
        layout.addWidget(box)
        title = QLabel("Best score per iteration (lower is better)", panel)
        title.setToolTip(self.energy_plot.toolTip())
        layout.addWidget(title)
        layout.addWidget(self.energy_plot, 1)
        layout.addWidget(self.energy_label)
        return panel

    def _build_layout_panel(self) -> QWidget:
        panel = QWidget(self)
        self.layout_list = QListWidget(panel)
        visible_check_boxes(self.layout_list)           # "tick 2 to 4": the boxes must show on the dark theme
        self.layout_list.itemChanged.connect(self._checks_changed)
        self.layout_list.currentRowChanged.connect(lambda _row: self._update_enabled())
        self.open_button = QPushButton("Open layout…", panel)
        self.open_button.clicked.connect(self.choose_layout_file)
        self.save_session_button = QPushButton("Save to session" if self.save_to_session else "Save as…", panel)
        self.save_session_button.setToolTip("Make the selected layout the one labelling uses" if self.save_to_session
                                            else "Write the selected layout to a JSON file")
        self.save_session_button.clicked.connect(self.save_selected)
        self.sheet_button = QPushButton("Placement sheet…", panel)
        self.sheet_button.setToolTip("Export a printable A4 sheet (PNG or PDF) of the selected layout")
        self.sheet_button.clicked.connect(self.choose_sheet_path)
        self.remove_button = QPushButton("Remove", panel)
        self.remove_button.clicked.connect(self.remove_selected)
        layout = QVBoxLayout(panel)
        layout.addWidget(QLabel(f"Layouts — tick 2 to {MAX_VIEWS} to compare", panel))
        layout.addWidget(self.layout_list, 1)
        for button in (self.open_button, self.save_session_button, self.sheet_button, self.remove_button):
            layout.addWidget(button)
        return panel

    def _build_metrics_tab(self) -> QWidget:
        tab = QWidget(self)
        self.metrics_button = QPushButton("Compute metrics of the ticked layouts", tab)
        self.metrics_button.clicked.connect(self.start_metrics)
        note = QLabel("Conditioning and distances over the chosen motions; reconstruction: layered IK of "
                      f"{METRIC_RECONSTRUCTION_FRAMES} held-out grasp frames (global pose given).", tab)
        note.setWordWrap(True)
        layout = QVBoxLayout(tab)
        layout.addWidget(self.metrics_button)
        layout.addWidget(note)
        layout.addWidget(self.metrics_table, 1)
        return tab

    def _build_error_tab(self) -> QWidget:
        tab = QWidget(self)
        self.table_min_spin = QSpinBox(tab)
        self.table_min_spin.setRange(1, 40)
        self.table_min_spin.setValue(4)
        self.table_max_spin = QSpinBox(tab)
        self.table_max_spin.setRange(1, 40)
        self.table_max_spin.setValue(12)
        self.generic_combo = QComboBox(tab)
        for text, key in MOTION_CHOICES[:3]:
            self.generic_combo.addItem(text, key)
        self.generic_combo.setCurrentIndex([key for _, key in MOTION_CHOICES].index(GENERIC_MOTIONS))
        self.error_button = QPushButton("Compute", tab)
        self.error_button.clicked.connect(self.start_error_table)
        row = QHBoxLayout()
        row.addWidget(QLabel("Markers from", tab))
        row.addWidget(self.table_min_spin)
        row.addWidget(QLabel("to", tab))
        row.addWidget(self.table_max_spin)
        row.addWidget(QLabel("generic:", tab))
        row.addWidget(self.generic_combo)
        row.addWidget(self.error_button)
        row.addStretch(1)
        note = QLabel("For each count: PSO layouts optimised for the chosen motions (specific) and for the generic "
                      "set, each reconstructing held-out grasps with layered IK. Uses the PSO settings on the left.",
                      tab)
        note.setWordWrap(True)
        layout = QVBoxLayout(tab)
        layout.addLayout(row)
        layout.addWidget(note)
        layout.addWidget(self.error_plot, 1)
        return tab

    # -------------------------------------------------------------------------------------- entries
    def _add_entry(self, entry: LayoutEntry, select: bool = True, checked: bool = False) -> None:
        """Add ``entry`` to the list (a layout of the same name and origin is replaced)."""
        for index, existing in enumerate(self.entries):
            if existing.layout.name == entry.layout.name and existing.origin == entry.origin:
                self.entries[index] = entry
                item = self.layout_list.item(index)
                item.setText(self._entry_text(entry))
                if select:
                    self.layout_list.setCurrentRow(index)
                return
        self.entries.append(entry)
        item = QListWidgetItem(self._entry_text(entry))
        item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
        item.setCheckState(Qt.CheckState.Checked if checked else Qt.CheckState.Unchecked)
        item.setToolTip(entry.layout.description or entry.layout.name)
        self.layout_list.addItem(item)
        if select:
            self.layout_list.setCurrentRow(self.layout_list.count() - 1)

    @staticmethod
    def _entry_text(entry: LayoutEntry) -> str:
        energy = f", score {entry.energy:.2f}" if entry.energy is not None else ""
        return f"{entry.layout.name} ({len(entry.layout.markers)} markers, {entry.origin}{energy})"

    def _add_session_layouts(self) -> None:
        """The session's layouts (objects with ``layouts`` entries and ``layout_path(name)``)."""
        session = self.session
        if session is None:
            return
        for item in getattr(session, "layouts", []) or []:
            try:
                path = session.layout_path(item.name)
                if path is not None:
                    self._add_entry(LayoutEntry(load_layout(path), "session"), select=False)
            except (HandMocapError, AttributeError) as error:
                self.status.setText(f"session layout skipped: {error}")

    def selected_entry(self) -> LayoutEntry | None:
        row = self.layout_list.currentRow()
        return self.entries[row] if 0 <= row < len(self.entries) else None

    def checked_entries(self) -> list[LayoutEntry]:
        return [entry for index, entry in enumerate(self.entries)
                if self.layout_list.item(index).checkState() == Qt.CheckState.Checked]

    def set_checked(self, names: list[str]) -> None:
        """Tick exactly the layouts called ``names`` (the latest of a name)."""
        for index, entry in enumerate(self.entries):
            state = Qt.CheckState.Checked if entry.layout.name in names else Qt.CheckState.Unchecked
            self.layout_list.item(index).setCheckState(state)

    def _checks_changed(self, _item: QListWidgetItem | None = None) -> None:
        checked = self.checked_entries()
        if len(checked) > MAX_VIEWS:
            self.status.setText(f"Comparing the first {MAX_VIEWS} ticked layouts")
        shown = []
        for entry in checked[:MAX_VIEWS]:
            try:
                shown.append((entry.layout.name, resolve_layout(self.model, entry.layout)))
            except HandMocapError as error:
                self.show_error("Cannot show the layout", str(error))
        self.compare.set_layouts(shown)
        self._update_enabled()

    # --------------------------------------------------------------------------------------- motions
    def motion_key(self) -> str:
        return self.motion_combo.currentData()

    def motion_source(self) -> str | list[str | Path]:
        """What :func:`motion_set` gets: a set name or the chosen result files (InputError when none)."""
        if self.motion_key() == "results":
            if not self.result_files:
                raise InputError("the motion set is empty: choose solved-take result files (.npz) first")
            files: list[str | Path] = list(self.result_files)
            return files
        return self.motion_key()

    def _motion(self) -> np.ndarray:
        """The motion played and evaluated in the comparison (cached per source)."""
        source = self.motion_source()
        key = "|".join(map(str, source)) if isinstance(source, list) else source
        if key not in self._motion_cache:
            self._motion_cache[key] = (motion_set(source) if isinstance(source, list)
                                       else motion_set(source, n_frames=COMPARE_FRAMES))
        return self._motion_cache[key]

    def _motion_changed(self) -> None:
        results = self.motion_key() == "results"
        self.results_button.setVisible(results)
        self.results_label.setVisible(results)
        try:
            self.compare.set_motion(self._motion())
        except HandMocapError as error:
            self.status.setText(str(error))
        self._update_enabled()

    def choose_result_files(self) -> None:
        paths, _ = QFileDialog.getOpenFileNames(self, "Solved takes", "", "IK results (*.npz)")
        if paths:
            self.set_result_files(paths)

    def set_result_files(self, paths: list[str]) -> None:
        """Use solved-take result files as the motion set (checked at once; bad files are reported)."""
        try:
            motion = motion_set([str(path) for path in paths])
        except HandMocapError as error:
            self.show_error("Cannot use these results", str(error))
            return
        self.result_files = [str(path) for path in paths]
        self._motion_cache["|".join(self.result_files)] = motion
        self.results_label.setText(f"{len(paths)} file(s), {len(motion)} solved frames")
        self.motion_combo.setCurrentIndex([key for _, key in MOTION_CHOICES].index("results"))
        self._motion_changed()

    # ---------------------------------------------------------------------------------- optimising
    def settings(self) -> PSOSettings:
        return PSOSettings(particles=self.particles_spin.value(), iterations=self.iterations_spin.value())

    def start_optimisation(self) -> None:
        """Optimise with the panel's choices on the worker; bad input is reported before starting."""
        try:
            source = self.motion_source()
        except HandMocapError as error:
            self.show_error("Cannot optimise", str(error))
            return
        method = self.method_combo.currentData()
        count = self.markers_spin.value()
        dims = self.dims_spin.value() or None
        base = self.base_combo.currentText()
        settings, seed, keyframes = self.settings(), self.seed_spin.value(), self.keyframes_spin.value()
        label = self.motion_key() if self.motion_key() != "results" else "takes"
        name = f"{label}-{count}-{method}" + (f"-s{seed}" if method.startswith("pso") else "")
        model = self.model
        self._run_id += 1
        run = self._run_id
        bridge = self._bridge

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]):
            def report(fraction: float, energy: float) -> None:
                bridge.energy.emit(run, float(energy))
                progress(fraction)

            return optimise_layout(model, source, count, method, base_layout=base, subspace_dims=dims,
                                   n_keyframes=keyframes, seed=seed, progress=report, cancelled=cancelled,
                                   settings=settings, name=name)

        self.energy_plot.start_run(name)
        self.energy_label.setText("")
        self.status.setText(f"Optimising {count} markers by {method}…")
        self.optimiser.start(task)

    def _energy_reported(self, run: int, energy: float) -> None:
        if run == self._run_id:
            self.energy_plot.add_energy(energy)
            self.energy_label.setText(f"iteration {len(self.energy_plot.current_values()) - 1}: best score "
                                      f"{energy:.3f}")
            self.energy_label.setToolTip("the optimiser's energy E = 0.1 E_cond + 100 E_dist of the best layout")

    def _optimised(self, _request: int, outcome: object) -> None:
        layout, result = cast(tuple[MarkerLayout, OptimisationResult], outcome)   # optimise_layout's
        self._add_entry(LayoutEntry(layout, "optimised", result.energy))
        self.progress.setVisible(False)
        self.status.setText(f"{layout.name}: score {result.energy:.3f} ({result.evaluations} layouts evaluated): "
                            f"{', '.join(layout.names)}")

    def cancel(self) -> None:
        """Cancel whatever runs (optimisation, metrics or the error table)."""
        self.optimiser.cancel()
        self.evaluator.cancel()

    # -------------------------------------------------------------------------------- evaluations
    def start_metrics(self) -> None:
        """Metrics of the ticked layouts on the worker."""
        entries = self.checked_entries()[:MAX_VIEWS]
        if not entries:
            self.show_error("Nothing to evaluate", "tick one to four layouts in the list first")
            return
        try:
            motion = self._motion()
        except HandMocapError as error:
            self.show_error("Cannot evaluate", str(error))
            return
        model = self.model
        chosen_dims = self.dims_spin.value() or None

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]):
            columns = []
            for index, entry in enumerate(entries):
                count = len(entry.layout.markers)
                dims = chosen_dims or default_subspace_dims(count)

                def report(fraction: float, index: int = index) -> None:
                    progress((index + fraction) / len(entries))

                metrics = evaluate_layout(model, entry.layout, motion, dims, step=10,
                                          reconstruction_frames=METRIC_RECONSTRUCTION_FRAMES,
                                          progress=report, cancelled=cancelled)
                columns.append((entry.layout.name, count, metrics))
            return ("metrics", columns)

        self.tabs.setCurrentIndex(1)
        self.status.setText(f"Evaluating {len(entries)} layout(s)…")
        self.evaluator.start(task)

    def start_error_table(self) -> None:
        """Reconstruction error against the number of markers (specific vs generic) on the worker."""
        low, high = self.table_min_spin.value(), self.table_max_spin.value()
        if low > high:
            self.show_error("Cannot compute", f"the marker range {low} to {high} is empty")
            return
        if self.motion_key() == "results":
            self.show_error("Cannot compute", "the error table compares simulated motion sets; choose grasps, "
                            "gestures or all motions")
            return
        specific, generic = self.motion_key(), self.generic_combo.currentData()
        settings, seed, model = self.settings(), self.seed_spin.value(), self.model
        self._run_id += 1
        run, bridge = self._run_id, self._bridge

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]):
            rows = error_against_markers(model, list(range(low, high + 1)), specific, generic, settings, seed,
                                         reconstruction_frames=METRIC_RECONSTRUCTION_FRAMES, progress=progress,
                                         cancelled=cancelled, row_done=lambda row: bridge.row.emit(run, row))
            return ("table", rows)

        self.error_plot.clear_rows()
        self.error_plot.set_names(specific, generic)
        self.tabs.setCurrentIndex(2)
        self.status.setText(f"Error against {low}..{high} markers ({specific} vs {generic})…")
        self.evaluator.start(task)

    def _row_reported(self, run: int, row: object) -> None:
        if run == self._run_id:
            self.error_plot.add_row(row)

    def _evaluated(self, _request: int, outcome: object) -> None:
        kind, payload = cast(tuple[str, list], outcome)     # ("metrics", metrics) or ("errors", error rows)
        self.progress.setVisible(False)
        if kind == "metrics":
            self.metrics_table.set_metrics(payload)
            self.status.setText(f"Metrics of {len(payload)} layout(s) computed")
        else:
            better = sum(row.specific_mean_mm < row.generic_mean_mm for row in payload)
            self.status.setText(f"Error table done: specific layouts better for {better} of {len(payload)} counts")

    # ------------------------------------------------------------------------------- task outcome
    def _show_progress(self, fraction: float) -> None:
        self.progress.setVisible(True)
        self.progress.setValue(round(1000 * fraction))

    def _task_failed(self, title: str, message: str) -> None:
        self.progress.setVisible(False)
        self.show_error(title, message)

    def _task_cancelled(self, message: str) -> None:
        self.progress.setVisible(False)
        self.status.setText(f"{message}; nothing was changed")

    def show_error(self, title: str, message: str) -> None:
        """Tell the operator (one line) and keep it in the status bar."""
        self.status.setText(message)
        QMessageBox.warning(self, title, message)

    def _update_enabled(self, *_args: object) -> None:
        busy = self.optimiser.is_busy() or self.evaluator.is_busy()
        has_selection = self.selected_entry() is not None
        self.optimise_button.setEnabled(not self.optimiser.is_busy())
        self.cancel_button.setEnabled(busy)
        self.metrics_button.setEnabled(not self.evaluator.is_busy())
        self.error_button.setEnabled(not self.evaluator.is_busy())
        self.save_session_button.setEnabled(has_selection)
        self.sheet_button.setEnabled(has_selection)
        self.remove_button.setEnabled(has_selection)
        method = self.method_combo.currentData()
        self.base_combo.setEnabled(method == "subset")
        for spin in (self.particles_spin, self.iterations_spin, self.seed_spin):
            spin.setEnabled(method.startswith("pso"))

    # ------------------------------------------------------------------------------ files, session
    def choose_layout_file(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open layout", "", "Marker layouts (*.json)")
        if path:
            self.open_layout_file(path)

    def open_layout_file(self, path: str | Path) -> None:
        try:
            layout = load_layout(Path(path))
            resolve_layout(self.model, layout)
        except HandMocapError as error:
            self.show_error("Cannot open the layout", str(error))
            return
        self._add_entry(LayoutEntry(layout, "file"))

    def save_selected(self) -> None:
        """Save the selected layout into the session (the callback) or, without one, to a JSON file."""
        entry = self.selected_entry()
        if entry is None:
            return
        if self.save_to_session is not None:
            try:
                self.save_to_session(entry.layout)
            except (HandMocapError, OSError) as error:
                self.show_error("Cannot save the layout", str(error))
                return
            self.status.setText(f"'{entry.layout.name}' saved into the session")
            self.layout_saved.emit(entry.layout)
            return
        path, _ = QFileDialog.getSaveFileName(self, "Save layout", f"{entry.layout.name}.json",
                                              "Marker layouts (*.json)")
        if path:
            self.save_layout_file(entry.layout, path)

    def save_layout_file(self, layout: MarkerLayout, path: str | Path) -> bool:
        try:
            save_layout(layout, path)
        except OSError as error:
            self.show_error("Cannot save the layout", f"{path}: {error.strerror or error}")
            return False
        self.status.setText(f"'{layout.name}' written to {path}")
        self.layout_saved.emit(layout)
        return True

    def choose_sheet_path(self) -> None:
        entry = self.selected_entry()
        if entry is None:
            return
        path, _ = QFileDialog.getSaveFileName(self, "Export placement sheet", f"{entry.layout.name}-placement.pdf",
                                              "PDF (*.pdf);;PNG image (*.png)")
        if path:
            self.export_sheet(entry.layout, path)

    def export_sheet(self, layout: MarkerLayout, path: str | Path) -> bool:
        """Write the placement sheet of ``layout`` (PNG or PDF by suffix); False after showing why not."""
        try:
            save_placement_sheet(placement_sheet(self.model, layout), path)
        except (HandMocapError, OSError) as error:
            self.show_error("Cannot export the placement sheet", str(error))
            return False
        self.status.setText(f"Placement sheet of '{layout.name}' written to {path}")
        return True

    def remove_selected(self) -> None:
        row = self.layout_list.currentRow()
        if 0 <= row < len(self.entries):
            self.entries.pop(row)
            self.layout_list.takeItem(row)
            self._checks_changed()

    def is_busy(self) -> bool:
        return self.optimiser.is_busy() or self.evaluator.is_busy()

    def window_image(self) -> QImage:
        """The whole window as an image with the shown 3D views drawn in (they render through OpenGL)."""
        return window_image(self, self.compare.views() if self.tabs.currentWidget() is self.compare else [])

    def save_screenshot(self, path: str | Path) -> bool:
        """Save the window as a PNG; shows the reason and returns False when it cannot."""
        return save_screenshot(self.window_image(), path, self.show_error)

    def closeEvent(self, event: QCloseEvent) -> None:  # noqa: N802 - Qt override
        """Cancel and wait for the workers, release the 3D views."""
        self.optimiser.stop()
        self.evaluator.stop()
        self.compare.close_views()
        super().closeEvent(event)


def run_layout_view(screenshot: str | None = None, compare: list[str] | None = None, frame: int = 700) -> int:
    """Start the application on the layout view alone (``handmocap layout view``). With ``screenshot``,
    tick the ``compare`` layouts, show ``frame``, save a PNG of the window and quit. Returns the exit code."""
    import sys

    from PySide6.QtWidgets import QApplication

    from handmocap.app.gui.palette import apply_dark_palette

    app = cast(QApplication, QApplication.instance()) or QApplication(sys.argv[:1])    # (a QApplication if any)
    app.setStyle("Fusion")
    apply_dark_palette(app)
    window = open_layout_view()
    if compare:
        window.set_checked(compare)
        window.compare.set_frame(frame)
    if screenshot is None:
        return app.exec()
    window.resize(1600, 950)
    for _ in range(10):
        app.processEvents()
    code = 0 if window.save_screenshot(screenshot) else 1
    window.close()
    return code


def open_layout_view(parent: QWidget | None = None, session: Session | None = None,
                     save_to_session: Callable[[MarkerLayout], object] | None = None,
                     off_screen: bool | None = None) -> LayoutWindow:
    """Open the layout tools as a top-level window (shown). ``session``: a :class:`core.session.Session`
    (its layouts are listed, and "Save to session" stores into it) or None; ``save_to_session(layout)``
    overrides where "Save to session" goes (None and no session: the button saves to a JSON file)."""
    window = LayoutWindow(parent, session=session, save_to_session=save_to_session, off_screen=off_screen)
    window.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose, parent is not None)
    window.show()
    return window
