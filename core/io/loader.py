"""Load and save takes. :data:`TAKE_FORMATS` is the one registry of the file formats takes are read from: the
loader, the file dialogs' filter and the drop targets read it; adding a format is one module and one entry.

A .c3d, .tsv or .trc file is read by its suffix. A .csv or .txt file is read by its content: the first
format whose ``recognises`` accepts its first lines (Motive, Vicon Nexus, NOKOV, then any axis CSV,
ours included).
"""

from collections.abc import Callable
from dataclasses import dataclass
from itertools import islice
from os import PathLike
from pathlib import Path

from handmocap.core.io.c3d_file import read_c3d
from handmocap.core.io.c3d_writer import write_c3d
from handmocap.core.io.csv_file import read_csv, recognises_axis_csv, write_csv
from handmocap.core.io.errors import TakeFormatError
from handmocap.core.io.motive_csv import read_motive_csv, recognises_motive_csv
from handmocap.core.io.nokov_csv import read_nokov_csv, recognises_nokov_csv
from handmocap.core.io.qualisys_tsv import read_tsv
from handmocap.core.io.take import Take, check_frame_rate, open_text_lines
from handmocap.core.io.trc import read_trc, write_trc
from handmocap.core.io.vicon_csv import read_vicon_csv, recognises_vicon_csv

#: lines of a .csv or .txt file its format is recognised from
HEAD_LINES = 24


@dataclass(frozen=True)
class TakeFormat:
    """A file format takes are read from: its ``name``, file ``suffixes``, its reader ``read(path,
    frame_rate)`` (Hz or None: the file's own) and, for the text exports that share .csv and .txt, the test
    ``recognises(first_lines)`` that tells it from the others (None: recognised by its suffix alone)."""

    name: str
    suffixes: tuple[str, ...]
    read: Callable[[Path, float | None], Take]
    recognises: Callable[[list[str]], bool] | None = None


#: every format takes are read from, in the order .csv and .txt files are tried
TAKE_FORMATS: tuple[TakeFormat, ...] = (
    TakeFormat("C3D", (".c3d",), read_c3d),
    TakeFormat("Qualisys TSV", (".tsv",), read_tsv),
    TakeFormat("TRC", (".trc",), read_trc),
    TakeFormat("OptiTrack Motive CSV", (".csv",), read_motive_csv, recognises_motive_csv),
    TakeFormat("Vicon Nexus CSV/TXT", (".csv", ".txt"), read_vicon_csv, recognises_vicon_csv),
    TakeFormat("NOKOV CSV", (".csv",), read_nokov_csv, recognises_nokov_csv),
    TakeFormat("CSV of <name>_x, <name>_y, <name>_z columns", (".csv", ".txt"), read_csv, recognises_axis_csv),
)

#: file types a take can be read from, and the file-dialog filter for them
READ_SUFFIXES = tuple(dict.fromkeys(suffix for fmt in TAKE_FORMATS for suffix in fmt.suffixes))
TAKE_FILE_FILTER = ";;".join(
    [f"Motion capture takes ({' '.join('*' + suffix for suffix in READ_SUFFIXES)})"]
    + [f"{fmt.name} ({' '.join('*' + suffix for suffix in fmt.suffixes)})" for fmt in TAKE_FORMATS]
    + ["All files (*)"])
_WRITERS: dict[str, Callable[[Take, Path], None]] = {".c3d": write_c3d, ".trc": write_trc, ".csv": write_csv}


def recognised_format(path: str | PathLike[str]) -> TakeFormat | None:
    """The format of the take file ``path`` by its suffix and, for .csv and .txt, by its first lines; None when
    no format takes it (a folder scan then skips notes and other tables)."""
    path = Path(path)
    candidates = [fmt for fmt in TAKE_FORMATS if path.suffix.lower() in fmt.suffixes]
    if all(fmt.recognises is None for fmt in candidates):
        return candidates[0] if candidates else None
    with open_text_lines(path) as lines:
        head = [line for _, line in islice(lines, HEAD_LINES)]
    return next((fmt for fmt in candidates if fmt.recognises is not None and fmt.recognises(head)), None)


def take_format(path: str | PathLike[str]) -> TakeFormat:
    """The format of the take file ``path``: by its suffix, and for .csv and .txt by its first lines (a file no
    format recognises goes to the last, most general one of its suffix). TakeFormatError for an unknown
    suffix."""
    path = Path(path)
    candidates = [fmt for fmt in TAKE_FORMATS if path.suffix.lower() in fmt.suffixes]
    if not candidates:
        raise TakeFormatError.at(path, f"unsupported file type '{path.suffix}' (expected "
                                       f"{', '.join(READ_SUFFIXES[:-1])} or {READ_SUFFIXES[-1]})")
    return recognised_format(path) or candidates[-1]   # the most general reader then says what the file lacks


def load_take(path: str | PathLike[str], frame_rate: float | None = None) -> Take:
    """Read a take of any format of :data:`TAKE_FORMATS`: positions (F, M, 3) in mm, NaN for missing.

    ``frame_rate`` (Hz), when given, is the take's rate even when the file states one (the take remembers it
    was given: ``Take.frame_rate_given``). Raises FrameRateMissingError when the file states no rate and none
    is given; TakeFormatError (one line naming the file) when the file is missing, empty, of an unknown type,
    malformed, or holds no frames or no markers.
    """
    path = Path(path)
    if not path.exists():
        raise TakeFormatError.at(path, "file not found")
    if not path.is_file():
        raise TakeFormatError.at(path, "not a file")
    if frame_rate is not None:
        frame_rate = check_frame_rate(frame_rate, path)
    try:
        if path.stat().st_size == 0:
            raise TakeFormatError.at(path, "file is empty")
        take = take_format(path).read(path, frame_rate)
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
