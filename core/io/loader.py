"""Load and save takes by file extension (case-insensitive)."""

from collections.abc import Callable
from os import PathLike
from pathlib import Path

from core.io.c3d_file import read_c3d
from core.io.c3d_writer import write_c3d
from core.io.csv_file import read_csv, write_csv
from core.io.errors import TakeFormatError
from core.io.qualisys_tsv import read_tsv
from core.io.take import Take
from core.io.trc import read_trc, write_trc

_READERS: dict[str, Callable[[Path], Take]] = {
    ".c3d": read_c3d,
    ".tsv": read_tsv,
    ".trc": read_trc,
    ".csv": read_csv,
}

#: file types a take can be read from, and the file-dialog filter for them
READ_SUFFIXES = tuple(_READERS)
TAKE_FILE_FILTER = f"Motion capture takes ({' '.join('*' + suffix for suffix in READ_SUFFIXES)});;All files (*)"
_WRITERS: dict[str, Callable[[Take, Path], None]] = {".c3d": write_c3d, ".trc": write_trc, ".csv": write_csv}


def load_take(path: str | PathLike[str]) -> Take:
    """Read a .c3d, .tsv (Qualisys), .trc or .csv take: positions (F, M, 3) in mm, NaN for missing.

    Raises TakeFormatError (one line naming the file) when the file is missing, empty, of an unknown
    type, malformed, or holds no frames or no markers.
    """
    path = Path(path)
    if not path.exists():
        raise TakeFormatError.at(path, "file not found")
    if not path.is_file():
        raise TakeFormatError.at(path, "not a file")
    reader = _READERS.get(path.suffix.lower())
    if reader is None:
        raise TakeFormatError.at(
            path, f"unsupported file type '{path.suffix}' (expected .c3d, .tsv, .trc or .csv)"
        )
    try:
        if path.stat().st_size == 0:
            raise TakeFormatError.at(path, "file is empty")
        take = reader(path)
    except OSError as error:
        raise TakeFormatError.at(path, f"cannot read the file ({error.strerror or error})") from None
    if take.n_frames == 0:
        raise TakeFormatError.at(path, "contains no frames")
    if take.n_markers == 0:
        raise TakeFormatError.at(path, "contains no markers")
    return take


def save_take(take: Take, path: str | PathLike[str]) -> None:
    """Write `take` as .c3d, .trc or .csv (by extension) through :mod:`core.io.durable`: the old file is
    replaced only by a complete new one. Raises TakeFormatError or WriteError (one line naming the file)."""
    path = Path(path)
    writer = _WRITERS.get(path.suffix.lower())
    if writer is None:
        raise TakeFormatError.at(
            path, f"cannot write file type '{path.suffix}' (expected .c3d, .trc or .csv)"
        )
    if take.n_frames == 0 or take.n_markers == 0:
        raise TakeFormatError.at(path, f"nothing to write ({take.n_frames} frames, {take.n_markers} markers)")
    if not path.parent.is_dir():
        raise TakeFormatError.at(path, f"folder '{path.parent}' does not exist")
    writer(take, path)
