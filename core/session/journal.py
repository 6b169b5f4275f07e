"""The edit journal of a take: every operation appended as a JSON line, fsync'ed before it counts.

Files in the take's result folder::

    review.npz        last snapshot (state + undo history + the journal sequence number it includes)
    journal.jsonl     one line per operation since that snapshot:
                      {"seq": 7, "op": "do", "time": "...Z", "command": {"type": "assign_label", ...}}
                      op is "do" (push), "attach" (part of the last step), "undo" or "redo"
    blobs/            arrays too large for a line (``<seq>-<n>.npy``), written before their line

Opening replays the entries whose ``seq`` is above the snapshot's through an :class:`UndoStack`, so the
state after a crash is the state after the last entry written. A torn last line (the process died
while writing it) is cut off: that operation had not returned to the caller. Saving writes a new
snapshot, then starts an empty journal; entries at or below the snapshot's ``seq`` are skipped if a
crash came between the two.
"""

from __future__ import annotations

import json
import logging
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from core.errors import InputError
from core.io.durable import fsync_folder, write_atomic
from core.review.commands import Command, UndoStack, command_from_json

_log = logging.getLogger(__name__)

JOURNAL_NAME = "journal.jsonl"
BLOB_FOLDER = "blobs"
OPERATIONS = ("do", "attach", "undo", "redo")


class FileBlobs:
    """Arrays of journal entries as ``.npy`` files in ``folder`` (durable before their line is written)."""

    def __init__(self, folder: Path, seq: int) -> None:
        self.folder, self.seq, self.count = folder, seq, 0

    def put(self, array: np.ndarray) -> str:
        self.folder.mkdir(exist_ok=True)
        key = f"{self.seq}-{self.count}.npy"
        self.count += 1
        buffer = _npy_bytes(array)
        write_atomic(self.folder / key, buffer)
        return key

    def get(self, key: str) -> np.ndarray:
        path = self.folder / Path(key).name
        try:
            return np.load(path, allow_pickle=False)
        except (OSError, ValueError) as error:
            raise InputError(f"journal data {key} is missing or damaged ({error})") from None


def _npy_bytes(array: np.ndarray) -> bytes:
    import io

    buffer = io.BytesIO()
    np.save(buffer, np.ascontiguousarray(array), allow_pickle=False)
    return buffer.getvalue()


class Journal:
    """Append-only, fsync'ed record of the operations on one take (module docstring).

    ``folder``: the take's result folder; ``next_seq``: the sequence number of the next entry (one more
    than the snapshot's). :meth:`record` has the signature of an :class:`UndoStack` recorder.
    """

    def __init__(self, folder: str | os.PathLike[str], next_seq: int = 1) -> None:
        self.folder = Path(folder)
        self.path = self.folder / JOURNAL_NAME
        self.next_seq = int(next_seq)
        self._handle = None

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
                entry["command"] = command.to_json(FileBlobs(self.folder / BLOB_FOLDER, seq))
            line = (json.dumps(entry, separators=(",", ":"), allow_nan=False) + "\n").encode()
            handle = self._open()
            handle.write(line)
            handle.flush()
            os.fsync(handle.fileno())
        except OSError as error:
            self.close()
            raise InputError(f"cannot write the edit journal {self.path} ({error.strerror or error}); "
                             "the edit was not applied") from None
        except (TypeError, ValueError) as error:
            raise InputError(f"the edit cannot be recorded ({error}); it was not applied") from None
        self.next_seq = seq + 1

    def _open(self):
        if self._handle is None:
            existed = self.path.exists()
            self._handle = open(self.path, "ab")
            if not existed:
                fsync_folder(self.folder)
        return self._handle

    def close(self) -> None:
        if self._handle is not None:
            try:
                self._handle.close()
            except OSError:
                pass
            self._handle = None

    def restart(self) -> None:
        """Start an empty journal (after a snapshot that includes every entry) and drop the blobs."""
        self.close()
        write_atomic(self.path, b"")
        blobs = self.folder / BLOB_FOLDER
        if blobs.is_dir():
            for path in blobs.iterdir():
                path.unlink(missing_ok=True)

    # -- reading --
    def entries(self, after_seq: int = 0, repair: bool = True) -> tuple[list[dict[str, Any]], list[str]]:
        """Entries with ``seq > after_seq`` and warnings. A torn last line is dropped (and cut from the
        file when ``repair``); a damaged line elsewhere stops the reading there (the file is kept aside
        as ``journal.jsonl.damaged-<time>`` when ``repair``)."""
        if not self.path.exists():
            return [], []
        try:
            raw = self.path.read_bytes()
        except OSError as error:
            raise InputError(f"cannot read the edit journal {self.path} ({error.strerror or error})") from None
        warnings: list[str] = []
        entries: list[dict[str, Any]] = []
        lines = raw.split(b"\n")
        complete, tail = lines[:-1], lines[-1]
        good_bytes = 0
        for number, line in enumerate(complete):
            try:
                entry = json.loads(line)
                if not isinstance(entry, dict) or entry.get("op") not in OPERATIONS or "seq" not in entry:
                    raise ValueError("not a journal entry")
            except ValueError:
                warnings.append(f"edit journal line {number + 1} is damaged; the edits after it were not replayed "
                                f"(kept in {self.path.name}.damaged)")
                if repair:
                    self._set_aside(raw)
                    self._truncate(good_bytes)
                return entries, warnings
            good_bytes += len(line) + 1
            if int(entry["seq"]) > after_seq:
                entries.append(entry)
        if tail.strip():
            warnings.append("the last edit journal entry was incomplete (the program stopped while writing it) "
                            "and was dropped")
            if repair:
                self._truncate(good_bytes)
        return entries, warnings

    def _truncate(self, size: int) -> None:
        try:
            with open(self.path, "r+b") as handle:
                handle.truncate(size)
                handle.flush()
                os.fsync(handle.fileno())
        except OSError as error:
            _log.warning("cannot repair %s: %s", self.path, error)

    def _set_aside(self, raw: bytes) -> None:
        try:
            write_atomic(self.path.with_name(f"{self.path.name}.damaged-{time.strftime('%Y%m%d-%H%M%S')}"), raw)
        except OSError as error:
            _log.warning("cannot keep a copy of %s: %s", self.path, error)

    def replay(self, stack: UndoStack, after_seq: int = 0) -> tuple[int, list[str]]:
        """Apply the entries after ``after_seq`` to ``stack`` (whose recorder must not be this journal
        yet). Returns the number replayed and warnings; stops at the first entry that cannot be applied
        (the rest stay in the file, and are set aside when the caller restarts the journal)."""
        entries, warnings = self.entries(after_seq)
        blobs_folder = self.folder / BLOB_FOLDER
        replayed = 0
        last_seq = after_seq
        for entry in entries:
            seq, operation = int(entry["seq"]), entry["op"]
            try:
                if operation in ("do", "attach"):
                    command = command_from_json(entry.get("command", {}), FileBlobs(blobs_folder, seq))
                    (stack.push if operation == "do" else stack.attach)(command)
                elif operation == "undo":
                    stack.undo()
                else:
                    stack.redo()
            except InputError as error:
                warnings.append(f"edit {seq} of the journal could not be replayed ({error}); "
                                "it and the later edits were not applied")
                self._set_aside(self.path.read_bytes())
                break
            replayed += 1
            last_seq = seq
        self.next_seq = max(self.next_seq, last_seq + 1, after_seq + 1)
        if entries and replayed < len(entries):
            self.next_seq = max(self.next_seq, int(entries[-1]["seq"]) + 1)
        return replayed, warnings
