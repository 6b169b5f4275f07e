"""Tools ▸ Learn a labelling template…: learn a lab's template from takes the lab labelled.

The operator ticks the labelled takes (the shown take when it carries labels, the session's takes whose
files came labelled, or files added here), names the template and clicks Learn: the takes are read and
:func:`core.labelling.templates.learn_template` runs on a worker with progress and Cancel. The result is
shown per hand (each marker, where it was found to sit and the fitted placement, the placement residual),
with the rigid objects found and the markers ignored. Save writes the template into the open session's
``layouts`` folder, where the Auto-label dialog lists it by name, or, without a session, to a file the
operator picks. A file that states no frame rate is asked for one, and the learning runs again.
"""

from __future__ import annotations

import html
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QAbstractItemView,
    QDialog,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QMessageBox,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from handmocap.app.gui.application import Application
from handmocap.app.gui.palette import visible_check_boxes
from handmocap.app.gui.workers import Task, TaskRunner, one_line
from handmocap.core.errors import CancelledError, HandMocapError
from handmocap.core.io import TAKE_FILE_FILTER, FrameRateMissingError, Take, is_marker_label, load_take
from handmocap.core.labelling.templates import LearnedTemplate, learn_template
from handmocap.core.model.lab_template import LabTemplate, TemplateHand, layout_path, save_lab_template
from handmocap.core.model.markers import LAYOUT_DIR, MarkerSpec
from handmocap.core.model.skeleton import DIGITS
from handmocap.widgets.frame_rate_dialog import FrameRatePrompt
from handmocap.widgets.progress_bar import ProgressBar

LOAD_SHARE = 0.25                 # share of the progress bar for reading the take files
NAME_PATTERN = re.compile(r"^[A-Za-z0-9](?:[A-Za-z0-9._-]*[A-Za-z0-9-])?$")   # a session keeps it as <name>.json
NAME_RULE = "Name the template: letters, digits, - _ . (the file is <name>.json)"
SEGMENT_WORDS = {"thumb": ("metacarpal", "proximal", "distal"), "finger": ("proximal", "middle", "distal")}
SOURCE_ROLE = Qt.ItemDataRole.UserRole
DEFAULT_NAME = "lab-template"


def where_it_sits(digit: str, segment: int) -> str:
    """What the operator reads for a marker found on ``digit`` (a digit name or ``palm``) at ``segment``
    (1 proximal … 3 distal): ``"index, segment 3 (distal)"``, ``"thumb, segment 1 (metacarpal)"``, ``"palm"``."""
    if digit == "palm" or segment <= 0:
        return "palm (back of the hand)" if digit == "palm" else digit or "?"
    words = SEGMENT_WORDS["thumb" if digit == "thumb" else "finger"]
    word = f" ({words[segment - 1]})" if 1 <= segment <= len(words) else ""
    return f"{digit}, segment {segment}{word}"


def placement_text(spec: MarkerSpec) -> str:
    """The fitted placement of a marker in words: ``"index dip → tip at 60 %, 3.2 mm off the skin"``."""
    height = f"{spec.offset_mm:.1f} mm off the skin"
    if spec.between is None:
        return f"mesh vertex {spec.vertex}, {height}"
    first, second = (joint.replace("_", " ") for joint in spec.between)
    digit = first.split(" ")[0]
    if second.startswith(digit + " ") and first.startswith(digit + " "):
        second = second[len(digit) + 1:]
    return f"{first} → {second} at {100 * spec.along:.0f} %, {height}"


def _hand_rows(hand: TemplateHand) -> list[tuple[str, str, str]]:
    """(marker, where it sits, placement) of a hand's markers, palm first, then thumb to little finger,
    proximal to distal."""
    order = {digit: number for number, digit in enumerate(("palm", *DIGITS))}
    rows = sorted(zip(hand.layout.markers, hand.digits, hand.segments, strict=True),
                  key=lambda row: (order.get(row[1], len(order)), row[2], row[0].name))
    return [(spec.name, where_it_sits(digit, segment), placement_text(spec)) for spec, digit, segment in rows]


@dataclass
class TakeSource:
    """A take offered for learning: ``title`` as listed; ``take`` in memory (the shown take with its labels)
    or ``path`` read on the worker, with ``frame_rate`` (Hz) when known (the session recorded it, or the
    operator gave it for a file that states none)."""

    title: str
    take: Take | None = None
    path: Path | None = None
    frame_rate: float | None = None


@dataclass
class RateNeeded:
    """The worker's answer when the file of ``sources[index]`` states no frame rate: ask, then learn again."""

    index: int


def learn_task(sources: list[TakeSource], name: str) -> Task:
    """Worker task: read the file ``sources`` (the first :data:`LOAD_SHARE` of the progress), then learn the
    template ``name`` from all of them. Returns a :class:`LearnedTemplate`, or :class:`RateNeeded`."""

    def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> LearnedTemplate | RateNeeded:
        takes = []
        for index, source in enumerate(sources):
            if cancelled():
                raise CancelledError("template learning cancelled; nothing was written")
            if source.take is not None:
                takes.append(source.take)
            else:
                assert source.path is not None, "a take source has a take or a path"
                try:
                    takes.append(load_take(source.path, frame_rate=source.frame_rate))
                except FrameRateMissingError:
                    return RateNeeded(index)
            progress(LOAD_SHARE * (index + 1) / len(sources))
        return learn_template(takes, name, lambda fraction: progress(LOAD_SHARE + (1 - LOAD_SHARE) * fraction),
                              cancelled)

    return task


def current_take_source(app: Application) -> TakeSource | None:
    """The shown take as a learning source when it carries labels: the labels of its review (what the operator
    checked and fixed; fills left out), else its file's labelled columns. None when it has none."""
    document = app.document
    if document is None:
        return None
    review = document.review
    if review is not None and review.label_names and (review.assignment >= 0).any():
        take = review.labelled_take(include_fills=False)
    elif not document.is_raw and any(is_marker_label(name) for name in document.take.marker_names):
        take = document.take
    else:
        return None
    return TakeSource(f"{document.title} (shown take)", take=take)


def session_sources(app: Application) -> list[tuple[str, TakeSource]]:
    """(take id, source) of the open session's takes whose files came labelled."""
    session = app.session
    if session is None:
        return []
    sources = []
    for entry in session.takes:
        if not entry.labelled_source:
            continue
        try:
            path = session.source_path(entry.id)
        except HandMocapError:
            continue                     # its file moved away: the browser says so
        sources.append((entry.id, TakeSource(f"{entry.name} (session)", path=path,
                                             frame_rate=entry.given_frame_rate)))
    return sources


def default_name(session_name: str) -> str:
    """The name offered for a template: ``<session>-template`` (file-name safe), else :data:`DEFAULT_NAME`."""
    stem = re.sub(r"[^A-Za-z0-9._-]+", "-", session_name).strip("._-")
    return f"{stem}-template" if stem else DEFAULT_NAME


class LearnTemplateDialog(QDialog):
    """The dialog (module docstring). ``save_to_session`` stores the template in the open session's layouts
    (None: no session; Save asks for a file)."""

    saved = Signal(str)      # the path written

    def __init__(self, parent: QWidget | None, sources: list[tuple[TakeSource, bool]],
                 save_to_session: Callable[[LabTemplate], Path] | None = None, name: str = DEFAULT_NAME) -> None:
        super().__init__(parent)
        self.setWindowTitle("Learn a labelling template")
        self.save_to_session = save_to_session
        self.learned: LearnedTemplate | None = None
        self._learning: list[TakeSource] = []
        self.rate_prompt = FrameRatePrompt(self)
        self.runner = TaskRunner(self)
        self.runner.progressed.connect(lambda _request, fraction: self.progress_bar.setValue(round(100 * fraction)))
        self.runner.succeeded.connect(self._succeeded)
        self.runner.failed.connect(self._failed)
        self.runner.cancelled.connect(lambda _request: self._ended("Cancelled: nothing learned, nothing written"))
        self.runner.busy_changed.connect(self._busy_changed)

        layout = QVBoxLayout(self)
        top = QHBoxLayout()
        top.addWidget(self._takes_box(sources), 3)
        top.addLayout(self._settings(name), 2)
        layout.addLayout(top)
        layout.addLayout(self._run_row())
        self.summary_label = QLabel("Tick the labelled takes, name the template and click Learn.", self)
        self.summary_label.setWordWrap(True)
        self.hands_row = QHBoxLayout()
        self.hand_boxes: dict[str, QGroupBox] = {}
        self.hand_tables: dict[str, QTableWidget] = {}
        self.objects_label = QLabel("", self)
        self.objects_label.setWordWrap(True)
        self.objects_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(self.summary_label)
        layout.addLayout(self.hands_row, 1)
        layout.addWidget(self.objects_label)
        layout.addLayout(self._bottom_row())
        self._busy_changed(False)

    def _takes_box(self, sources: list[tuple[TakeSource, bool]]) -> QGroupBox:
        self.take_list = QListWidget(self)
        visible_check_boxes(self.take_list)
        self.take_list.setToolTip("Takes the lab labelled: the template learns their marker names, which hand and "
                                  "digit each marker sits on, and the rigid objects")
        self.take_list.setSelectionMode(QAbstractItemView.SelectionMode.ExtendedSelection)
        self.take_list.setMaximumHeight(110)
        for source, checked in sources:
            self._add_source(source, checked)
        add_button = QPushButton("Add files…", self)
        add_button.clicked.connect(self.choose_files)
        remove_button = QPushButton("Remove", self)
        remove_button.clicked.connect(self._remove_selected)
        buttons = QVBoxLayout()
        buttons.addWidget(add_button)
        buttons.addWidget(remove_button)
        buttons.addStretch(1)
        box = QGroupBox("Labelled takes to learn from", self)
        row = QHBoxLayout(box)
        row.addWidget(self.take_list, 1)
        row.addLayout(buttons)
        return box

    def _settings(self, name: str) -> QVBoxLayout:
        self.name_edit = QLineEdit(name, self)
        self.name_edit.setToolTip("Letters, digits, - _ . : the file is <name>.json")
        where = ("the session's layouts folder: Auto-label lists it by this name" if self.save_to_session is not None
                 else "a file you choose (open a session first to keep it with the session's layouts)")
        self.where_label = QLabel(where, self)
        self.where_label.setWordWrap(True)
        form = QFormLayout()
        form.addRow("Template name", self.name_edit)
        form.addRow("Saved into", self.where_label)
        settings = QVBoxLayout()
        settings.addLayout(form)
        settings.addStretch(1)
        return settings

    def _run_row(self) -> QHBoxLayout:
        self.progress_bar = ProgressBar(self)
        self.progress_bar.setRange(0, 100)
        self.progress_bar.setFormat("%p %")
        self.learn_button = QPushButton("Learn", self)
        self.learn_button.setDefault(True)
        self.learn_button.clicked.connect(self.learn)
        self.cancel_button = QPushButton("Cancel", self)
        self.cancel_button.clicked.connect(self.runner.cancel)
        row = QHBoxLayout()
        row.addWidget(self.learn_button)
        row.addWidget(self.progress_bar, 1)
        row.addWidget(self.cancel_button)
        return row

    def _bottom_row(self) -> QHBoxLayout:
        self.status_label = QLabel("", self)
        self.status_label.setWordWrap(True)
        self.save_button = QPushButton("Save template", self)
        self.save_button.clicked.connect(lambda: self.save())  # noqa: PLW0108 (drops Qt's `checked`, not a path)
        close_button = QPushButton("Close", self)
        close_button.clicked.connect(self.reject)
        row = QHBoxLayout()
        row.addWidget(self.status_label, 1)
        row.addWidget(self.save_button)
        row.addWidget(close_button)
        return row


    # ------------------------------------------------------------------------------------- takes
    def _add_source(self, source: TakeSource, checked: bool) -> None:
        item = QListWidgetItem(source.title)
        item.setData(SOURCE_ROLE, source)
        item.setToolTip(str(source.path) if source.path is not None else "the labels of the shown take's review")
        item.setFlags(item.flags() | Qt.ItemFlag.ItemIsUserCheckable)
        item.setCheckState(Qt.CheckState.Checked if checked else Qt.CheckState.Unchecked)
        self.take_list.addItem(item)

    def add_files(self, paths: Sequence[str | Path]) -> None:
        """List take files (ticked) to learn from; a file listed already is ticked."""
        for path in map(Path, paths):
            listed = next((item for item in self._items() if item.data(SOURCE_ROLE).path == path), None)
            if listed is not None:
                listed.setCheckState(Qt.CheckState.Checked)
            else:
                self._add_source(TakeSource(path.name, path=path), True)

    def choose_files(self) -> None:
        paths, _ = QFileDialog.getOpenFileNames(self, "Labelled takes", "", TAKE_FILE_FILTER)
        self.add_files(paths)

    def _remove_selected(self) -> None:
        for item in self.take_list.selectedItems():
            self.take_list.takeItem(self.take_list.row(item))

    def _items(self) -> list[QListWidgetItem]:
        return [self.take_list.item(row) for row in range(self.take_list.count())]

    def chosen_sources(self) -> list[TakeSource]:
        """The ticked takes, in list order."""
        return [item.data(SOURCE_ROLE) for item in self._items() if item.checkState() == Qt.CheckState.Checked]

    # ----------------------------------------------------------------------------------- learning
    def template_name(self) -> str:
        return self.name_edit.text().strip()

    def learn(self) -> bool:
        """Start learning on the worker; False (and a one-line message) when the input is not usable."""
        if self.runner.is_busy():
            return False
        sources, name = self.chosen_sources(), self.template_name()
        problem = ("Tick at least one labelled take to learn from" if not sources else
                   NAME_RULE if not NAME_PATTERN.match(name) else "")
        if problem:
            QMessageBox.warning(self, "Cannot learn the template", problem)
            return False
        self.learned = None
        self._show_result()
        self._learning = sources
        self.progress_bar.setValue(0)
        self.status_label.setText(f"Learning '{name}' from {len(sources)} take(s)…")
        self.runner.start(learn_task(sources, name))
        return True

    def _succeeded(self, _request: int, result: object) -> None:
        if isinstance(result, RateNeeded):
            self._ask_rate(self._learning[result.index])
            return
        learned = self.learned = cast(LearnedTemplate, result)     # the task's result when no rate was needed
        self._show_result()
        self._ended(f"Learned '{learned.template.name}': check where each marker sits, then save it")

    def _ask_rate(self, source: TakeSource) -> None:
        """A file stated no frame rate: ask for it and learn again (nothing learned when the operator declines)."""
        assert source.path is not None, "only a file needs its rate"
        rate = self.rate_prompt.ask(source.path)
        if rate is None:
            self._ended(f"Nothing learned: {source.path.name} needs its frame rate")
            return
        source.frame_rate = rate
        self.learn()

    def _failed(self, _request: int, message: str) -> None:
        self._ended("Nothing learned")
        QMessageBox.warning(self, "Cannot learn the template", one_line(message))

    def _ended(self, text: str) -> None:
        self.status_label.setText(text)
        self._busy_changed(self.runner.is_busy())

    def _busy_changed(self, busy: bool) -> None:
        for widget in (self.learn_button, self.take_list, self.name_edit):
            widget.setEnabled(not busy)
        self.cancel_button.setEnabled(busy)
        self.save_button.setEnabled(not busy and self.learned is not None)

    # ------------------------------------------------------------------------------------- result
    def _show_result(self) -> None:
        """The learned hands side by side (a table each), the summary, objects and ignored markers."""
        for box in self.hand_boxes.values():
            self.hands_row.removeWidget(box)
            box.deleteLater()
        self.hand_boxes, self.hand_tables = {}, {}
        if self.learned is None:
            self.summary_label.setText("")
            self.objects_label.setText("")
            return
        template, report = self.learned.template, self.learned.report
        for side in template.sides:
            hand, entry = template.hands[side], report["hands"][side]
            box = QGroupBox(f"{side.capitalize()} hand: {len(hand.names)} markers, placement residual "
                            f"{entry['residual_mm']:.1f} mm", self)
            table = QTableWidget(0, 3, box)
            table.setHorizontalHeaderLabels(["Marker", "Sits on", "Fitted placement"])
            table.verticalHeader().setVisible(False)
            table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
            table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
            table.setAlternatingRowColors(True)
            for row, cells in enumerate(_hand_rows(hand)):
                table.insertRow(row)
                for column, text in enumerate(cells):
                    table.setItem(row, column, QTableWidgetItem(text))
            header = table.horizontalHeader()
            header.setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
            header.setSectionResizeMode(1, QHeaderView.ResizeMode.ResizeToContents)
            header.setStretchLastSection(True)
            table.verticalHeader().setDefaultSectionSize(table.fontMetrics().height() + 6)
            box_layout = QVBoxLayout(box)
            box_layout.setContentsMargins(4, 4, 4, 4)
            box_layout.addWidget(table)
            self.hands_row.addWidget(box, 1)
            self.hand_boxes[side], self.hand_tables[side] = box, table
        takes = len(self._learning)
        self.summary_label.setText(
            f"Learned from {takes} take{'s' if takes != 1 else ''}, {report['frames']} frames; marker noise "
            f"σ {report['noise_mm']:.2f} mm. Placement residual: mean distance of the markers from where the "
            "fitted hand model puts them.")
        objects = "; ".join(f"<b>{html.escape(name)}</b> (rigid, {len(markers)} markers: "
                            f"{html.escape(', '.join(markers))})" for name, markers in report["objects"].items())
        ignored = html.escape(", ".join(report["ignored_markers"])) or "none"
        self.objects_label.setText(f"Objects: {objects or 'none'}<br>"
                                   f"Markers ignored (neither hand nor object): {ignored}")

    def sits_on(self, side: str) -> dict[str, str]:
        """{marker: where it sits} as the ``side`` table shows it."""
        table = self.hand_tables[side]

        def text(row: int, column: int) -> str:
            item = table.item(row, column)      # every cell has one (_show_result)
            return item.text() if item is not None else ""
        return {text(row, 0): text(row, 1) for row in range(table.rowCount())}

    # ------------------------------------------------------------------------------------- saving
    def save(self, path: str | Path | None = None) -> Path | None:
        """Save the learned template (named as the name field says now): into the session's layouts, else to
        ``path`` or a file the operator picks. Returns the path written (None: not saved)."""
        if self.learned is None:
            return None
        name = self.template_name()
        if not NAME_PATTERN.match(name):
            QMessageBox.warning(self, "Cannot save the template", NAME_RULE)
            return None
        if (LAYOUT_DIR / f"{name}.json").exists():
            QMessageBox.warning(self, "Cannot save the template",
                                f"'{name}' is a layout shipped with the application; choose another name")
            return None
        if self.save_to_session is not None and layout_path(name) is not None:
            answer = QMessageBox.question(self, "Replace the layout?",
                                          f"The session has a layout '{name}'. Replace it?")
            if answer != QMessageBox.StandardButton.Yes:
                return None
        template = LabTemplate(name=name, hands=self.learned.template.hands, objects=self.learned.template.objects,
                               description=self.learned.template.description,
                               learned_from=self.learned.template.learned_from,
                               noise_mm=self.learned.template.noise_mm)
        try:
            if self.save_to_session is not None:
                written = Path(self.save_to_session(template))
                message = f"Saved '{name}' into the session's layouts: Auto-label ▸ Marker layout lists it"
            else:
                if path is None:
                    path, _ = QFileDialog.getSaveFileName(self, "Save the template", f"{name}.json",
                                                          "Layout JSON (*.json)")
                    if not path:
                        return None
                written = Path(path)
                save_lab_template(template, written)
                message = f"Saved {written}; label with it: handmocap label --layout {written}"
        except (HandMocapError, OSError) as error:
            QMessageBox.warning(self, "Cannot save the template", one_line(str(error)))
            return None
        self.status_label.setText(message)
        self.saved.emit(str(written))
        return written

    def done(self, result: int) -> None:
        """Closing cancels the learning and waits for the worker."""
        self.runner.stop()
        super().done(result)


def open_learn_template(parent: QWidget, app: Application, selected_take_id: str = "") -> LearnTemplateDialog:
    """Show the dialog (window-modal) for ``app``: the shown take ticked when it carries labels, else the session
    take selected in the browser (``selected_take_id``), else every session take whose file came labelled."""
    shown = current_take_source(app)
    listed = session_sources(app)
    sources = [(shown, True)] if shown is not None else []
    selected = any(take_id == selected_take_id for take_id, _ in listed)
    sources += [(source, shown is None and (take_id == selected_take_id or not selected))
                for take_id, source in listed]
    session = app.session
    dialog = LearnTemplateDialog(parent, sources, app.save_layout if session is not None else None,
                                 name=default_name(session.folder.name if session is not None else ""))
    dialog.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose, True)
    dialog.resize(1180, 720)
    dialog.open()
    return dialog


__all__ = ["LearnTemplateDialog", "TakeSource", "open_learn_template", "placement_text", "where_it_sits"]
