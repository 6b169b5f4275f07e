"""Labelled C3D export and import, with the provenance of every sample.

Points: the labels first (``POINT:LABELS`` = the label names, e.g. the layout's markers, ``R_``/``L_``
prefixed for two hands), then optionally the unlabelled points as ``*<column>`` (one C3D point per raw
column that is unlabelled in some frame, holding that column's point in the frames where no label
took it — so a fragmented raw export keeps its trajectories). Coordinates are written as float32 in
mm through :func:`core.io.c3d_writer.write_c3d_points` (streamed): a measured sample is exactly the input point (bit for
bit when the input came from a float C3D; other inputs are rounded to float32, under 0.1 µm at 1 m).
Filled samples are written too, as valid points.

Residual word (C3D standard, see :mod:`core.io.c3d_writer`): -1 for a missing sample; 0 for a filled
sample (the standard's "valid, not the measured value": interpolated or modelled); for a measured
sample its residual in units of ``|POINT:SCALE|`` mm, at least 1: the labelling/IK residual (distance
from the solved hand's marker to the point) where the review has one, else 1 (measured, residual not
known). The fill method of each filled sample is kept exactly by the ``PROVENANCE`` group.

``PROVENANCE`` parameter group (C3D parameters are limited to 255 per dimension, so per-sample codes
are run-length encoded and split over numbered parameters, like ``POINT:LABELS2``):

* ``FORMAT`` (int) 1; ``SOFTWARE`` (text); ``DESCRIPTION`` (text, this scheme in one line);
* ``LABELLED`` (int): the number of labelled points (the first points; the rest are ``*n``);
* ``CODES`` (text list): the code legend ``-1 missing, 0 measured, 1 linear, 2 spline, 3 pattern,
  4 rigid, 5 model, 6 PCA``;
* ``RUNS``, ``RUNS2``, ``RUNS3``... (float, dims 4 × n ≤ 255): one column per run of a labelled
  point's samples whose code is not 0 (measured): point index (0-based in ``POINT:LABELS``), first
  frame (0-based from the file's first frame), number of frames, code. Samples not covered are
  measured (0). Frame numbers are exact in float32 up to 16 777 216;
* ``EDITED``, ``EDITED2``... (float, 3 × n): runs of samples whose label was set by hand: point,
  first frame, number of frames;
* ``GHOSTS``, ``GHOSTS2``... (float, 3 × n): runs of unlabelled (``*n``) samples judged ghosts;
* ``SOURCE`` (text): the raw take the labels were made from; ``HANDS`` (text list, optional):
  ``"<name>:<side>:<layout>"`` per solved hand.

``HAND_SUBJECT`` parameter group (optional; :class:`SubjectCalibration`): the subject calibration the
labelling fitted to each hand, relative to the shipped template of its side, so that a solve of the
labelled file uses the subject's hand: ``FORMAT`` 1, ``SIDES`` (text list), then per side ``RIGHT_``/
``LEFT_``: ``LAYOUT`` (text), ``MARKERS`` (text list, the layout's marker order), ``SCALES`` (float, 15:
joint offset scales of joints 1..15), ``OFFSETS`` (float, 3·M: marker offsets in mm in the rest pose,
x, y, z per marker). The group is copied on when the file is filled or exported again.

Other parameter groups of the source take are copied when they can be written.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np

from handmocap.core.errors import InputError
from handmocap.core.io.c3d_file import _INTEL, ParameterValue, _parse, read_c3d
from handmocap.core.io.c3d_writer import RESIDUAL_PROCESSED, write_c3d_points
from handmocap.core.io.errors import TakeFormatError
from handmocap.core.io.take import Take

_log = logging.getLogger(__name__)

GROUP = "PROVENANCE"
FORMAT_VERSION = 1
RUN_LIMIT = 255  # C3D: at most 255 per dimension
CODE_LEGEND = ["-1 missing", "0 measured", "1 linear fill", "2 spline fill", "3 pattern fill", "4 rigid body fill",
               "5 model fill", "6 PCA fill"]
DESCRIPTION = ("per-sample provenance of the labelled points: RUNS* (point, first frame, frames, code), "
               "samples not in a run are measured; EDITED* and GHOSTS* runs (point, first frame, frames)")
UNLABELLED_PREFIX = "*"
SUBJECT_GROUP = "HAND_SUBJECT"
SUBJECT_SCALES = 15


@dataclass
class LabelledC3D:
    """A labelled C3D read back: ``take`` holds every point of the file (labels first, then the
    unlabelled ``*n`` points); ``n_labels`` labelled points; ``provenance (F, n_labels)`` int8 codes;
    ``edited (F, n_labels)`` bool; ``ghost (F, P - n_labels)`` bool for the unlabelled points;
    ``residuals_mm (F, n_labels)``: the residual the file stores for measured samples (NaN none or not
    known); ``source``: the raw take it came from; ``hands``: ``"name:side:layout"`` strings. A C3D without
    a PROVENANCE group reads as all-labelled, measured where present."""

    take: Take
    n_labels: int
    provenance: np.ndarray
    edited: np.ndarray
    ghost: np.ndarray
    source: str | None = None
    hands: list[str] | None = None
    residuals_mm: np.ndarray | None = None

    @property
    def label_names(self) -> list[str]:
        return self.take.marker_names[:self.n_labels]

    @property
    def labelled_positions(self) -> np.ndarray:
        """``(F, n_labels, 3)`` mm, measured and filled samples."""
        return self.take.marker_positions[:, :self.n_labels]

    @property
    def unlabelled_positions(self) -> np.ndarray:
        """``(F, P - n_labels, 3)`` mm."""
        return self.take.marker_positions[:, self.n_labels:]


def encode_runs(values: np.ndarray, skip: int = 0) -> np.ndarray:
    """Runs of equal values along frames of ``values (F, N)`` int, except runs of ``skip``:
    ``(4, R)`` float64 rows point, first frame, length, value (ordered by point then frame)."""
    values = np.asarray(values)
    frames, count = values.shape
    if frames == 0 or count == 0:
        return np.zeros((4, 0))
    change = np.ones((frames, count), dtype=bool)
    change[1:] = values[1:] != values[:-1]
    point, start = np.nonzero(change.T)
    ends = np.append(start[1:], frames)
    ends[np.append(point[1:] != point[:-1], True)] = frames
    value = values[start, point]
    keep = value != skip
    return np.vstack([point[keep], start[keep], (ends - start)[keep], value[keep]]).astype(np.float64)


def decode_runs(runs: np.ndarray, shape: tuple[int, int], default: int = 0, dtype: type = np.int8) -> np.ndarray:
    """Inverse of :func:`encode_runs` into an array of ``shape (F, N)`` filled with ``default``; runs
    outside the shape are clipped (a damaged file never raises here)."""
    result: np.ndarray = np.full(shape, default, dtype=dtype)
    runs = np.asarray(runs, dtype=np.float64).reshape(4, -1) if np.size(runs) else np.zeros((4, 0))
    for point, start, length, value in np.rint(runs.T).astype(np.int64):
        if 0 <= point < shape[1] and length > 0:
            result[max(start, 0):max(start + length, 0), point] = value
    return result


def _split(runs: np.ndarray, name: str) -> dict[str, np.ndarray]:
    """``{NAME: runs[:, :255], NAME2: runs[:, 255:510], ...}`` (nothing when there are no runs)."""
    parts = {}
    for index, first in enumerate(range(0, runs.shape[1], RUN_LIMIT)):
        parts[name if index == 0 else f"{name}{index + 1}"] = np.ascontiguousarray(runs[:, first:first + RUN_LIMIT])
    return parts


def _joined(parameters: dict, name: str, rows: int) -> np.ndarray:
    """The runs of ``NAME``, ``NAME2``... concatenated, ``(rows, R)``."""
    parts = []
    for index in range(1, 10_000):
        key = name if index == 1 else f"{name}{index}"
        if key not in parameters:
            break
        value = np.asarray(parameters[key], dtype=np.float64)
        if value.size % rows:
            raise InputError(f"{GROUP}:{key} has {value.size} values, not a multiple of {rows}")
        parts.append(value.reshape(rows, -1, order="F") if value.ndim < 2 else value.reshape(rows, -1))
    return np.concatenate(parts, axis=1) if parts else np.zeros((rows, 0))


def write_labelled_c3d(path: str | PathLike[str], label_names: list[str], positions: np.ndarray,
                       provenance: np.ndarray, frame_rate: float, first_frame: int = 1, *,
                       edited: np.ndarray | None = None, unlabelled: np.ndarray | None = None,
                       unlabelled_names: list[str] | None = None, ghost: np.ndarray | None = None,
                       source: str | None = None, hands: list[str] | None = None,
                       parameters: dict[str, dict] | None = None, residuals_mm: np.ndarray | None = None) -> None:
    """Write a labelled C3D (scheme in the module docstring), atomically.

    ``positions (F, M, 3)`` mm: measured and filled samples of the M labels (NaN missing);
    ``provenance (F, M)`` codes (0 measured, a fill method's code as core.gaps.provenance_names, -1 missing);
    ``edited (F, M)`` bool; ``residuals_mm (F, M)``: the measured samples' residuals (NaN not known);
    ``unlabelled (F, U, 3)`` mm named ``unlabelled_names`` (default ``*0``, ``*1``...), ``ghost (F, U)``
    bool; ``parameters``: other groups to copy (a group the writer cannot store is dropped with a
    warning). The points are streamed to the file, never joined in memory. Raises TakeFormatError (one
    line) when the take cannot be stored as C3D, WriteError when the file cannot be written (the old file
    is then kept).
    """
    positions = np.asarray(positions, dtype=np.float64)
    frames, count = positions.shape[:2]
    provenance = np.asarray(provenance)
    if provenance.shape != (frames, count):
        raise TakeFormatError.at(path, f"provenance must be {(frames, count)}, got {provenance.shape}")
    present = np.isfinite(positions).all(axis=2)
    codes = np.where(present, np.where(provenance == -1, 0, provenance), -1).astype(np.int8)  # codes -1..6
    edited = np.zeros((frames, count), dtype=bool) if edited is None else np.asarray(edited, dtype=bool)
    residuals = np.full((frames, count), np.nan) if residuals_mm is None else np.asarray(residuals_mm, float)
    if residuals.shape != (frames, count):
        raise TakeFormatError.at(path, f"residuals must be {(frames, count)}, got {residuals.shape}")
    residuals = np.where(codes > 0, RESIDUAL_PROCESSED, np.where(residuals > 0, residuals, np.nan))
    names = list(label_names)
    columns = [positions]
    unlabelled_count = 0
    ghost_runs = np.zeros((3, 0))
    if unlabelled is not None and np.size(unlabelled):
        unlabelled = np.asarray(unlabelled)
        unlabelled_count = unlabelled.shape[1]
        names += list(unlabelled_names or [f"{UNLABELLED_PREFIX}{i}" for i in range(unlabelled_count)])
        columns.append(unlabelled)
        if ghost is not None:
            ghost_runs = encode_runs(np.asarray(ghost, dtype=np.int8))[:3]
            ghost_runs[0] += count
    group: dict[str, ParameterValue] = {
        "FORMAT": FORMAT_VERSION, "SOFTWARE": "Hand Mocap Studio", "DESCRIPTION": DESCRIPTION,
        "LABELLED": int(count), "CODES": CODE_LEGEND,
    }
    group.update(_split(encode_runs(codes), "RUNS"))
    group.update(_split(encode_runs(edited.astype(np.int8))[:3], "EDITED"))
    group.update(_split(ghost_runs, "GHOSTS"))
    if source:
        group["SOURCE"] = str(source)
    if hands:
        group["HANDS"] = list(hands)
    kept = {name: dict(values) for name, values in (parameters or {}).items() if name.upper() != GROUP}
    block_residuals = [residuals] + [None] * (len(columns) - 1)
    try:
        write_c3d_points(path, names, columns, frame_rate, first_frame, {**kept, GROUP: group}, block_residuals)
    except TakeFormatError:
        if not kept:
            raise
        _log.warning("%s: the source take's parameter groups cannot all be written; writing without them",
                     Path(path).name)
        write_c3d_points(path, names, columns, frame_rate, first_frame, {GROUP: group}, block_residuals)


def read_labelled_c3d(path: str | PathLike[str]) -> LabelledC3D:
    """Read a labelled C3D written by :func:`write_labelled_c3d` (or any labelled C3D: without a
    PROVENANCE group every point is a label, measured where present). Raises TakeFormatError."""
    take = read_c3d(path)
    frames, points = take.n_frames, take.n_markers
    group = take.parameters.get(GROUP)
    present = np.isfinite(take.marker_positions).all(axis=2)
    if not isinstance(group, dict) or "LABELLED" not in group:
        starred = [name.startswith(UNLABELLED_PREFIX) for name in take.marker_names]
        count = starred.index(True) if True in starred and all(starred[starred.index(True):]) else points
        provenance = np.where(present[:, :count], 0, -1).astype(np.int8)
        return LabelledC3D(take, count, provenance, np.zeros((frames, count), dtype=bool),
                           np.zeros((frames, points - count), dtype=bool))
    try:
        count = int(np.asarray(group["LABELLED"]).ravel()[0])
        if not 0 <= count <= points:
            raise ValueError(f"{count} labelled points of {points}")
        runs = _joined(group, "RUNS", 4)
        edited_runs = _joined(group, "EDITED", 3)
        ghost_runs = _joined(group, "GHOSTS", 3)
    except (InputError, ValueError, TypeError, IndexError) as error:
        raise TakeFormatError.at(path, f"damaged {GROUP} parameter group ({error})") from None
    provenance = decode_runs(runs, (frames, count))
    provenance[~present[:, :count]] = -1
    provenance[present[:, :count] & (provenance == -1)] = 0
    edited = decode_runs(np.vstack([edited_runs, np.ones((1, edited_runs.shape[1]))]), (frames, count),
                         dtype=bool)
    ghost_runs = ghost_runs.copy()
    ghost_runs[0] -= count
    ghost = decode_runs(np.vstack([ghost_runs, np.ones((1, ghost_runs.shape[1]))]), (frames, points - count),
                        dtype=bool)
    source = group.get("SOURCE")
    hands = group.get("HANDS")
    hands = [hands] if isinstance(hands, str) else (list(hands) if isinstance(hands, list) else None)
    take.parameters = {name: values for name, values in take.parameters.items() if name != GROUP}
    residuals = np.where(provenance == 0, read_residuals_mm(path, frames, count), np.nan)
    return LabelledC3D(take, count, provenance, edited, ghost & present[:, count:],
                       source=source if isinstance(source, str) and source else None, hands=hands,
                       residuals_mm=residuals)


def read_residuals_mm(path: str | PathLike[str], frames: int, count: int) -> np.ndarray:
    """The residuals ``(frames, count)`` mm of the first ``count`` points of an Intel float C3D as this
    package writes them (residual byte x ``|POINT:SCALE|``); NaN where the word is not a measured residual
    (missing, filled, and 1: the value written for "measured, residual not known", so a residual under 1.5
    scale units, 0.05 mm at 1 m, also reads as not known) and for every sample of other C3D variants."""
    result = np.full((frames, count), np.nan)
    with Path(path).open("rb") as stream:
        head = stream.read(1 << 20)
    try:
        parsed = _parse(head, path)
    except TakeFormatError:
        return result
    scale = parsed.scale
    if parsed.processor != _INTEL or not scale < 0 or parsed.n_points < count or not count:
        return result
    width = 4 * parsed.n_points + parsed.analog_words_per_frame
    offset = (parsed.data_block - 1) * 512
    if Path(path).stat().st_size < offset + 4 * width * frames:
        return result
    data = np.memmap(path, dtype="<f4", mode="r", offset=offset, shape=(frames, width))
    words = np.array(data[:, 3:4 * count:4], dtype=np.float64)
    del data
    units = np.where(np.isfinite(words) & (words > 0), np.fmod(np.rint(words), 256.0), 0.0)
    return np.where(units > 1, units * abs(scale), np.nan)


@dataclass(frozen=True, eq=False)
class SubjectCalibration:
    """A hand's subject calibration relative to the shipped template of its ``side`` (Zhao et al. eq. 2):
    the ``layout`` name and its ``marker_names (M,)``, ``scales (15,)`` of the joint offsets of joints
    1..15 and ``offsets_mm (M,3)`` of the markers in the rest pose (mm)."""

    side: str
    layout: str
    marker_names: tuple[str, ...]
    scales: np.ndarray
    offsets_mm: np.ndarray

    def as_dict(self) -> dict:
        """Plain JSON form (lists of numbers)."""
        return {"side": self.side, "layout": self.layout, "marker_names": list(self.marker_names),
                "scales": np.asarray(self.scales, float).tolist(),
                "offsets_mm": np.asarray(self.offsets_mm, float).tolist()}

    @staticmethod
    def from_dict(values: dict) -> SubjectCalibration:
        """Inverse of :meth:`as_dict`; InputError when the values do not fit together."""
        try:
            names = tuple(str(name) for name in values["marker_names"])
            scales = np.asarray(values["scales"], dtype=np.float64).reshape(SUBJECT_SCALES)
            offsets = np.asarray(values["offsets_mm"], dtype=np.float64).reshape(len(names), 3)
            return SubjectCalibration(str(values["side"]), str(values["layout"]), names, scales, offsets)
        except (KeyError, TypeError, ValueError) as error:
            raise InputError(f"not a subject calibration ({error})") from None


def subject_group(calibrations: list[SubjectCalibration]) -> dict[str, object]:
    """The ``HAND_SUBJECT`` parameter group (module docstring) holding ``calibrations`` (one per side)."""
    group: dict[str, object] = {"FORMAT": FORMAT_VERSION, "SIDES": [calibration.side for calibration in calibrations]}
    for calibration in calibrations:
        prefix = calibration.side.upper()
        group[f"{prefix}_LAYOUT"] = calibration.layout
        group[f"{prefix}_MARKERS"] = list(calibration.marker_names)
        group[f"{prefix}_SCALES"] = np.asarray(calibration.scales, dtype=np.float64).reshape(SUBJECT_SCALES)
        group[f"{prefix}_OFFSETS"] = np.asarray(calibration.offsets_mm, dtype=np.float64).reshape(-1)
    return group


def subject_calibrations(parameters: dict[str, dict], source: str | PathLike[str] | None = None
                         ) -> list[SubjectCalibration]:
    """The subject calibrations a take's ``HAND_SUBJECT`` parameter group holds (none without the group).
    Raises TakeFormatError (one line) when the group is damaged."""
    group = parameters.get(SUBJECT_GROUP)
    if not isinstance(group, dict):
        return []
    try:
        sides = group["SIDES"]
        calibrations = []
        for side in [sides] if isinstance(sides, str) else list(sides):
            prefix = str(side).strip().upper()
            markers = group[f"{prefix}_MARKERS"]
            markers = tuple(str(name).strip() for name in ([markers] if isinstance(markers, str) else markers))
            scales = np.asarray(group[f"{prefix}_SCALES"], dtype=np.float64).reshape(SUBJECT_SCALES)
            offsets = np.asarray(group[f"{prefix}_OFFSETS"], dtype=np.float64).reshape(len(markers), 3)
            if not (np.isfinite(scales).all() and np.isfinite(offsets).all()):
                raise ValueError("values that are not finite")
            calibrations.append(SubjectCalibration(str(side).strip().lower(), str(group[f"{prefix}_LAYOUT"]).strip(),
                                                   markers, scales, offsets))
    except (KeyError, ValueError, TypeError) as error:
        raise TakeFormatError.at(source, f"damaged {SUBJECT_GROUP} parameter group ({error})") from None
    return calibrations
