"""TRC takes (PathFileType 4, Motion Analysis / OpenSim), tab separated:

    PathFileType  4  (X/Y/Z)  <file name>
    DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
    100.0     100.0       3000       21          mm     100.0         1                   3000
    Frame#  Time  <name 1>        <name 2> ...
                  X1  Y1  Z1  X2  Y2  Z2 ...
    <blank line>
    1       0.000000  x  y  z  x  y  z ...

Units are "mm", "cm" or "m" (converted to mm on reading; written in mm unless asked). Missing samples
are empty cells (also "NaN" or (0, 0, 0) on reading). The first frame number is the first Frame# cell.

Written as OpenSim's TRC reader (``TRCFileAdapter``) expects: exactly the eight header keys above in
that order with eight values; the marker name row ``Frame#``, ``Time`` then each name followed by three
tabs; the ``X1 Y1 Z1 ...`` row after two tabs; one blank line; data rows of exactly 2 + 3 x markers
cells, each row ending in a tab like OpenSim's own writer (its reader drops an empty last cell, so a
row whose last marker is missing would otherwise be a cell short), empty cells for missing samples
and no blank line inside the data. OpenSim models are Y up in metres: write with ``units="m"`` and
``up="y"`` (:mod:`core.io.axes`).
"""

import itertools
import logging
import math
from os import PathLike
from pathlib import Path

from handmocap.core.io.axes import check_units, convert_points
from handmocap.core.io.durable import write_text_atomic
from handmocap.core.io.errors import TakeFormatError
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

_log = logging.getLogger(__name__)

_HEADER_KEYS = (
    "DataRate",
    "CameraRate",
    "NumFrames",
    "NumMarkers",
    "Units",
    "OrigDataRate",
    "OrigDataStartFrame",
    "OrigNumFrames",
)


def read_trc(path: str | PathLike[str], frame_rate: float | None = None) -> Take:
    """Read a TRC file into a Take (mm, NaN for missing) at its DataRate, or at ``frame_rate`` (Hz) when
    given; raises TakeFormatError."""
    with open_text_lines(path) as lines:
        head = [line for _, line in itertools.islice(lines, 5)]
        if len(head) < 5 or not head[0].startswith("PathFileType"):
            raise TakeFormatError.at(path, "not a TRC file (the first line must start with 'PathFileType')")
        header = dict(
            zip(
                (key.strip() for key in head[1].split("\t")),
                (value.strip() for value in head[2].split("\t")),
                strict=False,
            )
        )
        rate = chosen_frame_rate(path, _positive_number(header, "DataRate") or _positive_number(header, "CameraRate"),
                                 frame_rate, f"line 3: invalid DataRate '{header.get('DataRate', '')[:40]}'")
        units = header.get("Units") or "mm"
        scale = mm_per_unit(units, path)
        names = unique_marker_names([cell for cell in head[3].split("\t")[2:] if cell.strip()])
        declared = header.get("NumMarkers", "")
        if declared.isascii() and declared.isdigit() and declared.lstrip("0") != str(len(names)).lstrip("0"):
            _log.warning(
                "%s: NumMarkers says %s, the file names %d markers", Path(path).name, declared[:20], len(names)
            )
        table = read_number_rows(lines, 2 + 3 * len(names), "\t", path)
    positions = zeros_to_nan(table[:, 2:].reshape(len(table), len(names), 3)) * scale  # a new contiguous array
    first_frame = int(table[0, 0]) if len(table) and math.isfinite(table[0, 0]) else 1
    return Take(
        marker_names=names,
        marker_positions=positions,
        frame_rate=rate,
        first_frame=first_frame,
        source_units=units,
        source_path=str(path),
        frame_rate_given=frame_rate is not None,
    )


def write_trc(take: Take, path: str | PathLike[str], units: str = "mm", up: str = "z") -> None:
    """Write `take` as a TRC file in ``units`` ("mm", "cm", "m") with ``up`` ("z" as recorded, or "y"),
    missing samples as empty cells (module docstring), atomically."""
    unusable = [name for name in take.marker_names if "\t" in name or "\n" in name or "\r" in name or not name.strip()]
    if unusable:
        raise TakeFormatError.at(path, f"marker name {unusable[0]!r} is empty or contains a tab or line break")
    check_units(units)
    rate = repr(take.frame_rate)
    header = [
        f"PathFileType\t4\t(X/Y/Z)\t{Path(path).name}",
        "\t".join(_HEADER_KEYS),
        "\t".join([rate, rate, str(take.n_frames), str(take.n_markers), units, rate, str(take.first_frame),
                   str(take.n_frames)]),
        "\t".join(["Frame#", "Time"] + [f"{name}\t\t" for name in take.marker_names]),
        "\t".join(["", ""] + [f"X{i}\tY{i}\tZ{i}" for i in range(1, take.n_markers + 1)]),
        "",
    ]
    positions = convert_points(take.marker_positions, units, up) if (units, up) != ("mm", "z") \
        else take.marker_positions
    body = format_number_rows(take.first_frame, take.frame_rate, positions, "\t").replace("\n", "\t\n")
    write_text_atomic(path, "\n".join(header) + "\n" + body)


def _positive_number(header: dict[str, str], key: str) -> float | None:
    try:
        value = float(header.get(key, ""))
    except ValueError:
        return None
    return value if math.isfinite(value) and value > 0 else None
