"""Session ▸ Process takes…: edit and save a batch pipeline, run it on the session's takes, follow each take.

The batch runs as ``handmocap batch`` does (:mod:`core.batch`: a local Dask cluster of worker processes)
from a Python thread, so the window stays live; progress arrives through a queued Qt signal. Each
take's state is listed as it changes; a take that finishes is announced through the
:class:`~app.gui.application.Application`, so the session browser shows its new state at once. Cancel
stops the batch: finished takes are kept, the others are untouched. A take open in this window is
held by it, so the batch skips it and says so.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable
from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDialog,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.gui.application import Application
from core.batch.pipeline import EXPORTS, HANDS, SOLVE_METHODS, STEPS, Pipeline, load_pipeline, save_pipeline
from core.batch.runner import BatchProgress, plan_batch, run_batch
from core.errors import HandMocapError
from core.gaps import FILL_METHODS
from core.model import layout_names


class BatchPanel(QDialog):
    """The batch panel of the open session (module docstring)."""

    progressed = Signal(object)   # BatchProgress, from the batch thread
    batch_ended = Signal(object, str)  # final BatchProgress (or None), error text ("" when none)

    def __init__(self, app: Application, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.app = app
        self.setWindowTitle("Process takes")
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._announced: set[str] = set()
        self.steps = {step: QCheckBox(step) for step in STEPS}
        self.exports = {kind: QCheckBox(kind) for kind in EXPORTS}
        self.layout_box = QComboBox()
        self.layout_box.setEditable(True)
        self.layout_box.addItems(layout_names())
        self.hands_box = QComboBox()
        self.hands_box.addItems(HANDS)
        self.max_gap = QSpinBox()
        self.max_gap.setRange(1, 100_000)
        self.fill_box = QComboBox()
        self.fill_box.addItems(["auto", *FILL_METHODS])
        self.solve_box = QComboBox()
        self.solve_box.addItems(SOLVE_METHODS)
        self.output = QLineEdit()
        self.output.setPlaceholderText("<session>/exports")
        self.workers = QSpinBox()
        self.workers.setRange(1, 256)
        self.workers.setValue(2)
        self.table = QTableWidget(0, 3)
        self.table.setHorizontalHeaderLabels(["take", "state", "reason / figures"])
        self.table.horizontalHeader().setStretchLastSection(True)
        self.status = QLabel("")
        self.start_button = QPushButton("Start")
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self._build()
        self.set_pipeline(Pipeline())
        self.progressed.connect(self._show_progress, Qt.ConnectionType.QueuedConnection)
        self.batch_ended.connect(self._done, Qt.ConnectionType.QueuedConnection)
        self._list_takes()

    def _build(self) -> None:
        form = QFormLayout()
        form.addRow("Steps", _side_by_side(self.steps.values()))
        form.addRow("Layout", self.layout_box)
        form.addRow("Hands", self.hands_box)
        form.addRow("Fill gaps up to (frames)", self.max_gap)
        form.addRow("Fill method", self.fill_box)
        form.addRow("Solve method", self.solve_box)
        form.addRow("Exports", _side_by_side(self.exports.values()))
        form.addRow("Export folder", self.output)
        form.addRow("Worker processes", self.workers)
        buttons = QHBoxLayout()
        for text, slot in (("Load pipeline…", self.choose_load), ("Save pipeline…", self.choose_save)):
            button = QPushButton(text)
            button.clicked.connect(slot)
            buttons.addWidget(button)
        buttons.addStretch(1)
        self.start_button.clicked.connect(self.start)
        self.cancel_button.clicked.connect(self.cancel)
        buttons.addWidget(self.start_button)
        buttons.addWidget(self.cancel_button)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addLayout(buttons)
        layout.addWidget(self.table, 1)
        layout.addWidget(self.status)
        self.resize(760, 560)

    # ---------------------------------------------------------------------------- the pipeline
    def set_pipeline(self, pipeline: Pipeline) -> None:
        """Show ``pipeline`` in the editor."""
        for step, box in self.steps.items():
            box.setChecked(pipeline.runs(step))
        for kind, box in self.exports.items():
            box.setChecked(kind in pipeline.exports)
        self.layout_box.setCurrentText(pipeline.layout)
        self.hands_box.setCurrentText(pipeline.hands)
        self.max_gap.setValue(pipeline.max_gap)
        self.fill_box.setCurrentText(pipeline.fill_method)
        self.solve_box.setCurrentText(pipeline.solve_method)
        self.output.setText(pipeline.output)

    def pipeline(self) -> Pipeline:
        """The pipeline the editor shows (checked as a pipeline file is; InputError otherwise)."""
        from core.batch.pipeline import pipeline_from_dict

        return pipeline_from_dict({
            "steps": [step for step, box in self.steps.items() if box.isChecked()],
            "layout": self.layout_box.currentText().strip(), "hands": self.hands_box.currentText(),
            "max_gap": self.max_gap.value(), "fill_method": self.fill_box.currentText(),
            "solve_method": self.solve_box.currentText(),
            "exports": [kind for kind, box in self.exports.items() if box.isChecked()],
            "output": self.output.text().strip()}, "the pipeline", self._folder())

    def _folder(self) -> Path:
        return self.app.session.folder if self.app.session is not None else Path.cwd()

    def choose_load(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Load pipeline", str(self._folder()), "Pipeline (*.toml *.json)")
        if path:
            self._try(lambda: self.set_pipeline(load_pipeline(path)))

    def choose_save(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Save pipeline", str(self._folder() / "pipeline.toml"),
                                              "Pipeline (*.toml *.json)")
        if path:
            self._try(lambda: save_pipeline(self.pipeline(), path))

    def _try(self, action) -> bool:
        try:
            action()
        except HandMocapError as error:
            self.status.setText(f"⚠ {error}")
            return False
        return True

    # ---------------------------------------------------------------------------- running
    def _list_takes(self, states: dict[str, str] | None = None, summaries: dict | None = None) -> None:
        """One row per session take: name, batch state, reason or figures."""
        takes = self.app.session.takes if self.app.session is not None else []
        self.table.setRowCount(len(takes))
        for row, entry in enumerate(takes):
            state = (states or {}).get(entry.id, "")
            summary = (summaries or {}).get(entry.id, {})
            if summary.get("status") == "done":
                detail = (f"{100 * summary.get('labelled_share', 0):.1f} % labelled, longest gap "
                          f"{summary.get('longest_gap', 0)}, {summary.get('seconds', 0):.1f} s")
            else:
                detail = summary.get("reason", "")
            for column, text in enumerate((entry.name, state, detail)):
                self.table.setItem(row, column, QTableWidgetItem(text))

    def start(self) -> None:
        """Plan the batch of the open session and run it on a thread."""
        if self.app.session is None or self._thread is not None:
            return
        session, workers = self.app.session, self.workers.value()
        plans = []
        if not self._try(lambda: plans.append(plan_batch(session, self.pipeline()))):
            return
        plan = plans[0]
        self.status.setText(f"{len(plan.jobs)} takes to process, {len(plan.up_to_date)} up to date")
        self._stop.clear()
        self._announced.clear()
        self.start_button.setEnabled(False)
        self.cancel_button.setEnabled(True)

        def work() -> None:
            try:
                progress = run_batch(plan, workers, on_progress=self.progressed.emit, stop=self._stop.is_set)
            except HandMocapError as error:
                self.batch_ended.emit(None, str(error))
            except Exception as error:  # noqa: BLE001 - shown as one line, the window stays up
                self.batch_ended.emit(None, f"internal error: {type(error).__name__}: {error}")
            else:
                self.batch_ended.emit(progress, "")

        self._thread = threading.Thread(target=work, name="batch", daemon=True)
        self._thread.start()

    def cancel(self) -> None:
        """Stop the batch: finished takes are kept."""
        self._stop.set()
        self.status.setText("stopping: finished takes are kept…")

    def _show_progress(self, progress: BatchProgress) -> None:
        self._list_takes(dict(progress.states), dict(progress.summaries))
        for take_id, state in list(progress.states.items()):
            if state in ("done", "failed", "skipped") and take_id not in self._announced:
                self._announced.add(take_id)
                self.app.take_processed(take_id)
        self.status.setText(f"{progress.count('done')} done, {progress.count('failed')} failed, "
                            f"{progress.count('running')} running of {progress.total}; "
                            f"{progress.frames_per_s:.0f} frames/s" +
                            (f"; dashboard {progress.dashboard}" if progress.dashboard else ""))

    def _done(self, progress: BatchProgress | None, error: str) -> None:
        if self._thread is not None:
            self._thread.join()
        self._thread = None
        self.start_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        if progress is not None:
            self._show_progress(progress)
            self.status.setText(self.status.text() + ("; cancelled" if progress.interrupted else "; finished"))
        if error:
            self.status.setText(f"⚠ {error}")

    def closeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Closing the panel cancels a running batch (finished takes are kept) and waits for it to stop."""
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None
        super().closeEvent(event)


def _side_by_side(widgets: Iterable[QWidget]) -> QHBoxLayout:
    """A row holding ``widgets`` left to right."""
    row = QHBoxLayout()
    for widget in widgets:
        row.addWidget(widget)
    return row
