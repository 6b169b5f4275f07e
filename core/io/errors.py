"""The errors raised for take files that cannot be read or written."""

from os import PathLike
from pathlib import Path
from typing import Self

from handmocap.core.errors import InputError


class TakeFormatError(InputError):
    """A take file is missing, malformed or cannot be represented; the message is one line naming the file."""

    @classmethod
    def at(cls, path: str | PathLike[str] | None, problem: str) -> Self:
        """Build the error `"<file name>: <problem>"` (or `"take: <problem>"` when there is no file)."""
        where = Path(path).name if path is not None else "take"
        return cls(" ".join(f"{where}: {problem}".split()))


class FrameRateMissingError(TakeFormatError):
    """A take file states no frame rate (NOKOV CSV, a CSV without a time column) and none was given: the
    caller asks the user (``--rate``, the open dialog, the pipeline's ``rate``) and reads the file again."""

    @classmethod
    def at_file(cls, path: str | PathLike[str] | None, why: str = "the file has no frame rate") -> Self:
        """The error `"<file name>: <why>; give it with --rate HZ"`."""
        return cls.at(path, f"{why}; give it with --rate HZ")
