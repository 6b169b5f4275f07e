"""NOKOV / XING (XINGYING) CSV as the system exports it:

    Marker1-X,Marker1-Y,Marker1-Z,L-A1-X,L-A1-Y,L-A1-Z,...
    205.278137,103.990356,753.238281,nan,nan,nan,...

One column row `<name>-X,<name>-Y,<name>-Z` per marker (names may hold hyphens: `R-Wan-nei`), no frame or
time column, millimetres, `nan` where a marker was not reconstructed, and NO frame rate: the caller gives it
(``--rate``, the open dialog, the pipeline's ``rate``), else FrameRateMissingError. Frames are numbered
from 1. Read by the axis-CSV reader (:mod:`core.io.csv_file`) with the vendor named.
"""

import re
from os import PathLike

from handmocap.core.io.csv_file import read_csv, split_cells
from handmocap.core.io.take import Take

_NOKOV_COLUMN = re.compile(r".*\S-[XYZ]", re.DOTALL)


def recognises_nokov_csv(head: list[str]) -> bool:
    """True when the first line is a NOKOV column row: every cell `<name>-X`, `-Y` or `-Z` (upper case), a
    multiple of three of them, no frame or time column."""
    if not head or "," not in head[0]:
        return False
    try:
        cells = split_cells(head[0], ",")
    except ValueError:
        return False
    while cells and not cells[-1]:
        cells.pop()
    return bool(cells) and len(cells) % 3 == 0 and all(_NOKOV_COLUMN.fullmatch(cell) for cell in cells)


def read_nokov_csv(path: str | PathLike[str], frame_rate: float | None = None) -> Take:
    """Read a NOKOV CSV export (module docstring) at ``frame_rate`` (Hz); FrameRateMissingError without it."""
    return read_csv(path, frame_rate, vendor="NOKOV")
