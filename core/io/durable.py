"""Durable file writes: a crash, a full disk or a file-size limit leaves either the old file or the new one.

Every file the program writes goes through this module. The bytes go to a new temporary file in the
target's folder with an unpredictable name, created with ``O_EXCL | O_NOFOLLOW`` (mode 0o666 less the
umask), so a planted file or link of that name is never followed or reused. The temporary is flushed,
fsync'ed and its size checked (and, for formats cheap to re-read, opened again by ``verify``), then
renamed over the target, and the folder is fsync'ed so that the rename itself survives a power cut.

On any error (ENOSPC, EFBIG under ``ulimit -f``, EACCES, ...) the old file is untouched, the temporary is
removed and :class:`WriteError` names the file in one line. A target that is a symbolic link is refused:
writing through it would replace a file elsewhere.

Three ways in: :func:`write_atomic` (bytes in memory), :func:`durable_stream` (a binary stream to write
to, for large outputs written piece by piece) and :func:`durable_path` (a temporary path, for libraries
that write by file name).
"""

from __future__ import annotations

import errno
import os
import secrets
import stat
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import BinaryIO

from handmocap.core.errors import InputError

#: called on the finished temporary file before it replaces the target; raises OSError or InputError if bad
Verify = Callable[[Path], None]

_CREATE_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0)


class WriteError(InputError, OSError):
    """A file could not be written; the message is one line naming it. Also an OSError (``errno`` and
    ``strerror`` the system's reason) so that callers that wrap OSError in their own message keep working."""

    def __init__(self, message: str, code: int | None = None, reason: str | None = None) -> None:
        OSError.__init__(self, code, reason or message)
        self.message = message

    def __str__(self) -> str:
        return self.message


def fsync_folder(folder: Path) -> None:
    """Make a rename or a new file in ``folder`` durable (no-op where folders cannot be opened)."""
    try:
        descriptor = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(descriptor)
    except OSError:
        pass
    finally:
        os.close(descriptor)


def check_target(path: str | os.PathLike[str]) -> Path:
    """``path`` as a Path once it is known to be writable as a file: its folder exists, and it is neither
    a folder nor a symbolic link. Raises :class:`WriteError` (one line) otherwise."""
    target = Path(path)
    if target.is_symlink():
        raise WriteError(f"{target} is a symbolic link; refusing to write through it", errno.ELOOP,
                         "is a symbolic link")
    if target.is_dir():
        raise WriteError(f"cannot write {target}: it is a folder", errno.EISDIR, "is a folder")
    folder = target.parent
    if not folder.is_dir():
        raise WriteError(f"cannot write {target}: folder {folder} does not exist", errno.ENOENT,
                         "folder does not exist")
    return target


def write_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Replace ``path`` by ``data`` atomically and durably. Raises :class:`WriteError` (an InputError and
    an OSError) naming the file; the old file is then unchanged."""
    with durable_stream(path) as stream:
        stream.write(data)


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """:func:`write_atomic` of ``text`` encoded as UTF-8."""
    write_atomic(path, text.encode("utf-8"))


@contextmanager
def durable_stream(path: str | os.PathLike[str], verify: Verify | None = None) -> Iterator[BinaryIO]:
    """Yield a binary stream whose bytes replace ``path`` when the block ends without an error (module
    docstring); the size written is checked against the file, then ``verify`` runs on the temporary."""
    with _replacing(path) as (target, temporary, descriptor):
        with os.fdopen(descriptor, "wb") as stream:
            yield stream
            stream.flush()
            size = stream.tell()
            os.fsync(stream.fileno())
        _finish(temporary, target, size, verify)


@contextmanager
def durable_path(path: str | os.PathLike[str], verify: Verify | None = None) -> Iterator[Path]:
    """Yield the path of a new empty temporary file (named like ``path``, same suffix) for a writer that
    needs a file name; when the block ends without an error it is fsync'ed, checked by ``verify`` and
    renamed over ``path`` (module docstring)."""
    with _replacing(path) as (target, temporary, descriptor):
        os.close(descriptor)
        yield temporary
        _finish(temporary, target, None, verify)


def verify_zip(path: Path) -> None:
    """Check that ``path`` is a complete zip file (e.g. ``.npz``): its central directory, at the end of the
    file, reads. Raises OSError otherwise."""
    try:
        with zipfile.ZipFile(path) as archive:
            archive.infolist()
    except zipfile.BadZipFile as error:
        raise OSError(errno.EIO, f"the written file does not read back as a zip file ({error})") from None


@contextmanager
def _replacing(path: str | os.PathLike[str]) -> Iterator[tuple[Path, Path, int]]:
    """Yield ``(target, temporary, descriptor)``: the checked target and a new temporary beside it, open
    for writing. An OSError in the block is the one :class:`WriteError` of the target; the temporary is
    removed however the block ends (after :func:`_finish` renamed it there is nothing left to remove)."""
    target = check_target(path)
    temporary = None
    try:
        temporary, descriptor = _create_temporary(target)
        yield target, temporary, descriptor
    except WriteError:
        raise
    except OSError as error:
        raise _failure(target, error) from None
    finally:
        if temporary is not None:
            _remove(temporary)


def _create_temporary(target: Path) -> tuple[Path, int]:
    """A new file next to ``target`` with a 64-bit random name (ending in the target's suffix, which some
    writers require): ``(path, write descriptor)``."""
    name = f".{target.stem[:100]}.{secrets.token_hex(8)}.tmp{target.suffix[:20]}"
    temporary = target.with_name(name)
    return temporary, os.open(temporary, _CREATE_FLAGS, 0o666)


def _finish(temporary: Path, target: Path, size: int | None, verify: Verify | None) -> None:
    """fsync and check the temporary (a regular file of ``size`` bytes, passes ``verify``), then rename it
    over ``target`` and fsync the folder."""
    descriptor = os.open(temporary, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        status = os.fstat(descriptor)
        if not stat.S_ISREG(status.st_mode):
            raise OSError(errno.EIO, "the temporary file was replaced while writing")
        if size is not None and status.st_size != size:
            raise OSError(errno.EIO, f"{status.st_size} of {size} bytes reached the disk")
        os.fsync(descriptor)
    finally:
        os.close(descriptor)
    if verify is not None:
        try:
            verify(temporary)
        except InputError as error:
            raise OSError(errno.EIO, f"the written file does not read back ({error})") from None
    if target.is_symlink():
        raise WriteError(f"{target} is a symbolic link; refusing to write through it", errno.ELOOP,
                         "is a symbolic link")
    os.replace(temporary, target)
    fsync_folder(target.parent)


def _failure(target: Path, error: OSError) -> WriteError:
    """The one-line error for a write of ``target`` that failed with ``error``."""
    reason = error.strerror or str(error) or type(error).__name__
    kept = "the old file is kept" if target.exists() else "nothing was written"
    return WriteError(f"cannot write {target}: {reason} ({kept})", error.errno, reason)


def _remove(temporary: Path) -> None:
    """Remove a temporary file left by a failed write (it is ours: created with O_EXCL)."""
    with suppress(OSError):  # e.g. the folder became read-only: the hidden temporary stays, the target is intact
        temporary.unlink()
