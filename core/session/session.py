"""A session: a folder with a JSON manifest, subject models, layouts and per-take review results.

Folder layout::

    session.json          manifest (below); replaced atomically; the previous one kept as session.json.bak
    models/<subject>.npz  calibrated subject hand models (HandModel.save)
    layouts/<name>.json   marker layouts used by the session (save_layout)
    session.lock          OS lock held while the manifest is read, changed and written (core.session.lock)
    takes/<take id>/      review.npz + review-<seq>.npz (the last three snapshots), journal.jsonl,
                          journal-<seq>.jsonl + blobs/ (the edits since the oldest of them), lock (OS lock
                          of the process editing the take; it says who holds it), save.lock (held while
                          a save renames files, so that a read-only opening never sees them half-way)

Raw takes are referenced, not copied (they are large and the lab keeps them in its own store): the
manifest keeps the absolute path, and also the path relative to the session folder, tried first, so a
session moved together with its data still finds them. Results live inside the session.

Manifest (``format`` "handmocap-session", ``version`` 1)::

    {"format": ..., "version": 1, "name": str, "created": iso, "modified": iso,
     "subjects": [{"name", "model": "models/x.npz" | null, "notes"}],
     "layouts": [{"name", "path": "layouts/x.json"}],
     "takes": [{"id", "name", "source", "source_relative", "subject", "layout", "hands": ["right"],
                "labelled_source": bool, "state": "raw|labelled|reviewed|exported",
                "frames", "points", "frame_rate", "frame_rate_given", "added",
                "results": {"review": "takes/<id>/review.npz"}, "exports": {"c3d": path, ...},
                "cameras": [camera entry (core.session.cameras)]}]}

``frame_rate`` is the rate (Hz) the take is read at; ``frame_rate_given`` (false when absent) says the user
gave it (``--rate``, the open dialog, the pipeline's ``rate``: the file states none, or it was overridden),
so the raw file is read again at that rate without asking.

A corrupt manifest is never overwritten: :meth:`Session.open` raises an InputError naming it and the
``.bak`` copy; :meth:`Session.restore_backup` puts the backup back (keeping the damaged file aside).
A read-only folder raises an InputError on open unless ``read_only=True`` (then nothing is written:
takes open read-only). A take already open for editing elsewhere (another process, or another
:class:`Session` of the same folder) opens read-only too, saying who holds it; a read-only take refuses
edits with an InputError, so no acknowledged edit can be lost.

Every change of the manifest is a read-modify-write under ``session.lock``: the manifest on disk is
read again, the change applied and the result written, so processes working on different takes keep
each other's changes. Nothing in the folder is read, written or deleted through a symbolic link
(:mod:`core.session.files`).
"""

from __future__ import annotations

import json
import os
import re
import secrets
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io import Take, load_take, looks_unlabelled
from handmocap.core.model import HandModel, MarkerLayout, best_layout_for, detect_hands
from handmocap.core.model.lab_template import LabTemplate, save_lab_template
from handmocap.core.review.commands import Command, UndoStack
from handmocap.core.review.events import FrameSpan
from handmocap.core.review.take import HandTrack, ReviewTake
from handmocap.core.session.files import (
    make_folder,
    read_bytes,
    refuse_links,
    refuse_links_within,
    regular_files,
    remove_file,
    write_file,
)
from handmocap.core.session.journal import BLOB_FOLDER, Journal
from handmocap.core.session.lock import SESSION_LOCK_NAME, TAKE_LOCK_NAME, FileLock, manifest_lock
from handmocap.core.session.storage import (
    SNAPSHOT_NAME,
    SnapshotMismatch,
    keep_older,
    load_snapshot,
    prune_snapshots,
    read_snapshot_file,
    set_aside,
    snapshot_bytes,
    snapshot_files,
    strict_json,
)

MANIFEST_NAME = "session.json"
BACKUP_SUFFIX = ".bak"
SESSION_FORMAT = "handmocap-session"
SESSION_VERSION = 1
TAKE_STATES = ("raw", "labelled", "reviewed", "exported")
LOCK_NAME = TAKE_LOCK_NAME
SAVE_LOCK_NAME = "save.lock"  # held while a take's snapshot and journal files are being rotated
AUTOSAVE_SECONDS = 60.0
MANIFEST_LIMIT = 64 * 2**20  # bytes; a manifest of 100 000 takes is about 60 MB


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
    frame_rate_given: bool = False
    added: str = ""
    results: dict[str, str] = field(default_factory=dict)
    exports: dict[str, str] = field(default_factory=dict)
    cameras: list[dict[str, Any]] = field(default_factory=list)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TakeEntry:
        """The entry of a manifest item; TypeError or ValueError when a field has the wrong type."""
        if not isinstance(data, dict):
            raise TypeError("a take is not a JSON object")
        known = {name: data[name] for name in cls.__dataclass_fields__ if name in data}
        entry = cls(**known)
        for name, kinds in _TAKE_FIELD_TYPES.items():
            value = getattr(entry, name)
            if not isinstance(value, kinds) or (isinstance(value, bool) and kinds is not bool):
                raise TypeError(f"take field '{name}' has the wrong type")
        if not all(isinstance(hand, str) for hand in entry.hands):
            raise TypeError("take field 'hands' must list 'right' or 'left'")
        for mapping in (entry.results, entry.exports):
            if not all(isinstance(key, str) and isinstance(value, str) for key, value in mapping.items()):
                raise TypeError("take results and exports must map names to paths")
        if not all(isinstance(item, dict) and all(isinstance(item.get(key), str) for key in ("name", "camera", "media"))
                   for item in entry.cameras):
            raise TypeError("take cameras must each have a name, a camera file and a media path")
        if entry.state not in TAKE_STATES:
            raise ValueError(f"take '{entry.name}' has unknown state '{entry.state}'")
        return entry

    @property
    def given_frame_rate(self) -> float | None:
        """The rate (Hz) the user gave for the take, to read its raw file at; None: the file's own."""
        return self.frame_rate if self.frame_rate_given else None


_TAKE_FIELD_TYPES: dict[str, Any] = {
    "id": str, "name": str, "source": str, "source_relative": (str, type(None)), "subject": (str, type(None)),
    "layout": (str, type(None)), "hands": list, "labelled_source": bool, "state": str, "frames": int,
    "points": int, "frame_rate": (int, float), "frame_rate_given": bool,
    "added": str, "results": dict, "exports": dict,
    "cameras": list}


class Session:
    """A session folder (module docstring). Create with :meth:`create`, open with :meth:`open`."""

    def __init__(self, folder: Path, manifest: dict[str, Any], read_only: bool = False) -> None:
        self.folder = folder
        self.read_only = read_only
        self.subjects: list[SubjectEntry] = []
        self.layouts: list[LayoutEntry] = []
        self.takes: list[TakeEntry] = []
        self._apply(manifest)
        self._open_takes: dict[str, OpenTake] = {}

    def _apply(self, manifest: dict[str, Any]) -> None:
        """Take the manifest's contents; the entries of takes already known are updated in place (an
        :class:`OpenTake` keeps its entry). InputError when a field is malformed."""
        try:
            name, created, modified = (manifest.get(key, default) for key, default in
                                       (("name", self.folder.name), ("created", ""), ("modified", "")))
            subjects = [SubjectEntry(**item) for item in _list(manifest.get("subjects", []))]
            layouts = [LayoutEntry(**item) for item in _list(manifest.get("layouts", []))]
            takes = [TakeEntry.from_json(item) for item in _list(manifest.get("takes", []))]
            if not all(isinstance(text, str) for text in (name, created, modified)):
                raise TypeError("name and times must be text")
            if not all(isinstance(item.name, str) for item in subjects + layouts):
                raise TypeError("subject and layout names must be text")
        except (TypeError, ValueError) as error:
            raise InputError(f"{self.folder / MANIFEST_NAME}: damaged session manifest ({error}); it was left as "
                             "it is") from None
        self.name, self.created, self.modified = name, created, modified
        self.subjects, self.layouts = subjects, layouts
        known = {entry.id: entry for entry in self.takes}
        self.takes = []
        for fresh in takes:
            entry = known.get(fresh.id)
            if entry is None:
                self.takes.append(fresh)
            else:
                entry.__dict__.update(fresh.__dict__)
                self.takes.append(entry)

    # --- creating and opening -----------------------------------------------------------------------

    @classmethod
    def create(cls, folder: str | os.PathLike[str], name: str | None = None) -> Session:
        """A new empty session in ``folder`` (created if needed; must not hold a session already)."""
        folder = Path(folder).expanduser().absolute()
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise InputError(f"cannot create the session folder {folder} ({error.strerror or error})") from None
        _check_writable(folder)
        now = _now()
        session = cls(folder, {"name": name or folder.name, "created": now, "modified": now})
        with manifest_lock(folder):
            refuse_links(folder, session.manifest_path)
            if os.path.lexists(session.manifest_path):
                raise InputError(f"{folder} already holds a session; open it instead")
            session._write()
        return session

    @classmethod
    def open(cls, folder: str | os.PathLike[str], read_only: bool = False) -> Session:
        """Open the session in ``folder``. InputError (one line) when there is none, the manifest is
        damaged (left untouched; see :meth:`restore_backup`), the folder holds a symbolic link where the
        session keeps its files, or the folder is read-only and ``read_only`` is False."""
        folder = Path(folder).expanduser().absolute()
        if not folder.is_dir():
            raise InputError(f"session folder {folder} does not exist")
        if not os.path.lexists(folder / MANIFEST_NAME):
            raise InputError(f"{folder} is not a session folder (no {MANIFEST_NAME})")
        _refuse_session_links(folder)
        manifest = _read_manifest(folder)
        if not read_only:
            _check_writable(folder)
            _remove_temporaries(folder, folder)
        return cls(folder, manifest, read_only=read_only)

    @staticmethod
    def restore_backup(folder: str | os.PathLike[str]) -> Path:
        """Put ``session.json.bak`` back as the manifest; the damaged manifest is kept as
        ``session.json.damaged-<time>``. Returns the manifest path."""
        folder = Path(folder).expanduser().absolute()
        path = folder / MANIFEST_NAME
        backup = path.with_name(MANIFEST_NAME + BACKUP_SUFFIX)
        if not os.path.lexists(backup):
            raise InputError(f"{folder} has no {backup.name} to restore")
        with manifest_lock(folder):
            try:
                data = read_bytes(folder, backup, MANIFEST_LIMIT)
                strict_json(data)
                if os.path.lexists(path):
                    damaged = read_bytes(folder, path, MANIFEST_LIMIT)
                    write_file(folder, path.with_name(f"{MANIFEST_NAME}.damaged-{time.strftime('%Y%m%d-%H%M%S')}"),
                               damaged)
                write_file(folder, path, data)
            except (OSError, InputError) as error:
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

    def reload(self) -> None:
        """Read the manifest again (changes other processes made); InputError when it is damaged."""
        self._apply(_read_manifest(self.folder))

    def update(self, change: Callable[[], Any]) -> Any:
        """Change the manifest: under the session lock the manifest on disk is read again, ``change()``
        applied to this session and the result written (see the module docstring); returns what
        ``change`` returns. InputError when read-only or when it cannot be written (the session then
        shows the manifest on disk)."""
        self._check_writable_session()
        with manifest_lock(self.folder):
            self.reload()
            result = change()
            try:
                self._write()
            except InputError:
                self.reload()
                raise
        return result

    def save(self) -> None:
        """Write the manifest under the session lock (the changes of other processes to takes, subjects
        and layouts are kept: it is :meth:`update` with no change)."""
        self.update(lambda: None)

    def _write(self) -> None:
        """Write the manifest atomically (the lock is held); the manifest it replaces is kept as
        ``session.json.bak`` (only when it was valid: a damaged manifest never replaces a good backup)."""
        self.modified = _now()
        data = json.dumps(self.to_json(), indent=2).encode("utf-8")
        path = self.manifest_path
        try:
            if os.path.lexists(path):
                previous = read_bytes(self.folder, path, MANIFEST_LIMIT)
                try:
                    strict_json(previous)
                    write_file(self.folder, path.with_name(MANIFEST_NAME + BACKUP_SUFFIX), previous)
                except InputError:
                    pass
            write_file(self.folder, path, data)
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
                 labelled: bool | None = None, take: Take | None = None,
                 frame_rate: float | None = None) -> TakeEntry:
        """Add the raw take file ``path`` (read once to check it and record its size, at ``frame_rate`` Hz when
        given; pass ``take`` if it is already loaded). A rate the user gave (``Take.frame_rate_given``) is
        recorded, so the file is read at it again.
        ``labelled``: whether its columns are labelled markers (default: guessed:
        a labelled C3D from this program, names matching a shipped layout, or names that are not
        placeholders such as ``*12``, ``point_004``, ``Unlabeled 3``)."""
        self._check_writable_session()
        source = Path(path).expanduser().absolute()
        if take is None:
            take = load_take(source, frame_rate=frame_rate)
        for hand in hands:
            if hand not in ("right", "left"):
                raise InputError(f"hand must be 'right' or 'left', not '{hand}'")
        if labelled is None:
            labelled = _looks_labelled(take)

        def change() -> TakeEntry:
            if subject is not None and subject not in [s.name for s in self.subjects]:
                self.subjects.append(SubjectEntry(subject))
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
                              hands=list(hands), labelled_source=bool(labelled),
                              state="labelled" if labelled else "raw", frames=take.n_frames,
                              points=take.n_markers, frame_rate=take.frame_rate,
                              frame_rate_given=take.frame_rate_given, added=_now())
            self.takes.append(entry)
            return entry

        return self.update(change)

    def update_take(self, take_id: str, *, name: str | None = None, subject: str | None = None,
                    layout: str | None = None, hands: list[str] | None = None) -> TakeEntry:
        """Change a take's name, subject, layout or hands (arguments left None are kept)."""
        if hands is not None and (not hands or any(hand not in ("right", "left") for hand in hands)):
            raise InputError(f"hands must be 'right' and/or 'left', not {hands}")

        def change() -> TakeEntry:
            entry = self.take(take_id)
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
            return entry

        return self.update(change)

    def remove_take(self, take_id: str) -> None:
        """Remove a take from the manifest; its result folder is kept, renamed ``takes/<id>.removed-<time>``.
        InputError while the take is open (here or in another process)."""
        self._check_writable_session()
        entry = self.take(take_id)
        if entry.id in self._open_takes and not self._open_takes[entry.id].closed:
            raise InputError(f"close take '{entry.name}' before removing it")
        folder = self.take_folder(entry.id)
        lock = FileLock(self.folder, folder / LOCK_NAME)
        if os.path.lexists(folder):
            refuse_links(self.folder, folder)
            if not lock.acquire():
                raise InputError(f"take '{entry.name}' is open for editing by {lock.holder()}; close it there first")
        try:
            def change() -> None:
                removed = self.take(take_id)
                if os.path.lexists(folder):
                    try:
                        folder.rename(folder.with_name(f"{removed.id}.removed-{time.strftime('%Y%m%d-%H%M%S')}"))
                    except OSError as error:
                        raise InputError(f"cannot remove take '{removed.name}' ({error.strerror or error})"
                                         ) from None
                self.takes.remove(removed)

            self.update(change)
        finally:
            lock.release()

    def source_path(self, take_id: str) -> Path:
        """The raw file of a take: the session-relative path if it exists, else the absolute one.
        InputError when neither exists (moved or deleted)."""
        entry = self.take(take_id)
        try:
            if entry.source_relative is not None:
                relative = (self.folder / entry.source_relative).resolve()
                if relative.exists():
                    return relative
            absolute = Path(entry.source)
            if absolute.exists():
                return absolute
        except (OSError, RuntimeError, ValueError) as error:   # a link loop, a name the system refuses
            raise InputError(f"the raw file of take '{entry.name}' cannot be reached: {entry.source} "
                             f"({getattr(error, 'strerror', None) or error})") from None
        raise InputError(f"the raw file of take '{entry.name}' is missing: {entry.source} (relink it)")

    def relink_take(self, take_id: str, path: str | os.PathLike[str]) -> TakeEntry:
        """Point a take at a moved raw file (must have the same frames and points; read at the rate the user
        gave for the take, if any)."""
        self._check_writable_session()
        source = Path(path).expanduser().absolute()
        take = load_take(source, frame_rate=self.take(take_id).given_frame_rate)

        def change() -> TakeEntry:
            entry = self.take(take_id)
            if (take.n_frames, take.n_markers) != (entry.frames, entry.points):
                raise InputError(f"{source.name} has {take.n_frames} frames and {take.n_markers} points; take "
                                 f"'{entry.name}' had {entry.frames} and {entry.points}")
            entry.source, entry.source_relative = str(source), _relative(source, self.folder)
            return entry

        return self.update(change)

    def take_folder(self, take_id: str) -> Path:
        """Result folder of a take (``takes/<id>``; not created here)."""
        return self.folder / "takes" / _safe_name(take_id)

    def set_state(self, take_id: str, state: str) -> None:
        """Set a take's state: "raw", "labelled", "reviewed" or "exported"."""
        if state not in TAKE_STATES:
            raise InputError(f"unknown take state '{state}' (use {', '.join(TAKE_STATES)})")
        self.update(lambda: setattr(self.take(take_id), "state", state))

    def record_export(self, take_id: str, kind: str, path: str | os.PathLike[str]) -> None:
        """Remember an export (``kind`` e.g. "c3d", "csv", "bvh") and mark the take exported."""
        def change() -> None:
            entry = self.take(take_id)
            entry.exports[kind] = str(Path(path).absolute())
            entry.state = "exported"

        self.update(change)

    def open_take(self, take_id: str, loader: Callable[[Path], Take] | None = None,
                  label_names: list[str] | None = None) -> OpenTake:
        """Open a take for review: its raw file (read by ``loader``, by default :func:`load_take` at the rate
        the user gave for the take, if any), its newest readable snapshot and the journal replayed on top.

        A take never reviewed starts as :meth:`ReviewTake.from_labelled_take` when its source is labelled
        (with an unsolved hand per entry hand when every marker of the entry's layout is a column), else
        :meth:`ReviewTake.unlabelled` (with ``label_names`` if given; auto-label fills it). Opening the
        same take twice returns the same :class:`OpenTake`. The take is read-only (:attr:`OpenTake.read_only`)
        when the session is, or when another process holds it (:attr:`OpenTake.held_by` says who).
        """
        entry = self.take(take_id)
        if entry.id in self._open_takes and not self._open_takes[entry.id].closed:
            return self._open_takes[entry.id]
        source = self.source_path(entry.id)
        take = loader(source) if loader is not None else load_take(source, frame_rate=entry.given_frame_rate)
        if (take.n_frames, take.n_markers) != (entry.frames, entry.points) and entry.frames:
            raise InputError(f"the raw file of take '{entry.name}' changed: {take.n_frames} frames and "
                             f"{take.n_markers} points now, {entry.frames} and {entry.points} when added")
        opened = OpenTake(self, entry, take, label_names)
        self._open_takes[entry.id] = opened
        return opened

    # --- subjects, models, layouts ------------------------------------------------------------------

    def save_layout(self, layout: MarkerLayout | LabTemplate) -> Path:
        """Store ``layout`` (a marker layout or a lab's labelling template, which is a layout file too) as
        ``layouts/<name>.json`` (replacing one of the same name)."""
        from handmocap.core.model import save_layout

        def write(path: Path) -> None:
            if isinstance(layout, LabTemplate):
                save_lab_template(layout, path)
            else:
                save_layout(layout, path)

        path, relative = self._store("layouts", f"{_safe_name(layout.name)}.json", write, f"layout '{layout.name}'")

        def change() -> None:
            self.layouts = [item for item in self.layouts if item.name != layout.name] + [
                LayoutEntry(layout.name, relative)]

        self.update(change)
        return path

    def _store(self, folder_name: str, file_name: str, write: Callable[[Path], object], what: str
               ) -> tuple[Path, str]:
        """Write a session file ``<folder_name>/<file_name>`` with ``write(path)`` (the folder made, links
        refused): ``(path, path relative to the session folder)``; InputError "cannot save <what>" on failure."""
        self._check_writable_session()
        folder = self.folder / folder_name
        path = folder / file_name
        try:
            make_folder(self.folder, folder)
            refuse_links(self.folder, path)
            write(path)
        except OSError as error:
            raise InputError(f"cannot save {what} ({error.strerror or error})") from None
        return path, str(path.relative_to(self.folder))

    def layout_path(self, name: str) -> Path | None:
        """Path of a session layout by name, None when the session has none of that name."""
        for item in self.layouts:
            if item.name == name:
                return self.folder / item.path
        return None

    def save_subject_model(self, subject: str, model: HandModel) -> Path:
        """Store a subject's calibrated hand model as ``models/<subject>.npz`` and link it."""
        path, relative = self._store("models", f"{_safe_name(subject)}.npz", model.save,
                                     f"the model of '{subject}'")

        def change() -> None:
            for item in self.subjects:
                if item.name == subject:
                    item.model = relative
                    break
            else:
                self.subjects.append(SubjectEntry(subject, relative))

        self.update(change)
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

    The take is opened from its newest snapshot that reads; a damaged one is set aside (renamed
    ``.damaged-<time>``) and an older one used, with the journal since it; with none, the take is built
    from its raw file and the whole journal. ``read_only``: the session is read-only, or another
    process holds the take (``held_by`` says who, e.g. "ana on lab-pc (process 4711) since ..."); then
    every edit raises an InputError and the review is as it was when it was opened.

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
        self.held_by: str | None = None
        self.journal: Journal | None = None
        self._lock: FileLock | None = None
        self._last_save = time.monotonic()
        root = session.folder
        refuse_links_within(root, self.folder)
        writable = not session.read_only
        if writable:
            try:
                make_folder(root, self.folder)
            except OSError as error:
                raise InputError(f"cannot create {self.folder} ({error.strerror or error})") from None
            lock = FileLock(root, self.folder / LOCK_NAME)
            if lock.acquire():
                self._lock = lock
            else:
                self.held_by, writable = lock.holder(), False
        try:
            if self.held_by:
                with FileLock(root, self.folder / SAVE_LOCK_NAME):  # not in the middle of the holder's save
                    self._load(take, label_names, writable)
            else:
                self._load(take, label_names, writable)
        except BaseException:
            self._release()
            raise

    def _load(self, take: Take, label_names: list[str] | None, writable: bool) -> None:
        """The newest readable snapshot (or the initial review) and the journal replayed on top."""
        root, entry = self.session.folder, self.entry
        loaded, damaged = None, []
        path: Path | None = None   # the snapshot opened (None: none could be)
        for path, _ in snapshot_files(root, self.folder):
            try:
                loaded = (path, *load_snapshot(read_snapshot_file(root, path), take, path.name))
                break
            except SnapshotMismatch:
                raise
            except InputError as error:
                damaged.append(path)
                self.warnings.append(str(error))
        if loaded is not None:
            path, review, meta, commands = loaded
            base = int(meta["journal_seq"])
            history = meta.get("history", {})
            self._newest_seq: int | None = base if path.name == SNAPSHOT_NAME else None
        else:
            path, commands, history, base, self._newest_seq = None, [], {}, 0, None
            if entry.labelled_source:
                review = ReviewTake.from_labelled_take(take, hands=_layout_hands(take, entry, self.session))
            else:
                review = ReviewTake.unlabelled(take, label_names)
        if damaged:
            self.warnings.append(f"take '{entry.name}' was opened from {path.name if path else 'its raw file'} "
                                 "and the edits journalled since")
        self.review = review
        self.stack = UndoStack(review)
        if commands:
            self.stack.restore_history(commands, int(history.get("index", len(commands))),
                                       history.get("clean_index"))
        journal = Journal(root, self.folder, base + 1)
        if writable:
            for path in damaged:
                try:
                    set_aside(root, path)
                except (OSError, InputError) as error:
                    self.warnings.append(f"cannot set the damaged {path.name} aside ({error})")
            _remove_temporaries(root, self.folder, self.folder / BLOB_FOLDER)
        self.replayed, warnings = journal.replay(self.stack, after_seq=base, repair=writable)
        self.warnings.extend(warnings)
        if not writable:
            self.stack.recorder = self._refuse
            return
        self.journal = journal
        self.stack.recorder = journal.record
        if self.warnings:
            self.save()  # keep what was recovered in a snapshot

    # --- editing ------------------------------------------------------------------------------------

    @property
    def read_only(self) -> bool:
        """Whether edits are refused (the session is read-only or another process holds the take)."""
        return self.journal is None

    def read_only_reason(self) -> str:
        """Why the take is read-only, as one clause."""
        if self.held_by:
            return f"take '{self.entry.name}' is open read-only: {self.held_by} is editing it"
        return f"session {self.session.folder} is open read-only"

    def _refuse(self, operation: str, command: Command | None) -> None:
        raise InputError(f"{self.read_only_reason()}; the edit was not applied")

    def push(self, command: Command) -> FrameSpan:
        """Do ``command`` (undoable, journalled); returns the frames to re-solve."""
        self._check_editable()
        return self.stack.push(command)

    def attach(self, command: Command) -> FrameSpan:
        """Do ``command`` as part of the last step (e.g. the re-solve after an edit)."""
        self._check_editable()
        return self.stack.attach(command)

    def undo(self) -> FrameSpan:
        self._check_editable()
        return self.stack.undo()

    def redo(self) -> FrameSpan:
        self._check_editable()
        return self.stack.redo()

    def _check_open(self) -> None:
        if self.closed:
            raise InputError(f"take '{self.entry.name}' is closed")

    def _check_editable(self) -> None:
        self._check_open()
        if self.journal is None:
            self._refuse("", None)

    # --- saving -------------------------------------------------------------------------------------

    @property
    def snapshot_path(self) -> Path:
        return self.folder / SNAPSHOT_NAME

    def is_modified(self) -> bool:
        """True when there are edits since the last save (they are journalled either way)."""
        return not self.stack.is_clean()

    def save(self) -> None:
        """Write a new snapshot (state + undo history) atomically, keep the previous ones (the last three
        in all) and their journals, start an empty journal and update the take's state in the manifest
        (a raw take with labels becomes "labelled")."""
        self._check_open()
        if self.journal is None:
            raise InputError(f"{self.read_only_reason()}; take '{self.entry.name}' cannot be saved")
        root, seq = self.session.folder, self.journal.next_seq - 1
        try:
            data = snapshot_bytes(self.review, self.stack, seq)
            with FileLock(root, self.folder / SAVE_LOCK_NAME):  # a read-only opening waits for the files
                if seq != self._newest_seq:
                    self.journal.rotate(seq)
                    if self._newest_seq is not None:
                        keep_older(root, self.folder, self._newest_seq)
                    elif os.path.lexists(self.snapshot_path):
                        set_aside(root, self.snapshot_path)  # a damaged newest snapshot
                write_file(root, self.snapshot_path, data)
                self._newest_seq = seq
                self.journal.prune(prune_snapshots(root, self.folder))
        except OSError as error:
            raise InputError(f"cannot save take '{self.entry.name}' ({error.strerror or error}); "
                             "the edits are still in the journal") from None
        self._last_save = time.monotonic()
        self.stack.set_clean()
        relative = str(self.snapshot_path.relative_to(self.session.folder))
        labelled = bool((self.review.assignment >= 0).any())

        def change() -> None:
            entry = self.session.take(self.entry.id)
            entry.results["review"] = relative
            if entry.state == "raw" and labelled and not entry.labelled_source:
                entry.state = "labelled"

        if self.entry.results.get("review") != relative or (self.entry.state == "raw" and labelled
                                                             and not self.entry.labelled_source):
            self.session.update(change)

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
        """Save (when writable and modified), release the journal and the take lock. Without ``save`` the
        edits stay in the journal and come back on the next open. A failed save is raised after the
        take was released (its edits are in the journal)."""
        if self.closed:
            return
        try:
            if save and self.journal is not None and (self.is_modified() or self.replayed):
                self.save()
        finally:
            self._release()
            self.closed = True

    def _release(self) -> None:
        if self.journal is not None:
            self.journal.close()
        if self._lock is not None:
            self._lock.release()
            self._lock = None


def _looks_labelled(take: Take) -> bool:
    """Whether a take's columns are labelled markers rather than raw points (see :meth:`Session.add_take`)."""
    if "PROVENANCE" in take.parameters or best_layout_for(take.marker_names) is not None:
        return True
    return not looks_unlabelled(take.marker_names)


def _layout_hands(take: Take, entry: TakeEntry, session: Session) -> list[HandTrack]:
    """Hands of a labelled take at its first opening (unsolved): those :func:`core.model.detect_hands` finds
    with the entry's layout when it has one (a session layout, a template, or a shipped one), else among the
    session's layouts and the known ones; the entry's side for a hand whose names do not say it."""
    hint = entry.hands[0] if len(entry.hands) == 1 else None
    paths = {str(session.folder / item.path): item.name for item in session.layouts}
    layout = (session.layout_path(entry.layout) or entry.layout) if entry.layout else None
    try:
        found = detect_hands(take.marker_names, layout, hint, candidates=list(paths))
    except InputError:
        found = []
    if not found and layout is not None:
        found = detect_hands(take.marker_names, None, hint, candidates=list(paths))
    return [HandTrack(hand.side, hand.side, paths.get(hand.layout_name, hand.layout_name), hand.labels,
                      np.full((take.n_frames, 26), np.nan)) for hand in found]


def _relative(path: Path, folder: Path) -> str | None:
    """``path`` relative to ``folder`` (with ``..`` if needed), None on another drive."""
    try:
        return os.path.relpath(path, folder)
    except ValueError:
        return None


def _list(value: Any) -> list[Any]:
    if not isinstance(value, list):
        raise TypeError("subjects, layouts and takes must be lists")
    return value


SESSION_ENTRIES = (MANIFEST_NAME, MANIFEST_NAME + BACKUP_SUFFIX, SESSION_LOCK_NAME, "takes", "models", "layouts")


def _refuse_session_links(folder: Path) -> None:
    """InputError when an entry the session keeps its files in is a symbolic link."""
    for name in SESSION_ENTRIES:
        refuse_links(folder, folder / name)


def _read_manifest(folder: Path) -> dict[str, Any]:
    """The manifest of the session in ``folder`` as a dict; InputError (naming the backup) when it is
    damaged or written by a newer version."""
    path = folder / MANIFEST_NAME
    try:
        manifest = strict_json(read_bytes(folder, path, MANIFEST_LIMIT))
        if not isinstance(manifest, dict) or manifest.get("format") != SESSION_FORMAT:
            raise InputError("not a Hand Mocap Studio session manifest")
    except (OSError, InputError) as error:
        if isinstance(error, InputError) and "symbolic link" in str(error):
            raise
        backup = path.with_name(MANIFEST_NAME + BACKUP_SUFFIX)
        hint = (f"; the previous manifest is in {backup.name} (Session.restore_backup puts it back)"
                if os.path.lexists(backup) else "")
        raise InputError(f"{path} is damaged ({str(error).splitlines()[0][:80]}); it was left untouched{hint}"
                         ) from None
    version = manifest.get("version", 0)
    if type(version) is not int:
        raise InputError(f"{path} is damaged (version {str(version)[:20]}); it was left untouched")
    if version > SESSION_VERSION:
        raise InputError(f"{path} was written by a newer Hand Mocap Studio (version {version})")
    return manifest


TEMPORARY = re.compile(r"\..*\.[0-9a-f]{8,32}\.tmp(\.[^.]{1,20})?")  # core.io.durable's, old and new


def _remove_temporaries(root: Path, *folders: Path) -> None:
    """Delete the temporary files (``.<name>.<hex>.tmp[.<suffix>]``) an interrupted atomic write left
    behind in ``folders`` inside the session folder ``root`` (regular files older than a minute, so that a
    write in progress in another process is left alone; never through a link)."""
    now = time.time()
    for folder in folders:
        for path in regular_files(root, folder, ".*.tmp*"):
            try:
                if TEMPORARY.fullmatch(path.name) and now - os.lstat(path).st_mtime > 60.0:
                    remove_file(root, path)
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
