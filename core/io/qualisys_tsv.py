"""Qualisys TSV (QTM 3D export) reading.

Layout: header lines `KEY<TAB>value...` (NO_OF_FRAMES, NO_OF_MARKERS, FREQUENCY, MARKER_NAMES,
DATA_INCLUDED, ...), then optionally a column row (`Frame<TAB>Time<TAB><name> X<TAB><name> Y<TAB>
<name> Z...`), then one row per frame. Without a column row the data have 3 M columns, or 3 M + 2
with frame and time first. Coordinates are millimetres; missing samples are empty cells, "nan" or
(0, 0, 0), all read as NaN. The first frame number is the first Frame cell (1 when absent).
"""

import collections
import itertools
import logging
import math
import re
from collections.abc import Iterable
from os import PathLike
from pathlib import Path

from handmocap.core.io.errors import TakeFormatError
from handmocap.core.io.take import (
    Take,
    chosen_frame_rate,
    open_text_lines,
    positive_number,
    read_number_rows,
    unique_marker_names,
    zeros_to_nan,
)

_log = logging.getLogger(__name__)

_HEADER_KEY = re.compile(r"[A-Z][A-Z0-9_]*")


def read_tsv(path: str | PathLike[str], frame_rate: float | None = None) -> Take:
    """Read a Qualisys TSV file into a Take (mm, NaN for missing) at its FREQUENCY, or at ``frame_rate`` (Hz)
    when given; raises TakeFormatError."""
    with open_text_lines(path) as lines:
        header: dict[str, list[str]] = {}
        current = next(lines, None)
        while current is not None:
            cells = current[1].split("\t")
            if not _HEADER_KEY.fullmatch(cells[0].strip()):
                break
            header.setdefault(cells[0].strip(), [cell.strip() for cell in cells[1:]])
            current = next(lines, None)
        if "MARKER_NAMES" not in header:
            raise TakeFormatError.at(path, "not a Qualisys TSV file (no MARKER_NAMES header line)")
        included = " ".join(header.get("DATA_INCLUDED", ["3D"])).strip()
        if included.upper() != "3D":
            raise TakeFormatError.at(path, f"contains '{included[:40]}' data; only 3D marker data can be read")
        file_names = [name.strip() for name in _trim(header["MARKER_NAMES"])]
        names = unique_marker_names(file_names)
        text = (header.get("FREQUENCY") or [""])[0]
        rate = chosen_frame_rate(path, positive_number(text), frame_rate,
                                 f"missing or invalid FREQUENCY header ('{text[:20]}')")

        columns = [cell.strip() for cell in current[1].split("\t")] if current is not None else []
        if current is not None and ("Frame" in columns or any(f"{name} X" in columns for name in names[:1])):
            frame_column = columns.index("Frame") if "Frame" in columns else None
            marker_columns = _marker_columns(columns, file_names, current[0], path)
            width = len(columns)
            data: Iterable[tuple[int, str]] = lines
        else:
            width = len(_trim(columns)) if columns else 3 * len(names)
            if current is not None and width not in (3 * len(names), 3 * len(names) + 2):
                raise TakeFormatError.at(path, f"line {current[0]}: {width} columns for {len(names)} markers")
            offset = width - 3 * len(names)
            frame_column = 0 if offset else None
            marker_columns = list(range(offset, width))
            data = itertools.chain([current], lines) if current is not None else lines
        table = read_number_rows(data, width, "\t", path)
    n_frames = len(table)
    positions = zeros_to_nan(table[:, marker_columns].reshape(n_frames, len(names), 3))
    declared = header.get("NO_OF_FRAMES", [""])[0]
    if declared.isascii() and declared.isdigit() and declared.lstrip("0") != str(n_frames).lstrip("0"):
        _log.warning("%s: NO_OF_FRAMES says %s, the file has %d frames", Path(path).name, declared[:20], n_frames)
    first_frame = 1
    if frame_column is not None and n_frames and math.isfinite(table[0, frame_column]):
        first_frame = int(table[0, frame_column])
    return Take(
        marker_names=names,
        marker_positions=positions,
        frame_rate=rate,
        first_frame=first_frame,
        vendor="Qualisys",
        source_units="mm",
        source_path=str(path),
        frame_rate_given=frame_rate is not None,
    )


def _marker_columns(columns: list[str], file_names: list[str], line: int, path: str | PathLike[str]) -> list[int]:
    """Column of each coordinate `<name> X/Y/Z`, marker by marker; the n-th marker of a name takes the n-th
    column of that name (one pass over the columns, so linear in their number)."""
    free: dict[str, collections.deque[int]] = {}
    for index, column in enumerate(columns):
        free.setdefault(column, collections.deque()).append(index)
    marker_columns: list[int] = []
    for name in file_names:
        for axis in "XYZ":
            label = f"{name} {axis}"
            if not free.get(label):
                raise TakeFormatError.at(path, f"line {line}: no column '{label[:80]}'")
            marker_columns.append(free[label].popleft())
    return marker_columns


def _trim(cells: list[str]) -> list[str]:
    """Cells without the empty ones a trailing tab leaves at the end."""
    end = len(cells)
    while end and not cells[end - 1].strip():
        end -= 1
    return cells[:end]
