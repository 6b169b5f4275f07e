"""Simple CSV takes, one row per frame:

    # handmocap take: frame_rate=100.0, units=mm
    frame,time,hand_top_x,hand_top_y,hand_top_z,thumb_tip_x,thumb_tip_y,thumb_tip_z
    1,0.000000,110.406000,135.075000,460.584000,,,
    2,0.010000,110.763000,135.349000,460.458000,141.625000,248.964000,391.280000

- Comment lines start with "#" and may carry `frame_rate=<Hz>` and `units=<mm|cm|m>` (default mm).
  Without `frame_rate` the rate is 1 / median step of the `time` column (seconds).
- The column row names `frame` and `time` (both optional) and three columns `<name>_x`, `<name>_y`,
  `<name>_z` per marker, in that order. Names containing commas are quoted (RFC 4180).
- `frame` is the file's frame number (the first one becomes `Take.first_frame`, 1 when absent).
- Missing samples are empty cells (also "nan" or (0, 0, 0) on reading). Written values are mm.
"""

import csv
import io
import math
import re
from os import PathLike

import numpy as np

from core.io.durable import write_text_atomic
from core.io.errors import TakeFormatError
from core.io.take import (
    Take,
    format_number_rows,
    mm_per_unit,
    open_text_lines,
    read_number_rows,
    unique_marker_names,
    zeros_to_nan,
)

_SETTING = re.compile(r"(\w+)\s*=\s*([^\s,;]+)")


def read_csv(path: str | PathLike[str]) -> Take:
    """Read a CSV take (format in the module docstring) into a Take; raises TakeFormatError."""
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
        try:
            columns = [cell.strip() for cell in next(csv.reader([column_row]))]
        except csv.Error as error:
            raise TakeFormatError.at(path, f"line {row}: malformed column row ({error})") from None
        lowered = [column.lower() for column in columns]
        frame_column = lowered.index("frame") if "frame" in lowered else None
        time_column = lowered.index("time") if "time" in lowered else None
        coordinate_columns = [i for i in range(len(columns)) if i not in (frame_column, time_column)]
        if len(coordinate_columns) % 3:
            raise TakeFormatError.at(
                path,
                f"line {row}: expected columns frame,time,<name>_x,<name>_y,<name>_z,"
                f"... ({len(coordinate_columns)} coordinate columns, not 3 per marker)",
            )
        names: list[str] = []
        for start in range(0, len(coordinate_columns), 3):
            triple = [columns[i] for i in coordinate_columns[start : start + 3]]
            name = triple[0][:-2]
            if [column.lower() for column in triple] != [f"{name}_{axis}".lower() for axis in "xyz"]:
                raise TakeFormatError.at(
                    path, f"line {row}: expected columns <name>_x,<name>_y,<name>_z, got {','.join(triple)[:80]}"
                )
            names.append(name)
        data = ((number, line) for number, line in lines if not line.startswith("#"))
        table = read_number_rows(data, len(columns), ",", path)
    units = settings.get("units", "mm")
    scale = mm_per_unit(units, path)
    positions = zeros_to_nan(table[:, coordinate_columns].reshape(len(table), len(names), 3)) * scale
    frame_rate = _frame_rate(settings, table[:, time_column] if time_column is not None else None, path)
    first_frame = 1
    if frame_column is not None and len(table) and math.isfinite(table[0, frame_column]):
        first_frame = int(table[0, frame_column])
    return Take(
        marker_names=unique_marker_names(names),
        marker_positions=positions,
        frame_rate=frame_rate,
        first_frame=first_frame,
        vendor="handmocap" if "handmocap" in " ".join(comments).lower() else "unknown",
        source_units=units,
        source_path=str(path),
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


def _frame_rate(settings: dict[str, str], times: np.ndarray | None, path: str | PathLike[str]) -> float:
    """Rate in Hz from the `frame_rate` setting, else from the median step of the time column (s)."""
    if "frame_rate" in settings:
        try:
            return float(settings["frame_rate"])
        except ValueError:
            raise TakeFormatError.at(path, f"invalid frame_rate '{settings['frame_rate']}'") from None
    steps = np.diff(times) if times is not None else np.empty(0)
    steps = steps[np.isfinite(steps)]
    if steps.size == 0 or np.median(steps) <= 0:
        raise TakeFormatError.at(path, "no frame rate: add a '# frame_rate=<Hz>' line or a time column")
    return float(1.0 / np.median(steps))
