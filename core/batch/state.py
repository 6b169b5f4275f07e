"""The batch state of a session's takes: ``takes/<take id>/batch.json``, one small file per take.

::

    {"format": "handmocap-batch", "version": 1, "state": "running|done|failed|skipped",
     "key": "<input key>", "reason": str, "summary": {...}, "updated": iso}

A take is *done* for a key when its file says "done" with that key (:func:`input_key`: the raw file's
content and the pipeline's) and its summary's outputs (path and sha256 of each export) are still there,
unchanged, where the batch now writes them (:func:`core.batch.runner.plan_batch` checks). The worker
processing a take writes its file while it holds the take's
lock ("running" before it writes anything else, "done" once the review step is saved); the driver
writes "failed" or "skipped" after the task ended (its worker is gone or let the lock go). Each write
is atomic (:mod:`core.session.files`: never through a link). One file per take rather than one for the
study: an update then costs the same for 10 takes or 10 000 and needs no session-wide lock (a single
state file of 1126 takes took 165 ms per read-modify-write under the machine's load, serialised over
every take). A damaged or missing file means "not done": the take runs again.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
import time
from pathlib import Path
from typing import Any

from handmocap.core.errors import InputError
from handmocap.core.session.files import make_folder, read_bytes, write_file
from handmocap.core.session.storage import strict_json

STATE_NAME = "batch.json"
STATE_FORMAT = "handmocap-batch"
STATES = ("running", "done", "failed", "skipped")
STATE_LIMIT = 2**20  # bytes; a take's summary is about 1 kB
#: what a take id may be (the session makes ``t0001``...): a file name inside ``takes/``, never a path
TAKE_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,127}")


def valid_take_id(take_id: object) -> bool:
    """Whether ``take_id`` is a take id a batch may use as a file name (:data:`TAKE_ID`, no '..')."""
    return isinstance(take_id, str) and TAKE_ID.fullmatch(take_id) is not None and ".." not in take_id


def input_key(raw: Path, pipeline_key: str) -> str:
    """The hex sha256 of the raw take file's bytes and the pipeline's key. InputError when the raw file
    is no regular file (a FIFO or a device would block or never end)."""
    digest = hashlib.sha256(pipeline_key.encode())
    digest.update(file_sha256(raw, "raw take file").encode())
    return digest.hexdigest()


def file_sha256(path: Path, what: str = "file") -> str:
    """The hex sha256 of the regular file ``path``; InputError for anything else (a FIFO, a device)."""
    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as error:
        raise InputError(f"cannot read the {what} {path} ({error.strerror or error})") from None
    with os.fdopen(descriptor, "rb") as handle:
        if not stat.S_ISREG(os.fstat(handle.fileno()).st_mode):
            raise InputError(f"the {what} {path} is not a regular file")
        digest = hashlib.sha256()
        try:
            for block in iter(lambda: handle.read(1 << 20), b""):
                digest.update(block)
        except OSError as error:
            raise InputError(f"cannot read the {what} {path} ({error.strerror or error})") from None
    return digest.hexdigest()


def state_path(folder: Path, take_id: str) -> Path:
    """The batch state file of take ``take_id`` of the session in ``folder`` (InputError for an id that is
    not a plain name: a damaged manifest must not send a write outside ``takes/``)."""
    if not valid_take_id(take_id):
        raise InputError(f"take id {str(take_id)[:40]!r} is not a valid take id (letters, digits, '.', '_', '-')")
    return folder / "takes" / take_id / STATE_NAME


def read_state(folder: Path, take_ids: list[str]) -> dict[str, dict[str, Any]]:
    """The batch entries of those of ``take_ids`` that have a readable state file."""
    entries = {}
    for take_id in take_ids:
        if not valid_take_id(take_id):
            continue
        path = state_path(folder, take_id)
        if not os.path.lexists(path):
            continue
        try:
            data = strict_json(read_bytes(folder, path, STATE_LIMIT))
        except (OSError, InputError):
            continue
        if isinstance(data, dict) and data.get("format") == STATE_FORMAT and data.get("state") in STATES:
            entries[take_id] = data
    return entries


def write_state(folder: Path, take_id: str, state: str, key: str = "", reason: str = "",
                summary: dict[str, Any] | None = None) -> None:
    """Replace the take's batch entry (atomically). InputError when it cannot be written."""
    if state not in STATES:
        raise InputError(f"unknown batch state {state!r}")
    path = state_path(folder, take_id)
    data = {"format": STATE_FORMAT, "version": 1, "state": state, "key": key, "reason": reason,
            "summary": summary or {}, "updated": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    try:
        make_folder(folder, path.parent)
        write_file(folder, path, json.dumps(data, indent=1).encode())
    except OSError as error:
        raise InputError(f"cannot write the batch state {path} ({error.strerror or error})") from None
