"""A session: a folder with a JSON manifest, subject models, layouts and per-take review results.

Folder layout::

    session.json          manifest (below); replaced atomically; the previous one kept as session.json.bak
    models/<subject>.npz  calibrated subject hand models (HandModel.save)
    layouts/<name>.json   marker layouts used by the session (save_layout)
    takes/<take id>/      review.npz (snapshot), journal.jsonl + blobs/ (edits since), lock (pid@host of
                          the process editing it; a lock of a dead process is taken over)

Raw takes are referenced, not copied (they are large and the lab keeps them in its own store): the
manifest keeps the absolute path, and also the path relative to the session folder, tried first, so a
session moved together with its data still finds them. Results live inside the session.

Manifest (``format`` "handmocap-session", ``version`` 1)::

    {"format": ..., "version": 1, "name": str, "created": iso, "modified": iso,
     "subjects": [{"name", "model": "models/x.npz" | null, "notes"}],
     "layouts": [{"name", "path": "layouts/x.json"}],
     "takes": [{"id", "name", "source", "source_relative", "subject", "layout", "hands": ["right"],
                "labelled_source": bool, "state": "raw|labelled|reviewed|exported",
                "frames", "points", "frame_rate", "added", "results": {"review": "takes/<id>/review.npz"},
                "exports": {"c3d": path, ...}}]}

A corrupt manifest is never overwritten: :meth:`Session.open` raises an InputError naming it and the
``.bak`` copy; :meth:`Session.restore_backup` puts the backup back (keeping the damaged file aside).
A read-only folder raises an InputError on open unless ``read_only=True`` (then nothing is written:
edits stay in memory and saving raises an InputError).
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import socket
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from core.errors import InputError
from core.io import Take, load_take, looks_unlabelled
from core.io.durable import write_atomic
from core.model import HandModel, MarkerLayout, best_layout_for, load_layout, marker_columns
from core.review.commands import Command, FrameSpan, UndoStack
from core.review.take import HandTrack, ReviewTake
from core.session.journal import Journal
from core.session.storage import load_snapshot, snapshot_bytes

MANIFEST_NAME = "session.json"
BACKUP_SUFFIX = ".bak"
SESSION_FORMAT = "handmocap-session"
SESSION_VERSION = 1
TAKE_STATES = ("raw", "labelled", "reviewed", "exported")
SNAPSHOT_NAME = "review.npz"
LOCK_NAME = "lock"
AUTOSAVE_SECONDS = 60.0


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


def _safe_name(name: str) -> str:
    """A file-name-safe version of ``name`` (letters, digits, ``-``, ``_``, ``.``)."""
    cleaned = re.sub(r"[^A-Za-z0-9._-]+", "_", name.strip()).strip("._")
    return cleaned or "unnamed"


@dataclass
class SubjectEntry:
    """A subject of the session; ``model``: session-relative path of its calibrated model, or None."""

    name: str
    model: str | None = None
    notes: str = ""


@dataclass
class LayoutEntry:
    """A marker layout stored in the session (``path`` relative to the session folder)."""

    name: str
    path: str


@dataclass
class TakeEntry:
    """One take of the session (manifest fields in the module docstring)."""

    id: str
    name: str
    source: str
    source_relative: str | None = None
    subject: str | None = None
    layout: str | None = None
    hands: list[str] = field(default_factory=lambda: ["right"])
    labelled_source: bool = False
    state: str = "raw"
    frames: int = 0
    points: int = 0
    frame_rate: float = 0.0
    added: str = ""
    results: dict[str, str] = field(default_factory=dict)
    exports: dict[str, str] = field(default_factory=dict)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TakeEntry:
        known = {name: data[name] for name in cls.__dataclass_fields__ if name in data}
        entry = cls(**known)
        if entry.state not in TAKE_STATES:
            raise ValueError(f"take '{entry.name}' has unknown state '{entry.state}'")
        return entry


class Session:
    """A session folder (module docstring). Create with :meth:`create`, open with :meth:`open`."""

    def __init__(self, folder: Path, manifest: dict[str, Any], read_only: bool = False) -> None:
        self.folder = folder
        self.read_only = read_only
        self.name: str = str(manifest.get("name", folder.name))
        self.created: str = str(manifest.get("created", ""))
        self.modified: str = str(manifest.get("modified", ""))
        try:
            self.subjects = [SubjectEntry(**item) for item in manifest.get("subjects", [])]
            self.layouts = [LayoutEntry(**item) for item in manifest.get("layouts", [])]
            self.takes = [TakeEntry.from_json(item) for item in manifest.get("takes", [])]
        except (TypeError, ValueError) as error:
            raise InputError(f"{folder / MANIFEST_NAME}: damaged session manifest ({error}); it was left as it is"
                             ) from None
        self._open_takes: dict[str, OpenTake] = {}

    # --- creating and opening -----------------------------------------------------------------------

    @classmethod
    def create(cls, folder: str | os.PathLike[str], name: str | None = None) -> Session:
        """A new empty session in ``folder`` (created if needed; must not hold a session already)."""
        folder = Path(folder).expanduser().absolute()
        if (folder / MANIFEST_NAME).exists():
            raise InputError(f"{folder} already holds a session; open it instead")
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(f"cannot create the session folder {folder} ({error.strerror or error})") from None
        _check_writable(folder)
        now = _now()
        session = cls(folder, {"name": name or folder.name, "created": now, "modified": now})
        session.save()
        return session

    @classmethod
    def open(cls, folder: str | os.PathLike[str], read_only: bool = False) -> Session:
        """Open the session in ``folder``. InputError (one line) when there is none, the manifest is
        damaged (left untouched; see :meth:`restore_backup`) or the folder is read-only and
        ``read_only`` is False."""
        folder = Path(folder).expanduser().absolute()
        path = folder / MANIFEST_NAME
        if not folder.is_dir():
            raise InputError(f"session folder {folder} does not exist")
        if not path.exists():
            raise InputError(f"{folder} is not a session folder (no {MANIFEST_NAME})")
        try:
            manifest = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(manifest, dict) or manifest.get("format") != SESSION_FORMAT:
                raise ValueError("not a Hand Mocap Studio session manifest")
        except (OSError, UnicodeDecodeError, ValueError) as error:
            backup = path.with_name(MANIFEST_NAME + BACKUP_SUFFIX)
            hint = (f"; the previous manifest is in {backup.name} (Session.restore_backup puts it back)"
                    if backup.exists() else "")
            raise InputError(f"{path} is damaged ({str(error).splitlines()[0][:80]}); it was left untouched{hint}"
                             ) from None
        if int(manifest.get("version", 0)) > SESSION_VERSION:
            raise InputError(f"{path} was written by a newer Hand Mocap Studio (version {manifest.get('version')})")
        if not read_only:
            _check_writable(folder)
            _remove_temporaries(folder)
        return cls(folder, manifest, read_only=read_only)

    @staticmethod
    def restore_backup(folder: str | os.PathLike[str]) -> Path:
        """Put ``session.json.bak`` back as the manifest; the damaged manifest is kept as
        ``session.json.damaged-<time>``. Returns the manifest path."""
        folder = Path(folder).expanduser().absolute()
        path = folder / MANIFEST_NAME
        backup = path.with_name(MANIFEST_NAME + BACKUP_SUFFIX)
        if not backup.exists():
            raise InputError(f"{folder} has no {backup.name} to restore")
        try:
            json.loads(backup.read_text(encoding="utf-8"))
            if path.exists():
                shutil.copy2(path, path.with_name(f"{MANIFEST_NAME}.damaged-{time.strftime('%Y%m%d-%H%M%S')}"))
            write_atomic(path, backup.read_bytes())
        except (OSError, ValueError) as error:
            raise InputError(f"cannot restore {backup} ({error})") from None
        return path

    # --- manifest -----------------------------------------------------------------------------------

    @property
    def manifest_path(self) -> Path:
        return self.folder / MANIFEST_NAME

    def to_json(self) -> dict[str, Any]:
        return {"format": SESSION_FORMAT, "version": SESSION_VERSION, "name": self.name, "created": self.created,
                "modified": self.modified, "subjects": [asdict(s) for s in self.subjects],
                "layouts": [asdict(layout) for layout in self.layouts], "takes": [asdict(t) for t in self.takes]}

    def save(self) -> None:
        """Write the manifest atomically; the manifest it replaces is kept as ``session.json.bak``
        (only when it was valid: a damaged manifest never replaces a good backup)."""
        self._check_writable_session()
        self.modified = _now()
        data = json.dumps(self.to_json(), indent=2).encode("utf-8")
        path = self.manifest_path
        try:
            if path.exists():
                previous = path.read_bytes()
                try:
                    json.loads(previous)
                    write_atomic(path.with_name(MANIFEST_NAME + BACKUP_SUFFIX), previous)
                except ValueError:
                    pass
            write_atomic(path, data)
        except OSError as error:
            raise InputError(f"cannot save the session manifest {path} ({error.strerror or error})") from None

    def _check_writable_session(self) -> None:
        if self.read_only:
            raise InputError(f"session {self.folder} is open read-only; nothing can be saved")

    # --- takes --------------------------------------------------------------------------------------

    def take(self, take_id: str) -> TakeEntry:
        """The take with id (or, failing that, name) ``take_id``; InputError when unknown."""
        for entry in self.takes:
            if entry.id == take_id:
                return entry
        for entry in self.takes:
            if entry.name == take_id:
                return entry
        raise InputError(f"no take '{take_id}' in session {self.name}")

    def add_take(self, path: str | os.PathLike[str], subject: str | None = None, layout: str | None = None,
                 hands: list[str] | tuple[str, ...] = ("right",), name: str | None = None,
                 labelled: bool | None = None, take: Take | None = None) -> TakeEntry:
        """Add the raw take file ``path`` (read once to check it and record its size; pass ``take`` if it
        is already loaded). ``labelled``: whether its columns are labelled markers (default: guessed:
        a labelled C3D from this program, names matching a shipped layout, or names that are not
        placeholders such as ``*12``, ``point_004``, ``Unlabeled 3``)."""
        self._check_writable_session()
        source = Path(path).expanduser().absolute()
        if take is None:
            take = load_take(source)
        for hand in hands:
            if hand not in ("right", "left"):
                raise InputError(f"hand must be 'right' or 'left', not '{hand}'")
        if subject is not None and subject not in [s.name for s in self.subjects]:
            self.subjects.append(SubjectEntry(subject))
        if labelled is None:
            labelled = _looks_labelled(take)
        existing = {entry.id for entry in self.takes}
        number = len(self.takes) + 1
        while f"t{number:04d}" in existing:
            number += 1
        base = name or source.stem
        names = {entry.name for entry in self.takes}
        unique, copy = base, 1
        while unique in names:
            copy += 1
            unique = f"{base} ({copy})"
        entry = TakeEntry(id=f"t{number:04d}", name=unique, source=str(source),
                          source_relative=_relative(source, self.folder), subject=subject, layout=layout,
                          hands=list(hands), labelled_source=bool(labelled), state="labelled" if labelled else "raw",
                          frames=take.n_frames,
                          points=take.n_markers, frame_rate=take.frame_rate, added=_now())
        self.takes.append(entry)
        try:
            self.save()
        except InputError:
            self.takes.remove(entry)
            raise
        return entry

    def update_take(self, take_id: str, *, name: str | None = None, subject: str | None = None,
                    layout: str | None = None, hands: list[str] | None = None) -> TakeEntry:
        """Change a take's name, subject, layout or hands (arguments left None are kept)."""
        self._check_writable_session()
        entry = self.take(take_id)
        if hands is not None and (not hands or any(hand not in ("right", "left") for hand in hands)):
            raise InputError(f"hands must be 'right' and/or 'left', not {hands}")
        if name is not None:
            if not name.strip() or any(other.name == name for other in self.takes if other is not entry):
                raise InputError(f"take name '{name}' is empty or already used")
            entry.name = name.strip()
        if subject is not None:
            entry.subject = subject
            if subject not in [item.name for item in self.subjects]:
                self.subjects.append(SubjectEntry(subject))
        if layout is not None:
            entry.layout = layout
        if hands is not None:
            entry.hands = list(hands)
        self.save()
        return entry

    def remove_take(self, take_id: str) -> None:
        """Remove a take from the manifest; its result folder is kept, renamed ``takes/<id>.removed-<time>``."""
        self._check_writable_session()
        entry = self.take(take_id)
        if entry.id in self._open_takes:
            raise InputError(f"close take '{entry.name}' before removing it")
        folder = self.take_folder(entry.id)
        if folder.exists():
            try:
                folder.rename(folder.with_name(f"{entry.id}.removed-{time.strftime('%Y%m%d-%H%M%S')}"))
            except OSError as error:
                raise InputError(f"cannot remove take '{entry.name}' ({error.strerror or error})") from None
        self.takes.remove(entry)
        self.save()

    def source_path(self, take_id: str) -> Path:
        """The raw file of a take: the session-relative path if it exists, else the absolute one.
        InputError when neither exists (moved or deleted)."""
        entry = self.take(take_id)
        if entry.source_relative is not None:
            relative = (self.folder / entry.source_relative).resolve()
            if relative.exists():
                return relative
        absolute = Path(entry.source)
        if absolute.exists():
            return absolute
        raise InputError(f"the raw file of take '{entry.name}' is missing: {entry.source} (relink it)")

    def relink_take(self, take_id: str, path: str | os.PathLike[str]) -> TakeEntry:
        """Point a take at a moved raw file (must have the same frames and points)."""
        self._check_writable_session()
        entry = self.take(take_id)
        source = Path(path).expanduser().absolute()
        take = load_take(source)
        if (take.n_frames, take.n_markers) != (entry.frames, entry.points):
            raise InputError(f"{source.name} has {take.n_frames} frames and {take.n_markers} points; take "
                             f"'{entry.name}' had {entry.frames} and {entry.points}")
        entry.source, entry.source_relative = str(source), _relative(source, self.folder)
        self.save()
        return entry

    def take_folder(self, take_id: str) -> Path:
        """Result folder of a take (``takes/<id>``; not created here)."""
        return self.folder / "takes" / _safe_name(take_id)

    def set_state(self, take_id: str, state: str) -> None:
        """Set a take's state: "raw", "labelled", "reviewed" or "exported"."""
        if state not in TAKE_STATES:
            raise InputError(f"unknown take state '{state}' (use {', '.join(TAKE_STATES)})")
        self._check_writable_session()
        entry = self.take(take_id)
        entry.state = state
        self.save()

    def record_export(self, take_id: str, kind: str, path: str | os.PathLike[str]) -> None:
        """Remember an export (``kind`` e.g. "c3d", "csv", "bvh") and mark the take exported."""
        self._check_writable_session()
        entry = self.take(take_id)
        entry.exports[kind] = str(Path(path).absolute())
        entry.state = "exported"
        self.save()

    def open_take(self, take_id: str, loader: Callable[[Path], Take] = load_take,
                  label_names: list[str] | None = None) -> OpenTake:
        """Open a take for review: its raw file, its last snapshot and the journal replayed on top.

        A take never reviewed starts as :meth:`ReviewTake.from_labelled_take` when its source is labelled
        (with an unsolved hand per entry hand when every marker of the entry's layout is a column), else
        :meth:`ReviewTake.unlabelled` (with ``label_names`` if given; auto-label fills it). Opening the
        same take twice returns the same :class:`OpenTake`.
        """
        entry = self.take(take_id)
        if entry.id in self._open_takes and not self._open_takes[entry.id].closed:
            return self._open_takes[entry.id]
        take = loader(self.source_path(entry.id))
        if (take.n_frames, take.n_markers) != (entry.frames, entry.points) and entry.frames:
            raise InputError(f"the raw file of take '{entry.name}' changed: {take.n_frames} frames and "
                             f"{take.n_markers} points now, {entry.frames} and {entry.points} when added")
        opened = OpenTake(self, entry, take, label_names)
        self._open_takes[entry.id] = opened
        return opened

    # --- subjects, models, layouts ------------------------------------------------------------------

    def save_layout(self, layout: MarkerLayout) -> Path:
        """Store ``layout`` as ``layouts/<name>.json`` (replacing one of the same name)."""
        from core.model import save_layout

        self._check_writable_session()
        folder = self.folder / "layouts"
        path = folder / f"{_safe_name(layout.name)}.json"
        try:
            folder.mkdir(exist_ok=True)
            save_layout(layout, path)
        except OSError as error:
            raise InputError(f"cannot save layout '{layout.name}' ({error.strerror or error})") from None
        relative = str(path.relative_to(self.folder))
        self.layouts = [item for item in self.layouts if item.name != layout.name] + [LayoutEntry(layout.name,
                                                                                                  relative)]
        self.save()
        return path

    def layout_path(self, name: str) -> Path | None:
        """Path of a session layout by name, None when the session has none of that name."""
        for item in self.layouts:
            if item.name == name:
                return self.folder / item.path
        return None

    def save_subject_model(self, subject: str, model: HandModel) -> Path:
        """Store a subject's calibrated hand model as ``models/<subject>.npz`` and link it."""
        self._check_writable_session()
        folder = self.folder / "models"
        path = folder / f"{_safe_name(subject)}.npz"
        try:
            folder.mkdir(exist_ok=True)
            model.save(path)
        except OSError as error:
            raise InputError(f"cannot save the model of '{subject}' ({error.strerror or error})") from None
        relative = str(path.relative_to(self.folder))
        for item in self.subjects:
            if item.name == subject:
                item.model = relative
                break
        else:
            self.subjects.append(SubjectEntry(subject, relative))
        self.save()
        return path

    def load_subject_model(self, subject: str) -> HandModel:
        """The calibrated model of ``subject``; InputError when it has none."""
        for item in self.subjects:
            if item.name == subject and item.model:
                return HandModel.load(self.folder / item.model)
        raise InputError(f"subject '{subject}' has no calibrated model in this session")

    def close(self) -> None:
        """Save and close every open take."""
        for opened in list(self._open_takes.values()):
            if not opened.closed:
                opened.close()
        self._open_takes.clear()


class OpenTake:
    """A take opened for review: ``review`` (:class:`ReviewTake`), ``stack`` (:class:`UndoStack`) whose
    operations are journalled, and the session entry. Edit only through :meth:`push`, :meth:`attach`,
    :meth:`undo`, :meth:`redo`. ``warnings``: what recovery found on open (one line each);
    ``replayed``: journal entries applied on open (edits recovered after a crash).

    Undo and redo restore the solved joint angles and residuals too, so only :meth:`push` needs a
    re-solve (attach its :class:`~core.review.commands.SetSolve` result with :meth:`attach`, after
    checking ``review.version`` did not change meanwhile).
    """

    def __init__(self, session: Session, entry: TakeEntry, take: Take, label_names: list[str] | None = None) -> None:
        self.session, self.entry = session, entry
        self.folder = session.take_folder(entry.id)
        self.warnings: list[str] = []
        self.replayed = 0
        self.closed = False
        self._last_save = time.monotonic()
        snapshot = self.folder / SNAPSHOT_NAME
        next_seq = 1
        commands: list[Command] = []
        history: dict[str, Any] = {}
        if snapshot.exists():
            review, meta, commands = load_snapshot(snapshot, take)
            next_seq = int(meta.get("journal_seq", 0)) + 1
            history = meta.get("history", {})
        elif entry.labelled_source:
            review = ReviewTake.from_labelled_take(take, hands=_layout_hands(take, entry, session))
        else:
            review = ReviewTake.unlabelled(take, label_names)
        self.review = review
        self.stack = UndoStack(review)
        if commands:
            self.stack.restore_history(commands, int(history.get("index", len(commands))),
                                       history.get("clean_index"))
        self.journal: Journal | None = None
        if session.read_only:
            return
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(f"cannot create {self.folder} ({error.strerror or error})") from None
        _acquire_lock(self.folder / LOCK_NAME, entry.name)
        _remove_temporaries(self.folder, self.folder / "blobs")
        journal = Journal(self.folder, next_seq)
        self.replayed, warnings = journal.replay(self.stack, after_seq=next_seq - 1)
        self.warnings.extend(warnings)
        self.journal = journal
        self.stack.recorder = journal.record
        if warnings:
            self.save()  # keep what was recovered; the damaged journal was set aside

    # --- editing ------------------------------------------------------------------------------------

    def push(self, command: Command) -> FrameSpan:
        """Do ``command`` (undoable, journalled); returns the frames to re-solve."""
        self._check_open()
        return self.stack.push(command)

    def attach(self, command: Command) -> FrameSpan:
        """Do ``command`` as part of the last step (e.g. the re-solve after an edit)."""
        self._check_open()
        return self.stack.attach(command)

    def undo(self) -> FrameSpan:
        self._check_open()
        return self.stack.undo()

    def redo(self) -> FrameSpan:
        self._check_open()
        return self.stack.redo()

    def _check_open(self) -> None:
        if self.closed:
            raise InputError(f"take '{self.entry.name}' is closed")

    # --- saving -------------------------------------------------------------------------------------

    @property
    def snapshot_path(self) -> Path:
        return self.folder / SNAPSHOT_NAME

    def is_modified(self) -> bool:
        """True when there are edits since the last save (they are journalled either way)."""
        return not self.stack.is_clean()

    def save(self) -> None:
        """Write the snapshot (state + undo history) atomically, restart the journal and update the take's
        state in the manifest (a raw take with labels becomes "labelled")."""
        self._check_open()
        if self.journal is None:
            raise InputError(f"session {self.session.folder} is open read-only; take '{self.entry.name}' "
                             "cannot be saved")
        seq = self.journal.next_seq - 1
        try:
            write_atomic(self.snapshot_path, snapshot_bytes(self.review, self.stack, seq))
            self.journal.restart()
        except OSError as error:
            raise InputError(f"cannot save take '{self.entry.name}' ({error.strerror or error}); "
                             "the edits are still in the journal") from None
        self._last_save = time.monotonic()
        self.stack.set_clean()
        relative = str(self.snapshot_path.relative_to(self.session.folder))
        changed = self.entry.results.get("review") != relative
        self.entry.results["review"] = relative
        if self.entry.state == "raw" and (self.review.assignment >= 0).any() and not self.entry.labelled_source:
            self.entry.state = "labelled"
            changed = True
        if changed:
            self.session.save()

    def autosave_due(self, interval_s: float = AUTOSAVE_SECONDS) -> bool:
        """True when there are unsaved edits and the last save is older than ``interval_s``."""
        return self.is_modified() and time.monotonic() - self._last_save >= interval_s

    def autosave(self, interval_s: float = AUTOSAVE_SECONDS) -> bool:
        """Save if :meth:`autosave_due`; returns whether it saved."""
        if self.journal is not None and self.autosave_due(interval_s):
            self.save()
            return True
        return False

    def close(self, save: bool = True) -> None:
        """Save (when writable and modified) and release the journal. Without ``save`` the edits stay
        in the journal and come back on the next open."""
        if self.closed:
            return
        if save and self.journal is not None and (self.is_modified() or self.replayed):
            self.save()
        if self.journal is not None:
            self.journal.close()
            (self.folder / LOCK_NAME).unlink(missing_ok=True)
        self.closed = True


def _looks_labelled(take: Take) -> bool:
    """Whether a take's columns are labelled markers rather than raw points (see :meth:`Session.add_take`)."""
    if "PROVENANCE" in take.parameters or best_layout_for(take.marker_names) is not None:
        return True
    return not looks_unlabelled(take.marker_names)


def _layout_hands(take: Take, entry: TakeEntry, session: Session) -> list[HandTrack]:
    """Hands of a labelled take at its first opening: for each of the entry's hands, a track when every
    marker of the entry's layout is a column (``R_``/``L_`` prefixed with two hands); unsolved."""
    if not entry.layout:
        return []
    try:
        layout = load_layout(session.layout_path(entry.layout) or entry.layout)
    except InputError:
        return []
    hands = []
    for side in entry.hands:
        prefix = {"right": "R_", "left": "L_"}[side] if len(entry.hands) > 1 else ""
        columns = marker_columns(take.marker_names, [prefix + name for name in layout.names])
        if len(columns) and (columns >= 0).all():
            hands.append(HandTrack(side, side, entry.layout, columns, np.full((take.n_frames, 26), np.nan)))
    return hands


def _relative(path: Path, folder: Path) -> str | None:
    """``path`` relative to ``folder`` (with ``..`` if needed), None on another drive."""
    try:
        return os.path.relpath(path, folder)
    except ValueError:
        return None


def _acquire_lock(path: Path, name: str) -> None:
    """Mark a take as being edited by this process (``pid@host`` in ``path``). InputError when another
    live process on this computer holds it; a lock left by a process that died is taken over."""
    host = socket.gethostname()
    try:
        holder = path.read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        holder = ""
    pid_text, _, holder_host = holder.partition("@")
    if pid_text.isdigit() and int(pid_text) != os.getpid():
        if holder_host != host:
            raise InputError(f"take '{name}' is open on computer {holder_host} (delete {path} if it is not)")
        try:
            os.kill(int(pid_text), 0)
            alive = True
        except ProcessLookupError:
            alive = False
        except PermissionError:
            alive = True
        if alive:
            raise InputError(f"take '{name}' is open in another Hand Mocap Studio (process {pid_text}; "
                             f"delete {path} if it is not)")
    try:
        write_atomic(path, f"{os.getpid()}@{host}".encode())
    except OSError as error:
        raise InputError(f"cannot open take '{name}' for editing ({error.strerror or error})") from None


def _remove_temporaries(*folders: Path) -> None:
    """Delete the temporary files (``.<name>.<hex>.tmp``) an interrupted atomic write left behind (older
    than a minute, so that a write in progress in another process is left alone)."""
    now = time.time()
    for folder in folders:
        if folder.is_dir():
            for path in folder.glob(".*.tmp"):
                try:
                    if now - path.stat().st_mtime > 60.0:
                        path.unlink()
                except OSError:
                    pass


def _check_writable(folder: Path) -> None:
    """InputError unless a file can be created in ``folder``."""
    probe = folder / f".write-test-{secrets.token_hex(4)}"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as error:
        raise InputError(f"session folder {folder} is not writable ({error.strerror or error}); "
                         "open it read-only or copy it somewhere writable") from None
