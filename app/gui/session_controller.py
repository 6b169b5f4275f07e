"""Sessions: create/open a session folder, the session browser, adding takes, opening a take for review
(its journal replayed), take states, autosave, and closing cleanly.

A take file opened outside a session is reviewed the same way in an automatic session of its own
(:mod:`app.gui.loose_takes`); this controller tells the operator whether its review was restored, and
why its edits are not kept when the data folder cannot be written.

A take opened from the session is a document whose review lives in the session (:class:`OpenTake`):
every edit is journalled at once, the snapshot is written every ``AUTOSAVE_MS`` when there are edits
and when the take or the window closes. A take another instance is editing opens read-only: its title
says so, the status bar says who holds it, and edits are refused with that message.

Changes of the session folder go through the :class:`~app.gui.application.Application`, which announces
them; the session browser follows those events (and the shown take), whoever made the change.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from PySide6.QtCore import QObject, QTimer, Signal
from PySide6.QtWidgets import QFileDialog, QWidget

from handmocap.app.gui.actions import make_action
from handmocap.app.gui.application import (
    Application,
    CurrentDocumentChanged,
    DocumentOpened,
    SessionChanged,
    SessionFolderChanged,
    SessionPart,
)
from handmocap.app.gui.document import TakeDocument
from handmocap.app.gui.load_queue import LoadQueue
from handmocap.app.gui.review.dialogs import AutoLabelSettings
from handmocap.core.errors import HandMocapError
from handmocap.core.io import FrameRateMissingError, Take, load_take
from handmocap.core.io.durable import write_atomic
from handmocap.core.io.labelled_c3d import SubjectCalibration
from handmocap.core.model import HandModel, MarkerSet
from handmocap.core.session import OpenTake, Session
from handmocap.core.session.storage import read_marker_set, write_marker_set
from handmocap.widgets.frame_rate_dialog import FrameRatePrompt
from handmocap.widgets.session_browser import SessionBrowser, TakeRow

AUTOSAVE_MS = 15_000
TAKE_MODEL_NAME = "labelling_hand_{side}.npz"   # the hand model auto-label calibrated to the take
TAKE_MARKERS_NAME = "labelling_markers_{side}.npz"  # its calibrated markers (the subject's marker offsets)
TAKE_SUBJECT_NAME = "labelling_subject_{side}.json"  # the calibration relative to the template (C3D export)
SNAPSHOT_INTERVAL_S = 60.0


@dataclass
class LoadedTakes:
    """Takes read on the loader thread for adding to the session: (path, take) pairs, failures and the files
    that state no frame rate (their rate is asked, then they are read again)."""

    takes: list[tuple[Path, Take]]
    failures: list[str]
    rate_needed: list[Path] = field(default_factory=list)


class SessionController(QObject):
    """The open session (see the module docstring). It builds the session :attr:`browser` and the session
    actions; the window places them and shows what the signals below tell."""

    status_message = Signal(str, int)              # text, milliseconds to show it (0: until replaced)
    error_raised = Signal(str, str)                # title, message
    auto_label_requested = Signal(object, object)  # AutoLabelSettings, the document to label

    def __init__(self, app: Application, host: QWidget, loads: LoadQueue,
                 rate_prompt: FrameRatePrompt | None = None) -> None:
        super().__init__(host)
        self.app, self.host, self.loads = app, host, loads
        self.rate_prompt = rate_prompt or FrameRatePrompt(host)   # asks the rate of takes that state none
        self.browser = SessionBrowser(host)
        self.browser.add_requested.connect(self.add_takes)
        self.browser.open_requested.connect(self.open_take)
        self.browser.state_change_requested.connect(self.set_state)
        self.browser.remove_requested.connect(self.remove_take)
        self.new_action = make_action(host, "&New session…", self.choose_new_session, "new_session")
        self.open_action = make_action(host, "Open s&ession…", self.choose_session, "open_session")
        self.add_action = make_action(host, "&Add takes to session…", self.browser.choose_files, "add_takes")
        self.close_action = make_action(host, "C&lose session", self.close_session)
        self.process_action = make_action(host, "&Process takes…", self.open_batch_panel)
        app.add_listener(self._follow_app)
        self.autosave_timer = QTimer(self)
        self.autosave_timer.setInterval(AUTOSAVE_MS)
        self.autosave_timer.timeout.connect(self.autosave)
        self.autosave_timer.start()
        self.update_enabled()

    @property
    def session(self) -> Session | None:
        """The open session."""
        return self.app.session

    def _follow_app(self, event: object) -> None:
        """The browser follows the application: the session's takes and their states, the shown take (bold)."""
        if isinstance(event, SessionChanged):
            self._show_takes()
            self.update_enabled()
        elif isinstance(event, SessionFolderChanged) and self.session is not None:
            if event.what == SessionPart.TAKE_STATE and any(entry.id == event.take_id for entry in self.session.takes):
                self.browser.update_take(TakeRow.from_entry(self.session.take(event.take_id)))
            elif event.what & (SessionPart.TAKES | SessionPart.TAKE_STATE | SessionPart.SUBJECTS):
                self._show_takes()
        elif isinstance(event, DocumentOpened) and event.document.loose is not None:
            self._loose_take_opened(event.document)
        elif isinstance(event, CurrentDocumentChanged):
            document = event.document
            self.browser.set_current((document.session_take_id or "") if document is not None else "")
            if document is not None and document.open_take is not None and document.open_take.read_only:
                self.status_message.emit(f"{document.open_take.read_only_reason()}; edits are not possible", 0)
            elif document is not None and document.loose is not None and document.loose.notice:
                self.status_message.emit(document.loose.notice, 0 if document.loose.restored else 10000)
                document.loose.notice = ""     # said once, when the take is first shown

    def _show_takes(self) -> None:
        """Show the open session's takes and states in the browser (none when no session is open)."""
        entries = self.session.takes if self.session is not None else []
        self.browser.set_takes([TakeRow.from_entry(entry) for entry in entries])
        current = self.app.document
        self.browser.set_current((current.session_take_id or "") if current is not None else "")

    # -------------------------------------------------------------------------------- sessions
    def choose_new_session(self) -> None:
        folder = QFileDialog.getExistingDirectory(self.host, "New session: choose an empty folder")
        if folder:
            self.create_session(folder)

    def choose_session(self) -> None:
        folder = QFileDialog.getExistingDirectory(self.host, "Open session folder")
        if folder:
            self.open_session(folder)

    def create_session(self, folder: str | Path) -> bool:
        """Create a session in ``folder`` and show it; False (with a message) when it cannot."""
        try:
            session = Session.create(folder)
        except HandMocapError as error:
            self.error_raised.emit("Cannot create the session", str(error))
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
                self.error_raised.emit("Cannot open the session", str(error))
                return False
            self.error_raised.emit("Session opened read-only", f"{error}; edits cannot be saved")
        self._set_session(session)
        return True

    def _set_session(self, session: Session) -> None:
        self.close_session()
        self.app.set_session(session)
        self.status_message.emit(f"Session {session.name}: {len(session.takes)} takes", 8000)

    def close_session(self) -> None:
        """Save and close the session's open takes (their documents are closed too)."""
        session = self.session
        if session is None:
            return
        for document in [d for d in self.app.documents if d.session_take_id is not None]:
            problem = self.app.close_document(document)
            if problem:
                self.error_raised.emit("Cannot save", problem)
        session.close()
        self.app.set_session(None)

    def update_enabled(self) -> None:
        writable = self.session is not None and not self.session.read_only
        self.add_action.setEnabled(writable)
        self.close_action.setEnabled(self.session is not None)
        self.process_action.setEnabled(writable)

    def open_batch_panel(self) -> None:
        """Session ▸ Process takes…: the batch panel of the open session (:mod:`app.gui.batch_panel`)."""
        from handmocap.app.gui.batch_panel import BatchPanel

        if self.session is not None:
            BatchPanel(self.app, self.host).show()

    # ----------------------------------------------------------------------------------- takes
    def add_takes(self, paths: list[str], rates: dict[Path, float] | None = None) -> None:
        """Read the take files on the loader thread (at ``rates[path]`` Hz when given), then add them to the
        session; the rate of a file that states none is asked, and kept in the session."""
        if self.session is None:
            if not self.app.documents and not paths:
                return
            self.error_raised.emit("No session", "create or open a session first (File ▸ New session…)")
            return

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> LoadedTakes:
            loaded, failures, rate_needed = [], [], []
            for number, path in enumerate(paths):
                try:
                    loaded.append((Path(path), load_take(path, frame_rate=(rates or {}).get(Path(path)))))
                except FrameRateMissingError:
                    rate_needed.append(Path(path))
                except HandMocapError as error:
                    failures.append(f"{Path(path).name}: {error}")
                progress((number + 1) / len(paths))
            return LoadedTakes(loaded, failures, rate_needed)

        self.loads.queue("Adding takes…", task, self._takes_loaded)

    def _takes_loaded(self, loaded: LoadedTakes) -> None:
        takes, failures = loaded.takes, list(loaded.failures)
        for path, take in takes:
            try:
                self.app.add_take(path, take)
            except HandMocapError as error:
                failures.append(f"{path.name}: {error}")
        if failures:
            self.error_raised.emit("Some takes were not added", "\n".join(failures))
        if loaded.rate_needed:
            QTimer.singleShot(0, lambda: self._add_at_asked_rates(loaded.rate_needed))

    def _add_at_asked_rates(self, paths: list[Path]) -> None:
        """Ask the frame rate of each file in ``paths`` (they state none), then add those given one."""
        rates = {}
        for path in paths:
            rate = self.rate_prompt.ask(path)
            if rate is None:
                self.status_message.emit(f"{path.name} not added: it states no frame rate", 15000)
            else:
                rates[path] = rate
        if rates:
            self.add_takes([str(path) for path in rates], rates)

    def open_take(self, take_id: str, automatic: bool = False) -> None:
        """Open a session take for review (switch to it when it is open already). ``automatic``: then
        solve a labelled take with IK, or auto-label a raw one that was never labelled (the demo)."""
        if self.session is None:
            return
        document = self.app.document_of_session_take(take_id)
        if document is not None:
            if document is not self.app.document:
                self.app.show(document)
            return
        session = self.session

        def task(progress: Callable[[float], None], cancelled: Callable[[], bool]) -> OpenTake:
            return session.open_take(take_id)

        self.loads.queue("Opening take…", task, lambda opened: self._take_opened(opened, automatic))

    def _take_opened(self, opened: OpenTake, automatic: bool = False) -> None:
        entry = opened.entry
        automatic = automatic and not opened.read_only
        title = f"{entry.name} (read-only)" if opened.read_only else entry.name
        document = TakeDocument(take=opened.review.take, title=title, layout_name=entry.layout,
                                open_take=opened, session_take_id=entry.id,
                                auto_solve=automatic and entry.labelled_source)
        if self.session is not None and entry.subject:
            try:
                model = self.session.load_subject_model(entry.subject)
            except HandMocapError:
                model = None
            if model is not None:
                document.hand_models[model.side] = model
        self._load_take_models(document)
        self.app.open_document(document)
        self.app.show(document)
        if automatic and not entry.labelled_source and not opened.review.n_labels:
            self.auto_label_requested.emit(AutoLabelSettings(layout=entry.layout or "dense",
                                                             hands="both" if len(entry.hands) > 1
                                                             else entry.hands[0]), document)
        if opened.warnings:
            self.status_message.emit(f"{entry.name}: {opened.warnings[0]}"
                                     + (f" (and {len(opened.warnings) - 1} more)" if len(opened.warnings) > 1 else ""),
                                     0)
        if opened.replayed or opened.warnings:
            lines = [f"recovered {opened.replayed} edits from the journal"] if opened.replayed else []
            self.error_raised.emit("Take recovered", "\n".join(lines + opened.warnings))

    def _load_take_models(self, document: TakeDocument) -> None:
        """The hand models, markers and subject calibrations auto-label kept in the take's folder."""
        assert document.open_take is not None, "the take is open in a session"
        folder = document.open_take.folder
        for side in ("right", "left"):
            path = folder / TAKE_MODEL_NAME.format(side=side)
            markers = folder / TAKE_MARKERS_NAME.format(side=side)
            subject = folder / TAKE_SUBJECT_NAME.format(side=side)
            if path.exists():
                try:
                    document.hand_models[side] = HandModel.load(path)
                    if markers.exists():
                        document.marker_sets[side] = read_marker_set(markers)
                    if subject.exists():
                        document.subjects[side] = SubjectCalibration.from_dict(json.loads(subject.read_text()))
                except (HandMocapError, OSError, ValueError, KeyError):
                    self.status_message.emit(f"{path.name} is damaged; the template is used", 10000)
                    document.hand_models.pop(side, None)

    def _loose_take_opened(self, document: TakeDocument) -> None:
        """A file opened outside a session: the models kept with its review, what recovery found, or why its
        edits will not be kept (what became of its review is told when it is first shown)."""
        loose = document.loose
        assert loose is not None, "a loose take"      # (the caller checked)
        if loose.opened is None:
            self.status_message.emit(f"{loose.source.name}: {loose.warning}", 0)
            self.error_raised.emit("Edits will not be kept", f"{loose.source.name}: {loose.warning}")
            return
        self._load_take_models(document)
        if loose.opened.warnings:
            self.error_raised.emit("Take recovered", "\n".join(loose.opened.warnings))

    def keep_labelling(self, document: TakeDocument, models: dict[str, HandModel],
                       marker_sets: dict[str, MarkerSet]) -> None:
        """Auto-label was applied to ``document``: keep the hand models and markers it calibrated, and save a
        session take now (it is labelled)."""
        self.save_take_models(document, models, marker_sets)
        self.save_document(document)

    def save_take_models(self, document: TakeDocument, models: dict[str, HandModel],
                         marker_sets: dict[str, MarkerSet] | None = None) -> None:
        """Keep the hand models the labelling calibrated to this take's subject, and their calibrated
        markers, in the take's folder, so that drawing, solves and re-solves use them when the take is
        opened again."""
        if document.open_take is None or document.open_take.read_only:
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
            self.status_message.emit(f"Cannot keep the calibrated hand model: {error}", 10000)

    def set_state(self, take_id: str, state: str) -> None:
        try:
            self.app.set_take_state(take_id, state)
        except HandMocapError as error:
            self.error_raised.emit("Cannot change the state", str(error))

    def remove_take(self, take_id: str) -> None:
        if self.app.document_of_session_take(take_id) is not None:
            self.error_raised.emit("Cannot remove", "close the take first")
            return
        try:
            self.app.remove_take(take_id)
        except HandMocapError as error:
            self.error_raised.emit("Cannot remove the take", str(error))

    # ---------------------------------------------------------------------------------- saving
    def save_document(self, document: TakeDocument) -> None:
        """Write the snapshot of a take kept in a session now (after auto-label, before export)."""
        if document.open_take is None or document.open_take.read_only:
            return
        try:
            self.app.save_document(document)
        except HandMocapError as error:
            self.error_raised.emit("Cannot save", str(error))

    def autosave(self) -> None:
        """Snapshot the session takes with edits older than ``SNAPSHOT_INTERVAL_S`` (the journal has them
        already; the snapshot keeps replay short)."""
        for problem in self.app.autosave(SNAPSHOT_INTERVAL_S):
            self.status_message.emit(f"Autosave failed: {problem}", 10000)

    def export_done(self, document: TakeDocument, kind: str, path: str) -> None:
        if document.session_take_id and self.session is not None and not self.session.read_only:
            try:
                self.app.record_export(document.session_take_id, kind, path)
            except HandMocapError as error:
                self.error_raised.emit("Cannot record the export", str(error))

    def save_layout(self, layout) -> None:
        """Store a layout in the session: it is listed with the shipped ones and labelling can use it."""
        if self.session is None:
            raise HandMocapError("open or create a session first to keep layouts in it")
        self.app.save_layout(layout)

    def close(self) -> None:
        """The window is closing: save every open take and release the journals."""
        self.autosave_timer.stop()
        for document in self.app.documents:
            if document.open_take is not None and not document.open_take.closed:
                try:
                    document.open_take.close(save=True)
                except HandMocapError as error:
                    self.status_message.emit(f"Cannot save {document.title}: {error}", 0)
        if self.session is not None:
            self.session.close()
