"""Session ▸ Process takes…: edit and save a batch pipeline, run it on the session's takes, follow each take.

The batch runs as ``handmocap batch`` does (:mod:`core.batch`: a local Dask cluster of worker processes)
from a Python thread, so the window stays live; progress arrives through a queued Qt signal. Each
take's state is listed as it changes; a take that finishes is announced through the
:class:`~app.gui.application.Application`, so the session browser shows its new state at once. Cancel
stops the batch: finished takes are kept, the others are untouched.

A take open for editing in this window is held by it, so no batch worker may change it: the panel runs the
pipeline on a copy of its review on the batch thread (:mod:`core.batch.open_take`) and pushes the result
through the open document, as ONE undoable, journalled step ("batch …" in the Edit menu), unless the take
was edited meanwhile (then nothing is applied and the row says so). Every take has a row and a state —
queued, running, done (applied to the open take, or by a worker), failed, skipped or up to date — with its
reason, and the status line counts every state.
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
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from handmocap.app.gui.application import Application
from handmocap.app.gui.document import TakeDocument
from handmocap.core.batch.open_take import OpenTakeResult, process_review_copy, record_done
from handmocap.core.batch.pipeline import HANDS, SOLVE_METHODS, STEPS, Pipeline, load_pipeline, save_pipeline
from handmocap.core.batch.runner import BatchPlan, BatchProgress, TakeJob, plan_batch, run_batch
from handmocap.core.batch.task import step_description
from handmocap.core.errors import HandMocapError
from handmocap.core.gaps import fill_choices
from handmocap.core.model import layout_names
from handmocap.core.review import ReviewTake
from handmocap.core.review.export_formats import export_formats


class BatchPanel(QDialog):
    """The batch panel of the open session (module docstring)."""

    progressed = Signal(object)   # BatchProgress, from the batch thread
    batch_ended = Signal(object, str)  # final BatchProgress (or None), error text ("" when none)
    open_take_started = Signal(str)    # take id of a take open here whose copy the batch thread processes now
    open_take_done = Signal(str, object, str)  # take id, OpenTakeResult (None when it failed), error text

    def __init__(self, app: Application, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.app = app
        self.setWindowTitle("Process takes")
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._announced: set[str] = set()
        self._states: dict[str, str] = {}
        self._summaries: dict[str, dict] = {}
        self._open_jobs: list[tuple[TakeJob, TakeDocument, ReviewTake, int, bool]] = []
        self._plan: BatchPlan | None = None
        self.steps = {step: QCheckBox(step) for step in STEPS}
        self.exports = {registered.name: QCheckBox(registered.name) for registered in export_formats()}
        for registered in export_formats():
            self.exports[registered.name].setToolTip(registered.label)
        self.layout_box = QComboBox()
        self.layout_box.setEditable(True)
        self.layout_box.addItems(layout_names())
        self.hands_box = QComboBox()
        self.hands_box.addItems(HANDS)
        self.max_gap = QSpinBox()
        self.max_gap.setRange(1, 100_000)
        self.fill_box = QComboBox()
        self.fill_box.addItems(list(fill_choices()))
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
        self.table.horizontalHeader().setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
        self.table.horizontalHeader().setSectionResizeMode(1, QHeaderView.ResizeMode.ResizeToContents)
        self.table.verticalHeader().hide()
        self.status = QLabel("")
        self.start_button = QPushButton("Start")
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setEnabled(False)
        self._build()
        self.set_pipeline(Pipeline())
        self.progressed.connect(self._show_progress, Qt.ConnectionType.QueuedConnection)
        self.batch_ended.connect(self._done, Qt.ConnectionType.QueuedConnection)
        self.open_take_started.connect(self._open_started, Qt.ConnectionType.QueuedConnection)
        self.open_take_done.connect(self._open_done, Qt.ConnectionType.QueuedConnection)
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
        from handmocap.core.batch.pipeline import pipeline_from_dict

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
    def _list_takes(self) -> None:
        """One row per session take: name, state, reason or figures (states as the batch and the open takes
        report them)."""
        takes = self.app.session.takes if self.app.session is not None else []
        self.table.setRowCount(len(takes))
        for row, entry in enumerate(takes):
            state = self._states.get(entry.id, "")
            summary = self._summaries.get(entry.id, {})
            if summary.get("status") == "done":
                detail = (f"{100 * summary.get('labelled_share', 0):.1f} % labelled, longest gap "
                          f"{summary.get('longest_gap', 0)} frames, {summary.get('seconds', 0):.1f} s")
                if summary.get("applied"):
                    detail = f"applied to the open take as one step (Edit ▸ Undo undoes it); {detail}"
            else:
                detail = summary.get("reason", "")
            for column, text in enumerate((entry.name, state, detail)):
                item = QTableWidgetItem(text)
                item.setToolTip(text)
                self.table.setItem(row, column, item)

    def _set_state(self, take_id: str, state: str, summary: dict | None = None) -> None:
        self._states[take_id] = state
        if summary is not None:
            self._summaries[take_id] = summary

    def start(self) -> None:
        """Plan the batch of the open session and run it on a thread; takes open in this window are processed
        on a copy of their review and their result is pushed through the open document (module docstring)."""
        if self.app.session is None or self._thread is not None:
            return
        session, workers = self.app.session, self.workers.value()
        plans: list[BatchPlan] = []
        pipelines: list[Pipeline] = []
        if not self._try(lambda: pipelines.append(self.pipeline())) or \
                not self._try(lambda: plans.append(plan_batch(session, pipelines[0]))):
            return
        plan, pipeline = plans[0], pipelines[0]
        self._states, self._summaries = {}, {}
        self._open_jobs = []
        for take_id in plan.up_to_date:
            self._set_state(take_id, "up to date", {"status": "up to date", "reason": "done before with this "
                                                    "pipeline and this raw file; its exports are unchanged"})
        workers_jobs = []
        for job in plan.jobs:
            document = self.app.document_of_session_take(job.take_id)
            if document is None:
                workers_jobs.append(job)
                self._set_state(job.take_id, "queued")
            else:
                self._prepare_open(document, job, pipeline)
        plan.jobs = workers_jobs
        self._plan = plan
        self._stop.clear()
        self._announced.clear()
        self.start_button.setEnabled(False)
        self.cancel_button.setEnabled(True)
        open_jobs = [(job, review) for job, _document, review, _version, _undone in self._open_jobs]
        self._list_takes()
        self._show_counts()

        def work() -> None:
            try:
                if open_jobs and pipeline.runs("export"):
                    plan.output.mkdir(parents=True, exist_ok=True)
                for job, review in open_jobs:
                    if self._stop.is_set():
                        break
                    self.open_take_started.emit(job.take_id)
                    try:
                        outcome = process_review_copy(review, pipeline, job.key, plan.output, job.stem,
                                                      cancelled=self._stop.is_set)
                    except HandMocapError as error:
                        self.open_take_done.emit(job.take_id, None, _first_line(str(error)))
                    except OSError as error:
                        self.open_take_done.emit(job.take_id, None, f"cannot write: {error.strerror or error}")
                    except Exception as error:  # noqa: BLE001 - one take fails, the window stays up
                        self.open_take_done.emit(job.take_id, None,
                                                 f"internal error: {type(error).__name__}: {error}")
                    else:
                        self.open_take_done.emit(job.take_id, outcome, "")
                progress = run_batch(plan, workers, on_progress=self.progressed.emit, stop=self._stop.is_set)
            except HandMocapError as error:
                self.batch_ended.emit(None, str(error))
            except Exception as error:  # noqa: BLE001 - shown as one line, the window stays up
                self.batch_ended.emit(None, f"internal error: {type(error).__name__}: {error}")
            else:
                self.batch_ended.emit(progress, "")

        self._thread = threading.Thread(target=work, name="batch", daemon=True)
        self._thread.start()

    def _prepare_open(self, document: TakeDocument, job: TakeJob, pipeline: Pipeline) -> None:
        """A take open in this window: read-only here (another program edits it) it is skipped with that reason;
        else its earlier batch step of this pipeline is undone (it is run afresh, as a worker does) and a copy of
        its review is processed on the batch thread."""
        opened = document.open_take
        if opened is not None and opened.read_only:
            reason = (f"open here read-only: another program is editing it ({opened.held_by}); close it there, "
                      "then process it again" if opened.held_by else opened.read_only_reason())
            self._set_state(job.take_id, "skipped", {"status": "skipped", "reason": reason})
            return
        undone = False
        if document.stack is not None and document.stack.undo_text() == step_description(pipeline, job.key):
            try:
                document.undo()
                undone = True
            except HandMocapError as error:
                self._set_state(job.take_id, "failed", {"status": "failed", "reason": _first_line(str(error))})
                return
        review = document.ensure_review()
        self._open_jobs.append((job, document, review.copy(), review.version, undone))
        self._set_state(job.take_id, "queued", {"status": "queued", "reason": "open in this window: its result "
                                                "will be applied to it as one undoable step"})

    def _open_started(self, take_id: str) -> None:
        self._set_state(take_id, "running")
        self._list_takes()
        self._show_counts()

    def _open_done(self, take_id: str, outcome: OpenTakeResult | None, error: str) -> None:
        """Apply the result of an open take's pipeline through its open document (GUI thread)."""
        entry = next((item for item in self._open_jobs if item[0].take_id == take_id), None)
        if entry is None:
            return
        job, _, _, version, undone = entry
        document = self.app.document_of_session_take(take_id)
        if document is not entry[1]:
            self._set_state(take_id, "failed", {"status": "failed", "reason": "the take was closed before its "
                                                "result could be applied; process it again"})
        elif outcome is None:
            if undone:
                document.redo()         # the take keeps its earlier batch result
            self._set_state(take_id, "failed", {"status": "failed", "reason": error})
        elif document.review is None or document.review.version != version:
            self._set_state(take_id, "skipped", {"status": "skipped", "reason": "not applied: the take was edited "
                                                 "while it was processed; process it again"})
        else:
            self._apply_open(document, job, outcome)
        self._list_takes()
        self._show_counts()

    def _apply_open(self, document: TakeDocument, job: TakeJob, outcome: OpenTakeResult) -> None:
        take_id, session = job.take_id, self.app.session
        assert session is not None, "open takes are processed in the open session"
        try:
            if outcome.command is not None:
                document.push(outcome.command)
            document.hand_models.update(outcome.models)
            document.marker_sets.update(outcome.marker_sets)
            summary = outcome.summary | {"take": take_id, "name": job.name, "applied": outcome.command is not None}
            record_done(session.folder, take_id, job.key, summary)
            for kind, path in outcome.outputs.items():
                self.app.record_export(take_id, kind, str(path))
            entry = session.take(take_id)
            if not outcome.outputs and entry.state == "raw" and document.has_labels():
                self.app.set_take_state(take_id, "labelled")
        except HandMocapError as error:
            self._set_state(take_id, "failed", {"status": "failed", "reason": _first_line(str(error))})
            return
        self._set_state(take_id, "done", summary)

    def _show_counts(self, extra: str = "") -> None:
        """The status line: how many takes are in each state, of all the session's takes."""
        total = len(self.app.session.takes) if self.app.session is not None else 0
        counts = {state: sum(1 for value in self._states.values() if value == state) for state in STATE_ORDER}
        applied = sum(1 for summary in self._summaries.values() if summary.get("applied"))
        parts = [f"{counts['done']} done" + (f" ({applied} applied to takes open here)" if applied else "")]
        parts += [f"{counts[state]} {state}" for state in STATE_ORDER[1:] if counts[state]]
        self.status.setText(f"{', '.join(parts)} — of {total} takes{extra}")

    def cancel(self) -> None:
        """Stop the batch: finished takes are kept."""
        self._stop.set()
        self.status.setText("stopping: finished takes are kept…")

    def _show_progress(self, progress: BatchProgress) -> None:
        for take_id, state in progress.states.items():
            self._set_state(take_id, state, progress.summaries.get(take_id))
        self._list_takes()
        for take_id, state in list(progress.states.items()):
            if state in ("done", "failed", "skipped") and take_id not in self._announced:
                self._announced.add(take_id)
                self.app.take_processed(take_id)
        rate = f"; {progress.frames_per_s:.0f} frames/s" if progress.frames else ""
        self._show_counts(rate + (f"; dashboard {progress.dashboard}" if progress.dashboard else ""))

    def _done(self, progress: BatchProgress | None, error: str) -> None:
        if self._thread is not None:
            self._thread.join()
        self._thread = None
        self.start_button.setEnabled(True)
        self.cancel_button.setEnabled(False)
        for take_id, state in list(self._states.items()):
            if state in ("queued", "running") and (progress is None or progress.interrupted or error):
                self._set_state(take_id, "queued", {"status": "queued", "reason": "not run: the batch was "
                                                    "stopped before it"})
        if progress is not None:
            self._show_progress(progress)
            self.status.setText(self.status.text() + ("; cancelled" if progress.interrupted else "; finished"))
        else:
            self._list_takes()
        if error:
            self.status.setText(f"⚠ {error}")

    def closeEvent(self, event) -> None:  # noqa: N802 - Qt's name
        """Closing the panel cancels a running batch (finished takes are kept) and waits for it to stop."""
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self._thread = None
        super().closeEvent(event)


#: the states a take's row may show, in the order the status line counts them
STATE_ORDER = ("done", "failed", "skipped", "up to date", "running", "queued")


def _first_line(message: str) -> str:
    return next((line.strip() for line in message.splitlines() if line.strip()), message.strip())


def _side_by_side(widgets: Iterable[QWidget]) -> QHBoxLayout:
    """A row holding ``widgets`` left to right."""
    row = QHBoxLayout()
    for widget in widgets:
        row.addWidget(widget)
    return row
