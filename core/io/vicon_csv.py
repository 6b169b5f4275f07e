"""Vicon Nexus CSV / TXT export: the marker positions of its "Trajectories" block.

    Devices                                   (other blocks, skipped: Devices, Model Outputs, Joints, Segments)
    ...
                                              (a blank row ends a block)
    Trajectories
    100                                       the frame rate, Hz
    ,,Angelica:HV,,,Angelica:C7,,             each Subject:Marker name over its X column
    Frame,Sub Frame,X,Y,Z,X,Y,Z
    ,,mm,mm,mm,mm,mm,mm                       units of each column
    1,0,209.331,1219.74,1780.67,,,            data; empty cells where a marker is missing
    2,0,209.475,1219.82,1780.88,167.652,1280.88,1664.62

Cells are separated by commas (tabs or semicolons when the Frame row has no comma); rows are often padded
with delimiters to the widest block. Names keep the `Subject:Marker` form as given. The Frame column is the
file's own numbering (the first becomes `Take.first_frame`). Exactly (0, 0, 0) is read as missing.
"""

import re
from collections.abc import Iterator
from itertools import takewhile
from os import PathLike

import numpy as np

from handmocap.core.io.csv_file import delimiter_of, split_cells
from handmocap.core.io.errors import TakeFormatError
from handmocap.core.io.take import (
    Take,
    chosen_frame_rate,
    mm_per_unit,
    open_text_lines,
    positive_number,
    read_number_rows,
    unique_marker_names,
    zeros_to_nan,
)

#: the names of the blocks a Nexus export is made of
BLOCK_NAMES = ("Trajectories", "Devices", "Model Outputs", "Joints", "Segments")
_FIRST_CELL = re.compile(r"[,\t;]")


def _first_cell(line: str) -> str:
    return _FIRST_CELL.split(line, maxsplit=1)[0].strip()


def _blank(line: str) -> bool:
    return not line.strip(" \t,;\r")


def recognises_vicon_csv(head: list[str]) -> bool:
    """True when the first non-blank line names a Nexus block and nothing else."""
    rows = [line for line in head if not _blank(line)]
    if not rows or _first_cell(rows[0]).lower() not in {name.lower() for name in BLOCK_NAMES}:
        return False
    return _blank(rows[0].strip()[len(_first_cell(rows[0])):])


def read_vicon_csv(path: str | PathLike[str], frame_rate: float | None = None) -> Take:
    """Read the Trajectories block of a Nexus export (module docstring) into a Take (mm, NaN for missing) at
    the block's rate, or at ``frame_rate`` (Hz) when given; raises TakeFormatError."""
    with open_text_lines(path) as lines:
        start = next((number for number, line in lines if _first_cell(line).lower() == "trajectories"), None)
        if start is None:
            raise TakeFormatError.at(path, "no Trajectories block (export the marker trajectories from Nexus)")
        header: list[tuple[int, str]] = []
        for row in (next(lines, None) for _ in range(4)):
            if row is None:
                raise TakeFormatError.at(path, f"the Trajectories block of line {start} ends before its data "
                                               "(expected rate, names, 'Frame,Sub Frame,X,Y,Z...' and units rows)")
            header.append(row)
        (_, rate_row), (_, name_row), (axis_line, axis_row), (_, unit_row) = header
        delimiter = delimiter_of(axis_row)
        try:
            axes, names, units = (split_cells(row, delimiter) for row in (axis_row, name_row, unit_row))
        except ValueError as error:
            raise TakeFormatError.at(path, f"Trajectories block of line {start}: {error}") from None
        while axes and not axes[-1]:
            axes.pop()
        n_markers = (len(axes) - 2) // 3
        if axes[:2] != ["Frame", "Sub Frame"] or n_markers == 0 or axes[2:] != ["X", "Y", "Z"] * n_markers:
            raise TakeFormatError.at(path, f"line {axis_line}: expected 'Frame,Sub Frame,X,Y,Z,X,Y,Z...', got "
                                           f"'{axis_row[:60]}'")
        names = (names + [""] * len(axes))[2:len(axes):3]
        units = [unit or "mm" for unit in (units + [""] * len(axes))[2:len(axes):3]]
        scale = np.array([mm_per_unit(unit, path) for unit in units])
        rate_text = _first_cell(rate_row)
        rate = chosen_frame_rate(path, positive_number(rate_text), frame_rate,
                                 f"the Trajectories block has no frame rate ('{rate_text[:20]}')")
        table = read_number_rows(_block_rows(lines), len(axes), delimiter, path)
    positions = zeros_to_nan(table[:, 2:].reshape(len(table), n_markers, 3)) * scale[None, :, None]
    first_frame = int(table[0, 0]) if len(table) and np.isfinite(table[0, 0]) and table[0, 0] >= 0 else 1
    return Take(
        marker_names=unique_marker_names(names),
        marker_positions=positions,
        frame_rate=rate,
        first_frame=first_frame,
        vendor="Vicon",
        source_units=units[0],
        source_path=str(path),
        frame_rate_given=frame_rate is not None,
    )


def _block_rows(lines: Iterator[tuple[int, str]]) -> Iterator[tuple[int, str]]:
    """The data rows of a block: up to its blank row or the next block's name."""
    return takewhile(lambda item: not _blank(item[1]) and _first_cell(item[1]) not in BLOCK_NAMES, lines)

