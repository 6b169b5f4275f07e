"""CSV takes, one row per frame: our own, and any CSV whose columns are a marker name and an axis letter.

    # handmocap take: frame_rate=100.0, units=mm
    frame,time,hand_top_x,hand_top_y,hand_top_z,thumb_tip_x,thumb_tip_y,thumb_tip_z
    1,0.000000,110.406000,135.075000,460.584000,,,
    2,0.010000,110.763000,135.349000,460.458000,141.625000,248.964000,391.280000

- Comment lines start with "#" and may carry `frame_rate=<Hz>` and `units=<mm|cm|m>` (default mm).
- The column row names an optional frame column (`frame`, `Frame#`, `Frame number`...), an optional time
  column (`time`, `Time (s)`, `time_s`, `Time (ms)`...) and three columns per marker: the marker's name,
  a separator (`_`, `-`, `.` or a space) and the axis letter, X, Y then Z in any case (`thumb_tip_x`,
  `L-A1-X`, `RSHO.X`, `wrist Y`). Names containing the delimiter are quoted (RFC 4180).
- Cells are separated by commas; by tabs or semicolons when the column row has no comma.
- The frame rate is the one given by the caller (it overrides the file's), else the `frame_rate`
  setting, else 1 / median step of the time column; without any, FrameRateMissingError.
- `frame` is the file's frame number (the first one becomes `Take.first_frame`, 1 when absent).
- Missing samples are empty cells, "nan" or (0, 0, 0). Written values are mm.
"""

import csv
import io
import math
import re
from dataclasses import dataclass
from os import PathLike

import numpy as np

from handmocap.core.io.durable import write_text_atomic
from handmocap.core.io.errors import FrameRateMissingError, TakeFormatError
from handmocap.core.io.take import (
    Take,
    chosen_frame_rate,
    format_number_rows,
    mm_per_unit,
    open_text_lines,
    read_number_rows,
    unique_marker_names,
    zeros_to_nan,
)

_SETTING = re.compile(r"(\w+)\s*=\s*([^\s,;]+)")
_FRAME_COLUMN = re.compile(r"frames?(\s*#|[ _]?(no\.?|nr\.?|num(ber)?|index))?", re.IGNORECASE)
_TIME_COLUMN = re.compile(r"(time|timestamp)\s*(?:[\[(]\s*(?P<unit>s|sec|secs|seconds|ms|msec|milliseconds)\s*[\])]"
                          r"|_(?P<suffix>s|sec|ms))?", re.IGNORECASE)
_AXIS_COLUMN = re.compile(r"(?P<name>.*\S)[_\-. ](?P<axis>[xyz])", re.IGNORECASE | re.DOTALL)
_SECONDS_PER_TIME_UNIT = {"ms": 1e-3, "msec": 1e-3, "milliseconds": 1e-3}


@dataclass
class ColumnLayout:
    """What the columns of an axis CSV hold: marker names, their X, Y, Z columns (3 M, marker by marker), the
    frame and time columns (None when absent) and the seconds per unit of the time column."""

    marker_names: list[str]
    coordinate_columns: list[int]
    frame_column: int | None = None
    time_column: int | None = None
    seconds_per_time_unit: float = 1.0


def column_layout(columns: list[str]) -> ColumnLayout:
    """The layout of a column row (cells already split and stripped); ValueError saying which column does
    not fit. A trailing empty column (a row ending in a delimiter) is ignored."""
    while columns and not columns[-1]:
        columns = columns[:-1]
    layout = ColumnLayout([], [])
    index = 0
    while index < len(columns):
        column = columns[index]
        if layout.frame_column is None and not layout.marker_names and _FRAME_COLUMN.fullmatch(column):
            layout.frame_column = index
            index += 1
            continue
        time = _TIME_COLUMN.fullmatch(column)
        if layout.time_column is None and not layout.marker_names and time:
            layout.time_column = index
            unit = (time.group("unit") or time.group("suffix") or "s").lower()
            layout.seconds_per_time_unit = _SECONDS_PER_TIME_UNIT.get(unit, 1.0)
            index += 1
            continue
        triple = [_AXIS_COLUMN.fullmatch(cell) for cell in columns[index:index + 3]]
        if len(triple) < 3 or not all(triple):
            shown = ",".join(columns[index:index + 3])[:80]
            raise ValueError(f"expected columns <name>_x,<name>_y,<name>_z (or -X, .X, ' X') after optional frame "
                             f"and time columns, got '{shown}'")
        names = [match.group("name") for match in triple if match]
        axes = "".join(match.group("axis").lower() for match in triple if match)
        if axes != "xyz" or len(set(names)) != 1:
            shown = ",".join(columns[index:index + 3])[:80]
            raise ValueError(f"expected columns <name>_x,<name>_y,<name>_z of one marker in that order, got '{shown}'")
        layout.marker_names.append(names[0])
        layout.coordinate_columns += [index, index + 1, index + 2]
        index += 3
    if not layout.marker_names:
        raise ValueError("no marker columns (<name>_x,<name>_y,<name>_z)")
    return layout


def delimiter_of(column_row: str) -> str:
    """The cell delimiter of a text table from its column row: "," unless the row has none and has tabs or
    semicolons."""
    if "," in column_row:
        return ","
    return "\t" if "\t" in column_row else ";" if ";" in column_row else ","


def split_cells(row: str, delimiter: str) -> list[str]:
    """The stripped cells of one text row (quoted cells as RFC 4180); ValueError when malformed."""
    try:
        return [cell.strip() for cell in next(csv.reader([row], delimiter=delimiter), [])]
    except csv.Error as error:
        raise ValueError(f"malformed row ({error})") from None


def recognises_axis_csv(head: list[str]) -> bool:
    """True when the first lines of a file are those of an axis CSV: comments, then a column row of axis
    columns (with optional frame and time columns)."""
    rows = [line for line in head if line.strip() and not line.startswith("#")]
    if not rows:
        return bool(head) and head[0].startswith("#")
    try:
        column_layout(split_cells(rows[0], delimiter_of(rows[0])))
    except ValueError:
        return False
    return True


def read_csv(path: str | PathLike[str], frame_rate: float | None = None, vendor: str = "unknown") -> Take:
    """Read an axis CSV take (format in the module docstring) into a Take at ``frame_rate`` (Hz) when given,
    else at the file's rate; ``vendor`` names the system (our own files say "handmocap"). Raises
    TakeFormatError, FrameRateMissingError when the rate is in neither."""
    with open_text_lines(path) as lines:
        settings: dict[str, str] = {}
        comments: list[str] = []
        current = next(lines, None)
        while current is not None and (current[1].startswith("#") or not current[1].strip()):
            settings.update((key.lower(), value) for key, value in _SETTING.findall(current[1]))
            comments.append(current[1])
            current = next(lines, None)
        if current is None:
            raise TakeFormatError.at(path, "no column row (expected 'frame,time,<name>_x,<name>_y,<name>_z,...')")
        row, column_row = current
        delimiter = delimiter_of(column_row)
        try:
            layout = column_layout(split_cells(column_row, delimiter))
        except ValueError as error:
            raise TakeFormatError.at(path, f"line {row}: {error}") from None
        rate_in_file = _setting_rate(settings, path)
        if frame_rate is None and rate_in_file is None and layout.time_column is None:
            raise FrameRateMissingError.at_file(path)   # said before the data are read
        width = max(layout.coordinate_columns[-1], layout.frame_column or 0, layout.time_column or 0) + 1
        data = ((number, line) for number, line in lines if not line.startswith("#"))
        table = read_number_rows(data, width, delimiter, path)
    units = settings.get("units", "mm")
    scale = mm_per_unit(units, path)
    n_markers = len(layout.marker_names)
    positions = zeros_to_nan(table[:, layout.coordinate_columns].reshape(len(table), n_markers, 3)) * scale
    if rate_in_file is None and layout.time_column is not None:
        rate_in_file = _time_column_rate(table[:, layout.time_column] * layout.seconds_per_time_unit)
    rate = chosen_frame_rate(path, rate_in_file, frame_rate,
                             "the file has no frame rate (no frame_rate setting, and the time column does not "
                             "increase)" if layout.time_column is not None else "the file has no frame rate")
    first_frame = 1
    if layout.frame_column is not None and len(table) and math.isfinite(table[0, layout.frame_column]):
        first_frame = int(table[0, layout.frame_column])
    return Take(
        marker_names=unique_marker_names(layout.marker_names),
        marker_positions=positions,
        frame_rate=rate,
        first_frame=first_frame,
        vendor="handmocap" if "handmocap" in " ".join(comments).lower() else vendor,
        source_units=units,
        source_path=str(path),
        frame_rate_given=frame_rate is not None,
    )


def write_csv(take: Take, path: str | PathLike[str]) -> None:
    """Write `take` as a CSV take in mm (format in the module docstring) through :mod:`core.io.durable`."""
    column_row = io.StringIO()
    columns = ["frame", "time"] + [f"{name}_{axis}" for name in take.marker_names for axis in "xyz"]
    csv.writer(column_row, lineterminator="\n").writerow(columns)
    text = (
        f"# handmocap take: frame_rate={take.frame_rate!r}, units=mm\n"
        + column_row.getvalue()
        + format_number_rows(take.first_frame, take.frame_rate, take.marker_positions, ",")
    )
    write_text_atomic(path, text)


def _setting_rate(settings: dict[str, str], path: str | PathLike[str]) -> float | None:
    """The `frame_rate` setting of the comment lines (Hz), None when there is none."""
    if "frame_rate" not in settings:
        return None
    try:
        value = float(settings["frame_rate"])
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise TakeFormatError.at(path, f"invalid frame_rate '{settings['frame_rate'][:40]}'")
    return value


def _time_column_rate(times_s: np.ndarray) -> float | None:
    """1 / median step of the time column (s), None when the times do not increase."""
    steps = np.diff(times_s)
    steps = steps[np.isfinite(steps)]
    if steps.size == 0 or not np.median(steps) > 0:
        return None
    return float(1.0 / np.median(steps))
