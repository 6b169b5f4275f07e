"""The in-memory take (labelled marker trajectories) and the helpers every file format shares.

Inside the application positions are millimetres, time is seconds, missing samples are NaN and frame
indices are 0-based; `Take.first_frame` keeps the number the file gave to frame 0.
"""

import math
import operator
import os
import re
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np

from core.io.errors import TakeFormatError

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
    `parameters` holds extra C3D parameter groups `{"GROUP": {"NAME": value}}` (str, list[str],
    int, float or ndarray values) that the C3D writer writes back.
    """

    marker_names: list[str]
    marker_positions: np.ndarray
    frame_rate: float
    first_frame: int = 1
    vendor: str = "unknown"
    source_units: str = "mm"
    source_path: str | None = None
    parameters: dict[str, dict] = field(default_factory=dict)

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
        if len(set(self.marker_names)) != len(self.marker_names):
            duplicate = next(n for n in self.marker_names if self.marker_names.count(n) > 1)
            raise self._error(f"duplicate marker name '{duplicate}'")
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


def zeros_to_nan(positions: np.ndarray) -> np.ndarray:
    """Mark vendor "missing" samples, exactly (0, 0, 0), as NaN in place; (F, M, 3) in and out."""
    positions[(positions == 0.0).all(axis=2)] = np.nan
    return positions


def unique_marker_names(names: list[str]) -> list[str]:
    """Strip names, name blank ones `M<i>` (1-based column) and suffix repeats `_2`, `_3`... ."""
    result: list[str] = []
    taken: set[str] = set()
    for index, raw in enumerate(names):
        base = raw.strip() or f"M{index + 1}"
        name, copy = base, 1
        while name in taken:
            copy += 1
            name = f"{base}_{copy}"
        taken.add(name)
        result.append(name)
    return result


def read_text(path: str | PathLike[str]) -> str:
    """The whole text file, decoded as UTF-8 (with BOM) or, failing that, Latin-1."""
    raw = Path(path).read_bytes()
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def parse_number_rows(rows: list[tuple[int, list[str]]], width: int, path: str | PathLike[str]) -> np.ndarray:
    """(N, width) float64 from text rows given as (line number, cells); blank or absent cells -> NaN."""
    padding = [""] * width
    try:
        values = [
            [float(cell) if cell else math.nan for cell in (cells + padding)[:width]] for _, cells in rows
        ]
    except ValueError:
        values = []
        for line_number, cells in rows:
            row = []
            for column, cell in enumerate((cells + padding)[:width]):
                try:
                    row.append(float(cell) if cell.strip() else math.nan)
                except ValueError:
                    raise TakeFormatError.at(
                        path,
                        f"line {line_number}, column {column + 1}: '{cell.strip()[:20]}' is not a number",
                    ) from None
            values.append(row)
    return np.array(values, dtype=np.float64).reshape(len(rows), width)


def format_number_rows(first_frame: int, frame_rate: float, positions: np.ndarray, delimiter: str) -> str:
    """Text rows `frame, time_s, x, y, z, ...` for (F, M, 3) positions; NaN written as an empty cell."""
    n_frames = positions.shape[0]
    frames = np.arange(first_frame, first_frame + n_frames)
    table = np.column_stack([frames, (frames - first_frame) / frame_rate, positions.reshape(n_frames, -1)])
    row_format = delimiter.join(["%d"] + ["%.6f"] * (table.shape[1] - 1)) + "\n"
    return "".join(row_format % tuple(row) for row in table.tolist()).replace("nan", "")


@contextmanager
def atomic_target(path: str | PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to `path`; on success it replaces `path` at once, else it is removed."""
    target = Path(path)
    temporary = target.with_name(f".{target.name}.{secrets.token_hex(4)}{target.suffix.lower()}")
    try:
        yield temporary
        os.replace(temporary, target)
    finally:
        temporary.unlink(missing_ok=True)


#: point names that carry no label: "*12" (Vicon), "Unlabeled 3" (Motive), "point_004", "M7", "2003", and
#: their repeats suffixed "_2" by :func:`unique_marker_names`
UNLABELLED_NAME = re.compile(r"^(\*|point[_ ]?|unlabell?ed[_ ]?|unidentified[_ ]?|unnamed[_ ]?|uname\*?|marker[_ ]?|m|"
                             r"channel|ghost[_ ]?)?\d*(_\d+)?$", re.IGNORECASE)


def is_marker_label(name: str) -> bool:
    """True when a point ``name`` is a label someone gave a marker (``hand_top``, ``pillow_left``, ``LASI``);
    False for the placeholders of unlabelled points: empty, ``*12`` (C3D/Vicon), ``Unlabeled 3``
    (Motive), ``point_004``, ``M001`` (an unnamed column), bare numbers (see :data:`UNLABELLED_NAME`)."""
    stripped = name.strip()
    return bool(stripped) and not UNLABELLED_NAME.match(stripped)


def looks_unlabelled(marker_names: list[str]) -> bool:
    """True when most of a take's point names are placeholders rather than marker labels (a raw take)."""
    if not marker_names:
        return True
    placeholders = sum(not is_marker_label(name) for name in marker_names)
    return placeholders >= 0.5 * len(marker_names)
