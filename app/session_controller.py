"""Sessions in the main window: create/open a session folder, the session browser dock, adding takes,
opening a take for review (its journal replayed), take states, autosave, and closing cleanly.

A take opened from the session is a document whose review lives in the session (:class:`OpenTake`):
every edit is journalled at once, the snapshot is written every ``AUTOSAVE_MS`` when there are edits
and when the take or the window closes.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from PySide6.QtCore import QObject, Qt, QTimer
from PySide6.QtWidgets import QFileDialog

from app.document import TakeDocument
from app.review_controller import AutoLabelSettings
from core.errors import HandMocapError
from core.io import Take, load_take
from core.io.labelled_c3d import SubjectCalibration
from core.model import HandModel, MarkerSet, add_layout_folder, best_layout_for, remove_layout_folder
from core.session import OpenTake, Session
from core.session.storage import read_marker_set, write_atomic, write_marker_set
from widgets.session_browser import SessionBrowser, TakeRow

if TYPE_CHECKING:
    from app.main_window import MainWindow

AUTOSAVE_MS = 15_000
TAKE_MODEL_NAME = "labelling_hand_{side}.npz"   # the hand model auto-label calibrated to the take
TAKE_MARKERS_NAME = "labelling_markers_{side}.npz"  # its calibrated markers (the subject's marker offsets)
TAKE_SUBJECT_NAME = "labelling_subject_{side}.json"  # the calibration relative to the template (C3D export)
SNAPSHOT_INTERVAL_S = 60.0


@dataclass
class LoadedTakes:
    """Takes read on the loader thread for adding to the session: (path, take) pairs and failures."""

    takes: list[tuple[Path, Take]]
    failures: list[str]


class SessionController(QObject):
    """The session side of :class:`~app.main_window.MainWindow` (see the module docstring)."""

    def __init__(self, window: MainWindow) -> None:
        super().__init__(window)
        self.window = window
        self.session: Session | None = None
        self.browser = SessionBrowser(window)
        self.browser.add_requested.connect(self.add_takes)
        self.browser.open_requested.connect(self.open_take)
        self.browser.state_change_requested.connect(self.set_state)
        self.browser.remove_requested.connect(self.remove_take)
        self.dock = window._add_dock("Session", self.browser, Qt.DockWidgetArea.LeftDockWidgetArea)
        self.dock.hide()
        action = window._action
        self.new_action = action("&New session…", self.choose_new_session, "Ctrl+Shift+N")
        self.open_action = action("Open s&ession…", self.choose_session, "Ctrl+Shift+O")
        self.add_action = action("&Add takes to session…", self.browser.choose_files, "Ctrl+Shift+A")
        self.close_action = action("C&lose session", self.close_session)
        self.autosave_timer = QTimer(self)
        self.autosave_timer.setInterval(AUTOSAVE_MS)
        self.autosave_timer.timeout.connect(self.autosave)
        self.autosave_timer.start()
        self.update_enabled()

    # -------------------------------------------------------------------------------- sessions
    def choose_new_session(self) -> None:
        folder = QFileDialog.getExistingDirectory(self.window, "New session: choose an empty folder")
        if folder:
            self.create_session(folder)

    def choose_session(self) -> None:
        folder = QFileDialog.getExistingDirectory(self.window, "Open session folder")
        if folder:
            self.open_session(folder)

    def create_session(self, folder: str | Path) -> bool:
        """Create a session in ``folder`` and show it; False (with a message) when it cannot."""
        try:
            session = Session.create(folder)
        except HandMocapError as error:
            self.window.show_error("Cannot create the session", str(error))
            return False
        self._set_session(session)
        return True

    def open_session(self, folder: str | Path) -> bool:
        """Open the session in ``folder`` (read-only when the folder is); False with a message when
        it cannot be opened (a damaged manifest is left untouched)."""
        try:
            session = Session.open(folder)
        except HandMocapError as error:
            try:
                session = Session.open(folder, read_only=True)
            except HandMocapError:
                self.window.show_error("Cannot open the session", str(error))
                return False
            self.window.show_error("Session opened read-only", f"{error}; edits cannot be saved")
        self._set_session(session)
        return True

    def _set_session(self, session: Session) -> None:
        self.close_session()
        self.session = session
        add_layout_folder(session.folder / "layouts")
        self.window.refresh_layout_names()
        self.refresh()
        self.dock.show()
        self.dock.raise_()
        self.window.statusBar().showMessage(f"Session {session.name}: {len(session.takes)} takes", 8000)
        self.update_enabled()

    def close_session(self) -> None:
        """Save and close the session's open takes (their documents are closed too)."""
        if self.session is None:
            return
        for document in [d for d in self.window.documents if d.open_take is not None]:
            self.window.close_document(document)
        self.session.close()
        remove_layout_folder(self.session.folder / "layouts")
        self.window.refresh_layout_names()
        self.session = None
        self.browser.set_takes([])
        self.dock.hide()
        self.update_enabled()

    def refresh(self) -> None:
        """Show the session's takes and states in the browser."""
        if self.session is not None:
            self.browser.set_takes([TakeRow.from_entry(entry) for entry in self.session.takes])
            current = self.window.document
            if current is not None and current.session_take_id:
                self.browser.set_current(current.session_take_id)

    def update_enabled(self) -> None:
        writable = self.session is not None and not self.session.read_only
        self.add_action.setEnabled(writable)
        self.close_action.setEnabled(self.session is not None)

    # ----------------------------------------------------------------------------------- takes
    def add_takes(self, paths: list[str]) -> None:
        """Read the take files on the loader thread, then add them to the session."""
        if self.session is None:
            if not self.window.documents and not paths:
                return
            self.window.show_error("No session", "create or open a session first (File ▸ New session…)")
            return

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> LoadedTakes:
            loaded, failures = [], []
            for number, path in enumerate(paths):
                try:
                    loaded.append((Path(path), load_take(path)))
                except HandMocapError as error:
                    failures.append(f"{Path(path).name}: {error}")
                progress((number + 1) / len(paths))
            return LoadedTakes(loaded, failures)

        self.window.queue_load("Adding takes…", task, self._takes_loaded)

    def _takes_loaded(self, loaded: LoadedTakes) -> None:
        takes, failures = loaded.takes, list(loaded.failures)
        for path, take in takes:
            try:
                self.session.add_take(path, layout=best_layout_for(take.marker_names), take=take)
            except HandMocapError as error:
                failures.append(f"{path.name}: {error}")
        self.refresh()
        if failures:
            self.window.show_error("Some takes were not added", "\n".join(failures))

    def open_take(self, take_id: str, automatic: bool = False) -> None:
        """Open a session take for review (switch to it when it is open already). ``automatic``: then
        solve a labelled take with IK, or auto-label a raw one that was never labelled (the demo)."""
        if self.session is None:
            return
        for document in self.window.documents:
            if document.session_take_id == take_id:
                self.window.take_box.setCurrentIndex(self.window.documents.index(document))
                return
        session = self.session

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> OpenTake:
            return session.open_take(take_id)

        self.window.queue_load("Opening take…", task, lambda opened: self._take_opened(opened, automatic))

    def _take_opened(self, opened: OpenTake, automatic: bool = False) -> None:
        entry = opened.entry
        document = TakeDocument(take=opened.review.take, title=entry.name, layout_name=entry.layout,
                                open_take=opened, session_take_id=entry.id,
                                auto_solve=automatic and entry.labelled_source)
        if self.session is not None and entry.subject:
            try:
                model = self.session.load_subject_model(entry.subject)
            except HandMocapError:
                model = None
            if model is not None:
                document.hand_models[model.side] = model
        for side in ("right", "left"):
            path = opened.folder / TAKE_MODEL_NAME.format(side=side)
            markers = opened.folder / TAKE_MARKERS_NAME.format(side=side)
            subject = opened.folder / TAKE_SUBJECT_NAME.format(side=side)
            if path.exists():
                try:
                    document.hand_models[side] = HandModel.load(path)
                    if markers.exists():
                        document.marker_sets[side] = read_marker_set(markers)
                    if subject.exists():
                        document.subjects[side] = SubjectCalibration.from_dict(json.loads(subject.read_text()))
                except (HandMocapError, OSError, ValueError, KeyError):
                    self.window.statusBar().showMessage(f"{path.name} is damaged; the template is used", 10000)
                    document.hand_models.pop(side, None)
        self.window.add_document(document)
        if automatic and not entry.labelled_source and not opened.review.n_labels:
            self.window.review.start_auto_label(AutoLabelSettings(layout=entry.layout or "dense",
                                                                  hands="both" if len(entry.hands) > 1
                                                                  else entry.hands[0]), document)
        if opened.replayed or opened.warnings:
            lines = [f"recovered {opened.replayed} edits from the journal"] if opened.replayed else []
            self.window.show_error("Take recovered", "\n".join(lines + opened.warnings))

    def save_take_models(self, document: TakeDocument, models: dict[str, HandModel],
                         marker_sets: dict[str, MarkerSet] | None = None) -> None:
        """Keep the hand models the labelling calibrated to this take's subject, and their calibrated
        markers, in the take's folder, so that drawing, solves and re-solves use them when the take is
        opened again."""
        if document.open_take is None or self.session is None or self.session.read_only:
            return
        folder = document.open_take.folder
        try:
            for side, model in models.items():
                model.save(folder / TAKE_MODEL_NAME.format(side=side))
                markers = folder / TAKE_MARKERS_NAME.format(side=side)
                if marker_sets and side in marker_sets:
                    write_marker_set(markers, marker_sets[side])
                else:
                    markers.unlink(missing_ok=True)
                subject = folder / TAKE_SUBJECT_NAME.format(side=side)
                if side in document.subjects:
                    write_atomic(subject, json.dumps(document.subjects[side].as_dict()).encode("utf-8"))
                else:
                    subject.unlink(missing_ok=True)
        except (OSError, HandMocapError) as error:
            self.window.statusBar().showMessage(f"Cannot keep the calibrated hand model: {error}", 10000)

    def set_state(self, take_id: str, state: str) -> None:
        try:
            self.session.set_state(take_id, state)
        except HandMocapError as error:
            self.window.show_error("Cannot change the state", str(error))
        self.refresh()

    def remove_take(self, take_id: str) -> None:
        if any(document.session_take_id == take_id for document in self.window.documents):
            self.window.show_error("Cannot remove", "close the take first")
            return
        try:
            self.session.remove_take(take_id)
        except HandMocapError as error:
            self.window.show_error("Cannot remove the take", str(error))
        self.refresh()

    # ---------------------------------------------------------------------------------- saving
    def save_document(self, document: TakeDocument) -> None:
        """Write the snapshot of a session take now (after auto-label, before export)."""
        if document.open_take is None or self.session is None or self.session.read_only:
            return
        try:
            document.open_take.save()
        except HandMocapError as error:
            self.window.show_error("Cannot save", str(error))
        self.refresh()

    def autosave(self) -> None:
        """Snapshot the session takes with edits older than ``SNAPSHOT_INTERVAL_S`` (the journal has them
        already; the snapshot keeps replay short)."""
        for document in self.window.documents:
            if document.open_take is not None and not document.open_take.closed:
                try:
                    document.open_take.autosave(SNAPSHOT_INTERVAL_S)
                except HandMocapError as error:
                    self.window.statusBar().showMessage(f"Autosave failed: {error}", 10000)

    def export_done(self, document: TakeDocument, kind: str, path: str) -> None:
        if document.session_take_id and self.session is not None and not self.session.read_only:
            try:
                self.session.record_export(document.session_take_id, kind, path)
            except HandMocapError as error:
                self.window.show_error("Cannot record the export", str(error))
            self.refresh()

    def save_layout(self, layout) -> None:
        """Store a layout in the session: it is listed with the shipped ones and labelling can use it."""
        if self.session is None:
            raise HandMocapError("open or create a session first to keep layouts in it")
        self.session.save_layout(layout)
        self.window.refresh_layout_names()

    def close(self) -> None:
        """The window is closing: save every open take and release the journals."""
        self.autosave_timer.stop()
        for document in self.window.documents:
            if document.open_take is not None and not document.open_take.closed:
                try:
                    document.open_take.close(save=True)
                except HandMocapError as error:
                    self.window.statusBar().showMessage(f"Cannot save {document.title}: {error}")
        if self.session is not None:
            self.session.close()
