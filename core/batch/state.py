"""The batch state of a session: ``batch.json`` in the session folder, one entry per take.

::

    {"format": "handmocap-batch", "version": 1,
     "takes": {"<take id>": {"state": "queued|done|failed|skipped", "key": "<input key>", "reason": str,
                             "outputs": [path], "summary": {...}, "updated": iso}}}

A take is *done* for a key when its entry says "done" with that key (:func:`input_key`: the raw file's
content and the pipeline's). Every change is a read-modify-write under the session lock
(``session.lock``), written atomically through :mod:`core.session.files`, so workers and the driver
keep each other's entries and a killed batch never leaves a half-written file. A damaged state file is
set aside (renamed) and the batch starts afresh: it only says what can be skipped.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path
from typing import Any

from core.errors import InputError
from core.session.files import read_bytes, write_file
from core.session.lock import manifest_lock
from core.session.storage import set_aside, strict_json

STATE_NAME = "batch.json"
STATE_FORMAT = "handmocap-batch"
STATES = ("queued", "done", "failed", "skipped")
STATE_LIMIT = 256 * 2**20  # bytes; about 1 kB per take


def input_key(raw: Path, pipeline_key: str) -> str:
    """The hex sha256 of the raw take file's bytes and the pipeline's key."""
    digest = hashlib.sha256(pipeline_key.encode())
    with open(raw, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def read_state(folder: Path) -> dict[str, dict[str, Any]]:
    """The take entries of the session in ``folder`` (empty when there is no state file)."""
    path = folder / STATE_NAME
    if not os.path.lexists(path):
        return {}
    try:
        data = strict_json(read_bytes(folder, path, STATE_LIMIT))
        takes = data["takes"] if isinstance(data, dict) and data.get("format") == STATE_FORMAT else None
        if not isinstance(takes, dict) or not all(isinstance(entry, dict) for entry in takes.values()):
            raise InputError("not a batch state")
    except (OSError, InputError, KeyError):
        return {}
    return takes


def update_state(folder: Path, changes: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Merge ``changes`` (take id → fields) into the entries under the session lock; returns the entries.
    A damaged state file is set aside first. InputError when it cannot be written."""
    path = folder / STATE_NAME
    with manifest_lock(folder):
        takes = read_state(folder)
        if not takes and os.path.lexists(path):
            try:
                set_aside(folder, path)
            except OSError as error:
                raise InputError(f"cannot set the damaged {path} aside ({error.strerror or error})") from None
        now = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        for take_id, fields in changes.items():
            if fields.get("state") not in STATES:
                raise InputError(f"unknown batch state {fields.get('state')!r}")
            takes[take_id] = {"state": fields["state"], "key": "", "reason": "", "outputs": [], "summary": {},
                              "updated": now} | takes.get(take_id, {}) | fields | {"updated": now}
        data = json.dumps({"format": STATE_FORMAT, "version": 1, "takes": takes}, indent=1).encode()
        try:
            write_file(folder, path, data)
        except OSError as error:
            raise InputError(f"cannot write the batch state {path} ({error.strerror or error})") from None
    return takes
