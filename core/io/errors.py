"""The error raised for take files that cannot be read or written."""

from os import PathLike
from pathlib import Path

from core.errors import InputError


class TakeFormatError(InputError):
    """A take file is missing, malformed or cannot be represented; the message is one line naming the file."""

    @classmethod
    def at(cls, path: str | PathLike[str] | None, problem: str) -> "TakeFormatError":
        """Build the error `"<file name>: <problem>"` (or `"take: <problem>"` when there is no file)."""
        where = Path(path).name if path is not None else "take"
        return cls(" ".join(f"{where}: {problem}".split()))
