"""The edit journal of a take: every operation appended as a JSON line, fsync'ed before it counts.

Files in the take's result folder::

    journal.jsonl        one line per operation since the newest snapshot:
                         {"seq": 7, "op": "do", "time": "...Z", "command": {"type": "assign_label", ...}}
                         op is "do" (push), "attach" (part of the last step), "undo" or "redo"
    journal-<seq>.jsonl  the operations up to entry <seq> (an older snapshot's journal), kept while an
                         older snapshot may need them
    blobs/               arrays too large for a line (``<seq>-<n>.npy``), written before their line

Opening replays the entries whose ``seq`` is above the snapshot's, from every journal file, through an
:class:`UndoStack`, so the state after a crash is the state after the last entry written. A torn last
line (the process died while writing it) is cut off: that operation had not returned to the caller. A
damaged line, or an entry that cannot be applied, is skipped with a warning and the entries after it
are replayed (an attach, undo or redo of a skipped step is skipped with it). Saving writes a new
snapshot and starts an empty journal (:meth:`Journal.rotate`); entries at or below the snapshot's
``seq`` are skipped if a crash came between the two.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import re
import time
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.durable import fsync_folder
from handmocap.core.review.commands import Command, UndoStack, command_from_json
from handmocap.core.session.files import (
    make_folder,
    open_append,
    read_bytes,
    refuse_links,
    regular_files,
    remove_file,
    truncate,
    write_file,
)
from handmocap.core.session.storage import MALFORMED, check_npy, strict_json

_log = logging.getLogger(__name__)

JOURNAL_NAME = "journal.jsonl"
SEGMENT = re.compile(r"journal-(\d{1,15})\.jsonl")
BLOB_FOLDER = "blobs"
BLOB = re.compile(r"(\d{1,15})-\d{1,9}\.npy")
OPERATIONS = ("do", "attach", "undo", "redo")
MAX_SEQ = 2**53  # sequence numbers stay exact in JSON readers that use doubles


class FileBlobs:
    """Arrays of journal entries as ``.npy`` files in ``folder`` inside the session folder ``root``
    (durable before their line is written)."""

    def __init__(self, root: Path, folder: Path, seq: int) -> None:
        self.root, self.folder, self.seq, self.count = root, folder, seq, 0

    def put(self, array: np.ndarray) -> str:
        make_folder(self.root, self.folder)
        key = f"{self.seq}-{self.count}.npy"
        self.count += 1
        write_file(self.root, self.folder / key, _npy_bytes(array))
        return key

    def get(self, key: str) -> np.ndarray:
        path = self.folder / Path(str(key)).name
        try:
            data = read_bytes(self.root, path)
            stream = io.BytesIO(data)
            check_npy(stream, len(data), path.name)
            return np.load(stream, allow_pickle=False)
        except (OSError, ValueError, EOFError) as error:
            raise InputError(f"journal data {path.name} is missing or damaged ({error})") from None


def _npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, np.ascontiguousarray(array), allow_pickle=False)
    return buffer.getvalue()


def _parse(line: bytes) -> dict[str, Any] | None:
    """A journal entry from one line, None when the line is not one."""
    try:
        entry = strict_json(line)
    except InputError:
        return None
    if not isinstance(entry, dict) or entry.get("op") not in OPERATIONS:
        return None
    seq = entry.get("seq")
    if type(seq) is not int or not 0 < seq < MAX_SEQ:
        return None
    if "command" in entry and not isinstance(entry["command"], dict):
        return None
    return entry


def _segment_end(path: Path) -> int | None:
    match = SEGMENT.fullmatch(path.name)
    return int(match.group(1)) if match else None


class Journal:
    """Append-only, fsync'ed record of the operations on one take (module docstring).

    ``root``: the session folder; ``folder``: the take's result folder; ``next_seq``: the sequence
    number of the next entry (one more than the snapshot's). :meth:`record` has the signature of an
    :class:`UndoStack` recorder.
    """

    def __init__(self, root: str | os.PathLike[str], folder: str | os.PathLike[str], next_seq: int = 1) -> None:
        self.root, self.folder = Path(root), Path(folder)
        self.path = self.folder / JOURNAL_NAME
        self.next_seq = int(next_seq)
        self._handle: BinaryIO | None = None
        self._highest = 0  # the highest sequence number seen in the journal files read

    # -- writing --
    def record(self, operation: str, command: Command | None) -> None:
        """Append one operation durably (line written, flushed and fsync'ed before returning).
        Raises InputError when it cannot be written (the stack then reverts the operation)."""
        if operation not in OPERATIONS:
            raise ValueError(f"unknown journal operation {operation!r}")
        seq = self.next_seq
        entry: dict[str, Any] = {"seq": seq, "op": operation,
                                 "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        try:
            if command is not None:
                entry["command"] = command.to_json(FileBlobs(self.root, self.folder / BLOB_FOLDER, seq))
            line = (json.dumps(entry, separators=(",", ":"), allow_nan=False) + "\n").encode()
            handle = self._open()
            handle.write(line)
            handle.flush()
            os.fsync(handle.fileno())
        except (OSError, InputError) as error:
            self.close()
            reason = error.strerror or error if isinstance(error, OSError) else error
            raise InputError(f"cannot write the edit journal {self.path} ({reason}); "
                             "the edit was not applied") from None
        except (TypeError, ValueError) as error:
            raise InputError(f"the edit cannot be recorded ({error}); it was not applied") from None
        self.next_seq = seq + 1

    def _open(self) -> BinaryIO:
        if self._handle is None:
            existed = os.path.lexists(self.path)
            self._handle = open_append(self.root, self.path)
            if not existed:
                fsync_folder(self.folder)
        return self._handle

    def close(self) -> None:
        if self._handle is not None:
            with contextlib.suppress(OSError):
                self._handle.close()
            self._handle = None

    def rotate(self, end_seq: int) -> None:
        """Keep the journal's entries (those up to ``end_seq``, the snapshot just written) as
        ``journal-<end_seq>.jsonl`` and start an empty journal. OSError or InputError when it fails."""
        self.close()
        refuse_links(self.root, self.path)
        if self.path.exists() and self.path.stat().st_size > 0:
            os.replace(self.path, self.folder / f"journal-{int(end_seq)}.jsonl")
        write_file(self.root, self.path, b"")

    def prune(self, keep_after: int) -> None:
        """Delete the journal files and blobs of entries up to ``keep_after`` (no kept snapshot needs them)."""
        for path in regular_files(self.root, self.folder, "journal-*.jsonl"):
            end = _segment_end(path)
            if end is not None and end <= keep_after:
                remove_file(self.root, path)
        for path in regular_files(self.root, self.folder / BLOB_FOLDER, "*.npy"):
            match = BLOB.fullmatch(path.name)
            if match and int(match.group(1)) <= keep_after:
                remove_file(self.root, path)

    # -- reading --
    def files(self, after_seq: int = 0) -> list[Path]:
        """The journal files that may hold entries above ``after_seq``, oldest first."""
        segments = [(end, path) for path in regular_files(self.root, self.folder, "journal-*.jsonl")
                    if (end := _segment_end(path)) is not None and end > after_seq]
        current = [self.path] if os.path.lexists(self.path) else []
        return [path for _, path in sorted(segments)] + current

    def entries(self, after_seq: int = 0, repair: bool = True) -> tuple[list[dict[str, Any]], list[str], int]:
        """Entries with ``seq > after_seq`` in order, warnings and the number of damaged lines among them.
        A torn last line of the journal is dropped (and cut from the file when ``repair``); a damaged
        line is skipped (its file is copied to ``<name>.damaged-<time>`` when ``repair``)."""
        warnings: list[str] = []
        found: dict[int, dict[str, Any]] = {}
        damaged_count = 0
        files = self.files(after_seq)
        for path in files:
            try:
                raw = read_bytes(self.root, path)
            except OSError as error:
                raise InputError(f"cannot read the edit journal {path} ({error.strerror or error})") from None
            lines = raw.split(b"\n")
            complete, tail = lines[:-1], lines[-1]
            parsed = [_parse(line) for line in complete]
            damaged = [number for number, (line, entry) in enumerate(zip(complete, parsed, strict=True))
                       if entry is None and line.strip() and _concerns(parsed, number, after_seq)]
            for entry in parsed:
                if entry is not None:
                    self._highest = max(self._highest, entry["seq"])
                    if entry["seq"] > after_seq:
                        found.setdefault(entry["seq"], entry)
            for number in damaged:
                warnings.append(f"{path.name} line {number + 1} is damaged and was skipped; "
                                "the edits after it were replayed")
            damaged_count += len(damaged)
            if damaged and repair:
                self._set_aside(path, raw)
            if tail.strip():
                if path == self.path:
                    warnings.append("the last edit journal entry was incomplete (the program stopped while "
                                    "writing it) and was dropped")
                    if repair:
                        self._cut(len(raw) - len(tail))
                else:
                    warnings.append(f"{path.name} ends in an incomplete line; it was skipped")
                    damaged_count += 1
        ends = [end for path in files if (end := _segment_end(path)) is not None]
        self._highest = max([self._highest, *ends])
        return [found[seq] for seq in sorted(found)], warnings, damaged_count

    def _cut(self, size: int) -> None:
        try:
            truncate(self.root, self.path, size)
        except (OSError, InputError) as error:
            _log.warning("cannot repair %s: %s", self.path, error)

    def _set_aside(self, path: Path, raw: bytes) -> None:
        try:
            write_file(self.root, path.with_name(f"{path.name}.damaged-{time.strftime('%Y%m%d-%H%M%S')}"), raw)
        except (OSError, InputError) as error:
            _log.warning("cannot keep a copy of %s: %s", path, error)

    def replay(self, stack: UndoStack, after_seq: int = 0, repair: bool = True) -> tuple[int, list[str]]:
        """Apply the entries after ``after_seq`` to ``stack`` (whose recorder must not be this journal
        yet). Returns the number applied and warnings (one line each). An entry that cannot be applied
        is skipped with what hangs on it (module docstring); ``repair``: as for :meth:`entries` (False
        when another process holds the take: nothing is written)."""
        entries, warnings, damaged = self.entries(after_seq, repair)
        blobs_folder = self.folder / BLOB_FOLDER
        applied = [True] * len(stack.commands)  # per undo step: whether it is in the stack (not skipped)
        index, replayed = stack.index, 0
        missing = (entries[-1]["seq"] - after_seq - len(entries)) if entries else 0
        if missing > damaged:
            warnings.append(f"{missing - damaged} journalled edits after edit {after_seq} are missing "
                            "(a journal file was deleted or damaged)")
        for entry in entries:
            seq, operation = entry["seq"], entry["op"]
            try:
                if operation == "do":
                    stack.push(command_from_json(entry["command"], FileBlobs(self.root, blobs_folder, seq)))
                elif operation == "attach" and (index == 0 or applied[index - 1]):
                    stack.attach(command_from_json(entry["command"], FileBlobs(self.root, blobs_folder, seq)))
                elif operation == "undo" and index > 0 and applied[index - 1]:
                    stack.undo()
                elif operation == "redo" and index < len(applied) and applied[index]:
                    stack.redo()
                else:
                    index = _move(operation, index, len(applied))
                    continue
            except MALFORMED as error:
                reason = str(error).splitlines()[0][:200] if str(error) else type(error).__name__
                warnings.append(f"edit {seq} of the journal could not be replayed ({reason}); it was skipped")
                if operation == "do":
                    applied[index:] = [False]
                    index += 1
                continue
            if operation == "do":
                applied[index:] = [True]
                while sum(applied) > len(stack.commands):  # the stack dropped its oldest steps
                    drop = applied.index(True) + 1
                    del applied[:drop]
                    index -= drop
            index = _move(operation, index, len(applied))
            replayed += 1
        self.next_seq = max(self.next_seq, after_seq + 1, self._highest + 1)
        return replayed, warnings


def _move(operation: str, index: int, steps: int) -> int:
    """The undo position after ``operation`` ("do" counts its step already added)."""
    if operation == "do" or (operation == "redo" and index < steps):
        return index + 1
    if operation == "undo" and index > 0:
        return index - 1
    return index


def _concerns(parsed: list[dict[str, Any] | None], number: int, after_seq: int) -> bool:
    """Whether the damaged line ``number`` may be an entry above ``after_seq`` (judged by its neighbours)."""
    following = next((entry["seq"] for entry in parsed[number + 1:] if entry is not None), None)
    if following is not None:
        return following > after_seq + 1
    previous = next((entry["seq"] for entry in reversed(parsed[:number]) if entry is not None), None)
    return previous is None or previous >= after_seq
