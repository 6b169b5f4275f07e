"""The application's state, without Qt: the open session, the open takes and the one shown, the
current frame, the operator's selection in it and the running jobs.

The window and the controllers change it through its methods; views hear what changed through
:meth:`Application.add_listener`. Besides its own events it passes on the
:class:`~core.review.events.ReviewChanged` events of the shown take's undo stack, so a view follows
every edit, undo, redo and solve of that take whoever made it; a whole-take IK solve kept on a take is
announced as :class:`SolveApplied`. Changes of the session folder made through it (takes added or removed,
a take's state, subjects, layouts) are announced as :class:`SessionFolderChanged`.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from handmocap.app.gui.document import TakeDocument
from handmocap.core.errors import HandMocapError
from handmocap.core.ik import IKResult
from handmocap.core.io import Take
from handmocap.core.model import HandModel, MarkerLayout, add_layout_folder, best_layout_for, remove_layout_folder
from handmocap.core.model.lab_template import LabTemplate
from handmocap.core.review.events import ReviewChanged
from handmocap.core.session import Session, TakeEntry


@dataclass
class Selection:
    """What the operator selected in the shown take: a label and the raw point column holding it (-1:
    none), the points picked for a rigid body, and the frame range marked with I and O (0-based
    frames, None: not marked)."""

    label: int = -1
    column: int = -1
    rigid_points: list[int] = field(default_factory=list)
    range_in: int | None = None
    range_out: int | None = None


@dataclass(frozen=True)
class Job:
    """Long work running on a worker: its ``kind`` (e.g. "solve", "auto-label"), the take it works on
    and how to ask it to stop."""

    kind: str
    document: TakeDocument | None
    cancel: Callable[[], None]


@dataclass(frozen=True)
class DocumentOpened:
    """A take was opened (it is not shown yet)."""

    document: TakeDocument


@dataclass(frozen=True)
class DocumentClosing:
    """A take is about to be closed: work on it stops now."""

    document: TakeDocument


@dataclass(frozen=True)
class DocumentClosed:
    """A take was closed (``index``: where it was in :attr:`Application.documents`); when it was the shown
    one, another is shown next."""

    document: TakeDocument
    index: int


@dataclass(frozen=True)
class CurrentDocumentChanged:
    """Another take is shown (None: none is open any more); ``previous``: the one shown before."""

    document: TakeDocument | None
    previous: TakeDocument | None


@dataclass(frozen=True)
class SelectionChanged:
    """The selection of the shown take changed (see :attr:`Application.selection`)."""


@dataclass(frozen=True)
class SessionChanged:
    """A session was opened, or closed (``session`` None)."""

    session: Session | None


class SessionPart(enum.Flag):
    """What of the open session folder changed (combined with ``|``)."""

    NONE = 0
    TAKES = enum.auto()       #: takes were added or removed
    TAKE_STATE = enum.auto()  #: a take's state, its saved review or its exports
    SUBJECTS = enum.auto()    #: subjects and their calibrated hand models
    LAYOUTS = enum.auto()     #: the session's marker layouts


@dataclass(frozen=True)
class SessionFolderChanged:
    """The open session's folder changed: ``what``, and the one take it is about (``take_id``, "" when
    it is about no take or several)."""

    what: SessionPart
    take_id: str = ""


@dataclass(frozen=True)
class FrameChanged:
    """Another frame of the shown take is current (0-based, see :attr:`Application.frame`)."""

    frame: int


@dataclass(frozen=True)
class SolveApplied:
    """A whole-take IK solve of ``document`` was kept (see :meth:`Application.apply_solve`)."""

    document: TakeDocument


@dataclass(frozen=True)
class JobsChanged:
    """A job started or ended (see :attr:`Application.jobs`)."""


Event = (DocumentOpened | DocumentClosing | DocumentClosed | CurrentDocumentChanged | FrameChanged
         | SelectionChanged | SessionChanged | SessionFolderChanged | SolveApplied | JobsChanged | ReviewChanged)
Listener = Callable[[Event], None]


class Application:
    """The state the window shows (module docstring). Listeners are called in the order they were
    added, on the thread that made the change (the GUI thread)."""

    def __init__(self) -> None:
        self.session: Session | None = None
        self.documents: list[TakeDocument] = []
        self.document: TakeDocument | None = None
        self.frame = 0                              # current frame of the shown take (0-based)
        self.selection = Selection()
        self.jobs: dict[str, Job] = {}
        self._listeners: list[Listener] = []

    # ---------------------------------------------------------------------------------- listening
    def add_listener(self, callback: Listener) -> None:
        """``callback(event)`` after every change."""
        self._listeners.append(callback)

    def remove_listener(self, callback: Listener) -> None:
        if callback in self._listeners:
            self._listeners.remove(callback)

    def _announce(self, event: Event) -> None:
        for callback in list(self._listeners):
            callback(event)

    # ----------------------------------------------------------------------------------- takes
    def open_document(self, document: TakeDocument) -> None:
        """Add an opened take to :attr:`documents` (:meth:`show` shows it)."""
        self.documents.append(document)
        self._announce(DocumentOpened(document))

    def show(self, document: TakeDocument | None) -> None:
        """Show ``document`` (one of :attr:`documents`, or None) at the frame it was left at: its review is
        made if it has none, the selection starts empty, and the edits of its undo stack are passed on to
        the listeners."""
        previous = self.document
        if previous is not None:
            previous.current_frame = self.frame
            if previous.stack is not None:
                previous.stack.remove_listener(self._announce)
        self.document = document
        self.selection = Selection()
        self.frame = 0
        if document is not None:
            document.ensure_review()
            assert document.stack is not None, "made with the review"
            document.stack.add_listener(self._announce)
            self.frame = min(max(document.current_frame, 0), max(document.take.n_frames - 1, 0))
        self._announce(CurrentDocumentChanged(document, previous))

    def close_document(self, document: TakeDocument) -> str | None:
        """Close an open take: listeners stop its work, a take kept in a session (the open one's, or a file's
        automatic one) is saved, the next open take is shown (none when it was the last). Returns why the
        save failed (None when it did not)."""
        self._announce(DocumentClosing(document))
        problem, saved = None, False
        if document.open_take is not None and not document.open_take.closed:
            try:
                document.open_take.close(save=True)
                saved = True
            except HandMocapError as error:
                problem = f"{document.title}: {error}; the edits stay in its journal"
        index = self.documents.index(document)
        self.documents.pop(index)
        self._announce(DocumentClosed(document, index))
        if self.document is document:
            self.show(self.documents[min(index, len(self.documents) - 1)] if self.documents else None)
        if saved and self.session is not None and document.session_take_id is not None:
            self._announce(SessionFolderChanged(SessionPart.TAKE_STATE, document.session_take_id))
        return problem

    def document_of_session_take(self, take_id: str) -> TakeDocument | None:
        """The open take that is session take ``take_id``, if it is open."""
        return next((document for document in self.documents if document.session_take_id == take_id), None)

    def document_of_file(self, path: str | Path) -> TakeDocument | None:
        """The open take of the file ``path`` opened outside a session, if it is open."""
        source = Path(path).expanduser().absolute()
        return next((document for document in self.documents
                     if document.loose is not None and document.loose.source == source), None)

    # ---------------------------------------------------------------------------------- frame
    def set_frame(self, frame: int) -> None:
        """Make ``frame`` (0-based, clamped to the shown take, to its trim range when it is trimmed) the
        current one."""
        low, high = 0, self.document.take.n_frames if self.document is not None else 1
        if self.document is not None and self.document.review is not None:
            low, high = self.document.review.frame_range()
        frame = min(max(int(frame), low), max(high - 1, low))
        if frame != self.frame:
            self.frame = frame
            self._announce(FrameChanged(frame))

    # ------------------------------------------------------------------------------- selection
    def select(self, label: int = -1, column: int = -1) -> None:
        """Select ``label`` and the point ``column`` holding it now (-1: none)."""
        self.selection.label, self.selection.column = label, column
        self._announce(SelectionChanged())

    def clear_selection(self) -> None:
        """Select nothing: no label or point, no rigid-body points, no marked range."""
        self.selection = Selection()
        self._announce(SelectionChanged())

    def toggle_rigid_point(self, column: int) -> None:
        """Add raw point ``column`` to the points of a new rigid body (or take it out again)."""
        points = self.selection.rigid_points
        if column in points:
            points.remove(column)
        else:
            points.append(column)
        self._announce(SelectionChanged())

    def clear_rigid_points(self) -> None:
        self.selection.rigid_points = []
        self._announce(SelectionChanged())

    def mark_range(self, range_in: int | None, range_out: int | None) -> None:
        """Mark frames ``range_in .. range_out`` (0-based, inclusive; None: that end is not marked)."""
        self.selection.range_in, self.selection.range_out = range_in, range_out
        self._announce(SelectionChanged())

    # --------------------------------------------------------------------------------- session
    def set_session(self, session: Session | None) -> None:
        """The open session (None: closed); its layouts are listed with the shipped ones while it is open."""
        if self.session is not None:
            remove_layout_folder(self.session.folder / "layouts")
        self.session = session
        if session is not None:
            add_layout_folder(session.folder / "layouts")
        self._announce(SessionChanged(session))

    def _open_session(self) -> Session:
        if self.session is None:
            raise HandMocapError("open or create a session first")
        return self.session

    def add_take(self, path: Path, take: Take) -> TakeEntry:
        """Add the take file ``path`` (read already: ``take``) to the session, with the layout its names fit."""
        entry = self._open_session().add_take(path, layout=best_layout_for(take.marker_names), take=take)
        self._announce(SessionFolderChanged(SessionPart.TAKES, entry.id))
        return entry

    def remove_take(self, take_id: str) -> None:
        """Remove a (closed) take from the session."""
        self._open_session().remove_take(take_id)
        self._announce(SessionFolderChanged(SessionPart.TAKES, take_id))

    def set_take_state(self, take_id: str, state: str) -> None:
        """Set a session take's state ("raw", "labelled", "reviewed", "exported")."""
        self._open_session().set_state(take_id, state)
        self._announce(SessionFolderChanged(SessionPart.TAKE_STATE, take_id))

    def record_export(self, take_id: str, kind: str, path: str) -> None:
        """Remember an export of a session take (it becomes "exported")."""
        self._open_session().record_export(take_id, kind, path)
        self._announce(SessionFolderChanged(SessionPart.TAKE_STATE, take_id))

    def take_processed(self, take_id: str) -> None:
        """A batch (its worker processes) changed a take of the session: read the manifest again and say so."""
        self._open_session().reload()
        self._announce(SessionFolderChanged(SessionPart.TAKE_STATE, take_id))

    def save_document(self, document: TakeDocument) -> None:
        """Write the snapshot of a take kept in a session (its own, for a file opened outside one) now (a raw
        take with labels becomes "labelled")."""
        assert document.open_take is not None, "a take kept in a session"
        document.open_take.save()
        if document.session_take_id is not None:
            self._announce(SessionFolderChanged(SessionPart.TAKE_STATE, document.session_take_id))

    def autosave(self, interval_s: float) -> list[str]:
        """Snapshot the open takes kept in sessions (the open one's and files' automatic ones) with edits older
        than ``interval_s`` seconds; one line per failure."""
        problems = []
        for document in self.documents:
            if document.open_take is None or document.open_take.closed:
                continue
            try:
                saved = document.open_take.autosave(interval_s)
            except HandMocapError as error:
                problems.append(str(error))
                continue
            if saved and document.session_take_id is not None:
                self._announce(SessionFolderChanged(SessionPart.TAKE_STATE, document.session_take_id))
        return problems

    def save_layout(self, layout: MarkerLayout | LabTemplate) -> Path:
        """Store a layout or a lab's labelling template in the session (listed with the shipped layouts,
        labelling can use it)."""
        path = self._open_session().save_layout(layout)
        self._announce(SessionFolderChanged(SessionPart.LAYOUTS))
        return path

    def save_subject_model(self, subject: str, model: HandModel) -> Path:
        """Store a subject's calibrated hand model in the session."""
        path = self._open_session().save_subject_model(subject, model)
        self._announce(SessionFolderChanged(SessionPart.SUBJECTS))
        return path

    # ----------------------------------------------------------------------------------- solves
    def apply_solve(self, document: TakeDocument, results: list[IKResult]) -> None:
        """Keep a whole-take IK solve (one result per hand) on ``document``: as its IK result, and in its review
        as one undoable step when the review has the labels (a :class:`ReviewChanged` when it is shown); then
        :class:`SolveApplied`."""
        document.set_result(results)
        document.record_solve(results)
        self._announce(SolveApplied(document))

    # ------------------------------------------------------------------------------------ jobs
    def job_started(self, name: str, job: Job) -> None:
        """``job`` runs on the worker called ``name`` (one job per worker)."""
        self.jobs[name] = job
        self._announce(JobsChanged())

    def job_ended(self, name: str) -> None:
        if self.jobs.pop(name, None) is not None:
            self._announce(JobsChanged())

    def is_busy(self) -> bool:
        """Whether a job is running."""
        return bool(self.jobs)
