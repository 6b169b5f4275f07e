"""Takes opened outside a session (File ▸ Open, drag and drop, files on the command line) are reviewed in
an automatic session of their own, so that every edit is journalled at once, as a session take's is, and
comes back when the same file is opened again.

Each file gets the session folder ``<data folder>/loose-takes/<key>/``: ``key`` is the first 16 hex digits
of the SHA-256 of the file's absolute path; the data folder is ``$HANDMOCAP_DATA``, else
``$XDG_DATA_HOME/handmocap``, else ``~/.local/share/handmocap``. Never next to the file: its folder may
be read-only or a colleague's. ``source.json`` beside the manifest records the file's size and SHA-256,
so a file replaced by other content under the same path starts a fresh review (the old folder is kept,
renamed ``<key>.replaced-<time>``) instead of replaying edits made on other data.

When the data folder cannot be written the take is reviewed in memory only, and
:attr:`LooseTake.warning` says that its edits will not survive.

The frame rate the user gave for a file that states none is kept in its automatic session's manifest:
:func:`remembered_frame_rate` gives it back when the same file is opened again, so it is asked once.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path

from handmocap.app.gui.document import LooseTake, TakeDocument
from handmocap.core.errors import HandMocapError
from handmocap.core.io import Take, looks_unlabelled
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.session import Session

LOOSE_FOLDER = "loose-takes"
SOURCE_NAME = "source.json"     # the file the folder's review belongs to: path, size, SHA-256
READ_CHUNK = 1 << 20            # bytes read at a time to hash a file


def data_folder() -> Path:
    """The user data folder of Hand Mocap Studio (module docstring)."""
    configured = os.environ.get("HANDMOCAP_DATA")
    if configured:
        return Path(configured).expanduser()
    xdg = os.environ.get("XDG_DATA_HOME")
    return (Path(xdg) if xdg else Path.home() / ".local" / "share") / "handmocap"


def loose_folder(source: Path) -> Path:
    """The automatic session folder of the take file ``source``."""
    key = hashlib.sha256(str(Path(source).expanduser().absolute()).encode("utf-8")).hexdigest()[:16]
    return data_folder() / LOOSE_FOLDER / key


def file_identity(path: Path) -> dict[str, object]:
    """What tells a file's content apart: its absolute path, size (bytes) and SHA-256."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        while chunk := stream.read(READ_CHUNK):
            digest.update(chunk)
    return {"path": str(path), "size": path.stat().st_size, "sha256": digest.hexdigest()}


def loose_document(path: str | os.PathLike[str], take: Take, auto_solve: bool = False) -> TakeDocument:
    """A document of the take file ``path`` (read already: ``take``) reviewed in its automatic session
    (:func:`open_loose_take`); its title says when the take is read-only or its edits are not kept."""
    loose = open_loose_take(path, take)
    title = loose.source.name
    if loose.opened is None:
        title += " (edits not kept)"
    elif loose.opened.read_only:
        title += " (read-only)"
    return TakeDocument(take, title, auto_solve=auto_solve, open_take=loose.opened, loose=loose)


def remembered_frame_rate(path: str | os.PathLike[str]) -> float | None:
    """The rate (Hz) the user gave for the take file ``path`` when it was opened before (its automatic
    session keeps it); None when none was given, or the file changed since."""
    source = Path(path).expanduser().absolute()
    folder = loose_folder(source)
    try:
        if json.loads((folder / SOURCE_NAME).read_text(encoding="utf-8")) != file_identity(source):
            return None
        entry = json.loads((folder / "session.json").read_text(encoding="utf-8"))["takes"][0]
        rate = float(entry["frame_rate"])
    except (OSError, ValueError, KeyError, IndexError, TypeError):
        return None
    return rate if entry.get("frame_rate_given") is True and rate > 0 else None


def open_loose_take(path: str | os.PathLike[str], take: Take) -> LooseTake:
    """Open the take file ``path`` (read already: ``take``) in its automatic session, with the review and
    edits kept there from an earlier opening. Never raises for a folder problem: the take is then
    reviewed in memory (see :attr:`LooseTake.warning`)."""
    source = Path(path).expanduser().absolute()
    folder = loose_folder(source)
    try:
        identity = file_identity(source)
        fresh, replaced = _prepare(folder, identity)
        session = Session.create(folder, name=source.name) if fresh else Session.open(folder)
    except (HandMocapError, OSError) as error:
        return LooseTake(source, warning=_in_memory(error))
    try:
        if not session.takes:
            session.add_take(source, take=take, labelled=not looks_unlabelled(take.marker_names))
        opened = session.open_take(session.takes[0].id, loader=lambda _path: take)
    except HandMocapError as error:
        session.close()
        return LooseTake(source, warning=_in_memory(error))
    loose = LooseTake(source, session, opened, restored=opened.stack.index)
    if replaced:
        loose.notice = f"{source.name} changed on disk: a new review was started (the old one is in {replaced})"
    elif opened.read_only:
        loose.notice = f"{opened.read_only_reason()}; edits are not possible"
    elif loose.restored:
        loose.notice = (f"{source.name}: review restored with its {loose.restored} edit"
                        f"{'s' if loose.restored != 1 else ''} (kept in {folder})")
    else:
        loose.notice = f"{source.name}: every edit is kept in {folder}"
    return loose


def _prepare(folder: Path, identity: dict[str, object]) -> tuple[bool, str]:
    """Make sure ``folder`` belongs to the file of ``identity``: returns whether a session must be created
    there, and the folder the review of an earlier content was moved to ("" when none was)."""
    record = folder / SOURCE_NAME
    replaced = ""
    if (folder / "session.json").exists():
        try:
            known = json.loads(record.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            known = None
        if known == identity:
            return False, ""
        aside = folder.with_name(f"{folder.name}.replaced-{time.strftime('%Y%m%d-%H%M%S')}")
        folder.rename(aside)
        replaced = str(aside)
    folder.mkdir(parents=True, exist_ok=True)
    write_text_atomic(record, json.dumps(identity, indent=2))
    return True, replaced


def _in_memory(error: BaseException) -> str:
    reason = str(error).splitlines()[0] if str(error) else type(error).__name__
    return f"edits will not survive closing: cannot keep the review in {data_folder() / LOOSE_FOLDER} ({reason})"
