"""The in-memory take (labelled marker trajectories) and the helpers every file format shares.

Inside the application positions are millimetres, time is seconds, missing samples are NaN and frame
indices are 0-based; `Take.first_frame` keeps the number the file gave to frame 0.
"""

import math
import operator
import re
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np

from handmocap.core.io.errors import FrameRateMissingError, TakeFormatError

_MM_PER_UNIT = {
    "mm": 1.0,
    "millimeter": 1.0,
    "millimeters": 1.0,
    "millimetre": 1.0,
    "millimetres": 1.0,
    "cm": 10.0,
    "centimeter": 10.0,
    "centimeters": 10.0,
    "centimetre": 10.0,
    "centimetres": 10.0,
    "m": 1000.0,
    "meter": 1000.0,
    "meters": 1000.0,
    "metre": 1000.0,
    "metres": 1000.0,
}


@dataclass(eq=False)
class Take:
    """Marker trajectories of one recording.

    `marker_positions` is (F, M, 3) float64 in mm with NaN for missing samples; `marker_names` has
    M unique names; `frame_rate` is in Hz; `first_frame` is the file's number of frame 0;
    `frame_rate_given` is True when the rate came from the user (``--rate``, the open dialog, the
    pipeline) rather than from the file; `parameters` holds extra C3D parameter groups
    `{"GROUP": {"NAME": value}}` (str, list[str], int, float or ndarray values) that the C3D writer
    writes back.
    """

    marker_names: list[str]
    marker_positions: np.ndarray
    frame_rate: float
    first_frame: int = 1
    vendor: str = "unknown"
    source_units: str = "mm"
    source_path: str | None = None
    parameters: dict[str, dict] = field(default_factory=dict)
    frame_rate_given: bool = False

    def __post_init__(self) -> None:
        self.marker_names = list(self.marker_names)
        self.marker_positions = np.asarray(self.marker_positions, dtype=np.float64)
        positions = self.marker_positions
        if positions.ndim != 3 or positions.shape[2] != 3:
            raise self._error(f"marker positions must have shape (frames, markers, 3), got {positions.shape}")
        if len(self.marker_names) != positions.shape[1]:
            raise self._error(f"{len(self.marker_names)} marker names for {positions.shape[1]} markers")
        for name in self.marker_names:
            if not isinstance(name, str) or not name.strip():
                raise self._error(f"invalid marker name {name!r}")
        seen: set[str] = set()
        for name in self.marker_names:
            if name in seen:
                raise self._error(f"duplicate marker name '{name[:80]}'")
            seen.add(name)
        if np.isinf(positions).any():
            raise self._error("marker positions contain infinite values")
        try:
            self.frame_rate = float(self.frame_rate)
            self.first_frame = operator.index(self.first_frame)
        except (TypeError, ValueError) as error:
            raise self._error(f"invalid frame rate or first frame ({error})") from None
        if not (math.isfinite(self.frame_rate) and self.frame_rate > 0):
            raise self._error(f"frame rate must be a positive number of Hz, got {self.frame_rate}")
        if self.first_frame < 0:
            raise self._error(f"first frame number must be >= 0, got {self.first_frame}")
        if not all(isinstance(group, dict) for group in self.parameters.values()):
            raise self._error("parameters must be a dict of parameter groups {'GROUP': {'NAME': value}}")

    def _error(self, problem: str) -> TakeFormatError:
        return TakeFormatError.at(self.source_path, problem)

    @property
    def n_frames(self) -> int:
        """Number of frames F."""
        return self.marker_positions.shape[0]

    @property
    def n_markers(self) -> int:
        """Number of markers M."""
        return self.marker_positions.shape[1]

    @property
    def duration_s(self) -> float:
        """Duration in seconds: F / frame_rate."""
        return self.n_frames / self.frame_rate

    @property
    def missing_mask(self) -> np.ndarray:
        """(F, M) bool: True where the marker has no position in that frame."""
        return np.isnan(self.marker_positions).any(axis=2)

    @property
    def missing_fraction(self) -> float:
        """Share of missing (frame, marker) samples, 0..1 (0 for an empty take)."""
        mask = self.missing_mask
        return float(mask.mean()) if mask.size else 0.0

    @property
    def missing_fraction_per_marker(self) -> np.ndarray:
        """(M,) share of frames where each marker is missing, 0..1 (zeros when F = 0)."""
        if self.n_frames == 0:
            return np.zeros(self.n_markers)
        return self.missing_mask.mean(axis=0)


def mm_per_unit(units: str, path: str | PathLike[str] | None) -> float:
    """Millimetres in one `units` ("mm", "cm", "m" or their long names, any case)."""
    factor = _MM_PER_UNIT.get(units.strip().lower())
    if factor is None:
        raise TakeFormatError.at(path, f"unsupported length units '{units}' (expected mm, cm or m)")
    return factor


def chosen_frame_rate(path: str | PathLike[str] | None, in_file: float | None, given: float | None,
                      why_missing: str = "the file has no frame rate") -> float:
    """The rate (Hz) a take is read with: ``given`` (the user's, it overrides the file's) when not None,
    else ``in_file``; FrameRateMissingError (``why_missing``) when neither is there, TakeFormatError when
    the given one is not a positive number."""
    if given is not None:
        return check_frame_rate(given, path)
    if in_file is None:
        raise FrameRateMissingError.at_file(path, why_missing)
    return in_file


def check_frame_rate(rate: float, path: str | PathLike[str] | None = None) -> float:
    """``rate`` (Hz) as a float once it is a finite positive number; TakeFormatError otherwise."""
    try:
        value = float(rate)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise TakeFormatError.at(path, f"the frame rate must be a positive number of Hz, not {rate!r:.40}")
    return value


def positive_number(text: str) -> float | None:
    """The finite positive number ``text`` holds (a rate, a scale), None when it holds none."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) and value > 0 else None


def zeros_to_nan(positions: np.ndarray) -> np.ndarray:
    """Mark vendor "missing" samples, exactly (0, 0, 0), as NaN in place; (F, M, 3) in and out."""
    positions[(positions == 0.0).all(axis=2)] = np.nan
    return positions


def unique_marker_names(names: list[str]) -> list[str]:
    """Strip names, name blank ones `*<i>` (1-based column; the C3D convention of an unlabelled point, so
    :func:`is_marker_label` keeps them unlabelled) and suffix repeats `_2`, `_3`... .

    Linear time: the next free suffix of each name is remembered, so each taken name is passed over at
    most once (a name "A_3" can only be the third copy of "A").
    """
    result: list[str] = []
    taken: set[str] = set()
    last_copy: dict[str, int] = {}
    for index, raw in enumerate(names):
        base = raw.strip() or f"*{index + 1}"
        name = base
        if name in taken:
            copy = last_copy.get(base, 1)
            while name in taken:
                copy += 1
                name = f"{base}_{copy}"
            last_copy[base] = copy
        taken.add(name)
        result.append(name)
    return result


#: text cells parsed per block: bounds the Python objects alive at once (about 32 bytes a cell)
_CELLS_PER_BLOCK = 1 << 20
_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")


@contextmanager
def open_text_lines(path: str | PathLike[str]) -> Iterator[Iterator[tuple[int, str]]]:
    """The lines of a text take as (1-based number, text without the line end), read as they are consumed.

    UTF-8 with or without a BOM (a line that is not UTF-8 is read as Latin-1), or UTF-16 recognised by its
    BOM or, without one, by the zero bytes of its ASCII characters.
    """
    path = Path(path)
    with path.open("rb") as stream:
        start = stream.read(4096)
    even, odd = start[0::2], start[1::2]
    if start[:2] in _UTF16_BOMS:
        encoding, errors = "utf-16", "replace"
    elif odd and odd.count(0) == len(odd) and 0 not in even:
        encoding, errors = "utf-16-le", "replace"
    elif even and even.count(0) == len(even) and 0 not in odd:
        encoding, errors = "utf-16-be", "replace"
    else:  # binary files too: the format's own checks then say what is missing
        encoding, errors = "utf-8-sig", "surrogateescape"
    with path.open(encoding=encoding, errors=errors) as stream:
        yield ((number, _latin1_if_undecodable(line.rstrip("\n"))) for number, line in enumerate(stream, 1))


def _latin1_if_undecodable(line: str) -> str:
    """A line decoded with "surrogateescape", decoded again as Latin-1 when it was not UTF-8."""
    if line.isascii() or not any("\udc80" <= char <= "\udcff" for char in line):
        return line
    return line.encode("utf-8", "surrogateescape").decode("latin-1")


def read_number_rows(lines: Iterable[tuple[int, str]], width: int, delimiter: str,
                     path: str | PathLike[str]) -> np.ndarray:
    """(N, width) float64 from numbered text rows: blank rows skipped, blank or absent cells NaN, cells past
    `width` ignored.

    Rows are parsed in blocks of about :data:`_CELLS_PER_BLOCK` cells, so the memory in use peaks near twice
    the table. Every cell of a row takes at least one byte (its delimiter or the line end), so a table with
    more cells than the file has bytes is made of rows that lack most of their cells: it is refused before
    it is allocated.
    """
    file_size = Path(path).stat().st_size
    rows_per_block = max(1, _CELLS_PER_BLOCK // max(width, 1))
    blocks: list[np.ndarray] = []
    block: list[tuple[int, str]] = []
    n_rows = 0
    for number, line in lines:
        if not line.strip():
            continue
        block.append((number, line))
        if len(block) == rows_per_block:
            n_rows = _check_cells(n_rows + len(block), width, file_size, path)
            blocks.append(_parse_block(block, width, delimiter, path))
            block = []
    if block:
        n_rows = _check_cells(n_rows + len(block), width, file_size, path)
        blocks.append(_parse_block(block, width, delimiter, path))
    return np.concatenate(blocks) if blocks else np.empty((0, width))


def _check_cells(n_rows: int, width: int, file_size: int, path: str | PathLike[str]) -> int:
    """`n_rows`, after checking that `n_rows` x `width` cells are no more than the file's bytes."""
    if n_rows * width > file_size:
        raise TakeFormatError.at(path, f"{n_rows} rows of {width} columns are more cells than the file has "
                                       f"bytes ({file_size}): the rows lack most of their cells")
    return n_rows


def _parse_block(block: list[tuple[int, str]], width: int, delimiter: str, path: str | PathLike[str]) -> np.ndarray:
    """(len(block), width) float64 of numbered rows; blank or absent cells NaN."""
    padding = [""] * width
    try:
        values = [float(cell) if cell else math.nan
                  for _, line in block for cell in (line.split(delimiter, width) + padding)[:width]]
    except ValueError:
        values = []
        for number, line in block:
            for column, cell in enumerate((line.split(delimiter, width) + padding)[:width]):
                try:
                    values.append(float(cell) if cell.strip() else math.nan)
                except ValueError:
                    shown = ascii(cell.strip()[:20])
                    raise TakeFormatError.at(path, f"line {number}, column {column + 1}: {shown} is not a number"
                                             ) from None
    return np.array(values, dtype=np.float64).reshape(len(block), width)


def format_number_rows(first_frame: int, frame_rate: float, positions: np.ndarray, delimiter: str) -> str:
    """Text rows `frame, time_s, x, y, z, ...` for (F, M, 3) positions; NaN written as an empty cell."""
    n_frames = positions.shape[0]
    frames = np.arange(first_frame, first_frame + n_frames)
    table = np.column_stack([frames, (frames - first_frame) / frame_rate, positions.reshape(n_frames, -1)])
    row_format = delimiter.join(["%d"] + ["%.6f"] * (table.shape[1] - 1)) + "\n"
    return "".join(row_format % tuple(row) for row in table.tolist()).replace("nan", "")


#: point names that carry no label: the vendors' own names of unlabelled points, our simulator's, and their
#: repeats suffixed "_2" by :func:`unique_marker_names`. Every other name a file gives is a label
#: (``Marker1``, ``M7``, ``2003``, ``Channel103``, ``New 0001``).
UNLABELLED_NAME = re.compile(
    r"""^(\*\d+                         # C3D (Vicon Nexus): *12; also a point the file gives no name
       |uname\*\d+                      # BTK / Mokka: uname*3
       |unlabell?ed[ _:]?\d+             # OptiTrack Motive: Unlabeled 1003, Unlabeled_1003, Unlabeled:108
       |unidentified[ _]?\d+             # Qualisys QTM: Unidentified 7
       |(point|ghost)_\d{3,}             # our simulator: point_004 (raw takes), ghost_012 (ghosts)
      )(_\d+)?$""", re.IGNORECASE | re.VERBOSE)


def is_marker_label(name: str) -> bool:
    """True when a point ``name`` is a label the file gives a marker (``hand_top``, ``Marker1``, ``LASI``,
    ``M7``); False for an empty name and the placeholders of unlabelled points in :data:`UNLABELLED_NAME`
    (``*12``, ``Unlabeled 1003``, ``Unidentified 7``, ``point_004``)."""
    stripped = name.strip()
    return bool(stripped) and not UNLABELLED_NAME.match(stripped)


def looks_unlabelled(marker_names: list[str]) -> bool:
    """True when most of a take's point names are placeholders rather than marker labels (a raw take)."""
    if not marker_names:
        return True
    placeholders = sum(not is_marker_label(name) for name in marker_names)
    return placeholders >= 0.5 * len(marker_names)
