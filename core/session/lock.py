"""OS locks of a session folder (``fcntl.flock``): the take lock and the manifest lock.

* ``takes/<id>/lock`` is held for as long as a process has the take open for editing; a second
  process (or a second opening in the same process) gets the take read-only and is told who holds it;
* ``session.lock`` is held for the few milliseconds of a read-modify-write of ``session.json``.

The kernel releases a lock when its process ends, however it ends, so a lock is never left stale. While
held, the lock file holds its holder as JSON (user, host, pid, since) for the message; it is emptied on
release and never deleted or replaced (a process waiting on the old file would otherwise lock a file
nobody else locks). Lock files are opened without following links (:mod:`core.session.files`).
"""

from __future__ import annotations

import contextlib
import fcntl
import getpass
import json
import os
import socket
import time
from pathlib import Path

from handmocap.core.errors import InputError
from handmocap.core.session.files import open_lock_file, read_bytes

SESSION_LOCK_NAME = "session.lock"
TAKE_LOCK_NAME = "lock"
HOLDER_WAIT_S = 1.0  # the holder writes itself in right after taking the lock
MANIFEST_WAIT_S = 10.0  # a manifest update takes milliseconds; this long means the folder is stuck


def _holder_text() -> bytes:
    try:
        user = getpass.getuser()
    except (OSError, KeyError):
        user = "unknown user"
    since = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    return json.dumps({"user": user, "host": socket.gethostname(), "pid": os.getpid(), "since": since}).encode()


class FileLock:
    """An exclusive ``flock`` on the file ``path`` inside the session folder ``root``."""

    def __init__(self, root: Path, path: Path) -> None:
        self.root, self.path = root, path
        self._descriptor: int | None = None

    @property
    def held(self) -> bool:
        return self._descriptor is not None

    def acquire(self, wait_s: float = 0.0) -> bool:
        """Take the lock, waiting up to ``wait_s`` seconds; False when another holder keeps it. InputError
        when the lock file cannot be opened (a link, an unwritable folder)."""
        if self._descriptor is not None:
            return True
        try:
            descriptor = open_lock_file(self.root, self.path)
        except OSError as error:
            raise InputError(f"cannot open the lock file {self.path} ({error.strerror or error})") from None
        deadline, pause = time.monotonic() + wait_s, 0.002
        while True:
            try:
                fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    os.close(descriptor)
                    return False
                time.sleep(pause)
                pause = min(2 * pause, 0.05)
        try:
            os.ftruncate(descriptor, 0)
            os.pwrite(descriptor, _holder_text(), 0)
        except OSError:
            pass  # the holder is only for the message; the lock itself is taken
        self._descriptor = descriptor
        return True

    def release(self) -> None:
        """Empty the lock file and release the lock (nothing when not held)."""
        descriptor, self._descriptor = self._descriptor, None
        if descriptor is None:
            return
        with contextlib.suppress(OSError):
            os.ftruncate(descriptor, 0)
        try:
            fcntl.flock(descriptor, fcntl.LOCK_UN)
        finally:
            os.close(descriptor)

    def holder(self) -> str:
        """Who holds the lock, as one phrase (e.g. "ana on lab-pc (process 4711) since 2026-11-24 21:55:02
        UTC"); "another Hand Mocap Studio" when the file does not say (a holder that has just taken the
        lock is given up to ``HOLDER_WAIT_S`` to write itself in)."""
        deadline = time.monotonic() + HOLDER_WAIT_S
        while True:
            try:
                data = json.loads(read_bytes(self.root, self.path, limit=4096))
                return (f"{str(data['user'])[:64]} on {str(data['host'])[:64]} (process {int(data['pid'])}) "
                        f"since {str(data['since'])[:32]}")
            except (InputError, OSError, ValueError, KeyError, TypeError, RecursionError):
                if time.monotonic() >= deadline:
                    return "another Hand Mocap Studio"
                time.sleep(0.01)

    def __enter__(self) -> FileLock:
        if not self.acquire(MANIFEST_WAIT_S):
            raise InputError(f"the session is busy: {self.holder()} has held {self.path.name} for more than "
                             f"{MANIFEST_WAIT_S:.0f} s; try again")
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def manifest_lock(root: Path) -> FileLock:
    """The lock of the session's manifest, to use as ``with manifest_lock(folder): ...``."""
    return FileLock(root, root / SESSION_LOCK_NAME)
