"""Files inside a session folder, never through a symbolic link.

A session folder may come from a collaborator, so any of its entries may be a planted link. Every path
the session reads, writes or deletes is checked here first: neither the file nor a folder between the
session folder and it may be a symbolic link (InputError naming it), the final open uses ``O_NOFOLLOW``,
and deletions only remove regular files inside the session folder (a link is never followed and never
deleted through). Writes go through :func:`core.io.durable.write_atomic`.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from handmocap.core.errors import InputError
from handmocap.core.io.durable import write_atomic

NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
CLOEXEC = getattr(os, "O_CLOEXEC", 0)
NONBLOCK = getattr(os, "O_NONBLOCK", 0)  # a planted FIFO must not block the open (no effect on regular files)


def _link_error(root: Path, path: Path) -> InputError:
    return InputError(f"{path} is a symbolic link; a session folder must not contain links "
                      f"(replace it by the file or folder itself): {root} was not changed")


def refuse_links(root: Path, path: Path) -> None:
    """InputError when ``path`` is not inside ``root`` or when it, or a folder between ``root`` and it,
    is a symbolic link (entries that do not exist yet are fine)."""
    try:
        relative = Path(path).relative_to(root)
    except ValueError:
        raise InputError(f"{path} is outside the session folder {root}") from None
    if ".." in relative.parts:
        raise InputError(f"{path} is outside the session folder {root}")
    current = Path(root)
    for part in relative.parts:
        current = current / part
        try:
            mode = os.lstat(current).st_mode
        except FileNotFoundError:
            return
        except OSError as error:
            raise InputError(f"cannot read {current} ({error.strerror or error})") from None
        if stat.S_ISLNK(mode):
            raise _link_error(root, current)


def _open(root: Path, path: Path, flags: int, mode: int = 0o644) -> int:
    """``os.open`` of a regular file inside ``root`` without following links (InputError otherwise)."""
    refuse_links(root, path)
    try:
        descriptor = os.open(path, flags | NOFOLLOW | CLOEXEC | NONBLOCK, mode)
    except OSError:
        if os.path.islink(path):
            raise _link_error(root, path) from None
        raise
    if not stat.S_ISREG(os.fstat(descriptor).st_mode):
        os.close(descriptor)
        raise InputError(f"{path} is not a regular file")
    return descriptor


def read_bytes(root: Path, path: Path, limit: int | None = None) -> bytes:
    """The bytes of the regular file ``path`` inside ``root`` (OSError when missing or unreadable;
    InputError for a link or when it is larger than ``limit`` bytes)."""
    descriptor = _open(root, path, os.O_RDONLY)
    with os.fdopen(descriptor, "rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        if limit is not None and size > limit:
            raise InputError(f"{path} is {size} bytes, more than the {limit} a session file may have")
        return handle.read()


def open_append(root: Path, path: Path) -> BinaryIO:
    """A binary append handle on ``path`` inside ``root`` (created when missing), never through a link."""
    return os.fdopen(_open(root, path, os.O_WRONLY | os.O_APPEND | os.O_CREAT), "ab")


def open_lock_file(root: Path, path: Path) -> int:
    """A read-write descriptor of the lock file ``path`` inside ``root`` (created when missing, never
    truncated, never through a link)."""
    return _open(root, path, os.O_RDWR | os.O_CREAT)


def truncate(root: Path, path: Path, size: int) -> None:
    """Cut the regular file ``path`` inside ``root`` to ``size`` bytes, durably."""
    descriptor = _open(root, path, os.O_WRONLY)
    try:
        os.ftruncate(descriptor, size)
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def write_file(root: Path, path: Path, data: bytes) -> None:
    """Replace ``path`` inside ``root`` by ``data`` atomically (OSError when it cannot be written)."""
    refuse_links(root, path)
    write_atomic(path, data)


def make_folder(root: Path, path: Path) -> None:
    """Create the folder ``path`` inside ``root`` (and the folders above it) unless it exists; never
    through a link."""
    refuse_links(root, path)
    path.mkdir(parents=True, exist_ok=True)
    refuse_links(root, path)


def regular_files(root: Path, folder: Path, pattern: str = "*") -> Iterator[Path]:
    """The regular files matching ``pattern`` directly in ``folder`` inside ``root`` (links are skipped;
    nothing when ``folder`` does not exist)."""
    refuse_links(root, folder)
    if not folder.is_dir():
        return
    for path in sorted(folder.glob(pattern)):
        if stat.S_ISREG(os.lstat(path).st_mode):
            yield path


def remove_file(root: Path, path: Path) -> None:
    """Delete the regular file ``path`` inside ``root`` (nothing when it is missing; a link or a file
    reached through one is never deleted)."""
    refuse_links(root, path.parent)
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    if stat.S_ISREG(mode):
        path.unlink(missing_ok=True)


def refuse_links_within(root: Path, folder: Path) -> None:
    """InputError when ``folder`` inside ``root``, a folder above it, or an entry in it or in its
    sub-folders is a symbolic link (nothing when ``folder`` does not exist)."""
    refuse_links(root, folder)
    if not folder.is_dir():
        return
    pending = [folder]
    while pending:
        with os.scandir(pending.pop()) as entries:
            for entry in entries:
                if entry.is_symlink():
                    raise _link_error(root, Path(entry.path))
                if entry.is_dir(follow_symlinks=False):
                    pending.append(Path(entry.path))
