"""OptiTrack Motive CSV export (format versions 1.2x and 1.3): the marker positions.

    Format Version,1.23,Take Name,T1,...,Capture Frame Rate,120.000000,Export Frame Rate,120.000000,...,
        Length Units,Meters,Coordinate Space,Global
    <blank>
    ,Type,Rigid Body,Rigid Body,...,Rigid Body Marker,...,Marker,Marker,Marker
    ,Name,hand,hand,...,hand_1,...,Unlabeled 1003,Unlabeled 1003,Unlabeled 1003
    ,ID,1,1,...
    ,Parent,...                               (some versions)
    ,,Rotation,Rotation,...,Position,Position,Position,Mean Marker Error,...,Position,Position,Position
    Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,,...,X,Y,Z
    0,0.000000,...

Version 1.21 writes the Type, Name and ID rows without their label cells (`,,Rigid Body,...`). The markers
are the Position X, Y, Z columns of the `Marker` (labelled, and `Unlabeled 1003` unlabelled), `Rigid Body
Marker` and `Bone Marker` types; rigid body and bone poses (rotation, position, error) are not markers.
The rate is the Export Frame Rate (else the Capture Frame Rate). Lengths are in the Length Units (Motive's
default is Meters) and converted to mm. Motive's world is Y up; it is turned to our Z-up frame with
:func:`core.io.axes.axes_rotation` (the inverse of our Y-up export): Motive's (x, y, z) becomes
(x, -z, y). Empty cells or exactly (0, 0, 0) are missing samples; frame numbers are the file's.
"""

from os import PathLike

import numpy as np

from handmocap.core.io.axes import axes_rotation
from handmocap.core.io.csv_file import split_cells
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

#: the column types whose Position columns are marker positions
MARKER_TYPES = ("Marker", "Rigid Body Marker", "Bone Marker")
_HEADER_LABELS = ("Type", "Name", "ID", "Parent")
#: header rows read before the Frame row at most (beyond, the file is not a Motive export)
_MAX_HEADER_ROWS = 16


def recognises_motive_csv(head: list[str]) -> bool:
    """True when the first line starts with Motive's `Format Version` cell."""
    return bool(head) and head[0].split(",", 1)[0].strip() == "Format Version"


def read_motive_csv(path: str | PathLike[str], frame_rate: float | None = None) -> Take:
    """Read the markers of a Motive CSV export (module docstring) into a Take (mm, Z up, NaN for missing) at
    the export rate, or at ``frame_rate`` (Hz) when given; raises TakeFormatError."""
    with open_text_lines(path) as lines:
        first = next(lines, None)
        if first is None or not recognises_motive_csv([first[1]]):
            raise TakeFormatError.at(path, "not a Motive CSV (the first line must start with 'Format Version')")
        settings = _settings(_cells(first, path))
        header_rows: list[list[str]] = []
        axis_line, axes = 0, None
        for number, line in lines:
            if not line.strip(" ,"):
                continue
            cells = _cells((number, line), path)
            if cells[0] == "Frame":
                axis_line, axes = number, cells
                break
            header_rows.append(cells)
            if len(header_rows) > _MAX_HEADER_ROWS:
                raise TakeFormatError.at(path, f"line {number}: no 'Frame,Time,...' row after the header")
        if axes is None:
            raise TakeFormatError.at(path, "the file ends before its 'Frame,Time (Seconds),X,Y,Z...' row")
        types, names, components = _header(header_rows, path)
        while axes and not axes[-1]:
            axes.pop()
        columns = _marker_columns(types, names, components, axes)
        if not columns:
            raise TakeFormatError.at(path, f"line {axis_line}: no marker positions (columns of type "
                                           f"{', '.join(MARKER_TYPES)}); export the markers from Motive")
        units = settings.get("Length Units", "Meters")
        scale = mm_per_unit(units, path)
        rate_text = settings.get("Export Frame Rate") or settings.get("Capture Frame Rate", "")
        rate = chosen_frame_rate(path, positive_number(rate_text), frame_rate,
                                 f"no valid Export Frame Rate ('{rate_text[:20]}')")
        table = read_number_rows(lines, len(axes), ",", path)
    coordinates = [column for _, start in columns for column in (start, start + 1, start + 2)]
    positions = zeros_to_nan(table[:, coordinates].reshape(len(table), len(columns), 3)) * scale
    positions = positions @ axes_rotation("y")   # Y up -> Z up: the inverse (transpose) of our Y-up export
    first_frame = int(table[0, 0]) if len(table) and np.isfinite(table[0, 0]) and table[0, 0] >= 0 else 0
    return Take(
        marker_names=unique_marker_names([name for name, _ in columns]),
        marker_positions=positions,
        frame_rate=rate,
        first_frame=first_frame,
        vendor="OptiTrack",
        source_units=units,
        source_path=str(path),
        frame_rate_given=frame_rate is not None,
    )


def _cells(row: tuple[int, str], path: str | PathLike[str]) -> list[str]:
    try:
        return split_cells(row[1], ",")
    except ValueError as error:
        raise TakeFormatError.at(path, f"line {row[0]}: {error}") from None


def _settings(cells: list[str]) -> dict[str, str]:
    """The `key,value,key,value...` pairs of the first line."""
    return {cells[index]: cells[index + 1] for index in range(0, len(cells) - 1, 2) if cells[index]}


def _header(rows: list[list[str]], path: str | PathLike[str]) -> tuple[list[str], list[str], list[str]]:
    """The Type, Name and component (Rotation / Position...) cells of each column. The Type and Name rows
    are found by their label cell (versions 1.22 on) or, without labels (1.21), are the first two rows;
    the component row is the last."""
    labelled = {row[1]: row for row in rows if len(row) > 1 and row[0] == "" and row[1] in _HEADER_LABELS}
    if "Type" in labelled and "Name" in labelled:
        types, names = labelled["Type"], labelled["Name"]
    elif len(rows) >= 3:
        types, names = rows[0], rows[1]
    else:
        raise TakeFormatError.at(path, f"{len(rows)} header rows before the Frame row; expected Type, Name, "
                                       "ID and the Rotation/Position row")
    return types, names, rows[-1]


def _marker_columns(types: list[str], names: list[str], components: list[str],
                    axes: list[str]) -> list[tuple[str, int]]:
    """(name, column of X) of each marker: Position X, Y, Z columns of one name and a marker type."""
    width = len(axes)

    def cell(row: list[str], index: int) -> str:
        return row[index] if index < len(row) else ""

    found = []
    for index in range(2, width - 2):
        if (axes[index:index + 3] == ["X", "Y", "Z"] and cell(types, index) in MARKER_TYPES
                and all(cell(components, index + k) == "Position" for k in range(3))
                and all(cell(names, index + k) == cell(names, index) for k in range(3))
                and all(cell(types, index + k) == cell(types, index) for k in range(3))):
            found.append((cell(names, index), index))
    return found
